"""The Gymnasium interface (hrc_suite/gym_env.py): registration, check_env
on every task, info['cost'], vector environments and SB3."""

import importlib.util
import subprocess
import sys
import textwrap
import warnings

import gymnasium
from gymnasium.utils import env_checker
import numpy as np
import pytest

from hrc_suite import gym_env
from hrc_suite import suite
from hrc_suite.tasks.runtime import cost as cost_lib


def test_every_task_is_registered():
  assert gym_env.ENV_IDS == tuple(
      f'hrc_suite/{domain}-{task}-v0' for domain, task in suite.ALL_TASKS)
  assert all(name in gymnasium.registry for name in gym_env.ENV_IDS)
  # Registering again changes nothing.
  assert tuple(gym_env.register_envs()) == gym_env.ENV_IDS


@pytest.mark.parametrize('name', gym_env.ENV_IDS)
def test_check_env_on_every_registered_task(name):
  env = gymnasium.make(name, time_limit=2.0)
  with warnings.catch_warnings():
    warnings.filterwarnings('error', message='.*WARN.*')
    # Unbounded observations (positions, velocities) are what they are
    # (a filter added later takes precedence).
    warnings.filterwarnings('ignore', message='.*infinity.*')
    env_checker.check_env(env.unwrapped)
  env.close()


def _episode(env, seed, steps=1000):
  observation, info = env.reset(seed=seed)
  rng = np.random.RandomState(seed)
  trace = [observation]
  for _ in range(steps):
    action = rng.uniform(-1, 1, env.action_space.shape).astype(np.float32)
    observation, reward, terminated, truncated, info = env.step(action)
    trace.append(observation)
    if terminated or truncated:
      break
  return np.array(trace), reward, terminated, truncated, info


def test_cost_in_info_and_metrics_at_the_end():
  env = gymnasium.make('hrc_suite/handover-robot_to_human-v0',
                       shield='off', time_limit=5.0, robot='panda')
  assert env.unwrapped.task.options.robot == 'panda'
  assert env.unwrapped.task.shield_mode == 'off'
  _, info = env.reset(seed=1)
  assert set(info) == set(cost_lib.metric_names())
  trace, _, terminated, truncated, info = _episode(env, 1)
  assert len(trace) == 51 and truncated and not terminated
  metrics = info['episode_metrics']
  assert metrics['steps'] == 50
  step = env.unwrapped.task.step_metrics
  for name in cost_lib.metric_names():
    assert info[name] == step[name]
  assert metrics['cost'] >= info['cost']
  # The same seed gives the same episode.
  again = _episode(env, 1)[0]
  assert np.array_equal(trace, again)
  env.close()
  env.close()   # twice is allowed


def test_terminated_at_success_and_dict_observations():
  env = gymnasium.make('hrc_suite/reach-dense-v0', flatten=False,
                       action_space='cartesian', robot='schunk')
  observation, _ = env.reset(seed=0)
  assert isinstance(env.observation_space, gymnasium.spaces.Dict)
  assert observation.keys() == env.observation_space.keys()
  # Toward the goal (the goal difference observed) until success.
  for _ in range(100):
    action = np.clip(observation['goal_difference'] * 10, -1, 1)
    observation, _, terminated, truncated, info = env.step(
        action.astype(np.float32))
    if terminated or truncated:
      break
  assert terminated and info['episode_metrics']['success'] == 1.0


def test_bad_arguments_are_named():
  with pytest.raises(ValueError, match="render_mode 'human'"):
    gymnasium.make('hrc_suite/reach-dense-v0', render_mode='human')
  with pytest.raises(ValueError, match='turns it off'):
    gymnasium.make('hrc_suite/reach-dense-v0', cost=None)
  with pytest.raises(ValueError, match='Unknown shield'):
    gymnasium.make('hrc_suite/reach-dense-v0', shield='ISO')
  env = gymnasium.make('hrc_suite/reach-dense-v0')
  env.reset(seed=0)
  with pytest.raises(ValueError, match=r'action of shape \(3,\)'):
    env.step(np.zeros(3))


def test_rendering():
  env = gymnasium.make('hrc_suite/reach-dense-v0', render_mode='rgb_array',
                       render_size=(48, 64))
  env.reset(seed=0)
  frame = env.render()
  assert frame.shape == (48, 64, 3) and frame.dtype == np.uint8
  assert frame.std() > 0


def test_vector_environments():
  envs = gymnasium.make_vec('hrc_suite/reach-dense-v0', num_envs=2,
                            vectorization_mode='sync', time_limit=1.0)
  observations, infos = envs.reset(seed=[3, 4])
  assert observations.shape == (2, 7)
  assert infos['cost'].shape == (2,)
  for _ in range(12):   # past the 10-step episodes: autoreset
    observations, rewards, terminated, truncated, infos = envs.step(
        envs.action_space.sample())
    assert rewards.shape == (2,) and infos['cost'].shape == (2,)
  envs.close()


@pytest.mark.skipif(
    importlib.util.find_spec('stable_baselines3') is None
    or importlib.util.find_spec('torch') is None,
    reason='Stable-Baselines3 and torch are not installed (pip install '
    'torch stable-baselines3)')
def test_sb3_sac_steps_a_registered_task():
  """In a fresh process: torch's triton imported into a process that has
  rendered with EGL (other tests here) crashes it (README.md, "Training
  with Stable-Baselines3")."""
  program = textwrap.dedent("""
      import gymnasium
      import hrc_suite.gym_env
      from stable_baselines3 import SAC
      env = gymnasium.make('hrc_suite/reach-dense-v0', time_limit=2.0)
      model = SAC('MlpPolicy', env, learning_starts=20, batch_size=16,
                  seed=0)
      model.learn(total_timesteps=60)
      print('timesteps', model.num_timesteps)
  """)
  result = subprocess.run([sys.executable, '-c', program],
                          capture_output=True, text=True, timeout=900,
                          check=False)
  assert result.returncode == 0, result.stderr[-2000:]
  assert 'timesteps 60' in result.stdout
