"""Inspection expert: picks the cube, presents it at the target, holds it
through the inspection (the Schunk succeeds in 2 of 3 seeds)."""

import numpy as np
import pytest

from hrc_suite import experts
from hrc_suite import suite
from hrc_suite.experts import inspection as inspection_expert
from hrc_suite.tasks import inspection
from hrc_suite.tasks.runtime import metrics


def _env(robot='schunk', space='cartesian', seed=0, **kwargs):
  return suite.load('inspection', 'default', task_kwargs={
      'robot': robot, 'action_space': space, **kwargs},
                    environment_kwargs={'random_state': seed})


def test_presents_the_cube_at_the_target_quickly():
  env = _env('schunk', 'cartesian', seed=1, time_limit=15.0)
  expert = experts.make(env)
  assert isinstance(expert, inspection_expert.InspectionExpert)
  timestep = env.reset()
  phases = []
  while not timestep.last():
    timestep = env.step(expert(timestep))
    phases.append(expert.phase)
    if env.task.episode_metrics['presentations']:
      break
  task = env.task
  assert task.episode_metrics['presentations'] == 1
  assert phases[0] == 'approach'
  assert phases.index('close') < phases.index('lift') < phases.index(
      'present')
  assert timestep.observation['object_gripped'][0] == 1.0
  distance = np.linalg.norm(task.cube.position(env.physics)
                            - task.target_position)
  assert distance <= inspection.SUCCESS_DISTANCE


@pytest.mark.slow
@pytest.mark.parametrize('space', ('cartesian', 'joint'))
def test_schunk_two_of_three(space):
  successes = 0
  for seed in range(3):
    env = _env('schunk', space, seed=seed)
    result = metrics.run_episode(env, experts.make(env))
    assert result['contacts_human_critical'] == 0
    assert result['contacts_static'] == 0
    if result['success']:
      assert result['presentations'] == 1
      assert env.task.step_metrics['reward'] == inspection.SUCCESS_REWARD
    successes += int(result['success'])
  assert successes >= 2


def test_takes_over_from_a_snapshot_and_holds_the_cube_to_success():
  # A snapshot taken while presenting, restored in another environment;
  # a fresh expert (no memory) keeps the cube at the target, through the
  # person's inspection, until success.
  env = _env('panda', 'joint', seed=2)
  expert = experts.make(env)
  timestep = env.reset()
  while not env.task.episode_metrics['presentations']:
    timestep = env.step(expert(timestep))
  state = env.task.get_state(env.physics)
  other = _env('panda', 'joint', seed=7)
  timestep = other.reset()
  other.task.set_state(other.physics, state)
  fresh = experts.make(other)
  phases = []
  while not timestep.last():
    timestep = other.step(fresh(timestep))
    phases.append(fresh.phase)
  assert set(phases) == {'present'}
  assert other.task.episode_metrics['success'] == 1.0
  assert other.task.episode_metrics['contacts_human_critical'] == 0
