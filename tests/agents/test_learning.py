"""Tests of agents/sac/learning.py."""

import jax
import numpy as np
import pytest

from agents import config as config_lib
from agents import replay
from agents.sac import learning
from agents.sac import networks

OBSERVATION_SIZE = 4
ACTION_SIZE = 2


def _learner(seed=0, **overrides):
  config = config_lib.default_config(hidden_sizes=(32, 32), **overrides)
  nets = networks.make_networks(OBSERVATION_SIZE, ACTION_SIZE,
                                config.hidden_sizes)
  return learning.SACLearner(nets, config, OBSERVATION_SIZE, ACTION_SIZE,
                             seed)


def _batch(size=64, seed=0):
  random_state = np.random.RandomState(seed)
  observation = random_state.randn(size, OBSERVATION_SIZE).astype(np.float32)
  return replay.Transition(
      observation=observation,
      action=random_state.uniform(-1, 1, (size, ACTION_SIZE)).astype(
          np.float32),
      reward=observation[:, 0].copy(),
      discount=(random_state.rand(size) > 0.1).astype(np.float32),
      next_observation=random_state.randn(size, OBSERVATION_SIZE).astype(
          np.float32),
      cost=(random_state.rand(size) > 0.7).astype(np.float32))


def _leaves(tree):
  return [np.asarray(leaf) for leaf in jax.tree_util.tree_leaves(tree)]


def test_critic_loss_decreases_on_a_fixed_batch():
  learner = _learner(learning_rate=1e-3)
  batch = _batch()
  first = learner.update(batch)['critic_loss']
  for _ in range(300):
    last = learner.update(batch)['critic_loss']
  assert last < 0.2 * first, (first, last)
  assert learner.steps == 301


def test_terminal_targets_are_the_scaled_rewards():
  batch = _batch()._replace(discount=np.zeros(64, np.float32))
  for scale in (1.0, 20.0):
    metrics = _learner(reward_scale=scale).update(batch)
    assert metrics['target_q_values'] == pytest.approx(
        scale * batch.reward.mean(), rel=1e-5)


def test_temperature_falls_while_entropy_is_above_target():
  learner = _learner(target_entropy=-10.0, learning_rate=1e-2)
  metrics = [learner.update(_batch(seed=i)) for i in range(30)]
  assert metrics[0]['entropy'] > -10.0
  temperatures = [m['temperature'] for m in metrics]
  assert temperatures[0] == pytest.approx(1.0)
  assert np.all(np.diff(temperatures) < 0)
  assert learner.temperature < 0.8


def test_temperature_rises_while_entropy_is_below_target():
  # A tanh-squashed policy on [-1, 1]^2 has entropy at most 2 log 2 < 3.
  learner = _learner(target_entropy=3.0, learning_rate=1e-2)
  metrics = [learner.update(_batch(seed=i)) for i in range(30)]
  temperatures = [m['temperature'] for m in metrics]
  assert np.all(np.diff(temperatures) > 0)
  assert learner.temperature > 1.2


def test_target_critics_follow_by_polyak_averaging():
  learner = _learner(tau=0.1)
  before = _leaves(learner.training_state.target_q_params)
  learner.update(_batch())
  state = learner.training_state
  online = _leaves(state.q_params)
  for old, new, current in zip(before, _leaves(state.target_q_params),
                               online):
    np.testing.assert_allclose(new, 0.9 * old + 0.1 * current, rtol=1e-5,
                               atol=1e-7)


def test_scanned_steps_equal_single_steps():
  sequential, scanned = _learner(seed=3), _learner(seed=3)
  batches = [_batch(seed=i) for i in range(4)]
  metrics = [dict(sequential.update(batch)) for batch in batches]
  stacked = replay.Transition(*(np.stack(field) for field in zip(*batches)))
  fused = scanned.update_steps(stacked)
  assert scanned.steps == sequential.steps == 4
  # A fused call reports the mean of its steps' metrics.
  for name in learning.METRIC_NAMES:
    assert fused[name] == pytest.approx(
        np.mean([m[name] for m in metrics]), rel=1e-4, abs=1e-6), name
  for a, b in zip(_leaves(sequential.training_state),
                  _leaves(scanned.training_state)):
    np.testing.assert_allclose(a, b, rtol=1e-4, atol=1e-5)


def test_background_compilation_leaves_the_state_and_serves_updates():
  # A batch size no other test uses: the compilation is this test's own.
  learner, reference = _learner(seed=5), _learner(seed=5)
  stacked = replay.Transition(*(np.stack(field) for field in zip(
      _batch(size=24, seed=0), _batch(size=24, seed=1))))
  compiled = learner._functions.sgd_steps   # pylint: disable=protected-access
  before = compiled._cache_size()
  learner.compile_in_background(stacked).join()
  assert compiled._cache_size() == before + 1
  assert learner.steps == 0
  for a, b in zip(_leaves(learner.training_state),
                  _leaves(reference.training_state)):
    np.testing.assert_array_equal(a, b)
  learner.update_steps(stacked)   # Served by that compilation.
  assert compiled._cache_size() == before + 1 and learner.steps == 2


def test_state_round_trip_is_exact_and_continues_identically():
  original = _learner(seed=0)
  for i in range(3):
    original.update(_batch(seed=i))
  state = original.state()
  assert 'policy_params/params/MLP_0/Dense_0/kernel' in state
  assert all(isinstance(value, np.ndarray) for value in state.values())
  restored = _learner(seed=7)
  restored.restore(state)
  for key, value in state.items():
    np.testing.assert_array_equal(restored.state()[key], value)
  assert original.update(_batch(seed=9)) == restored.update(_batch(seed=9))
  for key, value in original.state().items():
    np.testing.assert_array_equal(restored.state()[key], value)


def test_restore_rejects_mismatched_state():
  learner = _learner()
  state = learner.state()
  del state['log_temperature']
  with pytest.raises(ValueError, match="missing \\['log_temperature'\\]"):
    learner.restore(state)
  state = learner.state()
  state['log_temperature'] = np.zeros(2, np.float32)
  with pytest.raises(ValueError, match="'log_temperature' has shape"):
    learner.restore(state)


def test_bad_batch_shape_is_rejected():
  learner = _learner()
  batch = _batch()._replace(action=np.zeros((64, 3), np.float32))
  with pytest.raises(ValueError, match=r'action has shape \(64, 3\)'):
    learner.update(batch)


def test_update_metrics_are_floats_read_when_needed():
  learner = _learner()
  metrics = learner.update(_batch())
  # Names and length do not wait for the update; values are plain floats.
  assert 'critic_loss' in list(metrics) and len(metrics) == len(dict(metrics))
  assert all(isinstance(value, float) and np.isfinite(value)
             for value in metrics.values())
  assert dict(metrics) == dict(metrics)   # Fetched once, then kept.
