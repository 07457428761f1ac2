"""Uniform replay: a NumPy ring buffer of float32 transitions.

A transition is (s, a, r, discount, s', cost): the cost is the task's safety
cost of the step (hrc_suite/tasks/runtime/cost.py; 0 where the environment
reports none), stored for the learners that constrain it.
"""

import collections
from typing import Dict, Mapping, Optional

import numpy as np

Transition = collections.namedtuple(
    'Transition',
    ['observation', 'action', 'reward', 'discount', 'next_observation',
     'cost'])

_FIELD_SHAPES = {  # Per-transition shape of each field (None: a size).
    'observation': 'observation_size',
    'action': 'action_size',
    'reward': None,
    'discount': None,
    'next_observation': 'observation_size',
    'cost': None,
}
# Fields a replay state may lack (states written before the field existed
# restore it as zeros).
_OPTIONAL_FIELDS = ('cost',)


class ReplayBuffer:
  """Fixed-capacity ring buffer; the oldest transitions are overwritten.

  `discount` is the environment's discount of the step (0 at termination,
  1 otherwise, also at a time-limit truncation); the learner multiplies it
  by its own gamma.

  Args:
    capacity: transitions kept, an integer >= 1.
    observation_size: the flat observation's size, an integer >= 1.
    action_size: the action's size, an integer >= 1.

  Raises:
    ValueError: a size that is not an integer >= 1.
  """

  def __init__(self, capacity: int, observation_size: int, action_size: int):
    for name, value in (('capacity', capacity),
                        ('observation_size', observation_size),
                        ('action_size', action_size)):
      if not isinstance(value, (int, np.integer)) or value < 1:
        raise ValueError(f'{name}={value!r}: expected an integer >= 1')
    self._capacity = int(capacity)
    self._observation_size = int(observation_size)
    self._action_size = int(action_size)
    self._data = {
        field: np.zeros((self._capacity,) + self._row_shape(field),
                        dtype=np.float32) for field in Transition._fields}
    self._insert_index = 0   # Slot the next transition goes to.
    self._size = 0

  def _row_shape(self, field):
    size_name = _FIELD_SHAPES[field]
    return () if size_name is None else (getattr(self, '_' + size_name),)

  @property
  def capacity(self) -> int:
    """Transitions kept."""
    return self._capacity

  @property
  def observation_size(self) -> int:
    """The flat observation's size."""
    return self._observation_size

  @property
  def action_size(self) -> int:
    """The action's size."""
    return self._action_size

  def __len__(self):
    return self._size

  def add(self, observation: np.ndarray, action: np.ndarray, reward: float,
          discount: float, next_observation: np.ndarray,
          cost: float = 0.0) -> None:
    """Stores one transition.

    Args:
      observation: (observation_size,) s.
      action: (action_size,) a, in [-1, 1].
      reward: r.
      discount: the environment's discount of the step.
      next_observation: (observation_size,) s'.
      cost: the step's safety cost.

    Raises:
      ValueError: a field of the wrong shape.
    """
    self.add_batch(np.asarray(observation)[None], np.asarray(action)[None],
                   np.asarray(reward)[None], np.asarray(discount)[None],
                   np.asarray(next_observation)[None],
                   np.asarray(cost)[None])

  def add_batch(self, observations: np.ndarray, actions: np.ndarray,
                rewards: np.ndarray, discounts: np.ndarray,
                next_observations: np.ndarray,
                costs: Optional[np.ndarray] = None) -> None:
    """Stores a batch of transitions in order (leading axis = batch).

    Args:
      observations: (batch, observation_size).
      actions: (batch, action_size).
      rewards: (batch,).
      discounts: (batch,).
      next_observations: (batch, observation_size).
      costs: (batch,), or None for zeros.

    Raises:
      ValueError: fields of the wrong shapes or batch sizes.
    """
    if costs is None:
      costs = np.zeros(np.shape(rewards), np.float32)
    values = dict(zip(Transition._fields, (
        observations, actions, rewards, discounts, next_observations,
        costs)))
    batch = None
    for field, value in values.items():
      value = np.asarray(value)
      expected = self._row_shape(field)
      if value.ndim != len(expected) + 1 or value.shape[1:] != expected:
        raise ValueError(f'{field} has shape {value.shape}, expected '
                         f'(batch,) + {expected}')
      if batch is None:
        batch = value.shape[0]
      elif value.shape[0] != batch:
        raise ValueError(f'{field} has batch size {value.shape[0]}, '
                         f'expected {batch} like the other fields')
      values[field] = value
    if batch > self._capacity:   # Only the newest `capacity` survive.
      values = {k: v[batch - self._capacity:] for k, v in values.items()}
      batch = self._capacity
    slots = (self._insert_index + np.arange(batch)) % self._capacity
    for field, value in values.items():
      self._data[field][slots] = value
    self._insert_index = int((self._insert_index + batch) % self._capacity)
    self._size = min(self._size + batch, self._capacity)

  def sample(self, batch_size: int,
             random_state: np.random.RandomState) -> Transition:
    """Transitions drawn uniformly with replacement.

    Args:
      batch_size: rows to draw.
      random_state: the draw's random numbers.

    Returns:
      A Transition of `batch_size` rows per field.

    Raises:
      ValueError: an empty buffer.
      TypeError: a random_state that is not a np.random.RandomState.
    """
    if self._size == 0:
      raise ValueError('Cannot sample from an empty replay buffer')
    if not isinstance(random_state, np.random.RandomState):
      raise TypeError('random_state must be a np.random.RandomState, got '
                      f'{type(random_state).__name__}')
    indices = random_state.randint(0, self._size, size=batch_size)
    return Transition(*(self._data[field][indices]
                        for field in Transition._fields))

  def state(self) -> Dict[str, np.ndarray]:
    """{name: array} of the stored transitions and the insertion index."""
    state = {'capacity': np.int64(self._capacity),
             'insert_index': np.int64(self._insert_index),
             'size': np.int64(self._size)}
    for field in Transition._fields:
      state[field] = self._data[field][:self._size].copy()
    return state

  def restore(self, state: Mapping[str, np.ndarray]) -> None:
    """Restores a `state()` of a buffer of the same capacity and sizes.

    Args:
      state: of `state()` (without 'cost': zeros).

    Raises:
      ValueError: another capacity, a bad size or index, or fields missing
        or of the wrong shapes.
    """
    capacity = int(state['capacity'])
    if capacity != self._capacity:
      raise ValueError(f'Replay state has capacity {capacity}, expected '
                       f'{self._capacity}')
    size = int(state['size'])
    insert_index = int(state['insert_index'])
    if not 0 <= size <= capacity or not 0 <= insert_index < capacity:
      raise ValueError(f'Replay state has size {size} and insert_index '
                       f'{insert_index}, expected both in [0, {capacity}]')
    state = dict(state)
    for field in _OPTIONAL_FIELDS:
      if field not in state:
        state[field] = np.zeros((size,) + self._row_shape(field), np.float32)
    for field in Transition._fields:
      if field not in state:
        raise ValueError(f'Replay state lacks {field!r}: expected the '
                         f'fields {list(Transition._fields)}')
      expected = (size,) + self._row_shape(field)
      if state[field].shape != expected:
        raise ValueError(f'Replay state {field} has shape '
                         f'{state[field].shape}, expected {expected}')
    for field in Transition._fields:
      self._data[field][:size] = state[field]
      self._data[field][size:] = 0
    self._size = size
    self._insert_index = insert_index
