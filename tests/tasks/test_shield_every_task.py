"""Shield integration over every registered task: random actions with the
task's default shield make no critical human contact; with the shield off,
a robot driven into the person does, so the monitor sees them (and the
shield, on, stops the same robot)."""

import numpy as np
import pytest

from hrc_suite import suite
from hrc_suite.human import keypoints
from hrc_suite.tasks.runtime import actions
from hrc_suite.tasks.runtime import contacts
from hrc_suite.tasks.runtime import metrics

# RL steps of random actions per task: default run and @slow run.
STEPS = 300
SLOW_STEPS = 1500
EPISODE_TIME = 10.0      # s, 100 RL steps (episodes may end earlier)
# Robots: the default one and one with a short reach.
ROBOTS = ('panda', 'schunk')


def _random_policy(env, seed):
  rs = np.random.RandomState(seed)
  shape = env.action_spec().shape
  return lambda timestep: rs.uniform(-1.0, 1.0, shape)


def _shielded_random_run(domain, task, robot, steps, seed=0):
  """Episodes of random actions with the task's default shield until
  `steps` RL steps have run. Returns the summed metrics."""
  env = suite.load(domain, task, task_kwargs={
      'robot': robot, 'done_at_success': False, 'time_limit': EPISODE_TIME},
                   environment_kwargs={'random_state': seed})
  assert env.task.shield_mode != 'off'
  totals = {'steps': 0, 'episodes': 0, 'min_human_distance': np.inf}
  episode = 0
  while totals['steps'] < steps:
    result = metrics.run_episode(env, _random_policy(env, seed + episode))
    episode += 1
    totals['episodes'] += 1
    totals['steps'] += int(result['steps'])
    totals['min_human_distance'] = min(totals['min_human_distance'],
                                       result['min_human_distance'])
    for name in ('contacts_human_critical', 'contacts_human_allowed',
                 'shield_interventions'):
      totals[name] = totals.get(name, 0) + result[name]
  return totals


@pytest.mark.parametrize('domain, task', suite.ALL_TASKS)
def test_random_actions_make_no_critical_contact(domain, task):
  totals = _shielded_random_run(domain, task, 'panda', STEPS)
  assert totals['steps'] >= STEPS
  assert totals['contacts_human_critical'] == 0, totals


@pytest.mark.slow
@pytest.mark.parametrize('robot', ROBOTS)
@pytest.mark.parametrize('domain, task', suite.ALL_TASKS)
def test_many_random_episodes_make_no_critical_contact(domain, task, robot):
  totals = _shielded_random_run(domain, task, robot, SLOW_STEPS, seed=11)
  assert totals['contacts_human_critical'] == 0, totals


def _chase_the_hands(shield, seed=0, steps=80):
  """Pick and place with the person close: the TCP chases the person's
  nearer hand at full Cartesian speed, collision prevention off."""
  env = suite.load('pick_place', 'close', task_kwargs={
      'shield': shield, 'collision_prevention': 'off',
      'done_at_success': False, 'time_limit': steps / 10},
                   environment_kwargs={'random_state': seed})
  task = env.task
  hands = [keypoints.KEYPOINT_INDEX[f'{side}_hand']
           for side in ('left', 'right')]

  def policy(timestep):
    del timestep
    physics = env.physics
    tcp = physics.bind(task.robot.tcp_site).xpos
    offsets = task.human.keypoint_positions(physics)[hands] - tcp
    nearer = offsets[np.argmin(np.linalg.norm(offsets, axis=1))]
    return np.append(np.clip(nearer / actions.CARTESIAN_STEP, -1, 1), 1.0)

  return metrics.run_episode(env, policy)


def test_monitor_sees_critical_contacts_without_the_shield():
  unshielded = _chase_the_hands('off')
  assert unshielded['contacts_human_critical'] > 0, unshielded
  assert unshielded['max_human_contact_speed'] > (
      contacts.SSM_STOPPED_SPEED), unshielded
  # The same chase with the task's shield (SSM) makes none.
  shielded = _chase_the_hands(None)
  assert shielded['contacts_human_critical'] == 0, shielded
  assert shielded['shield_interventions'] > 0, shielded
