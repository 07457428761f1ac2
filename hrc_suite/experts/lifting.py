"""Lifting expert: carry the robot's end of the board where the person's
hands say the board should be, level, gripper closed.

The reference's expert keeps the end effector at the height of the midpoint
of the person's hands, a fixed distance from it horizontally. Here the
person holds the board at two points (the hold welds' anchors on the
board), so the board the person wants is known exactly: those two points at
the hands, the board level, its heading given by the line between the
hands. The expert aims the TCP at the handle of that board (keeping the
TCP's offset from the handle), led by LOOKAHEAD of the hands' velocity
because the trajectory planner lags a moving goal. Before the person takes
the board and after they put it down the TCP stays on the handle.

* Steps are short (MAX_STEP): near the person the SSM shield stops a robot
  commanded far ahead (the Schunk in joint space stalls for seconds with
  0.1 m steps; measured, 6/10 -> 6/10 Cartesian, 4/10 -> 6/10 joint).
  Horizontally they keep pace with the person's hands (`paced_step`): a
  person who pushes the board towards the robot and pulls it back faster
  than MAX_STEP per RL step stretched the compliant holds until they
  pried the handle out of the pads.
* Reach means gripper-down IK from the current joints succeeds and its
  posture collides neither with the table nor with the robot itself (the
  collision prevention would hold the robot still). Where the level
  board's handle is out of reach (recorded people lift their end by up to
  1 m), the aim is the handle of the least tilted board in reach (TILTS:
  turned about the line through the hands, as the rigid board moves; going
  straight down instead, the hold welds dragged the robot end towards the
  person). Where the next step is out of reach, the robot end stays
  further from the base (REACH_AWAY), then goes lower (REACH_DROPS).
  Recorded people also pull their end towards the robot by up to 0.14 m
  while they lift it: the Schunk's elbow folded against its upper arm, the
  robot stood still and the board tipped over (docs/tasks.md).
* Joint space turns the gripper with the board's heading (gripper-down IK at
  the grip yaw plus the heading); Cartesian actions keep the task's fixed
  grip yaw.

Measured (docs/results/experts.md): 50 of 50 episodes on the Schunk
(expert and noisy expert) and on the Panda (expert). Recorded people, each
clip alone (docs/motion_library.md, "On the shared recordings of the
other tasks"; clips 0-9, seeds 0-2): Panda 30/30 (28/30 with steps cut
to MAX_STEP as a whole: CollaborativeLifting_4, seeds 0 and 2), Schunk
24/30 (25/30; its misses move between clips and seeds from one version
to the next).
"""

from typing import Mapping, Optional

from dm_control import composer
import numpy as np

from hrc_suite import experts
from hrc_suite import rotations
from hrc_suite.experts import base
from hrc_suite.experts import steering
from hrc_suite.human import keypoints
from hrc_suite.tasks.runtime import actions
from hrc_suite.tasks import lifting

# Seconds of the hands' velocity the aim leads by: about the lag of the
# shielded trajectory planner behind a goal that moves at walking speed (it
# plans to stop at each new goal).
LOOKAHEAD = 0.2
# Longest TCP step aimed at per RL step (m); the Cartesian action space
# allows 0.1 m (module doc: the shield stalls longer ones near the person).
# Its horizontal part may be longer by the distance the person's hands
# move horizontally in an RL step (`paced_step`): recorded people push
# their end 0.5 m towards the robot and pull it back at up to 0.46 m/s
# (CollaborativeLifting_4), and a robot end that fell behind at 0.03 m per
# RL step let the compliant holds stretch by 0.4 m until they pried the
# handle out of the pads (Panda and Schunk). Vertically the step stays:
# a robot end rising faster than the board's pried the handle down in the
# Schunk's pads (CollaborativeLifting_0).
MAX_STEP = 0.03
# Where the aim is out of gripper-down reach, the robot end goes this much
# lower (m, the first that IK reaches): the board tilts towards the robot
# but stays held, and a lower TCP reaches further.
REACH_DROPS = (0.03, 0.06, 0.1, 0.15, 0.2)
# Board tilts tried, least first, where the level board's handle is out
# of reach (rad; the task fails at lifting.MAX_TILT, ~37 deg): the robot
# end on the circle about the person's hands that the rigid board allows
# (straight down, the hold welds stretched and dragged the robot end
# towards the person).
TILTS = tuple(np.radians((0.0, 5.0, 10.0, 15.0, 20.0, 25.0, 30.0)))
# Before dropping, the robot end first stays this much further from the
# base, horizontally (m): a fold that collides near the base opens there.
REACH_AWAY = (0.02, 0.04, 0.06)
GRIPPER_CLOSED = 1.0
_MJ_EQ_WELD = 1   # mujoco.mjtEq.mjEQ_WELD


@experts.register('lifting', 'default')
class LiftingExpert(base.Expert):
  """Keeps the board level with the person's hands (lifting/default).

  Privileged: the person's grip on the board, read from the model: which
  hold welds are active and their anchor points on the board (the points
  where the hands took it; a partner sees where the hands hold the board),
  and the hands' velocity (`task.player.velocities`, what a human tracker
  estimates).

  Args:
    env: the environment (hrc_suite.suite.load) whose task it solves.
  """

  OBSERVED = ('eef_position', 'eef_to_hands', 'joint_positions',
              'board_position', 'board_quaternion', 'handle_position')
  TASKS = (('lifting', 'default'),)

  def __init__(self, env: composer.Environment):
    super().__init__(env)
    self._steer = steering.Steering(self._task)
    self._hand_index = np.array(keypoints.index(
        ('left_hand', 'right_hand')))
    self._box = actions.workspace_box(self._task.kinematics)
    self._checker = self._task.collision_checker
    self._base = self._task.kinematics.base_pose[:3, 3]
    self._dt = float(self._task.control_timestep)

  def _anchors(self):
    """(2, 3) anchor points of the active hold welds on the board (board
    frame, left then right), or None when the person does not hold it."""
    physics = self.physics
    model, data = physics.model, physics.data
    board_id = physics.bind(self._task.board.body).element_id
    welds = np.flatnonzero((model.eq_obj2id == board_id)
                           & (data.eq_active != 0)
                           & (model.eq_type == _MJ_EQ_WELD))
    hand_of = {}
    for eq_id in welds:
      name = model.id2name(model.eq_obj1id[eq_id], 'body') or ''
      hand_of['left' if 'left' in name else 'right'] = eq_id
    if set(hand_of) != {'left', 'right'}:
      return None
    return np.stack([model.eq_data[hand_of[hand], 0:3]
                     for hand in ('left', 'right')])

  def _wanted_board(self, observation):
    """(middle of the hands, led by LOOKAHEAD; world vector from there to
    the handle of the level board the hands want; that board's heading:
    world yaw of its long axis, rad), or None when nobody holds it."""
    anchors = self._anchors()
    if anchors is None:
      return None
    hands = observation['eef_position'] + observation['eef_to_hands']
    rotation = rotations.quat_to_mat(observation['board_quaternion'])
    handle_local = rotation.T @ (observation['handle_position']
                                 - observation['board_position'])
    # Heading: the line between the hands against the line between the
    # anchors on the board (both horizontal).
    across_world = hands[0] - hands[1]
    across_board = anchors[0] - anchors[1]
    heading = float(rotations.wrap_angle(
        np.arctan2(across_world[1], across_world[0])
        - np.arctan2(across_board[1], across_board[0])))
    velocity = self._task.player.velocities[self._hand_index].mean(axis=0)
    middle = hands.mean(axis=0) + LOOKAHEAD * velocity
    offset = rotations.yaw_to_mat(heading) @ (
        handle_local - anchors.mean(axis=0))
    return middle, offset, heading

  def board_aim(self, observation: Mapping[str, np.ndarray]
                ) -> Optional[tuple[np.ndarray, float]]:
    """Where the person's hands want the board.

    Args:
      observation: the OBSERVED observables now.

    Returns:
      (world position (3,) of the handle on the board the hands want, that
      board's heading: world yaw of its long axis, rad), or None when
      nobody holds the board.
    """
    wanted = self._wanted_board(observation)
    if wanted is None:
      return None
    middle, offset, heading = wanted
    return middle + offset, heading

  def _tilted_aim(self, middle, offset, grasp, q):
    """The handle of the least tilted board (TILTS: the robot end lower,
    turned about the horizontal line through the hands) whose TCP (handle
    + `grasp`) gripper-down IK from q reaches free of collisions; the level
    board's handle if none."""
    axis = np.cross([0.0, 0.0, 1.0], offset)
    axis /= max(np.linalg.norm(axis), 1e-9)
    for tilt in TILTS:
      turned = rotations.axis_angle_to_mat(axis, tilt) @ offset
      if turned[2] > offset[2]:   # The robot end must go down.
        turned = rotations.axis_angle_to_mat(axis, -tilt) @ offset
      aim = middle + turned
      if self._reaches(np.clip(aim + grasp, *self._box), q):
        return aim
    return middle + offset

  def _away(self, point):
    """`point`, then moved REACH_AWAY further from the base."""
    away = point[:2] - self._base[:2]
    away = np.append(away / max(np.linalg.norm(away), 1e-9), 0.0)
    return [point] + [point + distance * away for distance in REACH_AWAY]

  def action(self, observation: Mapping[str, np.ndarray]) -> np.ndarray:
    """The action now.

    Args:
      observation: the OBSERVED observables now (`base.Expert.observe`).

    Returns:
      The action: the TCP a paced step towards the wanted board's handle
      (tilted or moved where out of reach), gripper closed.
    """
    tcp = observation['eef_position']
    q = observation['joint_positions']
    handle = observation['handle_position']
    wanted = self._wanted_board(observation)
    if wanted is None:   # Nobody holds the board: stay on the handle.
      rotation = rotations.quat_to_mat(observation['board_quaternion'])
      aim = handle
      heading = float(rotations.mat_yaw(rotation))
    else:
      middle, offset, heading = wanted
      aim = self._tilted_aim(middle, offset, tcp - handle, q)
    # Keep the TCP's offset from the handle (the grasp as it is).
    delta = self.paced_step(aim + (tcp - handle) - tcp)
    if self._steer.space == 'joint':
      self._steer.yaw = lifting.GRIP_YAW + heading
    aim = self._within_reach(tcp + delta, q)
    return self._steer.action(aim, tcp, q, GRIPPER_CLOSED)

  def hands_pace(self) -> float:
    """How far the middle of the person's hands moves horizontally in an
    RL step at its velocity now.

    Returns:
      The distance, m.
    """
    velocity = self._task.player.velocities[self._hand_index].mean(axis=0)
    return float(np.linalg.norm(velocity[:2])) * self._dt

  def paced_step(self, delta: np.ndarray) -> np.ndarray:
    """The TCP step towards `delta` (m, world): `delta` cut to MAX_STEP,
    then its horizontal part lengthened by `hands_pace` (at most to
    `delta`'s own), its vertical part kept.

    Args:
      delta: (3,) wanted TCP displacement.

    Returns:
      (3,) the displacement aimed at this RL step.
    """
    delta = np.asarray(delta, dtype=np.float64)
    norm = np.linalg.norm(delta)
    step = delta * (MAX_STEP / norm) if norm > MAX_STEP else delta.copy()
    pace = self.hands_pace()
    wanted = np.linalg.norm(delta[:2])
    if norm > MAX_STEP and pace > 0.0 and wanted > 0.0:
      reach = min(wanted, np.linalg.norm(step[:2]) + pace)
      step[:2] = delta[:2] * (reach / wanted)
    return step

  def _reaches(self, aim, q):
    """Whether gripper-down IK from q reaches `aim` without a collision."""
    return self._steer.reaches(aim, q, self._checker)

  def _within_reach(self, aim, q):
    """`aim` (inside the Cartesian workspace box), or, where gripper-down IK
    from q does not reach it free of collisions, the first that does of
    the aim further from the base (REACH_AWAY), then lower (REACH_DROPS)."""
    aim = np.clip(aim, *self._box)
    if self._reaches(aim, q):
      return aim
    for further in self._away(aim)[1:]:
      further = np.clip(further, *self._box)
      if self._reaches(further, q):
        return further
    for drop in REACH_DROPS:
      lower = aim - [0.0, 0.0, drop]
      if lower[2] < self._box[0][2]:
        break
      if self._reaches(lower, q):
        return lower
    return aim
