"""The environments pass gymnasium's checker when wrapped with shimmy."""

import os

os.environ.setdefault('MUJOCO_GL', 'egl')

import numpy as np
import pytest

shimmy = pytest.importorskip(
    'shimmy', reason='needs the [gym] extra: pip install -e ".[gym]"')
from gymnasium.utils import env_checker  # pylint: disable=g-import-not-at-top

from hrc_suite import suite


@pytest.mark.parametrize('domain, task, robot', [
    ('reach', 'dense', 'panda'),
    ('pick_place', 'default', 'schunk'),
    ('handover', 'robot_to_human', 'panda'),
])
def test_gymnasium_check_env(domain, task, robot):
  env = suite.load(domain, task, task_kwargs=dict(robot=robot, seed=0))
  gym_env = shimmy.DmControlCompatibilityV0(env)
  env_checker.check_env(gym_env, skip_render_check=True)
  observation, _ = gym_env.reset(seed=3)
  assert gym_env.observation_space.contains(observation)
  action = gym_env.action_space.sample()
  observation, reward, terminated, truncated, _ = gym_env.step(action)
  assert np.isfinite(reward)
  assert isinstance(terminated, bool) and isinstance(truncated, bool)
  gym_env.close()
