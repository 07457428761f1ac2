"""Ornstein-Uhlenbeck noise statistics and the noisy expert."""

import dm_env
import numpy as np
import pytest

from hrc_suite.experts import base
from hrc_suite.experts import noise as noise_lib


def _chain(noise, steps, seed=0):
  noise.reset(seed)
  return np.stack([noise.sample() for _ in range(steps)])


def _lag_correlation(x, lag):
  """Time-average autocorrelation of the rows of x (steps, dims)."""
  centred = x - x.mean(axis=0)
  return np.mean(np.sum(centred[lag:] * centred[:-lag], axis=0)
                 / np.sum(centred**2, axis=0))


def test_long_chain_matches_stationary_std_and_autocorrelation():
  # The reference's joint-space parameters: phi = exp(-0.1) = 0.905.
  noise = noise_lib.OrnsteinUhlenbeckNoise.reference(3, 'joint')
  x = _chain(noise, 100_000)
  # Effective sample size ~ N (1 - phi) / (1 + phi) = 5000 per dimension.
  np.testing.assert_allclose(x.mean(axis=0), 0.0, atol=0.04)
  np.testing.assert_allclose(x.std(axis=0), 0.5, rtol=0.04)
  for lag in (1, 5, 20):
    assert abs(_lag_correlation(x, lag) - noise.autocorrelation(lag)[0]) < (
        0.02), lag


def test_ensemble_with_reference_defaults_is_stationary_from_the_start():
  # Default (Cartesian) parameters: phi = exp(-0.005), slow to decorrelate,
  # so check across many independent dimensions instead of over time.
  dims = 20_000
  noise = noise_lib.OrnsteinUhlenbeckNoise(dims)
  assert noise.phi[0] == pytest.approx(np.exp(-0.5 * 0.01))
  x = _chain(noise, 301)
  for k in (0, 100, 300):
    assert x[k].std() == pytest.approx(0.5, rel=0.03), k
    assert abs(x[k].mean()) < 0.02
  for lag in (1, 50, 300):
    r = np.corrcoef(x[0], x[lag])[0, 1]
    assert r == pytest.approx(noise.phi[0]**lag, abs=0.02), lag


def test_start_at_mean_and_per_dimension_parameters():
  noise = noise_lib.OrnsteinUhlenbeckNoise(
      2, alpha=[1.0, 50.0], sigma=[0.0, 1.0], mu=[0.3, -0.2], start='mean')
  noise.reset(4)
  np.testing.assert_array_equal(noise.sample(), [0.3, -0.2])
  x = np.stack([noise.sample() for _ in range(20_000)])
  # Zero sigma: the first dimension stays at its mean.
  np.testing.assert_array_equal(x[:, 0], 0.3)
  assert x[:, 1].mean() == pytest.approx(-0.2, abs=0.03)
  assert x[:, 1].std() == pytest.approx(1.0, rel=0.03)


def test_same_seed_same_sequence_other_seed_other_sequence():
  noise = noise_lib.OrnsteinUhlenbeckNoise(4)
  first = _chain(noise, 50, seed=7)
  np.testing.assert_array_equal(first, _chain(noise, 50, seed=7))
  np.testing.assert_array_equal(
      first, _chain(noise, 50, seed=np.random.RandomState(7)))
  assert not np.array_equal(first, _chain(noise, 50, seed=8))


def test_bad_parameters_name_the_value():
  cls = noise_lib.OrnsteinUhlenbeckNoise
  with pytest.raises(ValueError, match='size must be a positive integer'):
    cls(0)
  with pytest.raises(ValueError, match=r'alpha must be finite and > 0'):
    cls(2, alpha=0.0)
  with pytest.raises(ValueError, match=r'sigma must be finite and >= 0.*-1'):
    cls(2, sigma=-1.0)
  with pytest.raises(ValueError, match='sigma must be a number or 2 numbers'):
    cls(2, sigma=[0.1, 0.2, 0.3])
  with pytest.raises(ValueError, match='dt must be a positive number'):
    cls(2, dt=float('nan'))
  with pytest.raises(ValueError, match=r'weight must be a number in \[0, 1\]'):
    cls(2, weight=1.5)
  with pytest.raises(ValueError, match="Unknown start 'zero'"):
    cls(2, start='zero')
  with pytest.raises(ValueError, match="Unknown action_space 'polar'"):
    cls.reference(2, 'polar')
  with pytest.raises(ValueError, match='Expected a seed'):
    cls(2).reset(-3)
  with pytest.raises(RuntimeError, match='before reset'):
    cls(2).sample()


class _FixedExpert(base.Expert):
  """A constant action, for the wrapper's bookkeeping."""

  def __init__(self, env, value):
    self._env = env
    self._value = np.asarray(value, dtype=float)
    self._action_shape = self._value.shape
    self.resets = 0

  def reset(self):
    self.resets += 1

  def action(self, observation):
    return self._value

  def observe(self):
    return {}


class _Env:
  def __init__(self, n):
    self._n = n
    self.task = None

  def action_spec(self):
    return np.zeros(self._n)


def _first():
  return dm_env.restart({})


def _mid():
  return dm_env.transition(0.0, {})


def _episode(policy, steps):
  out = [policy(_first())]
  out += [policy(_mid()) for _ in range(steps - 1)]
  return np.stack(out)


def test_noisy_expert_mixes_clips_and_is_seeded_per_episode():
  value = np.array([0.5, -0.5, 1.0])
  noise = noise_lib.OrnsteinUhlenbeckNoise(3, weight=0.25)
  expert = _FixedExpert(_Env(3), value)
  noisy = noise_lib.NoisyExpert(expert, noise, seed=10)
  episodes = [_episode(noisy, 30) for _ in range(3)]
  assert expert.resets == 3
  np.testing.assert_array_equal(noisy.last_expert_action, value)
  # The executed action is (1 - w) a_e + w X, clipped.
  expected = np.clip(0.75 * value + 0.25 * noisy.last_noise, -1.0, 1.0)
  np.testing.assert_array_equal(episodes[-1][-1], expected)
  assert np.all(np.abs(episodes[-1]) <= 1.0)
  # Episode k draws from episode_random_state(seed, k): seed 10 episode 2
  # equals seed 12 episode 0, and set_episode jumps there directly.
  other = noise_lib.NoisyExpert(
      _FixedExpert(_Env(3), value),
      noise_lib.OrnsteinUhlenbeckNoise(3, weight=0.25), seed=12)
  np.testing.assert_array_equal(_episode(other, 30), episodes[2])
  # set_episode(1) on seed 12 is seed 13's episode 0.
  other.set_episode(1)
  jumped = _episode(other, 30)
  fresh = noise_lib.NoisyExpert(
      _FixedExpert(_Env(3), value),
      noise_lib.OrnsteinUhlenbeckNoise(3, weight=0.25), seed=13)
  np.testing.assert_array_equal(jumped, _episode(fresh, 30))
  assert not np.array_equal(episodes[0], episodes[1])


def test_noisy_expert_checks_shapes_and_first_timestep():
  expert = _FixedExpert(_Env(3), np.zeros(3))
  with pytest.raises(ValueError, match='noise has 2 dimensions'):
    noise_lib.NoisyExpert(expert, noise_lib.OrnsteinUhlenbeckNoise(2))
  noisy = noise_lib.NoisyExpert(expert, noise_lib.OrnsteinUhlenbeckNoise(3))
  with pytest.raises(RuntimeError, match='before any first timestep'):
    noisy(_mid())
  with pytest.raises(ValueError, match='episode must be an integer'):
    noisy.set_episode(-1)
