"""The hammering/robot_hammers expert drives the nail with the hammer in
its gripper, without touching the person, on synthetic and recorded people
(marked `recordings`, tests/conftest.py)."""

import numpy as np
import pytest

from hrc_suite import experts
from hrc_suite import suite
from hrc_suite.experts import hammering_robot as expert_lib
from hrc_suite.human import recording_cache

import expert_checks   # tests/experts/expert_checks.py


def _env(robot, space='cartesian', seed=0, **kwargs):
  return suite.load('hammering', 'robot_hammers', task_kwargs={
      'robot': robot, 'action_space': space, **kwargs},
                    environment_kwargs={'random_state': seed})


def _episode(env):
  expert = experts.make(env)
  assert isinstance(expert, expert_lib.RobotHammersExpert)
  timestep = env.reset()
  while not timestep.last():
    action = expert(timestep)
    assert action[-1] == expert_lib.GRIPPER_CLOSED
    timestep = env.step(action)
  return env.task.episode_metrics


def _assert_nail_driven_safely(metrics):
  assert metrics['success'] == 1.0
  assert metrics['nail_blows'] >= 1
  assert metrics['contacts_human_critical'] == 0
  # The hammer (an object) never touched the person either.
  assert metrics['contacts_human_object'] == 0
  assert metrics['physics_errors'] == 0


@pytest.mark.parametrize('robot,space,seed', (
    ('panda', 'cartesian', 0), ('schunk', 'joint', 1)))
def test_drives_the_nail_in_safely(robot, space, seed):
  _assert_nail_driven_safely(_episode(_env(robot, space, seed)))


def test_without_the_expert_the_nail_stays_out():
  """The check above can fail: held still, no blow, no success."""
  env = _env('panda', time_limit=20.0)
  timestep = env.reset()
  action = np.zeros(env.action_spec().shape)
  action[-1] = 1.0
  while not timestep.last():
    timestep = env.step(action)
  assert env.task.episode_metrics['success'] == 0.0
  assert env.task.episode_metrics['nail_blows'] == 0


def test_same_seed_same_actions():
  expert_checks.assert_same_seed_same_actions(
      lambda: _env('panda', seed=2, time_limit=8.0))


@pytest.mark.recordings
@pytest.mark.parametrize('robot', ('panda', 'schunk'))
def test_drives_the_nail_of_a_recorded_person(robot, tmp_path, monkeypatch,
                                              recordings_dir):
  monkeypatch.setenv(recording_cache.CACHE_ENV, str(tmp_path))
  env = _env(robot, seed=3, motions=str(recordings_dir),
             outside_human_model='allow')
  _assert_nail_driven_safely(_episode(env))
