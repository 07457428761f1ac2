"""The actor-environment interaction loop (Acme's EnvironmentLoop shape).

  loop = EnvironmentLoop(env, agent, observers=[EpisodeMetricsObserver()])
  results = loop.run(num_steps=1000)     # list of finished-episode results

An agent has `select_action(observation)`, `observe_first(timestep)`,
`observe(action, next_timestep)` and `update()` (Acme's Actor protocol). An
observer has `observe_first(env, timestep)`, `observe(env, timestep,
action)` and `get_metrics()`; its metrics join each episode's result
(`hrc_suite.tasks.metrics.EpisodeMetricsObserver` logs the task's safety and
success metrics this way).

Unlike Acme's loop, `run(num_steps=n)` stops after exactly n environment
steps, even inside an episode; the next `run` call continues that episode.
A training binary can therefore interleave evaluation and checkpoints with
training at exact step counts. The environment is reset by the loop (never
by `env.step` after a last timestep), so every step counted is a transition.
"""

import time

import dm_env
import numpy as np

_COUNTS = ('steps', 'episodes')


class Counter:
  """Steps and episodes done; `state()` / `restore()` for checkpoints."""

  def __init__(self, steps=0, episodes=0):
    self.steps = int(steps)
    self.episodes = int(episodes)

  def state(self):
    return {name: getattr(self, name) for name in _COUNTS}

  def restore(self, state):
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
  """Runs an agent in a dm_env environment, updating it as it acts."""

  def __init__(self, environment, agent, observers=(), counter=None,
               should_update=True):
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
  def in_episode(self):
    """True between an episode's first and last timestep."""
    return self._timestep is not None

  def episode_state(self):
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

  def restore_episode(self, info, observation):
    """Continues an episode saved by `episode_state` (the environment and
    the agent restored separately); observers read the environment."""
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

  def step(self):
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

  def run_episode(self):
    """Runs (the rest of) one episode; returns its result."""
    while True:
      result = self.step()
      if result is not None:
        return result

  def run(self, num_episodes=None, num_steps=None, callback=None):
    """Runs until num_episodes episodes ended or num_steps steps were taken
    (whichever first; at least one must be given). `callback(result)` gets
    each finished episode's result. Returns the list of results."""
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


def evaluate(env, policy, num_episodes, observers=None):
  """Plays num_episodes episodes of `policy(timestep) -> action` without
  learning; returns one metrics dict per episode.

  With an hrc_suite environment (`env.task.episode_metrics`) each dict holds
  the task's episode metrics (success, return, steps, shield interventions,
  contacts ...) plus episode_return and episode_length; otherwise only the
  latter two.
  """
  if int(num_episodes) != num_episodes or num_episodes < 1:
    raise ValueError(f'num_episodes must be a positive integer, got '
                     f'{num_episodes!r}')
  if observers is None:
    observers = []
    if hasattr(getattr(env, 'task', None), 'episode_metrics'):
      from hrc_suite.tasks import metrics   # pylint: disable=g-import-not-at-top
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
  """

  def __init__(self, action_spec, seed):
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

  def select_action(self, observation):
    del observation
    return self._random_state.uniform(self._minimum, self._maximum)

  def policy(self, timestep):
    return self.select_action(timestep.observation)

  def observe_first(self, timestep):
    del timestep

  def observe(self, action, next_timestep):
    del action, next_timestep

  def update(self):
    pass
