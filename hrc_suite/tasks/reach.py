"""Reach: move the end effector (or the joints) to a goal while a human works
beside the robot (docs/reference_benchmark.md, Tasks).

* Goal: Cartesian action space: a TCP position uniform in the robot's table
  workspace box (`ik.table_workspace_box`, at least GOAL_MIN_HEIGHT above
  the table), kept only if gripper-down IK reaches it and the IK solution is
  free of static and self-collision; its joint solution is the joint goal.
  Joint action space: joint positions uniform within the limits, on joints
  with more than one turn within one turn around home
  (`layout.reach_joint_goal_range`), rejecting colliding ones; the goal
  position is their TCP position. Every goal keeps the robot's capsules
  on its side of the table edge beside the person
  (`layout.REACH_GOAL_MAX_Y`).
* Success: TCP within SUCCESS_DISTANCE of the goal (Cartesian) or joint
  error norm |q_goal - q| <= SUCCESS_JOINT_ERROR (joint).
* Reward: dense -0.1 x distance (m or rad), or sparse +1 on success, -1
  otherwise; illegal contacts add the collision reward. Done at success
  (configurable); horizon 100 RL steps; SSM shield; joint actions.
* Observations: 'paper' = the goal difference (goal position - TCP, or
  q_goal - q); 'full' adds everything in `HrcTask` plus the goal's world
  position, position in the TCP frame, distance, and joint difference.
"""

from dm_control.composer.observation import observable
import numpy as np

from hrc_suite import layout
from hrc_suite import suite
from hrc_suite.control import ik as ik_lib
from hrc_suite.entities import markers
from hrc_suite.tasks import base

SUCCESS_DISTANCE = 0.05        # m (reference)
SUCCESS_JOINT_ERROR = 0.1      # rad (reference)
DENSE_SCALE = 0.1              # reward per m (or rad) of distance (reference)
GOAL_MIN_HEIGHT = 0.05         # m above the table top
GOAL_ATTEMPTS = 200            # samples before giving up on a goal
GOAL_IK_RESTARTS = 5


# The lower decorator registers first: reach/dense, then reach/sparse.
@suite.register('reach', 'sparse',
                tags=('coexistence', 'sparse', 'ssm'), reward='sparse')
@suite.register('reach', 'dense', tags=('coexistence', 'dense', 'ssm'),
                reward='dense')
class Reach(base.HrcTask):
  """Reach a goal with the TCP (Cartesian) or the joints (joint)."""

  MOTIONS = 'reach'
  HUMAN_STATION = layout.HUMAN_STATION_BESIDE
  DEFAULT_SHIELD = 'ssm'
  DEFAULT_ACTION_SPACE = 'joint'
  REWARDS = ('dense', 'sparse')
  HORIZON = 100
  HAS_GRIPPER_ACTION = False
  OBSERVATION_PRESETS = {'paper': ('goal_difference',)}
  TASK_STATE = ('_goal_q', '_goal_position', '_success')

  def _build_task(self):
    # The visual-only marker hangs on a mocap attachment frame: its position
    # is physics state, so snapshots carry the goal.
    self._marker = markers.TargetMarker(name='reach_goal')
    self._marker.attach_mocap(self._arena)
    self._goal_position = np.zeros(3)
    self._goal_q = self._robot.description.q_home.copy()
    self._ik = ik_lib.InverseKinematics(self._kinematics)
    low, high = ik_lib.table_workspace_box(self._kinematics)
    low = low.copy()
    table = -layout.robot_mount(self._robot.description.name).height_above_table
    low[2] = max(low[2], table + GOAL_MIN_HEIGHT)   # Base frame.
    self._goal_box = (low, high)
    self._joint_goal_range = layout.reach_joint_goal_range(
        self._robot.description)
    self._success = False

  # --------------------------------------------------------------- goals

  @property
  def goal_position(self) -> np.ndarray:
    """(3,) world position of the episode's goal."""
    return self._goal_position.copy()

  @property
  def goal_joint_positions(self) -> np.ndarray:
    """(dof,) joint positions that reach the goal."""
    return self._goal_q.copy()

  def _beside_person(self, q):
    """Whether configuration q keeps every capsule (world) at y <=
    layout.REACH_GOAL_MAX_Y."""
    p1, p2, radii = self._collision_checker.reach.capsules(q)
    reach_y = np.maximum(p1[:, 1], p2[:, 1]) + radii
    return bool(np.all(reach_y <= layout.REACH_GOAL_MAX_Y))

  def _sample_goal(self, random_state):
    model, checker = self._kinematics, self._collision_checker
    base_pose = model.base_pose
    for _ in range(GOAL_ATTEMPTS):
      if self._action_space.name == 'joint':
        q = random_state.uniform(*self._joint_goal_range)
      else:
        local = random_state.uniform(*self._goal_box)
        target = base_pose[:3, :3] @ local + base_pose[:3, 3]
        result = self._ik.solve_with_restarts(
            target, self._robot.description.q_home, random_state,
            restarts=GOAL_IK_RESTARTS)
        if not result.success:
          continue
        q = result.q
      if not checker.in_collision(q) and self._beside_person(q):
        return q, model.tcp_pose(q)[:3, 3]
    raise RuntimeError(f'Reach: no collision-free goal at y <= '
                       f'{layout.REACH_GOAL_MAX_Y} m in {GOAL_ATTEMPTS} '
                       f'samples for {self._robot.description.name}')

  def _initialize_task(self, physics, random_state):
    self._goal_q, self._goal_position = self._sample_goal(random_state)
    self._marker.set_mocap_position(physics, self._goal_position)
    self._success = False

  # ------------------------------------------------------------ progress

  def _distance(self, physics):
    if self._action_space.name == 'joint':
      q = physics.data.qpos[self._qpos_index]
      return float(np.linalg.norm(self._goal_q - q))
    tcp = self._robot.tcp_frame(physics)[0]
    return float(np.linalg.norm(self._goal_position - tcp))

  def _update_task(self, physics):
    distance = self._distance(physics)
    threshold = (SUCCESS_JOINT_ERROR if self._action_space.name == 'joint'
                 else SUCCESS_DISTANCE)
    self._success = distance <= threshold
    self._last_distance = distance
    return {'success': float(self._success), 'goal_distance': distance}

  def _task_reward(self, physics):
    del physics
    if self.reward_kind == 'sparse':
      return 1.0 if self._success else -1.0
    return -DENSE_SCALE * self._last_distance

  def _task_reward_range(self):
    if self.reward_kind == 'sparse':
      return (-1.0, 1.0)
    model = self._kinematics
    if self._action_space.name == 'joint':
      largest = float(np.linalg.norm(model.q_max - model.q_min))
    else:  # Any two points within the robot's reach of its base.
      description = model.description
      reach = sum(np.linalg.norm(l.fixed_translation)
                  for l in description.links)
      reach += np.linalg.norm(description.flange_translation)
      reach += model.tcp_offset
      largest = float(2 * reach)
    return (-DENSE_SCALE * largest, 0.0)

  # -------------------------------------------------------- observables

  def _goal_difference(self, physics):
    if self._action_space.name == 'joint':
      return self._goal_q - physics.data.qpos[self._qpos_index]
    return self._goal_position - self._robot.tcp_frame(physics)[0]

  def _goal_in_eef(self, physics):
    xpos, xmat = self._robot.tcp_frame(physics)
    return (self._goal_position - xpos) @ xmat.reshape(3, 3)

  def _task_observables(self):
    return {
        'goal_difference': observable.Generic(self._goal_difference),
        'goal_position': observable.Generic(
            lambda physics: self._goal_position.copy()),
        'goal_in_eef_frame': observable.Generic(self._goal_in_eef),
        'goal_distance': observable.Generic(
            lambda physics: np.array([np.linalg.norm(
                self._goal_position - self._robot.tcp_frame(physics)[0])])),
        'goal_joint_difference': observable.Generic(
            lambda physics: self._goal_q
            - physics.data.qpos[self._qpos_index]),
    }


