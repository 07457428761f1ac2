"""The hammering expert: brings the nail to the person's target, holds the
board still under the blows, and gets the nail driven in."""

import numpy as np
import pytest

from hrc_suite import experts
from hrc_suite import suite
from hrc_suite.experts import hammering as hammering_expert
from hrc_suite.tasks.runtime import metrics


def _env(robot='schunk', space='cartesian', seed=0, time_limit=100.0):
  return suite.load('hammering', 'default', task_kwargs={
      'robot': robot, 'action_space': space, 'time_limit': time_limit,
      'observations': 'full'}, environment_kwargs={'random_state': seed})


@pytest.mark.parametrize('space', ('cartesian', 'joint'))
def test_brings_the_nail_to_the_target_and_holds_it(space):
  env = _env('panda', space, seed=1, time_limit=4.0)
  expert = experts.make(env)
  assert isinstance(expert, hammering_expert.HammeringExpert)
  timestep = env.reset()
  start = np.linalg.norm(timestep.observation['eef_to_target'])
  while not timestep.last():
    action = expert(timestep)
    assert action[-1] == 1.0
    timestep = env.step(action)
    assert env.task.step_metrics['object_gripped'] == 1.0
  offset = timestep.observation['eef_to_target'] + [
      0.0, 0.0, hammering_expert.HOLD_ABOVE_TARGET]
  assert start > 0.1
  assert np.linalg.norm(offset) < 0.01
  assert env.task.episode_metrics['contacts_human_critical'] == 0


def _successes(robot, space, seeds):
  successes = 0
  for seed in seeds:
    env = _env(robot, space, seed=seed)
    result = metrics.run_episode(env, experts.make(env))
    assert result['contacts_human_critical'] == 0
    assert env.task.step_metrics['object_gripped'] == 1.0   # never dropped
    successes += int(result['success'])
  return successes


@pytest.mark.slow
@pytest.mark.parametrize('robot', ('schunk', 'panda'))
def test_drives_the_nail_in(robot):
  # The quick table: 2 of 3 seeds (measured: 3 of 3 on both).
  assert _successes(robot, 'cartesian', (0, 1, 2)) >= 2


@pytest.mark.slow
def test_drives_the_nail_in_in_joint_space():
  assert _successes('schunk', 'joint', (0, 1, 2)) >= 2
