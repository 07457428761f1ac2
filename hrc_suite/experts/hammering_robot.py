"""hammering/robot_hammers expert: blows on the nail with the hammer in the
gripper, gripper closed.

* While the person carries the plank in (or away), the TCP waits at its
  home position (0.45 m ahead of the base, 1.07 m up for the Schunk and
  the Panda: the face 0.14 m above a carried plank's top).
* On the table: the face goes to HOVER above the nail head (straight up
  first when it is low and off to the side), lined up within ALIGN; then
  a blow: straight down to PRESS below the head (the controller presses
  the nail in while the face is on it), until the face has been on the
  head for CONTACT_STEPS RL steps or drifted MISS sideways; then back up
  to HOVER (hysteresis: the phase is kept in `_striking`). Near the nail
  the face moves at most STEP per RL step.
* Once the nail is in (`nail_progress`), the hammer goes up by LIFT and
  back to its home position, so the person can take the plank.

The shield (SSM) slows the arm near the person's hand, which rests on the
plank's handle 0.235 m from the nail (tasks/hammering_robot.py).
"""

from typing import Mapping

from dm_control import composer
import numpy as np

from hrc_suite import experts
from hrc_suite import rotations
from hrc_suite.experts import base
from hrc_suite.experts import steering
from hrc_suite.tasks import hammering_robot

GRIPPER_CLOSED = 1.0
HOVER = 0.05         # m, face above the nail head before a blow
ALIGN = 0.004        # m, horizontal face-to-head error that starts a blow
PRESS = 0.03         # m, face aim below the nail head in a blow
# The face within this of the head's top counts as on it (m): the face is
# a 25 mm disc, the head a 10 mm one, contacts sink ~1 mm.
ON_HEAD = 0.004
CONTACT_STEPS = 3    # RL steps on the head per blow
LIFT = 0.1           # m above the nail head once the nail is in
# A blow is broken off (back up to HOVER) when the face drifts this far
# sideways from the head (m): the face's and head's radii add to 17.5 mm.
MISS = 0.008
# Near the nail (within NEAR of the head, m) the face moves at most STEP
# (m) per RL step: PFL allows 5 mm per step there anyway, and a longer
# straight joint-space step bends the face's path (the Schunk's face
# drifted 2.5 cm sideways over a 7 cm stroke and missed the head).
NEAR = 0.15
STEP = 0.02


@experts.register('hammering', 'robot_hammers')
class RobotHammersExpert(base.Expert):
  """Drives the nail with blows (hammering/robot_hammers). Reads
  observables only, plus its own blow phase.

  Args:
    env: the environment (hrc_suite.suite.load) whose task it solves.
  """

  OBSERVED = ('eef_position', 'eef_quaternion', 'joint_positions',
              'nail_head_position', 'hammer_head_position', 'nail_progress',
              'board_placed', 'object_gripped')
  TASKS = (('hammering', 'robot_hammers'),)

  def __init__(self, env: composer.Environment):
    super().__init__(env)
    self._steer = steering.Steering(self._task)
    home = self._task.robot.description.q_home
    self._wait = self._task.kinematics.tcp_pose(home)[:3, 3].copy()
    self.reset()

  def reset(self) -> None:
    """Forgets the blow phase (not striking)."""
    self._striking = False
    self._on_head = 0

  def action(self, observation: Mapping[str, np.ndarray]) -> np.ndarray:
    """The action now.

    Args:
      observation: the OBSERVED observables now (`base.Expert.observe`).

    Returns:
      The action: the hammer face towards
      `face_goal`, at most STEP near the nail, gripper closed.
    """
    tcp = observation['eef_position']
    q = observation['joint_positions']
    if self._steer.space == 'joint':
      self._steer.yaw = rotations.quat_yaw(observation['eef_quaternion'])
    face = observation['hammer_head_position']
    move = self.face_goal(observation) - face
    near = np.linalg.norm(face - observation['nail_head_position']) < NEAR
    length = np.linalg.norm(move)
    if near and length > STEP:
      move *= STEP / length
    return self._steer.action(tcp + move, tcp, q, GRIPPER_CLOSED)

  def face_goal(self, observation: Mapping[str, np.ndarray]) -> np.ndarray:
    """Where the hammer face should go now; updates the blow phase.

    Args:
      observation: the OBSERVED observables now.

    Returns:
      The face's goal (3,), world, m.
    """
    face = observation['hammer_head_position']
    head = observation['nail_head_position']
    tcp = observation['eef_position']
    if observation['board_placed'][0] < 0.5:
      self.reset()
      return self._wait + face - tcp
    if observation['nail_progress'][0] > hammering_robot.SUCCESS_PROGRESS:
      self.reset()
      if face[2] < head[2] + LIFT - 0.01:
        return np.array([face[0], face[1], head[2] + LIFT])
      return self._wait + face - tcp
    hover = head + [0.0, 0.0, HOVER]
    lateral = np.linalg.norm(face[:2] - head[:2])
    if self._striking and lateral > MISS:
      self._striking = False
    if not self._striking:
      if abs(face[2] - hover[2]) < 0.01 and lateral < ALIGN:
        self._striking = True
        self._on_head = 0
      elif face[2] < hover[2] - 0.01 and lateral > ALIGN:
        return np.array([face[0], face[1], hover[2]])   # up first
      else:
        return hover
    if face[2] < head[2] + ON_HEAD:
      self._on_head += 1
    if self._on_head >= CONTACT_STEPS:
      self._striking = False
      return hover
    return head - [0.0, 0.0, PRESS]
