"""A safety-test policy that drives the robot at the person.

Uniform random actions seldom reach the person: on the real recordings,
with the shield off, they touched the person critically only in pick and
place (docs/results/safety_real.md), so a count of zero critical contacts
elsewhere says little about the shield. `PersonChaser` aims the TCP at
the person's keypoint nearest to it (a hand, the head leaning in, ...), as
fast as the action space allows, every step, with the gripper closed (a
held object stays held): with the shield off it strikes every person who
comes within the robot's reach; with the shield on the same episodes must
have no critical contact. Deterministic; any task with a person.

* Cartesian actions: the TCP step points at that keypoint (gripper-down,
  as every Cartesian action: a person beyond that reach stays untouched).
* Joint actions: the whole arm goes down the gradient of its distance to
  the person (robot capsules to body capsules, the shield's models; a
  finite-difference gradient), a full joint step along the steepest
  joint: any link, at any orientation, that can reach the person does.
"""

from typing import Mapping

from dm_control import composer
import numpy as np

from hrc_suite.experts import base
from hrc_suite.experts import steering
from hrc_suite.safety import geometry

CLOSED = 1.0
# Joint perturbation of the finite-difference gradient (rad).
GRADIENT_STEP = 1e-4


class PersonChaser(base.Expert):
  """Drives the robot at the person as fast as it can (see module doc).

  Privileged: none (the task's own observables, noise-free).

  Args:
    env: the environment (hrc_suite.suite.load) of a task with a person.
  """

  OBSERVED = ('eef_position', 'joint_positions', 'human_keypoints')
  # A safety test drives at the person as it is told: no detours.
  REPLANS = False

  def __init__(self, env: composer.Environment):
    super().__init__(env)
    self._steer = steering.Steering(self._task)
    self._gripper = CLOSED if self._steer.has_gripper else None
    shield = self._task.shield
    self._robot_capsules = shield.robot.capsules
    self._body_capsules = shield.human.body_capsules

  def action(self, observation: Mapping[str, np.ndarray]) -> np.ndarray:
    """The action now.

    Args:
      observation: the OBSERVED observables now (`base.Expert.observe`).

    Returns:
      The action: the TCP (Cartesian) or the arm (joint) towards the
      person, gripper closed.
    """
    q = observation['joint_positions']
    points = observation['human_keypoints']
    if self._steer.space == 'joint':
      arm = -self._distance_gradient(q, points)
      arm /= max(np.abs(arm).max(), 1e-12)
      return arm if self._gripper is None else np.append(arm, self._gripper)
    tcp = observation['eef_position']
    aim = points[int(np.argmin(np.linalg.norm(points - tcp, axis=1)))]
    return self._steer.action(aim, tcp, q, self._gripper)

  def distance(self, q: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Distance (m) between the robot's capsules and the person's body
    capsules.

    Args:
      q: joint positions (..., dof).
      points: the person's keypoints (the `human_keypoints` observable).

    Returns:
      The smallest capsule distance per configuration (...).
    """
    r1, r2, rr = self._robot_capsules(np.asarray(q, dtype=float))
    h1, h2, hr = self._body_capsules(points)
    return geometry.capsule_distance(
        r1[..., :, None, :], r2[..., :, None, :], rr[:, None], h1, h2,
        hr).min(axis=(-2, -1))

  def _distance_gradient(self, q, points):
    """d/dq of `distance` (forward differences)."""
    q = np.asarray(q, dtype=float)
    batch = q + np.vstack([np.zeros(q.size),
                           GRADIENT_STEP * np.eye(q.size)])
    distance = self.distance(batch, points)
    return (distance[1:] - distance[0]) / GRADIENT_STEP
