"""The person chaser: a test policy that can make the shield's check fail."""

import numpy as np
import pytest

from hrc_suite import suite
from hrc_suite.experts import adversary

STEPS = 150   # RL steps: the chaser reaches the synthetic person in ~50.


def _critical_contacts(shield=None, stop_at_first=False):
  """Episode metrics of the chaser (shield None: the task's default)."""
  kwargs = {'robot': 'panda'} if shield is None else {'robot': 'panda',
                                                      'shield': shield}
  env = suite.load('pick_place', 'close', task_kwargs=kwargs,
                   environment_kwargs={'random_state': 0})
  policy = adversary.PersonChaser(env)
  timestep = env.reset()
  for _ in range(STEPS):
    timestep = env.step(policy(timestep))
    metrics = env.task.episode_metrics
    if timestep.last() or (stop_at_first
                           and metrics['contacts_human_critical']):
      break
  return env.task.episode_metrics


def test_chaser_strikes_the_person_without_the_shield():
  metrics = _critical_contacts('off', stop_at_first=True)
  assert metrics['contacts_human_critical'] > 0
  assert metrics['min_human_distance'] < 0.0


def test_chaser_never_touches_critically_with_the_shield():
  metrics = _critical_contacts()
  assert metrics['contacts_human_critical'] == 0
  assert metrics['shield_interventions'] > 0


def test_chaser_aims_at_the_nearest_keypoint():
  env = suite.load('pick_place', 'close', task_kwargs={'robot': 'panda'},
                   environment_kwargs={'random_state': 0})
  policy = adversary.PersonChaser(env)
  timestep = env.reset()
  observation = policy.observe()
  tcp = observation['eef_position']
  points = observation['human_keypoints']
  nearest = points[np.argmin(np.linalg.norm(points - tcp, axis=1))]
  action = policy(timestep)
  # Cartesian action: the TCP step points at the nearest keypoint.
  direction = (nearest - tcp) / np.linalg.norm(nearest - tcp)
  step = action[:3] / np.linalg.norm(action[:3])
  assert step @ direction == pytest.approx(1.0, abs=1e-6)
  assert action[3] == adversary.CLOSED


def test_joint_chaser_brings_the_arm_to_the_person():
  env = suite.load('pick_place', 'close', task_kwargs={
      'robot': 'panda', 'shield': 'off', 'action_space': 'joint'},
                   environment_kwargs={'random_state': 0})
  policy = adversary.PersonChaser(env)
  timestep = env.reset()

  def distance():
    observation = policy.observe()
    return policy.distance(observation['joint_positions'],
                           observation['human_keypoints'])

  start = distance()
  for _ in range(20):
    timestep = env.step(policy(timestep))
  assert distance() < start - 0.1, (start, distance())
