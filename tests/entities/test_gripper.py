"""Parallel gripper: opens, closes, is enclosed, and really holds a cube."""

import numpy as np
import pytest
from dm_control import mjcf
from scipy import optimize

from hrc_suite import layout
from hrc_suite.control import controller as controller_lib
from hrc_suite.control import trajectory
from hrc_suite.entities import collision_groups
from hrc_suite.entities import gripper as gripper_lib
from hrc_suite.entities import robot as robot_lib
from hrc_suite.entities import workcell as workcell_lib
import entity_references   # tests/entities/entity_references.py


def _base(description):
  """World pose of the robot's base on its mount (layout.robot_mount)."""
  return layout.robot_mount(description.name).base_pose()

CUBE_HALF = 0.02   # m: the 4 cm cube.
CUBE_MASS = 0.1    # kg


def _gripper_alone():
  gripper = gripper_lib.ParallelGripper()
  gripper.mjcf_model.option.timestep = workcell_lib.PHYSICS_TIMESTEP
  return gripper, mjcf.Physics.from_mjcf_model(gripper.mjcf_model)


def test_opens_and_closes_over_the_full_stroke():
  gripper, physics = _gripper_alone()
  assert gripper_lib.MAX_APERTURE >= 0.08
  assert gripper_lib.ParallelGripper.TCP_OFFSET == 0.12
  gripper.set_command(physics, -1)
  physics.step(100)
  assert gripper.aperture(physics) == pytest.approx(1.0, abs=1e-3)
  opening = np.sum(physics.bind(gripper.finger_joints).qpos)
  assert opening == pytest.approx(gripper_lib.MAX_APERTURE, abs=1e-4)
  left, right = physics.bind(gripper.finger_joints).qpos
  assert left == pytest.approx(right, abs=1e-4)   # Symmetric fingers.
  gripper.set_command(physics, 1)
  physics.step(100)
  assert gripper.aperture(physics) < 1e-3
  gripper.set_command(physics, 0)   # Half way.
  physics.step(100)
  assert 0.3 < gripper.aperture(physics) < 0.7
  assert gripper.observables.aperture(physics)[0] == gripper.aperture(physics)


def test_command_is_clipped_and_checked():
  gripper, physics = _gripper_alone()
  gripper.set_command(physics, 7.0)
  assert physics.bind(gripper.actuator).ctrl == 1.0
  gripper.set_command(physics, -3.0)
  assert physics.bind(gripper.actuator).ctrl == -1.0
  with pytest.raises(ValueError, match='finite'):
    gripper.set_command(physics, float('nan'))


def _distance_to_segment(points, p1, p2):
  axis = p2 - p1
  t = np.clip((points - p1) @ axis / (axis @ axis), 0, 1)
  return np.linalg.norm(points - (p1 + t[:, None] * axis), axis=1)


@pytest.mark.parametrize('command', [-1.0, 1.0])
def test_enclosing_capsule_covers_every_geom(command):
  gripper, physics = _gripper_alone()
  gripper.set_command(physics, command)
  physics.step(100)
  p1, p2, radius = gripper.enclosing_capsule()
  geoms = physics.bind(gripper.geoms)
  signs = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1).T
  for pos, mat, size, kind in zip(geoms.xpos, geoms.xmat, geoms.size,
                                  physics.model.geom_type[geoms.element_id]):
    half = size if kind == 6 else np.array([size[0], size[0], size[1]])
    corners = pos + (signs * half) @ mat.reshape(3, 3).T   # box / cylinder
    assert _distance_to_segment(corners, p1, p2).max() <= radius + 1e-9
  assert radius < 0.08 and p2[2] - p1[2] < 0.2   # And it is not loose.


# --- Grasping: a 4 cm cube picked from the table, lifted and carried. ---


def _tcp_pose(description, q):
  flange = description.forward_kinematics(q, base=_base(description))[-1] @ (
      description.flange_transform())
  return flange[:3, 3] + flange[:3, 2] * gripper_lib.TCP_OFFSET, flange[:3, :3]


def _gripper_down_at(description, target, q0):
  """Joint vector with the TCP at target, gripper pointing down and its
  fingers closing along world x or y (so they meet the cube's faces).

  Least squares from q0, then from seeded random starts if that fails.
  """
  def residual(q):
    position, rot = _tcp_pose(description, q)
    return np.concatenate([position - target, 0.3 * (rot[:, 2] - [0, 0, -1]),
                           [0.3 * rot[0, 0] * rot[1, 0]]])
  lim = description.limits
  starts = [q0] + list(np.random.RandomState(0).uniform(
      np.maximum(lim.q_min, -3), np.minimum(lim.q_max, 3),
      (50, description.dof)))
  for start in starts:
    solution = optimize.least_squares(residual, start,
                                      bounds=(lim.q_min, lim.q_max))
    if np.abs(residual(solution.x)).max() < 1e-6:
      return solution.x
  raise AssertionError(f'no gripper-down pose at {target}')


def _grasp_scene(name):
  arena = workcell_lib.Workcell()
  robot = robot_lib.make_robot(name)
  gripper = robot.attach_gripper(gripper_lib.ParallelGripper())
  arena.attach_robot(robot)
  # 0.4 m ahead of the robot's base (the raised mounts stand at the
  # table's edge: layout.ROBOT_MOUNTS).
  base_x = layout.robot_mount(name).base_position[0]
  cube_position = np.array([base_x + 0.4, 0.05,
                            layout.TABLE_TOP_Z + CUBE_HALF])
  cube = arena.mjcf_model.worldbody.add('body', name='cube',
                                        pos=cube_position)
  cube.add('freejoint')
  collision_groups.set_object(cube.add(
      'geom', type='box', size=[CUBE_HALF] * 3, mass=CUBE_MASS))
  physics = mjcf.Physics.from_mjcf_model(arena.mjcf_model)
  return robot, gripper, cube, cube_position, physics


@pytest.mark.parametrize('name', robot_lib.ROBOTS)
def test_picks_lifts_and_carries_a_cube_for_five_seconds(name):
  robot, gripper, cube, cube_position, physics = _grasp_scene(name)
  description = robot.description
  lim = description.limits
  centre = np.where((lim.q_min <= 0) & (lim.q_max >= 0), 0.0,
                    (lim.q_min + lim.q_max) / 2)
  q_above = _gripper_down_at(description, cube_position + [0, 0, 0.15],
                             centre + 0.3)
  q_grasp = _gripper_down_at(description, cube_position, q_above)
  q_far = _gripper_down_at(description, cube_position + [0.0, -0.2, 0.12],
                           q_above)
  robot.set_joint_positions(physics, q_above)
  physics.forward()
  controller = controller_lib.JointTrackingController(physics, robot)
  cube_body = physics.bind(cube)
  tcp = physics.bind(robot.tcp_site)

  def follow(path, command, check=None):
    for q, dq, ddq in zip(*path):
      controller(physics, q, dq, ddq)
      gripper.set_command(physics, command)
      physics.step()
      if check:
        check()

  def rest(q, steps):
    zeros = np.zeros((steps, description.dof))
    return np.repeat(q[None], steps, 0), zeros, zeros

  follow(rest(q_above, 50), -1)
  assert not gripper.is_grasping(physics, cube)
  follow(trajectory.jerk_limited_trajectory(description, [q_above, q_grasp],
                                            limits='ltt'), -1)
  assert not gripper.is_grasping(physics, cube)
  follow(rest(q_grasp, 50), 1)   # Close for 0.2 s.
  assert gripper.is_grasping(physics, cube)
  held = []

  def check_held():
    held.append((gripper.is_grasping(physics, cube),
                 np.linalg.norm(cube_body.xpos - tcp.xpos)))

  # Lift and carry back and forth at the full limits, then hold: > 5 s.
  carry = trajectory.jerk_limited_trajectory(
      description, [q_grasp, q_above, q_far, q_above, q_far, q_above])
  follow(carry, 1, check_held)
  follow(rest(q_above, max(0, 1250 - len(carry[0]))), 1, check_held)
  grasping, distance = np.array(held).T
  assert len(held) * workcell_lib.PHYSICS_TIMESTEP >= 5.0
  assert grasping.all()
  # Stays between the pads: TCP to cube centre below half the cube size.
  assert distance.max() < CUBE_HALF, distance.max()
  assert cube_body.xpos[2] > layout.TABLE_TOP_Z + 0.1
  assert 0.3 < gripper.aperture(physics) < 0.5   # Fingers on a 4 cm cube.


def test_closing_on_air_is_not_a_grasp():
  robot, gripper, cube, cube_position, physics = _grasp_scene('ur5e')
  q = _gripper_down_at(robot.description, cube_position + [0, 0, 0.1],
                       np.array([0.0, -1.2, 1.5, 1.2, 1.57, 1.5]))
  robot.set_joint_positions(physics, q)
  physics.forward()
  controller = controller_lib.JointTrackingController(physics, robot)
  for _ in range(100):
    controller(physics, q, np.zeros(6), np.zeros(6))
    gripper.set_command(physics, 1)
    physics.step()
  assert gripper.aperture(physics) < 0.01
  assert not gripper.is_grasping(physics, cube)


@pytest.mark.parametrize('grip_force', [gripper_lib.GRIP_FORCE, 100.0])
def test_squeezes_a_3cm_block_with_its_grip_force(grip_force):
  gripper = gripper_lib.ParallelGripper(grip_force=grip_force)
  assert gripper.grip_force == grip_force
  block = gripper.mjcf_model.worldbody.add(
      'geom', name='block', type='box', size=(0.01, 0.015, 0.01),
      pos=(0, 0, gripper_lib.TCP_OFFSET))
  collision_groups.set_object(block)
  gripper.mjcf_model.option.timestep = workcell_lib.PHYSICS_TIMESTEP
  physics = mjcf.Physics.from_mjcf_model(gripper.mjcf_model)
  gripper.set_command(physics, 1.0)
  physics.step(200)
  assert np.sum(physics.bind(gripper.finger_joints).qpos) == pytest.approx(
      0.03, abs=2e-3)
  assert -physics.bind(gripper.actuator).force == pytest.approx(
      grip_force, rel=0.05)


def test_grip_force_outside_the_2f85_range_is_rejected():
  for bad in (10.0, 300.0, float('nan')):
    with pytest.raises(ValueError, match=r'grip_force=.*\[20, 235\] N'):
      gripper_lib.ParallelGripper(grip_force=bad)


@pytest.mark.parametrize('domain, task', [('stacking', 'default'),
                                          ('handover', 'robot_to_human')])
def test_compiled_grasp_test_decides_as_the_numpy_reference(domain, task):
  """gripper_kernels.grasped against its NumPy reference on
  an expert's episode (cubes picked, a hammer held): free objects (their
  subtrees) and bodies inside the robot's tree (themselves only)."""
  from hrc_suite import experts   # pylint: disable=g-import-not-at-top
  from hrc_suite import suite   # pylint: disable=g-import-not-at-top
  env = suite.load(domain, task, task_kwargs={'robot': 'panda'},
                   environment_kwargs={'random_state': 0})
  policy = experts.make(env)
  gripper = env.task._gripper
  objects = (list(env.task._cube_bodies) if domain == 'stacking'
             else [env.task._hammer.body])
  robot_bodies = list(env.task._robot.link_bodies[-2:])
  groups = [objects, objects[:1], robot_bodies, objects + robot_bodies]
  timestep = env.reset()
  grasps = 0
  for _ in range(250):
    for bodies in groups:
      got = gripper.grasping(env.physics, bodies)
      np.testing.assert_array_equal(
          got, entity_references.grasping(gripper, env.physics, bodies))
      grasps += int(got.any())
    if timestep.last():
      break
    timestep = env.step(policy(timestep))
  assert grasps > 0   # Grasps occurred, so both branches were compared.
