"""Code the object tasks share: object/target observables relative to the
TCP, and sampling of graspable points on the table."""

from dm_control.composer.observation import observable
import numpy as np

# Sparse rewards of pick and place, also object inspection's
# (docs/reference_benchmark.md, Rewards and success): success, object
# gripped, otherwise.
SUCCESS_REWARD = 1.0
GRIPPED_REWARD = -0.25
IDLE_REWARD = -1.0


def object_reward(success, gripped):
  """The pick-and-place family's sparse reward of one RL step."""
  if success:
    return SUCCESS_REWARD
  return GRIPPED_REWARD if gripped else IDLE_REWARD


def point_observables(tcp_frame, name, position, eef_name=None, world=None):
  """Observables of a world point given by `position(physics)`.

  '{name}_position' (world; the observable `world` if given, e.g. a prop's
  own), 'eef_to_{name}' (world vector from the TCP, or `eef_name`),
  '{name}_in_eef_frame' (that vector in the TCP frame) and
  '{name}_distance' (its length, shape (1,)). tcp_frame: the robot's
  `Robot.tcp_frame` (the TCP's world position and rotation).
  """

  def eef_to(physics):
    point = position(physics)
    return point - tcp_frame(physics)[0]

  def in_eef(physics):
    point = position(physics)
    tcp, rotation = tcp_frame(physics)
    return (point - tcp) @ rotation.reshape(3, 3)

  def distance(physics):
    return np.array([np.linalg.norm(eef_to(physics))])

  if world is None:
    world = observable.Generic(
        lambda physics: np.array(position(physics), dtype=float))
  return {
      f'{name}_position': world,
      eef_name or f'eef_to_{name}': observable.Generic(eef_to),
      f'{name}_in_eef_frame': observable.Generic(in_eef),
      f'{name}_distance': observable.Generic(distance),
  }


def object_target_observables(tcp_frame, prop, target, gripped,
                              success_distance):
  """The pick-and-place family's observables: 'object_gripped' (the flag
  `gripped()` the reward used), the object's and the target's point
  observables, 'object_quaternion' (the prop's own position and quaternion
  observables) and 'object_at_target' (the prop's body origin within
  `success_distance` of `target(physics)`)."""

  def object_position(physics):
    return prop.position(physics)

  def at_target(physics):
    offset = object_position(physics) - target(physics)
    return np.array([float(np.linalg.norm(offset) <= success_distance)])

  observables = {
      'object_gripped': observable.Generic(
          lambda physics: np.array([float(gripped())])),
      'object_quaternion': prop.observables.quaternion,
      'object_at_target': observable.Generic(at_target),
  }
  observables.update(point_observables(
      tcp_frame, 'object', object_position, world=prop.observables.position))
  observables.update(point_observables(tcp_frame, 'target', target))
  return observables


def top_grasp_reachable(ik, checker, centre, q_init, grasp_above,
                        approach_height, yaw=0.0):
  """True if gripper-down IK (at `yaw`) reaches the point approach_height
  above a grasp and, from there, the grasp itself (the TCP grasp_above over
  `centre`), both free of static and self-collision (`checker`)."""
  grasp = np.asarray(centre, dtype=float) + (0.0, 0.0, grasp_above)
  above = ik.solve(grasp + (0.0, 0.0, approach_height), q_init, yaw)
  if not above.success or checker.in_collision(above.q):
    return False
  down = ik.solve(grasp, above.q, yaw)
  return bool(down.success and not checker.in_collision(down.q))


def sample_table_point(random_state, base_pose, region_x, region_y, height,
                       accept, attempts, what):
  """A world point at `height` drawn uniformly in region_x x region_y (m,
  robot base frame; a range may run downwards) until `accept(point)`.

  Raises a RuntimeError naming `what` after `attempts` rejected draws.
  """
  for _ in range(attempts):
    local = np.array([random_state.uniform(*region_x),
                      random_state.uniform(*region_y), 0.0])
    point = base_pose[:3, :3] @ local + base_pose[:3, 3]
    point[2] = height
    if accept(point):
      return point
  raise RuntimeError(f'No reachable {what} in {attempts} samples of x in '
                     f'{tuple(region_x)}, y in {tuple(region_y)} (robot '
                     'base frame)')
