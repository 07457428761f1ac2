"""A safety-test policy that drives the TCP at the person's nearest point.

Uniform random actions seldom reach the person: on the real recordings,
with the shield off, they touched the person critically only in pick and
place (docs/results/safety_real.md), so a count of zero critical contacts
elsewhere says little about the shield. `PersonChaser` aims the TCP at
the person's keypoint nearest to it (a hand, the head leaning in, ...), as
fast as the action space allows, every step, with the gripper closed (a
held object stays held): with the shield off it strikes every person who
comes within the robot's reach; with the shield on the same episodes must
have no critical contact. Deterministic; it works in any task with a
person and either action space.
"""

import numpy as np

from hrc_suite.experts import base
from hrc_suite.experts import steering

CLOSED = 1.0


class PersonChaser(base.Expert):
  """Aims the TCP at the person's nearest keypoint (see module doc).

  Privileged: none (the task's own observables, noise-free)."""

  OBSERVED = ('eef_position', 'joint_positions', 'human_keypoints')

  def __init__(self, env):
    super().__init__(env)
    self._steer = steering.Steering(self._task)
    self._gripper = CLOSED if self._steer.has_gripper else None

  def action(self, observation):
    tcp = observation['eef_position']
    points = observation['human_keypoints']
    aim = points[int(np.argmin(np.linalg.norm(points - tcp, axis=1)))]
    return self._steer.action(aim, tcp, observation['joint_positions'],
                              self._gripper)
