"""Steering: a world-frame TCP aim (or a joint goal) as an agent action.

Experts decide where the TCP should go; `Steering` turns that aim into an
action of the task's action space:

* Cartesian: the TCP displacement towards the aim divided by
  CARTESIAN_STEP, scaled down as a whole (direction kept, a straight line)
  so that no entry exceeds 1.
* Joint: the displacement is first cut to at most `cartesian_step` metres,
  then one gripper-down IK solve at the task's CARTESIAN_YAW from the
  current joint positions gives a joint target one short Cartesian step
  ahead (a nearly straight TCP path); the action is its joint difference /
  JOINT_STEP, scaled down as a whole (joint direction kept) into [-1, 1].
* Joint goals (`joint_goal_action`): joint space, the joint difference /
  JOINT_STEP scaled into [-1, 1] (a straight joint path; or clipped per
  joint like the reference); Cartesian space, the goal's TCP position as
  the aim.

Tasks with a gripper get the gripper command (-1 open ... +1 closed)
appended. Everything is deterministic.
"""

import numpy as np

from hrc_suite.control import ik as ik_lib
from hrc_suite.tasks import actions


class Steering:
  """Aims to actions for one task (its action space, yaw and gripper)."""

  def __init__(self, task, cartesian_step=actions.CARTESIAN_STEP):
    if not cartesian_step > 0:
      raise ValueError(f'cartesian_step must be > 0 m, got {cartesian_step!r}')
    self._task = task
    self._model = task.kinematics
    self.space = task.action_space_name
    self.yaw = float(task.CARTESIAN_YAW)
    self.has_gripper = bool(task.HAS_GRIPPER_ACTION)
    self.cartesian_step = float(cartesian_step)
    self._ik = (ik_lib.InverseKinematics(self._model)
                if self.space == 'joint' else None)

  @property
  def ik(self):
    return self._ik

  def _finish(self, arm, gripper):
    if self.has_gripper:
      if gripper is None:
        raise ValueError('this task has a gripper action: give gripper in '
                         '[-1, 1] (-1 open, +1 closed)')
      return np.append(arm, float(np.clip(gripper, -1.0, 1.0)))
    if gripper is not None:
      raise ValueError(f'this task has no gripper action, got gripper='
                       f'{gripper!r}')
    return arm

  def _check(self, name, value, size):
    value = np.asarray(value, dtype=float)
    if value.shape != (size,) or not np.all(np.isfinite(value)):
      raise ValueError(f'{name} must be {size} finite numbers, got '
                       f'{np.asarray(value).tolist()!r}')
    return value

  def cartesian_arm(self, aim, tcp):
    """Cartesian arm action (3,) from the TCP towards `aim` (direction
    kept, largest entry at most 1)."""
    delta = (self._check('aim', aim, 3) - self._check('tcp', tcp, 3))
    arm = delta / actions.CARTESIAN_STEP
    largest = np.abs(arm).max()
    if largest > 1.0:
      arm /= largest
    return arm

  def ik_target(self, aim, tcp, q):
    """Joint positions one gripper-down IK step (<= cartesian_step) from
    q towards `aim` (the best iterate if the solve misses)."""
    aim = self._check('aim', aim, 3)
    tcp = self._check('tcp', tcp, 3)
    delta = aim - tcp
    norm = np.linalg.norm(delta)
    if norm > self.cartesian_step:
      delta *= self.cartesian_step / norm
    ik = self._ik or ik_lib.InverseKinematics(self._model)
    self._ik = ik
    return ik.solve(tcp + delta, q, self.yaw).q

  def joint_arm(self, q_goal, q, keep_direction=True):
    """Joint arm action (dof,) towards joint positions q_goal: the joint
    difference / JOINT_STEP, scaled down as a whole into [-1, 1] (a straight
    joint-space path) or, keep_direction=False, clipped per joint (the
    reference's clip(goal difference))."""
    dof = self._model.dof
    q_goal = self._check('q_goal', q_goal, dof)
    q = self._check('q', q, dof)
    arm = (q_goal - q) / actions.JOINT_STEP
    if not keep_direction:
      return np.clip(arm, -1.0, 1.0)
    largest = np.abs(arm).max()
    return arm / largest if largest > 1.0 else arm

  def action(self, aim, tcp, q, gripper=None):
    """The action moving the TCP from `tcp` (joint positions q) towards
    the world point `aim`, with the gripper command if the task has one."""
    if self.space == 'cartesian':
      arm = self.cartesian_arm(aim, tcp)
    else:
      q = self._check('q', q, self._model.dof)
      arm = self.joint_arm(self.ik_target(aim, tcp, q), q)
    return self._finish(arm, gripper)

  def joint_goal_action(self, q_goal, q, tcp, gripper=None,
                        keep_direction=True):
    """The action moving the joints to q_goal (joint space, see
    `joint_arm`) or the TCP to q_goal's TCP position (Cartesian space)."""
    if self.space == 'joint':
      arm = self.joint_arm(q_goal, q, keep_direction)
    else:
      q_goal = self._check('q_goal', q_goal, self._model.dof)
      arm = self.cartesian_arm(self._model.tcp_pose(q_goal)[:3, 3], tcp)
    return self._finish(arm, gripper)
