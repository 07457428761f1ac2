"""Lifting expert: carry the robot's end of the board where the person's
hands say the board should be, level, gripper closed.

The reference's expert keeps the end effector at the height of the midpoint
of the person's hands, a fixed distance from it horizontally. Here the
person holds the board at two points (the hold welds' anchors on the
board), so the board pose the person wants is known exactly: those two
points at the hands, the board level. The expert aims the TCP at the place
of the handle on that board (the TCP's offset from the handle kept), led
by LOOKAHEAD of the hands' velocity because the robot's trajectory
planner lags a moving goal. Before the person takes the board and after
they put it down the TCP stays on the handle.

Joint space turns the gripper with the board's heading (gripper-down IK at
the grip yaw plus the heading); Cartesian actions keep the task's fixed
grip yaw.
"""

import numpy as np

from hrc_suite.experts import base
from hrc_suite.experts import steering
from hrc_suite.human import keypoints
from hrc_suite.tasks import lifting

# Seconds of the hands' velocity the aim leads by: about the lag of the
# shielded trajectory planner behind a goal that moves at walking speed
# (it plans to stop at each new goal); measured, 0.1-0.3 s all track.
LOOKAHEAD = 0.2
GRIPPER_CLOSED = 1.0


def _rotation_from_quat(quat):
  w, x, y, z = quat / np.linalg.norm(quat)
  return np.array([
      [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
      [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
      [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def _yaw_rotation(angle):
  c, s = np.cos(angle), np.sin(angle)
  return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


class LiftingExpert(base.Expert):
  """Keeps the board level with the person's hands (lifting/default).

  Privileged: the person's grip on the board, read from the model: which
  hold welds are active and their anchor points on the board (the points
  where the hands took it; a partner sees where the hands hold the board),
  and the hands' velocity (`task.player.velocities`, what a human tracker
  estimates).
  """

  OBSERVED = ('eef_position', 'eef_to_hands', 'joint_positions',
              'board_position', 'board_quaternion', 'handle_position')
  TASKS = (('lifting', 'default'),)

  def __init__(self, env):
    super().__init__(env)
    self._steer = steering.Steering(self._task)
    self._hand_index = np.array(keypoints.index(
        ('left_hand', 'right_hand')))

  def _anchors(self):
    """(2, 3) anchor points of the active hold welds on the board (board
    frame, left then right), or None when the person does not hold it."""
    physics = self.physics
    board_id = physics.bind(self._task.board.body).element_id
    model, data = physics.model, physics.data
    welds = np.flatnonzero((model.eq_obj2id == board_id)
                           & (data.eq_active != 0)
                           & (model.eq_type == 1))   # mjEQ_WELD
    if len(welds) != 2:
      return None
    hand_of = {}
    for eq_id in welds:
      name = physics.model.id2name(model.eq_obj1id[eq_id], 'body') or ''
      hand_of['left' if 'left' in name else 'right'] = eq_id
    if set(hand_of) != {'left', 'right'}:
      return None
    return np.stack([model.eq_data[hand_of[h], 0:3].copy()
                     for h in ('left', 'right')])

  def board_aim(self, observation):
    """World position of the handle on the board the person's hands want
    (level, hold points at the hands) and that board's heading (world yaw
    of its long axis, rad), or None when nobody holds the board."""
    anchors = self._anchors()
    if anchors is None:
      return None
    tcp = observation['eef_position']
    hands = tcp + observation['eef_to_hands']
    rotation = _rotation_from_quat(observation['board_quaternion'])
    position = observation['board_position']
    handle_local = rotation.T @ (observation['handle_position'] - position)
    # Heading: the line between the hands against the line between the
    # anchors (both horizontal).
    across_world = hands[0] - hands[1]
    across_board = anchors[0] - anchors[1]
    heading = (np.arctan2(across_world[1], across_world[0])
               - np.arctan2(across_board[1], across_board[0]))
    heading = float((heading + np.pi) % (2 * np.pi) - np.pi)
    velocity = self._task.player.velocities[self._hand_index].mean(axis=0)
    middle = hands.mean(axis=0) + LOOKAHEAD * velocity
    aim = middle + _yaw_rotation(heading) @ (handle_local
                                             - anchors.mean(axis=0))
    return aim, heading

  def action(self, observation):
    tcp = observation['eef_position']
    q = observation['joint_positions']
    handle = observation['handle_position']
    wanted = self.board_aim(observation)
    if wanted is None:   # Nobody holds the board: stay on the handle.
      rotation = _rotation_from_quat(observation['board_quaternion'])
      wanted = handle, float(np.arctan2(rotation[1, 0], rotation[0, 0]))
    aim, heading = wanted
    # Keep the TCP's offset from the handle (the grasp as it is).
    aim = aim + (tcp - handle)
    if self._steer.space == 'joint':
      self._steer.yaw = lifting.GRIP_YAW + heading
    return self._steer.action(aim, tcp, q, GRIPPER_CLOSED)
