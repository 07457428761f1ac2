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

Speed (`limit_speed=True`, the default): a step is shrunk so that no
joint goal lies further ahead than SPEED_HEADROOM control steps at its
velocity limit (v_max x control_timestep each: 0.2 rad for 1 rad/s, so a
joint can still cruise at v_max). A goal further ahead than
the robot can follow makes it lag behind, and the next goal (computed from
where it is) bends the path: on the short Schunk, folded over a cube on the
table, the TCP drifted 9 cm off its line and into a pose whose every
continuation the collision prevention rejected. In Cartesian space the
joint change is predicted with the action space's own IK (from q, at the
task's yaw).

Tasks with a gripper get the gripper command (-1 open ... +1 closed)
appended. Everything is deterministic.
"""

from typing import Optional

from dm_control import composer
import numpy as np

from hrc_suite.control import ik as ik_lib
from hrc_suite.safety.collision_prevention import prevention
from hrc_suite.tasks.runtime import actions

# Joint goals at most this many control steps at v_max ahead: 2 lets the
# shield's plan (which must end at rest at the goal) cruise at v_max.
SPEED_HEADROOM = 2.0


class Steering:
  """Aims to actions for one task (its action space, yaw and gripper).

  Args:
    task: the task (an HrcTask) whose actions it makes.
    cartesian_step: the longest TCP step (m) of a joint-space action
      (module doc), > 0.
    limit_speed: whether steps are shrunk to the joints' velocity limits
      (SPEED_HEADROOM).

  Raises:
    ValueError: a cartesian_step that is not > 0.
  """

  def __init__(self, task: composer.Task,
               cartesian_step: float = actions.CARTESIAN_STEP,
               limit_speed: bool = True):
    if not cartesian_step > 0:
      raise ValueError(f'cartesian_step must be > 0 m, got {cartesian_step!r}')
    self._task = task
    self._model = task.kinematics
    self.space = task.action_space_name
    self.yaw = float(task.CARTESIAN_YAW)
    self.has_gripper = bool(task.HAS_GRIPPER_ACTION)
    self.cartesian_step = float(cartesian_step)
    self._ik = ik_lib.InverseKinematics(self._model)
    # Largest joint change per control step the robot can follow (rad).
    self.max_joint_step = None
    if limit_speed:
      limits = task.robot.description.limits
      self.max_joint_step = (SPEED_HEADROOM * task.control_timestep
                             * np.asarray(limits.v_max, dtype=float))

  @property
  def ik(self) -> ik_lib.InverseKinematics:
    """The gripper-down inverse kinematics of the task's robot."""
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

  def cartesian_arm(self, aim: np.ndarray, tcp: np.ndarray) -> np.ndarray:
    """Cartesian arm action from the TCP towards `aim`.

    Args:
      aim: the world point (3,) the TCP goes to, m.
      tcp: the TCP now (3,), m.

    Returns:
      The arm action (3,): the displacement / CARTESIAN_STEP, direction
      kept, largest entry at most 1.

    Raises:
      ValueError: an aim or tcp that is not 3 finite numbers.
    """
    delta = (self._check('aim', aim, 3) - self._check('tcp', tcp, 3))
    arm = delta / actions.CARTESIAN_STEP
    largest = np.abs(arm).max()
    if largest > 1.0:
      arm /= largest
    return arm

  def reaches(self, aim: np.ndarray, q: np.ndarray,
              checker: prevention.CollisionPrevention,
              first_step: bool = False) -> bool:
    """Whether gripper-down IK from q reaches `aim` in a configuration
    free of collisions; with `first_step`, also whether the straight joint
    path of the first Cartesian step towards it (<= cartesian_step) is
    free: what collision prevention checks before letting the step through.

    Args:
      aim: the world point (3,) of the TCP, m.
      q: joint positions (dof,) the IK starts from.
      checker: the task's collision prevention.
      first_step: whether the first step's path is checked too.

    Returns:
      True if it reaches.
    """
    result = self._ik.solve(aim, q, self.yaw)
    if not result.success or checker.in_collision(result.q):
      return False
    if not first_step:
      return True
    tcp = self._model.tcp_pose(q)[:3, 3]
    delta = aim - tcp
    norm = np.linalg.norm(delta)
    if norm > self.cartesian_step:
      result = self._ik.solve(tcp + delta * (self.cartesian_step / norm), q,
                              self.yaw)
      if not result.success:
        return False
    return checker.is_safe(q, result.q)

  def ik_target(self, aim: np.ndarray, tcp: np.ndarray,
                q: np.ndarray) -> np.ndarray:
    """Joint positions one gripper-down IK step (<= cartesian_step) from
    q towards `aim` (the best iterate if the solve misses).

    Args:
      aim: the world point (3,) the TCP goes to, m.
      tcp: the TCP now (3,), m.
      q: joint positions now (dof,).

    Returns:
      The joint positions (dof,).

    Raises:
      ValueError: an aim or tcp that is not 3 finite numbers.
    """
    aim = self._check('aim', aim, 3)
    tcp = self._check('tcp', tcp, 3)
    delta = aim - tcp
    norm = np.linalg.norm(delta)
    if norm > self.cartesian_step:
      delta *= self.cartesian_step / norm
    return self._ik.solve(tcp + delta, q, self.yaw).q

  def _speed_scale(self, dq):
    """Factor <= 1 keeping the joint change dq within max_joint_step."""
    if self.max_joint_step is None:
      return 1.0
    ratio = np.abs(dq) / self.max_joint_step
    largest = ratio.max()
    return 1.0 / largest if largest > 1.0 else 1.0

  def joint_arm(self, q_goal: np.ndarray, q: np.ndarray,
                keep_direction: bool = True) -> np.ndarray:
    """Joint arm action towards joint positions q_goal.

    Args:
      q_goal: the joint goal (dof,).
      q: joint positions now (dof,).
      keep_direction: whether the action is scaled down as a whole (a
        straight joint-space path, within the speed limit) or clipped per
        joint (the reference's clip(goal difference)).

    Returns:
      The arm action (dof,): the joint difference / JOINT_STEP, within
      [-1, 1].

    Raises:
      ValueError: a q_goal or q that is not dof finite numbers.
    """
    dof = self._model.dof
    q_goal = self._check('q_goal', q_goal, dof)
    q = self._check('q', q, dof)
    arm = (q_goal - q) / actions.JOINT_STEP
    if not keep_direction:
      return np.clip(arm, -1.0, 1.0)
    arm *= self._speed_scale(q_goal - q)
    largest = np.abs(arm).max()
    return arm / largest if largest > 1.0 else arm

  def action(self, aim: np.ndarray, tcp: np.ndarray,
             q: Optional[np.ndarray], gripper: Optional[float] = None,
             gain: float = 1.0) -> np.ndarray:
    """The action moving the TCP from `tcp` (joint positions q) towards
    the world point `aim`, with the gripper command if the task has one.

    Args:
      aim: the world point (3,) the TCP goes to, m.
      tcp: the TCP now (3,), m.
      q: joint positions now (dof,); in Cartesian space it may be None:
        the speed limit is then skipped.
      gripper: the gripper command (-1 open ... +1 closed), for a task
        with a gripper action; None for one without.
      gain: in (0, 1], the fraction of the way to the aim asked for in this
        step (1: all of it, up to the step limits; less: a gentler,
        proportional approach that lets the robot brake without
        overshooting the aim).

    Returns:
      The action of the task's action space.

    Raises:
      ValueError: a gain outside (0, 1], malformed positions, or a gripper
        command given (or missing) against the task's action space.
    """
    if not 0.0 < gain <= 1.0:
      raise ValueError(f'gain must be in (0, 1], got {gain!r}')
    tcp = self._check('tcp', tcp, 3)
    aim = tcp + gain * (self._check('aim', aim, 3) - tcp)
    if self.space == 'cartesian':
      arm = self.cartesian_arm(aim, tcp)
      if self.max_joint_step is not None and q is not None:
        q = self._check('q', q, self._model.dof)
        # The joint goal the action space will compute (clipped box aside).
        result = self._ik.solve(
            np.asarray(tcp, float) + actions.CARTESIAN_STEP * arm, q,
            self.yaw)
        if result.success:
          arm = arm * self._speed_scale(result.q - q)
    else:
      q = self._check('q', q, self._model.dof)
      arm = self.joint_arm(self.ik_target(aim, tcp, q), q)
    return self._finish(arm, gripper)

  def joint_goal_action(self, q_goal: np.ndarray, q: np.ndarray,
                        tcp: np.ndarray, gripper: Optional[float] = None,
                        keep_direction: bool = True) -> np.ndarray:
    """The action moving the joints to q_goal (joint space, see
    `joint_arm`) or the TCP to q_goal's TCP position (Cartesian space).

    Args:
      q_goal: the joint goal (dof,).
      q: joint positions now (dof,).
      tcp: the TCP now (3,), m.
      gripper: the gripper command, for a task with a gripper action.
      keep_direction: joint space: `joint_arm`'s keep_direction.

    Returns:
      The action of the task's action space.

    Raises:
      ValueError: malformed positions, or a gripper command given (or
        missing) against the task's action space.
    """
    if self.space == 'joint':
      arm = self.joint_arm(q_goal, q, keep_direction)
    else:
      q_goal = self._check('q_goal', q_goal, self._model.dof)
      arm = self.cartesian_arm(self._model.tcp_pose(q_goal)[:3, 3], tcp)
    return self._finish(arm, gripper)
