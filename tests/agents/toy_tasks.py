"""Toy dm_env tasks for the agents' tests: small, fast, with known answers."""

import collections

import dm_env
from dm_env import specs as dm_specs
import numpy as np

STEP_SCALE = 0.2   # Toy task: position change per step at |action| = 1.


class PointReach(dm_env.Environment):
  """Move a point in [-1, 1]^2 to a goal; reward -distance; fixed horizon.

  With `terminate_at` the episode ends (discount 0) within that distance of
  the goal; otherwise it is truncated (discount 1) after `horizon` steps.
  """

  def __init__(self, seed, horizon=20, terminate_at=None,
               action_bounds=(-1.0, 1.0)):
    self._random_state = np.random.RandomState(seed)
    self._horizon = horizon
    self._terminate_at = terminate_at
    self._bounds = action_bounds

  def observation_spec(self):
    return collections.OrderedDict(
        position=dm_specs.Array((2,), np.float64, 'position'),
        goal=dm_specs.Array((2,), np.float64, 'goal'))

  def action_spec(self):
    return dm_specs.BoundedArray((2,), np.float64, [self._bounds[0]] * 2,
                                 [self._bounds[1]] * 2, 'move')

  def _observation(self):
    return collections.OrderedDict(position=self._position.copy(),
                                   goal=self._goal.copy())

  def reset(self):
    self._position = self._random_state.uniform(-1, 1, 2)
    self._goal = self._random_state.uniform(-1, 1, 2)
    self._steps = 0
    return dm_env.restart(self._observation())

  def step(self, action):
    low, high = self._bounds
    move = 2 * (np.clip(action, low, high) - low) / (high - low) - 1
    self._position = np.clip(self._position + STEP_SCALE * move, -1, 1)
    self._steps += 1
    distance = np.linalg.norm(self._position - self._goal)
    if self._terminate_at is not None and distance < self._terminate_at:
      return dm_env.termination(-distance, self._observation())
    if self._steps >= self._horizon:
      return dm_env.truncation(-distance, self._observation())
    return dm_env.transition(-distance, self._observation())


HAZARD_HORIZON = 20


class HazardousActions(dm_env.Environment):
  """A point in [-1, 1]^2 that moves by 0.1 x action; no reward; the step
  costs 1 where the action's first component is positive.

  A policy indifferent to the cost pays about HAZARD_HORIZON / 2 per
  episode; one that keeps the first component negative pays nothing. The
  cost is reported as the observation 'cost', as hrc_suite's 'safe_rl'
  preset does.
  """

  def __init__(self, seed):
    self._random_state = np.random.RandomState(seed)

  def observation_spec(self):
    return collections.OrderedDict(
        position=dm_specs.Array((2,), np.float64, 'position'),
        cost=dm_specs.Array((1,), np.float64, 'cost'))

  def action_spec(self):
    return dm_specs.BoundedArray((2,), np.float64, -1.0, 1.0, 'move')

  def _observation(self, cost):
    return collections.OrderedDict(position=self._position.copy(),
                                   cost=np.array([cost]))

  def reset(self):
    self._position = self._random_state.uniform(-1, 1, 2)
    self._steps = 0
    return dm_env.restart(self._observation(0.0))

  def step(self, action):
    self._position = np.clip(self._position + 0.1 * action, -1, 1)
    self._steps += 1
    observation = self._observation(float(action[0] > 0))
    if self._steps >= HAZARD_HORIZON:
      return dm_env.truncation(0.0, observation)
    return dm_env.transition(0.0, observation)
