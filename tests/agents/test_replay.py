"""Tests of agents/replay.py."""

import numpy as np
import pytest

from agents import replay


def _add_numbered(buffer, first, count):
  """Transitions whose every entry equals their number."""
  for number in range(first, first + count):
    buffer.add(np.full(buffer.observation_size, number), np.full(
        buffer.action_size, number), number, number,
               np.full(buffer.observation_size, number))


def test_ring_buffer_wraps_and_keeps_the_newest():
  buffer = replay.ReplayBuffer(capacity=5, observation_size=3, action_size=2)
  _add_numbered(buffer, 0, 8)
  assert len(buffer) == 5
  state = buffer.state()
  assert int(state['insert_index']) == 3
  # Slots 0-2 hold 5, 6, 7 (overwritten), slots 3-4 hold 3, 4.
  np.testing.assert_array_equal(state['reward'], [5, 6, 7, 3, 4])
  np.testing.assert_array_equal(state['observation'][:, 0], [5, 6, 7, 3, 4])
  sample = buffer.sample(200, np.random.RandomState(0))
  assert set(sample.reward.tolist()) == {3.0, 4.0, 5.0, 6.0, 7.0}
  for field in ('observation', 'action', 'discount', 'next_observation'):
    values = getattr(sample, field)
    np.testing.assert_array_equal(
        values, np.broadcast_to(sample.reward.reshape(
            (-1,) + (1,) * (values.ndim - 1)), values.shape))


def test_add_batch_larger_than_capacity_keeps_the_last_rows():
  buffer = replay.ReplayBuffer(capacity=4, observation_size=1, action_size=1)
  numbers = np.arange(10.0)
  buffer.add_batch(numbers[:, None], numbers[:, None], numbers, numbers,
                   numbers[:, None])
  assert len(buffer) == 4
  assert sorted(buffer.state()['reward'].tolist()) == [6.0, 7.0, 8.0, 9.0]


def test_sampling_is_uniform():
  buffer = replay.ReplayBuffer(capacity=10, observation_size=1, action_size=1)
  _add_numbered(buffer, 0, 10)
  draws = 100_000
  sample = buffer.sample(draws, np.random.RandomState(1))
  counts = np.bincount(sample.reward.astype(int), minlength=10)
  expected = draws / 10
  chi_square = np.sum((counts - expected) ** 2 / expected)
  # 99.9th percentile of chi-square with 9 degrees of freedom: 27.88.
  assert chi_square < 27.88, counts


def test_same_random_state_same_sample():
  buffer = replay.ReplayBuffer(capacity=50, observation_size=2, action_size=1)
  _add_numbered(buffer, 0, 30)
  first = buffer.sample(16, np.random.RandomState(3))
  second = buffer.sample(16, np.random.RandomState(3))
  for a, b in zip(first, second):
    np.testing.assert_array_equal(a, b)


def test_state_round_trip_is_exact_and_continues_identically():
  original = replay.ReplayBuffer(capacity=6, observation_size=2,
                                 action_size=1)
  random_state = np.random.RandomState(0)
  for _ in range(9):
    original.add(random_state.randn(2), random_state.randn(1),
                 random_state.randn(), 1.0, random_state.randn(2))
  copy = replay.ReplayBuffer(capacity=6, observation_size=2, action_size=1)
  copy.restore(original.state())
  assert len(copy) == len(original)
  for key, value in original.state().items():
    np.testing.assert_array_equal(copy.state()[key], value)
  _add_numbered(original, 100, 2)
  _add_numbered(copy, 100, 2)
  for key, value in original.state().items():
    np.testing.assert_array_equal(copy.state()[key], value)
  for a, b in zip(original.sample(32, np.random.RandomState(5)),
                  copy.sample(32, np.random.RandomState(5))):
    np.testing.assert_array_equal(a, b)


def test_partial_buffer_round_trip():
  original = replay.ReplayBuffer(capacity=100, observation_size=2,
                                 action_size=1)
  _add_numbered(original, 0, 7)
  state = original.state()
  assert state['observation'].shape == (7, 2)
  copy = replay.ReplayBuffer(capacity=100, observation_size=2, action_size=1)
  copy.restore(state)
  assert len(copy) == 7 and int(copy.state()['insert_index']) == 7


def test_bad_input_is_rejected():
  with pytest.raises(ValueError, match='capacity=0'):
    replay.ReplayBuffer(capacity=0, observation_size=2, action_size=1)
  buffer = replay.ReplayBuffer(capacity=4, observation_size=2, action_size=1)
  with pytest.raises(ValueError, match='empty'):
    buffer.sample(1, np.random.RandomState(0))
  with pytest.raises(ValueError, match=r'observation has shape \(1, 3\)'):
    buffer.add(np.zeros(3), np.zeros(1), 0.0, 1.0, np.zeros(2))
  with pytest.raises(ValueError, match='batch size 2'):
    buffer.add_batch(np.zeros((3, 2)), np.zeros((2, 1)), np.zeros(3),
                     np.zeros(3), np.zeros((3, 2)))
  _add_numbered(buffer, 0, 1)
  with pytest.raises(TypeError, match='RandomState'):
    buffer.sample(1, 0)
  other = replay.ReplayBuffer(capacity=8, observation_size=2, action_size=1)
  with pytest.raises(ValueError, match='capacity 4, expected 8'):
    other.restore(buffer.state())
