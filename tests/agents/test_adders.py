"""The adder: one transition per step, the cost read from the observation."""

import dm_env
import numpy as np
import pytest

from agents import adders
from agents import replay as replay_lib
from toy_tasks import HazardousActions


def test_transitions_carry_the_steps_cost_and_episodes_report_theirs():
  env = HazardousActions(0)
  replay = replay_lib.ReplayBuffer(100, 2, 2)
  reported = []
  adder = adders.TransitionAdder(
      replay, lambda o: np.asarray(o['position'], np.float32),
      lambda a: np.asarray(a), cost_key='cost',
      on_episode_cost=reported.append)
  random_state = np.random.RandomState(0)
  costs = []
  for _ in range(2):
    timestep = env.reset()
    adder.add_first(timestep)
    while not timestep.last():
      action = random_state.uniform(-1, 1, 2)
      timestep = env.step(action)
      adder.add(action, timestep)
      costs.append(float(action[0] > 0))
  state = replay.state()
  np.testing.assert_array_equal(state['cost'], costs)
  assert reported == [sum(costs[:20]), sum(costs[20:])]
  assert 0 < reported[0] < 20
  # Mid-episode state round-trips.
  timestep = env.reset()
  adder.add_first(timestep)
  timestep = env.step(np.array([1.0, 0.0]))
  adder.add(np.array([1.0, 0.0]), timestep)
  other = adders.TransitionAdder(replay, None, None, cost_key='cost')
  other.restore(adder.state())
  assert other.episode_cost == 1.0
  np.testing.assert_array_equal(other.state()['last_observation'],
                                adder.state()['last_observation'])


def test_without_a_cost_key_the_cost_is_zero_and_not_checkpointed():
  replay = replay_lib.ReplayBuffer(10, 2, 2)
  adder = adders.TransitionAdder(replay, lambda o: np.zeros(2, np.float32),
                                 np.asarray)
  adder.add_first(dm_env.restart({}))
  adder.add(np.zeros(2), dm_env.truncation(1.0, {}))
  assert replay.state()['cost'].tolist() == [0.0]
  assert adder.state() == {}
  with pytest.raises(RuntimeError, match='observe_first'):
    adder.add(np.zeros(2), dm_env.transition(1.0, {}))


def test_a_cost_that_is_not_one_number_is_refused():
  with pytest.raises(ValueError, match="'cost' has shape \\(2,\\)"):
    adders.step_cost({'cost': np.zeros(2)}, 'cost')
