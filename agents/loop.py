"""The actor-environment interaction loop (Acme's EnvironmentLoop shape).

  loop = EnvironmentLoop(env, agent, observers=[EpisodeMetricsObserver()])
  results = loop.run(num_steps=1000)     # list of finished-episode results

An agent has `select_action(observation)`, `observe_first(timestep)`,
`observe(action, next_timestep)` and `update()` (Acme's Actor protocol). An
observer has `observe_first(env, timestep)`, `observe(env, timestep,
action)` and `get_metrics()`; its metrics join each episode's result
(`hrc_suite.tasks.runtime.metrics.EpisodeMetricsObserver` logs the task's safety
and success metrics this way).

Unlike Acme's loop, `run(num_steps=n)` stops after exactly n environment
steps, even inside an episode; the next `run` call continues that episode.
A training binary can therefore interleave evaluation and checkpoints with
training at exact step counts. The environment is reset by the loop (never
by `env.step` after a last timestep), so every step counted is a transition.
"""

import time
from typing import (Any, Callable, Dict, List, Mapping, Optional, Sequence,
                    Tuple)

import dm_env
from dm_env import specs
import numpy as np

# An episode's result: {metric name: value}.
Result = Dict[str, Any]

_COUNTS = ('steps', 'episodes')


class Counter:
  """Steps and episodes done; `state()` / `restore()` for checkpoints.

  Args:
    steps: environment steps done.
    episodes: episodes finished.
  """

  def __init__(self, steps: int = 0, episodes: int = 0):
    self.steps = int(steps)
    self.episodes = int(episodes)

  def state(self) -> Dict[str, int]:
    """{'steps', 'episodes'} for a checkpoint."""
    return {name: getattr(self, name) for name in _COUNTS}

  def restore(self, state: Mapping[str, int]) -> None:
    """Restores a `state()`.

    Args:
      state: of `state()`.

    Raises:
      ValueError: a key missing, or a count that is not an integer >= 0.
    """
    missing = [name for name in _COUNTS if name not in state]
    if missing:
      raise ValueError(f'Counter state lacks {missing}: expected keys '
                       f'{list(_COUNTS)}, got {sorted(state)}')
    for name in _COUNTS:
      value = state[name]
      if int(value) != value or value < 0:
        raise ValueError(f'Counter {name} must be an integer >= 0, got '
                         f'{value!r}')
      setattr(self, name, int(value))


def _check_observers(observers):
  for observer in observers:
    missing = [name for name in ('observe_first', 'observe', 'get_metrics')
               if not callable(getattr(observer, name, None))]
    if missing:
      raise TypeError(f'Observer {observer!r} lacks methods {missing}: an '
                      'observer needs observe_first(env, timestep), '
                      'observe(env, timestep, action) and get_metrics()')
  return tuple(observers)


class EnvironmentLoop:
  """Runs an agent in a dm_env environment, updating it as it acts.

  Args:
    environment: the environment.
    agent: has select_action, observe_first, observe and (with
      should_update) update.
    observers: each with observe_first(env, timestep), observe(env,
      timestep, action) and get_metrics().
    counter: the steps and episodes done (default: a new Counter).
    should_update: call agent.update() before every environment step.

  Raises:
    TypeError: an agent or observer without the methods.
  """

  def __init__(self, environment: dm_env.Environment, agent: Any,
               observers: Sequence[Any] = (),
               counter: Optional[Counter] = None,
               should_update: bool = True):
    for name in ('select_action', 'observe_first', 'observe'):
      if not callable(getattr(agent, name, None)):
        raise TypeError(f'Agent {agent!r} lacks {name}(): expected the '
                        'Acme actor protocol (select_action, observe_first, '
                        'observe, update)')
    if should_update and not callable(getattr(agent, 'update', None)):
      raise TypeError(f'Agent {agent!r} has no update(); pass '
                      'should_update=False to run it without learning')
    self._env = environment
    self._agent = agent
    self._observers = _check_observers(observers)
    self.counter = counter if counter is not None else Counter()
    # The metrics returned by the last agent.update() that returned any.
    self.update_metrics = {}
    self._should_update = should_update
    self._timestep = None       # None: the next step starts an episode.
    self._episode_return = 0.0
    self._episode_steps = 0
    self._episode_start = 0.0

  @property
  def in_episode(self) -> bool:
    """True between an episode's first and last timestep."""
    return self._timestep is not None

  def episode_state(self
                    ) -> Optional[Tuple[Dict[str, Any], Dict[str, np.ndarray]]]:
    """The episode in progress as (JSON-ready dict, {key: observation
    array}), or None between episodes (for mid-episode checkpoints)."""
    if self._timestep is None:
      return None
    timestep = self._timestep
    info = {
        'step_type': int(timestep.step_type),
        'reward': None if timestep.reward is None else float(timestep.reward),
        'discount': (None if timestep.discount is None
                     else float(timestep.discount)),
        'episode_return': self._episode_return,
        'episode_steps': self._episode_steps,
    }
    observation = {key: np.asarray(value)
                   for key, value in timestep.observation.items()}
    return info, observation

  def restore_episode(self, info: Mapping[str, Any],
                      observation: Mapping[str, np.ndarray]) -> None:
    """Continues an episode saved by `episode_state` (the environment and
    the agent restored separately); observers read the environment.

    Args:
      info: the first part of `episode_state()`.
      observation: its second part.
    """
    reward, discount = info['reward'], info['discount']
    self._timestep = dm_env.TimeStep(
        step_type=dm_env.StepType(info['step_type']),
        reward=None if reward is None else np.float64(reward),
        discount=None if discount is None else np.float64(discount),
        observation=dict(observation))
    self._episode_return = float(info['episode_return'])
    self._episode_steps = int(info['episode_steps'])
    self._episode_start = time.perf_counter()

  def _begin_episode(self):
    timestep = self._env.reset()
    self._agent.observe_first(timestep)
    for observer in self._observers:
      observer.observe_first(self._env, timestep)
    self._timestep = timestep
    self._episode_return = 0.0
    self._episode_steps = 0
    self._episode_start = time.perf_counter()

  def step(self) -> Optional[Result]:
    """One environment step (resetting first if needed); returns the
    episode's result dict if this step ended it, else None."""
    if self._timestep is None:
      self._begin_episode()
    action = self._agent.select_action(self._timestep.observation)
    if self._should_update:
      # Before the environment step: a JAX learner's update, dispatched
      # asynchronously, runs while the environment steps (it learns from
      # the transitions up to the previous step).
      metrics = self._agent.update()
      if metrics:
        self.update_metrics = metrics
    timestep = self._env.step(action)
    if timestep.first():
      raise RuntimeError('The environment restarted an episode inside '
                         'env.step: the loop resets it itself')
    self._agent.observe(action, timestep)
    for observer in self._observers:
      observer.observe(self._env, timestep, action)
    self.counter.steps += 1
    self._episode_steps += 1
    self._episode_return += float(timestep.reward)
    if not timestep.last():
      self._timestep = timestep
      return None
    self._timestep = None
    self.counter.episodes += 1
    return self._episode_result()

  def _episode_result(self):
    elapsed = time.perf_counter() - self._episode_start
    result = {
        'episode_length': self._episode_steps,
        'episode_return': self._episode_return,
        'steps_per_second': self._episode_steps / max(elapsed, 1e-9),
        'total_steps': self.counter.steps,
        'total_episodes': self.counter.episodes,
    }
    for observer in self._observers:
      result.update(observer.get_metrics())
    return result

  def run_episode(self) -> Result:
    """Runs (the rest of) one episode; returns its result."""
    while True:
      result = self.step()
      if result is not None:
        return result

  def run(self, num_episodes: Optional[int] = None,
          num_steps: Optional[int] = None,
          callback: Optional[Callable[[Result], None]] = None
          ) -> List[Result]:
    """Runs until num_episodes episodes ended or num_steps steps were taken
    (whichever first; at least one must be given).

    Args:
      num_episodes: None or an integer >= 0.
      num_steps: None or an integer >= 0.
      callback: None, or called with each finished episode's result.

    Returns:
      The finished episodes' results.

    Raises:
      ValueError: counts that are not integers >= 0, or neither given.
    """
    for name, value in (('num_episodes', num_episodes),
                        ('num_steps', num_steps)):
      if value is not None and (int(value) != value or value < 0):
        raise ValueError(f'{name} must be an integer >= 0 or None, got '
                         f'{value!r}')
    if num_episodes is None and num_steps is None:
      raise ValueError('Give num_episodes or num_steps: a loop without '
                       'either would never end')
    results = []
    steps = 0
    while ((num_episodes is None or len(results) < num_episodes) and
           (num_steps is None or steps < num_steps)):
      result = self.step()
      steps += 1
      if result is not None:
        results.append(result)
        if callback is not None:
          callback(result)
    return results


def evaluate(env: dm_env.Environment,
             policy: Callable[[dm_env.TimeStep], np.ndarray],
             num_episodes: int,
             observers: Optional[Sequence[Any]] = None) -> List[Result]:
  """Plays episodes of a policy without learning.

  With an hrc_suite environment (`env.task.episode_metrics`) each dict holds
  the task's episode metrics (success, return, steps, shield interventions,
  contacts ...) plus episode_return and episode_length; otherwise only the
  latter two.

  Args:
    env: the environment.
    policy: timestep -> action.
    num_episodes: an integer >= 1.
    observers: None (hrc_suite's EpisodeMetricsObserver where the
      environment has a task with episode metrics) or observers.

  Returns:
    One metrics dict per episode.

  Raises:
    ValueError: num_episodes that is not a positive integer.
    TypeError: an observer without the methods.
  """
  if int(num_episodes) != num_episodes or num_episodes < 1:
    raise ValueError(f'num_episodes must be a positive integer, got '
                     f'{num_episodes!r}')
  if observers is None:
    observers = []
    if hasattr(getattr(env, 'task', None), 'episode_metrics'):
      from hrc_suite.tasks.runtime import metrics   # pylint: disable=g-import-not-at-top
      observers.append(metrics.EpisodeMetricsObserver())
  observers = _check_observers(observers)
  episodes = []
  for _ in range(int(num_episodes)):
    timestep = env.reset()
    for observer in observers:
      observer.observe_first(env, timestep)
    episode_return, length = 0.0, 0
    while True:
      action = policy(timestep)
      timestep = env.step(action)
      for observer in observers:
        observer.observe(env, timestep, action)
      episode_return += float(timestep.reward)
      length += 1
      if timestep.last():
        break
    result = {'episode_return': episode_return, 'episode_length': length}
    for observer in observers:
      result.update(observer.get_metrics())
    episodes.append(result)
  return episodes


class RandomAgent:
  """Uniform random actions within a bounded action spec; learns nothing.

  A baseline for evaluation and the loop's tests.

  Args:
    action_spec: a bounded spec with finite bounds.
    seed: the actions' random seed.

  Raises:
    ValueError: a spec without finite bounds.
  """

  def __init__(self, action_spec: specs.BoundedArray, seed: int):
    if not hasattr(action_spec, 'minimum'):
      raise ValueError(f'RandomAgent needs a bounded action spec, got '
                       f'{action_spec!r}')
    minimum = np.broadcast_to(action_spec.minimum, action_spec.shape)
    maximum = np.broadcast_to(action_spec.maximum, action_spec.shape)
    if not (np.all(np.isfinite(minimum)) and np.all(np.isfinite(maximum))):
      raise ValueError(f'RandomAgent needs a bounded action spec, got '
                       f'{action_spec!r}')
    self._minimum = np.array(minimum, dtype=float)
    self._maximum = np.array(maximum, dtype=float)
    self._random_state = np.random.RandomState(seed)

  def select_action(self, observation: Any) -> np.ndarray:
    """A uniform random action.

    Args:
      observation: unused.

    Returns:
      The action, within the spec's bounds.
    """
    del observation
    return self._random_state.uniform(self._minimum, self._maximum)

  def policy(self, timestep: dm_env.TimeStep) -> np.ndarray:
    """A uniform random action (a policy for `evaluate`).

    Args:
      timestep: unused.

    Returns:
      The action.
    """
    return self.select_action(timestep.observation)

  def observe_first(self, timestep: dm_env.TimeStep) -> None:
    """Does nothing (Acme's actor protocol).

    Args:
      timestep: unused.
    """
    del timestep

  def observe(self, action: np.ndarray,
              next_timestep: dm_env.TimeStep) -> None:
    """Does nothing (Acme's actor protocol).

    Args:
      action: unused.
      next_timestep: unused.
    """
    del action, next_timestep

  def update(self) -> None:
    """Learns nothing."""
