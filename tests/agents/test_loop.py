"""Tests of the environment loop, evaluation and the statistics helper."""

import dm_env
from dm_env import specs
import numpy as np
import pytest

from agents import benchmark
from agents import loop as loop_lib
from hrc_suite import statistics
from hrc_suite import suite
from hrc_suite.tasks.runtime import metrics


class CountdownEnv(dm_env.Environment):
  """Episodes of `length` steps; reward = the action's first entry."""

  def __init__(self, length):
    self._length = length
    self._t = 0
    self.resets = 0

  def reset(self):
    self._t = 0
    self.resets += 1
    return dm_env.restart({'t': np.zeros(1)})

  def step(self, action):
    self._t += 1
    observation = {'t': np.array([self._t], dtype=float)}
    if self._t >= self._length:
      return dm_env.truncation(float(action[0]), observation)
    return dm_env.transition(float(action[0]), observation)

  def observation_spec(self):
    return {'t': specs.Array((1,), float)}

  def action_spec(self):
    return specs.BoundedArray((2,), float, -1.0, 1.0)


class RecordingAgent(loop_lib.RandomAgent):
  """A random agent that records the calls of the actor protocol."""

  def __init__(self, action_spec, seed):
    super().__init__(action_spec, seed)
    self.calls = []

  def observe_first(self, timestep):
    self.calls.append(('first', timestep.step_type))

  def observe(self, action, next_timestep):
    self.calls.append(('observe', next_timestep.step_type))

  def update(self):
    self.calls.append(('update', None))


def test_run_stops_at_exact_steps_and_continues_the_episode():
  env = CountdownEnv(length=4)
  agent = RecordingAgent(env.action_spec(), seed=0)
  loop = loop_lib.EnvironmentLoop(env, agent)
  results = loop.run(num_steps=6)
  assert [r['episode_length'] for r in results] == [4]
  assert loop.counter.steps == 6 and loop.counter.episodes == 1
  assert loop.in_episode
  results = loop.run(num_steps=2)   # Finishes the second episode.
  assert [r['episode_length'] for r in results] == [4]
  assert not loop.in_episode
  assert results[0]['total_steps'] == 8 and results[0]['total_episodes'] == 2
  assert env.resets == 2
  kinds = [kind for kind, _ in agent.calls]
  assert kinds.count('first') == 2
  assert kinds.count('observe') == 8 and kinds.count('update') == 8
  # observe_first, then (update, observe) per step, per episode: the
  # update is dispatched before the environment steps.
  assert kinds[:3] == ['first', 'update', 'observe']
  assert agent.calls[8] == ('observe', dm_env.StepType.LAST)
  assert agent.calls[9] == ('first', dm_env.StepType.FIRST)


def test_run_episodes_and_return_sum():
  env = CountdownEnv(length=3)
  agent = loop_lib.RandomAgent(env.action_spec(), seed=1)
  expected = np.random.RandomState(1).uniform(-1, 1, (6, 2))[:, 0]
  results = loop_lib.EnvironmentLoop(env, agent).run(num_episodes=2)
  assert len(results) == 2
  np.testing.assert_allclose(
      [r['episode_return'] for r in results],
      [expected[:3].sum(), expected[3:].sum()])


def test_loop_without_update_does_not_call_it():
  env = CountdownEnv(length=2)
  agent = RecordingAgent(env.action_spec(), seed=0)
  loop_lib.EnvironmentLoop(env, agent, should_update=False).run(
      num_episodes=1)
  assert ('update', None) not in agent.calls


def test_bad_arguments_raise():
  env = CountdownEnv(length=2)
  agent = loop_lib.RandomAgent(env.action_spec(), seed=0)
  loop = loop_lib.EnvironmentLoop(env, agent)
  with pytest.raises(ValueError, match='num_episodes or num_steps'):
    loop.run()
  with pytest.raises(ValueError, match='num_steps'):
    loop.run(num_steps=-1)
  with pytest.raises(TypeError, match='get_metrics'):
    loop_lib.EnvironmentLoop(env, agent, observers=[object()])
  with pytest.raises(TypeError, match='select_action'):
    loop_lib.EnvironmentLoop(env, object())
  with pytest.raises(ValueError, match='positive integer'):
    loop_lib.evaluate(env, agent.policy, 0)
  unbounded = specs.Array((2,), float)
  with pytest.raises(ValueError, match='bounded'):
    loop_lib.RandomAgent(unbounded, seed=0)


def test_counter_round_trip_and_errors():
  counter = loop_lib.Counter(steps=7, episodes=2)
  other = loop_lib.Counter()
  other.restore(counter.state())
  assert other.state() == {'steps': 7, 'episodes': 2}
  with pytest.raises(ValueError, match='lacks'):
    other.restore({'steps': 1})
  with pytest.raises(ValueError, match='episodes'):
    other.restore({'steps': 1, 'episodes': -3})


def _reach_env(seed):
  return suite.load('reach', 'dense',
                    task_kwargs={'robot': 'schunk', 'action_space': 'cartesian',
                                 'time_limit': 1.0},
                    environment_kwargs={'random_state': seed})


def test_task_metrics_per_episode_and_deterministic_evaluation():
  env = _reach_env(seed=3)
  agent = loop_lib.RandomAgent(env.action_spec(), seed=0)
  observer = metrics.EpisodeMetricsObserver()
  loop = loop_lib.EnvironmentLoop(env, agent, observers=[observer])
  results = loop.run(num_steps=25)
  assert len(results) == 2 and loop.counter.steps == 25
  for result in results:
    assert result['steps'] == result['episode_length'] == 10
    assert result['return'] == pytest.approx(result['episode_return'])
    for name in ('success', 'shield_interventions', 'contacts_static'):
      assert name in result
  assert observer.episodes == [
      {k: r[k] for k in observer.episodes[0]} for r in results]

  def evaluate(seed):
    env = _reach_env(seed)
    policy = loop_lib.RandomAgent(env.action_spec(), seed=5).policy
    return loop_lib.evaluate(env, policy, num_episodes=2)

  first, second = evaluate(4), evaluate(4)
  assert first == second
  assert first[0]['episode_length'] == 10
  assert first[0]['return'] == pytest.approx(first[0]['episode_return'])


def test_bootstrap_ci_on_known_data():
  rs = np.random.RandomState(0)
  # Constant data: no spread.
  assert statistics.bootstrap_ci(np.full(5, 2.5), rs) == (2.5, 2.5, 2.5)
  # Two values {0, 1}: resampled means are 0, 0.5, 1 with probabilities
  # 1/4, 1/2, 1/4, so the 95 % interval is [0, 1].
  assert statistics.bootstrap_ci([0.0, 1.0], rs) == (0.5, 0.0, 1.0)
  # Large Bernoulli sample: close to the normal approximation.
  data = (rs.uniform(size=2000) < 0.3).astype(float)
  mean, low, high = statistics.bootstrap_ci(data, rs)
  half_width = 1.96 * np.sqrt(mean * (1 - mean) / data.size)
  assert low == pytest.approx(mean - half_width, abs=0.004)
  assert high == pytest.approx(mean + half_width, abs=0.004)
  # Columns are independent curves; same seed, same interval.
  curves = np.stack([np.zeros(4), np.arange(4.0)], axis=1)
  mean, low, high = statistics.bootstrap_ci(
      curves, np.random.RandomState(1), num_resamples=1000)
  np.testing.assert_array_equal(mean, [0.0, 1.5])
  assert low[0] == high[0] == 0.0 and low[1] < 1.5 < high[1]
  again = statistics.bootstrap_ci(curves, np.random.RandomState(1),
                                  num_resamples=1000)
  np.testing.assert_array_equal(low, again[1])
  with pytest.raises(ValueError, match='finite'):
    statistics.bootstrap_ci([1.0, np.nan], rs)
  with pytest.raises(ValueError, match='confidence'):
    statistics.bootstrap_ci([1.0], rs, confidence=1.5)
  with pytest.raises(ValueError, match='RandomState'):
    statistics.bootstrap_ci([1.0], 0)


def test_benchmark_measures_every_section():
  results = benchmark.measure(steps=6, warmup=14, batch_size=8,
                              hidden_sizes=(8,), fused_steps=3)
  assert list(results) == ['training', 'environment only',
                           'update, 1 per call', 'update, 3 per call',
                           'actor only']
  for steps, wall, cpu, main in results.values():
    assert steps == 6 and wall > 0 and cpu >= 0 and main >= 0
  assert 's per 1000 RL steps' in benchmark.format_results(results)
  with pytest.raises(ValueError, match='warmup'):
    benchmark.measure(steps=5, warmup=13, batch_size=8, fused_steps=3)
