"""Agent action spaces: an action in [-1, 1]^n becomes a joint goal.

* 'joint': q_goal = q + JOINT_STEP * a (a has one entry per joint), clipped
  into the joint limits.
* 'cartesian': the TCP target is the current TCP position + CARTESIAN_STEP *
  a[:3], kept inside a workspace box above the table; inverse kinematics
  from the current q with the gripper pointing down gives the joint goal.
  When IK fails the previous goal is kept (and the failure is counted).

Tasks with a gripper append one dimension: -1 open, +1 closed. Actions
outside [-1, 1] are clipped (documented behaviour, as in the reference);
NaN or infinite entries, wrong shapes and non-numbers (e.g. a string) raise
a ValueError. `step_goal` turns an RL step's action into the shield's new
joint goal: validation, the action space's goal (IK), collision prevention.
"""

import dataclasses
from typing import Any, Optional

from dm_env import specs
import numpy as np

from hrc_suite import layout
from hrc_suite.control import ik as ik_lib

ACTION_SPACES = ('joint', 'cartesian')
# Reference benchmark (docs/reference_benchmark.md, Actions): 0.2 rad per RL
# step in joint space, 0.1 m per RL step in the workspace.
JOINT_STEP = 0.2       # rad
CARTESIAN_STEP = 0.1   # m
# Workspace box of TCP targets in the robot base frame (m): over the table
# (which starts 0.15 m in front of the base), from 3 cm above its top to
# 0.6 m above it. Scaled down with the robot's reach (see `workspace_box`).
WORKSPACE_LOW = (0.2, -0.55, 0.03)
WORKSPACE_HIGH = (0.8, 0.55, 0.6)
# Default TCP yaw of Cartesian goals (gripper down, fingers closing along
# y); tasks choose theirs with HrcTask.CARTESIAN_YAW.
GRIPPER_YAW = 0.0


def validate_action(action, shape):
  """The action as a float array clipped to [-1, 1]; clear errors else."""
  raw = np.asarray(action)
  if raw.dtype.kind not in 'biuf':
    raise ValueError(f'action must be an array of numbers of shape {shape} '
                     f'in [-1, 1], got {action!r:.80} (dtype {raw.dtype})')
  action = raw.astype(np.float64, copy=False)
  if action.shape != shape:
    raise ValueError(f'action must have shape {shape}, got {action.shape}')
  finite = np.isfinite(action)
  if not finite.all():
    bad = np.flatnonzero(~finite)
    raise ValueError('action has non-finite entries at indices '
                     f'{bad.tolist()}: {action[bad].tolist()}')
  return np.minimum(np.maximum(action, -1.0), 1.0)   # np.clip, cheaper


@dataclasses.dataclass(frozen=True)
class StepGoal:
  """What an RL step's action asks of the robot."""
  q_goal: np.ndarray          # the joint goal for the shield
  plan: Any                   # collision prevention's plan, or None
  gripper: Optional[float]    # the gripper command, None without one
  replaced: bool              # collision prevention replaced the goal
  ik_failed: bool             # the action's own goal had no IK solution


def step_goal(action, space, with_gripper, q, current_goal, checker, policy,
              random_state, shield):
  """The joint goal of an RL step's action.

  Args:
    action: the agent's action (`validate_action`; clipped to [-1, 1]).
    space: the task's action space (JointActionSpace or
      CartesianActionSpace).
    with_gripper: whether the action's last entry commands the gripper.
    q: the robot's joint positions.
    current_goal: the joint goal of the last action (kept where IK fails).
    checker: the task's `collision_prevention.CollisionPrevention`.
    policy: a collision prevention policy, or 'off'.
    random_state: collision prevention's random state.
    shield: the task's shield, from whose state a replacement is planned.

  Returns:
    A StepGoal; q_goal is a new float array.
  """
  action = validate_action(action, (space.num_arm + int(with_gripper),))
  arm = action[:space.num_arm]
  outcome = {}

  def to_goal(arm_action):
    goal, ok = space.goal(q, arm_action, current_goal)
    outcome.setdefault('ik_failed', not ok)
    return goal

  replaced, plan = False, None
  if policy == 'off':
    goal = to_goal(arm)
  else:
    _, goal, replaced, plan = checker.filter_action(
        arm, q, to_goal, policy, random_state=random_state, plan_from=shield)
  return StepGoal(
      q_goal=np.asarray(goal, dtype=float).copy(), plan=plan,
      gripper=action[-1] if with_gripper else None, replaced=bool(replaced),
      ik_failed=bool(outcome.get('ik_failed', False)))


def workspace_box(kinematic_model):
  """(low, high) world corners of the Cartesian workspace box.

  WORKSPACE_LOW/HIGH in the base frame, scaled about the base like
  `ik.table_workspace_box` for robots with a short reach, then moved to the
  world.
  """
  scale = ik_lib.workspace_scale(kinematic_model)
  base = kinematic_model.base_pose
  table = base[:3, 3] - [0.0, 0.0, layout.robot_mount(
      kinematic_model.description.name).height_above_table]
  low = table + scale * np.asarray(WORKSPACE_LOW)
  high = table + scale * np.asarray(WORKSPACE_HIGH)
  low[2] = table[2] + WORKSPACE_LOW[2]   # Keep the height above the table.
  return low, high


class JointActionSpace:
  """Joint-space deltas: q_goal = clip(q + JOINT_STEP * a, limits)."""

  name = 'joint'

  def __init__(self, kinematic_model, step=JOINT_STEP):
    self._model = kinematic_model
    self.step = float(step)
    self.num_arm = kinematic_model.dof

  def goal(self, q, arm_action, current_goal):
    """(joint goal, True) for the arm part of an action (never fails)."""
    del current_goal
    goal = q + self.step * arm_action
    return np.minimum(np.maximum(goal, self._model.q_min),
                      self._model.q_max), True


class CartesianActionSpace:
  """TCP position deltas turned into joint goals by gripper-down IK at a
  fixed yaw (`yaw`, rad about world z; a task may change it between
  episodes)."""

  name = 'cartesian'

  def __init__(self, kinematic_model, step=CARTESIAN_STEP, box=None,
               yaw=GRIPPER_YAW):
    self._model = kinematic_model
    self._ik = ik_lib.InverseKinematics(kinematic_model)
    self.step = float(step)
    self.yaw = float(yaw)
    self.num_arm = 3
    self.low, self.high = box if box is not None else workspace_box(
        kinematic_model)

  @property
  def ik(self):
    return self._ik

  def target(self, q, arm_action):
    """TCP target (world) of an action from joint positions q."""
    tcp = self._ik.tcp_position(q)
    return np.minimum(np.maximum(tcp + self.step * arm_action, self.low),
                      self.high)

  def goal(self, q, arm_action, current_goal):
    """(joint goal, IK succeeded): on IK failure the current goal."""
    result = self._ik.solve(self.target(q, arm_action), q, self.yaw)
    if result.success:
      return result.q, True
    return current_goal.copy(), False


def make_action_space(name, kinematic_model, yaw=GRIPPER_YAW):
  """The named action space; `yaw` is the Cartesian space's gripper yaw."""
  if name == 'joint':
    return JointActionSpace(kinematic_model)
  if name == 'cartesian':
    return CartesianActionSpace(kinematic_model, yaw=yaw)
  raise ValueError(f'Unknown action_space {name!r}: expected one of '
                   f'{", ".join(ACTION_SPACES)}')


def action_spec(action_space, with_gripper):
  """Bounded [-1, 1] spec of the agent's action."""
  size = action_space.num_arm + (1 if with_gripper else 0)
  names = ([f'joint{i + 1}' for i in range(action_space.num_arm)]
           if action_space.name == 'joint' else ['dx', 'dy', 'dz'])
  if with_gripper:
    names.append('gripper')
  return specs.BoundedArray(shape=(size,), dtype=np.float64,
                            minimum=-np.ones(size), maximum=np.ones(size),
                            name='\t'.join(names))
