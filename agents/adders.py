"""The one writer of transitions into replay (Acme's adder).

The actor side of an agent hands every timestep to a `TransitionAdder`:
`add_first(timestep)` at an episode's start, `add(action, next_timestep)`
after each step. The adder flattens observations, normalises the action
and writes (s, a, r, discount, s', cost) to the replay buffer
(agents/replay.py); it tracks the episode's summed cost and reports it at
the episode's end to whoever asked (`on_episode_cost`, e.g. a Lagrangian
learner's multiplier).

The cost of a step is read from the next timestep's observation entry
`cost_key` (the 'cost' observable of hrc_suite's 'safe_rl' preset: the
step's safety cost, hrc_suite/tasks/runtime/cost.py); without one it is 0.
"""

from typing import Any, Callable, Dict, Mapping, Optional

import dm_env
import numpy as np

from agents import replay as replay_lib

# Name of the cost observable (hrc_suite/tasks/runtime/observations.py,
# COST_OBSERVABLES; the observation entries that are signals, not state).
COST_KEY = 'cost'
COST_OBSERVATIONS = ('cost', 'cost_components')


def step_cost(observation: Mapping[str, Any],
              cost_key: Optional[str]) -> float:
  """The cost an observation reports under `cost_key`, or 0 without one.

  Args:
    observation: a timestep's observation.
    cost_key: the entry holding the step's cost, or None.

  Returns:
    The cost.

  Raises:
    ValueError: an entry that is not one value.
  """
  if cost_key is None:
    return 0.0
  value = np.asarray(observation[cost_key])
  if value.size != 1:
    raise ValueError(f'Observation {cost_key!r} has shape {value.shape}: '
                     'expected one value (the step\'s scalar cost)')
  return float(value.reshape(()))


class TransitionAdder:
  """Writes one transition per environment step into a replay buffer.

  Args:
    replay: the `agents.replay.ReplayBuffer`.
    flatten: observation dict -> float32 vector.
    normalise_action: environment action -> the replay's [-1, 1] action.
    cost_key: the observation entry holding the step's cost, or None.
    on_episode_cost: None or a function called with an episode's summed
      cost when its last step is added.
  """

  def __init__(self, replay: replay_lib.ReplayBuffer, flatten: Callable,
               normalise_action: Callable,
               cost_key: Optional[str] = None,
               on_episode_cost: Optional[Callable[[float], None]] = None):
    self._replay = replay
    self._flatten = flatten
    self._normalise_action = normalise_action
    self._cost_key = cost_key
    self._on_episode_cost = on_episode_cost
    self._last_observation = None   # Flat observation before the next action.
    self._episode_cost = 0.0

  @property
  def cost_key(self) -> Optional[str]:
    """The observation entry holding the step's cost, or None."""
    return self._cost_key

  @property
  def episode_cost(self) -> float:
    """The summed cost of the episode so far."""
    return self._episode_cost

  def add_first(self, timestep: dm_env.TimeStep) -> None:
    """Starts an episode.

    Args:
      timestep: the episode's first timestep.
    """
    self._last_observation = self._flatten(timestep.observation)
    self._episode_cost = 0.0

  def add(self, action: np.ndarray, next_timestep: dm_env.TimeStep) -> None:
    """Stores (s, a, r, discount, s', cost) of the step to next_timestep.

    Args:
      action: the environment action taken.
      next_timestep: the timestep it led to.

    Raises:
      RuntimeError: if the episode was not started with `add_first`.
    """
    if self._last_observation is None:
      raise RuntimeError('observe() called before observe_first() of the '
                         'episode')
    next_observation = self._flatten(next_timestep.observation)
    cost = step_cost(next_timestep.observation, self._cost_key)
    self._replay.add(self._last_observation,
                     self._normalise_action(action),
                     np.float32(next_timestep.reward),
                     np.float32(next_timestep.discount), next_observation,
                     np.float32(cost))
    self._episode_cost += cost
    if next_timestep.last():
      self._last_observation = None
      if self._on_episode_cost is not None:
        self._on_episode_cost(self._episode_cost)
    else:
      self._last_observation = next_observation

  def state(self) -> Dict[str, np.ndarray]:
    """{name: array} of the episode in progress (for checkpoints)."""
    arrays = {}
    if self._last_observation is not None:
      arrays['last_observation'] = self._last_observation
    if self._cost_key is not None:
      arrays['episode_cost'] = np.float64(self._episode_cost)
    return arrays

  def restore(self, arrays: Mapping[str, np.ndarray]) -> None:
    """Restores a `state()`.

    Args:
      arrays: a `state()` (it may hold other entries too).
    """
    self._last_observation = arrays.get('last_observation')
    self._episode_cost = float(arrays.get('episode_cost', 0.0))
