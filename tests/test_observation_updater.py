"""suite.Environment's OneStepUpdater gives composer's observations."""

from dm_control.composer.observation import updater as composer_updater
import numpy as np
import pytest

from hrc_suite import observation_updater
from hrc_suite import suite


def _episode(domain, task, steps, plain, **task_kwargs):
  """Observations of `steps` random RL steps (composer's Updater if
  plain), and the updater used."""
  env = suite.load(domain, task, task_kwargs=dict(seed=0, **task_kwargs),
                   environment_kwargs={'random_state': 0})
  if plain:   # The same updater's arguments, composer's class.
    lean = env._observation_updater
    env._observation_updater = composer_updater.Updater(
        env.task.observables, env.task.physics_steps_per_control_step,
        lean._strip_singleton_buffer_dim, lean._pad_with_initial_value)
  spec = env.action_spec()
  rng = np.random.RandomState(0)
  timestep = env.reset()
  seen = [timestep.observation]
  for _ in range(steps):
    action = rng.uniform(spec.minimum, spec.maximum).astype(spec.dtype)
    timestep = env.step(action)
    seen.append(timestep.observation)
    if timestep.last():
      timestep = env.reset()
      seen.append(timestep.observation)
  return seen, env._observation_updater


@pytest.mark.parametrize('domain, task, kwargs', [
    ('stacking', 'default', {'observations': 'full'}),
    ('pick_place', 'default', {'observation_noise': {'eef_to_object': 0.01}}),
    ('handover', 'robot_to_human', {'robot': 'panda'}),
    # A delayed observable: 25 composer substeps, composer's schedule.
    ('reach', 'dense', {'observation_delay': {'goal_difference': 0.008}}),
])
def test_observations_are_composers(domain, task, kwargs):
  lean, used = _episode(domain, task, 120, plain=False, **kwargs)
  plain, _ = _episode(domain, task, 120, plain=True, **kwargs)
  assert isinstance(used, observation_updater.OneStepUpdater)
  assert used._once_per_step == ('observation_delay' not in kwargs)
  assert len(lean) == len(plain)
  for got, expected in zip(lean, plain):
    assert list(got) == list(expected)
    for name in got:
      assert got[name].dtype == expected[name].dtype, name
      np.testing.assert_array_equal(got[name], expected[name], err_msg=name)
