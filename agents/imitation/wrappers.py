"""Imitation as environment wrappers (dm_env in, dm_env out).

* ReferenceStateInitialization (RSI): with probability p an episode starts
  from a state of an expert-dataset episode (any recorded step but the
  last), restored with HrcTask.set_state; otherwise a fresh task instance.
  The restored episode keeps the reference's clock (the person's clip and
  the time limit continue from that step) and its metrics so far.
* StateImitationReward (SIR, with RSI): every episode follows a reference
  episode from its start step; at the k-th step after it the reward is
  (1 - varsigma) r_env + varsigma * 2^(-(|s - s~_k| / iota)^2), s the TCP
  position (Cartesian action space) or the joint positions (joint) with the
  gripper aperture appended for tasks with a gripper action, s~ the
  reference's (noise-free, full-preset) observation; past the reference's
  end its last state. Default p = 1 (every episode has a reference; with
  p < 1 the fresh episodes get r_env unchanged).
* ActionImitationReward (AIR): the task's expert is queried online on the
  current state; only the agent's action is executed, and the reward is
  (1 - varsigma) r_env + varsigma * similarity(a, a~).
* 'rsi+air' (wrap): AIR over RSI, the reference's AIR (its agents all
  started from dataset states).

The reference (docs/reference_benchmark.md, Imitation) also started plain
SAC episodes from dataset states; here plain SAC samples fresh task
instances (no wrapper).
"""

from typing import Any, Callable, Optional

import dm_env
from dm_env import specs
import numpy as np

from agents.imitation import rewards as rewards_lib
from hrc_suite import experts as experts_lib
from hrc_suite.experts import dataset as dataset_lib

DEFAULT_RSI_PROBABILITY = 0.5    # docs/reference_benchmark.md, Imitation


class EnvironmentWrapper(dm_env.Environment):
  """Delegates everything to the wrapped environment (task, physics...).

  Args:
    environment: the wrapped environment (a composer.Environment or
      another wrapper).
  """

  def __init__(self, environment: dm_env.Environment):
    self._environment = environment

  @property
  def environment(self) -> dm_env.Environment:
    """The wrapped environment."""
    return self._environment

  def __getattr__(self, name):
    if name.startswith('__'):
      raise AttributeError(name)
    return getattr(self._environment, name)

  def reset(self) -> dm_env.TimeStep:
    """Starts an episode of the wrapped environment.

    Returns:
      Its first time step.
    """
    return self._environment.reset()

  def step(self, action: np.ndarray) -> dm_env.TimeStep:
    """Steps the wrapped environment.

    Args:
      action: the action.

    Returns:
      The next time step.
    """
    return self._environment.step(action)

  def observation_spec(self) -> Any:
    """The wrapped environment's observation spec (a nest of
    specs.Array)."""
    return self._environment.observation_spec()

  def action_spec(self) -> specs.Array:
    """The wrapped environment's action spec."""
    return self._environment.action_spec()

  def reward_spec(self) -> specs.Array:
    """The wrapped environment's reward spec."""
    return self._environment.reward_spec()

  def discount_spec(self) -> specs.Array:
    """The wrapped environment's discount spec."""
    return self._environment.discount_spec()

  def close(self) -> None:
    """Closes the wrapped environment."""
    return self._environment.close()


def _composer_environment(environment):
  """The innermost environment (the composer.Environment)."""
  while isinstance(environment, EnvironmentWrapper):
    environment = environment.environment
  return environment


def _check_dataset(environment, dataset):
  task = _composer_environment(environment).task
  meta = dataset.metadata
  name = tuple(getattr(task, 'suite_name', ()))
  expected = (meta.get('domain'), meta.get('task'))
  if name != expected:
    raise ValueError(f'The dataset in {dataset.directory} is of task '
                     f'{expected[0]}/{expected[1]}, the environment runs '
                     f'{"/".join(name) or "an unnamed task"}')
  robot = task.robot.description.name
  kwargs = meta.get('task_kwargs', {})
  if kwargs.get('robot', robot) != robot:
    raise ValueError(f'The dataset in {dataset.directory} was recorded '
                     f'with robot {kwargs["robot"]!r}, the environment uses '
                     f'{robot!r}')
  space = task.action_space_name
  if kwargs.get('action_space', space) != space:
    raise ValueError(f'The dataset in {dataset.directory} was recorded '
                     f'with {kwargs["action_space"]!r} actions, the '
                     f'environment uses {space!r}')
  if not dataset.metadata['episodes']:
    raise ValueError(f'The dataset in {dataset.directory} has no episodes')


def _restart_observation(environment):
  """The observation of the composer environment's current state, as a
  reset would produce it (observables re-initialised)."""
  # composer.Environment has no public call for this; reset() does the same.
  updater = environment._observation_updater   # pylint: disable=protected-access
  updater.reset(environment.physics, environment.random_state)
  return updater.get_observation()


class ReferenceStateInitialization(EnvironmentWrapper):
  """Starts episodes from expert-dataset states with probability p.

  Args:
    environment: the environment, of the dataset's task, robot and action
      space.
    dataset: the expert dataset (dataset.load_dataset).
    probability: p, in [0, 1].
    seed: the seed of the draws (whether and which reference state).

  Raises:
    ValueError: p is outside [0, 1], or the dataset is of another task,
      robot or action space, or has no episodes.
  """

  def __init__(self, environment: dm_env.Environment,
               dataset: dataset_lib.Dataset,
               probability: float = DEFAULT_RSI_PROBABILITY, seed: int = 0):
    super().__init__(environment)
    if not 0.0 <= probability <= 1.0:
      raise ValueError(f'probability must be in [0, 1], got {probability!r}')
    _check_dataset(environment, dataset)
    self._dataset = dataset
    self._probability = float(probability)
    self._random = np.random.RandomState(seed)
    # Every (episode, step) with a step after it: uniform over states.
    lengths = np.array([entry['steps']
                        for entry in dataset.metadata['episodes']])
    self._episode_of = np.repeat(np.arange(len(lengths)), lengths)
    self._step_of = np.concatenate([np.arange(n) for n in lengths])
    self.reference = None   # (episode, step) the episode started from.

  @property
  def dataset(self) -> dataset_lib.Dataset:
    """The expert dataset the reference states come from."""
    return self._dataset

  def _draw_reference(self):
    index = self._random.randint(len(self._episode_of))
    return int(self._episode_of[index]), int(self._step_of[index])

  def reset(self) -> dm_env.TimeStep:
    """Starts an episode: with probability p from a dataset state drawn
    uniformly (`reference` says which), else fresh.

    Returns:
      The first time step.
    """
    timestep = self._environment.reset()
    self.reference = None
    if self._random.uniform() < self._probability:
      episode, step = self._draw_reference()
      inner = _composer_environment(self._environment)
      inner.task.set_state(inner.physics,
                           self._dataset.snapshot(episode, step))
      timestep = dm_env.restart(_restart_observation(inner))
      self.reference = (episode, step)
    return timestep


def _state_names(task):
  names = ['eef_position' if task.action_space_name == 'cartesian'
           else 'joint_positions']
  if task.HAS_GRIPPER_ACTION:
    names.append('gripper_aperture')
  return tuple(names)


class StateImitationReward(ReferenceStateInitialization):
  """SIR: RSI plus a reward for staying near the reference episode.

  Args:
    environment: the environment, of the dataset's task, robot and action
      space.
    dataset: the expert dataset (dataset.load_dataset).
    probability: RSI's p, in [0, 1].
    seed: the seed of RSI's draws.
    weight: the imitation weight varsigma, in [0, 1].
    scale: the distance scale iota of the position part (m or rad).
    gripper_scale: the distance scale of the gripper part.
    position_weight: the position part's weight beta, in [0, 1].

  Raises:
    ValueError: as ReferenceStateInitialization's, or a weight or scale
      out of its range.
  """

  def __init__(self, environment: dm_env.Environment,
               dataset: dataset_lib.Dataset, probability: float = 1.0,
               seed: int = 0, weight: float = rewards_lib.IMITATION_WEIGHT,
               scale: float = rewards_lib.DISTANCE_SCALE,
               gripper_scale: float = rewards_lib.SIR_GRIPPER_SCALE,
               position_weight: float = rewards_lib.POSITION_WEIGHT):
    super().__init__(environment, dataset, probability, seed)
    task = _composer_environment(environment).task
    self._names = _state_names(task)
    self._reward = rewards_lib.ImitationReward(
        weight=weight, scale=scale, gripper_scale=gripper_scale,
        position_weight=position_weight,
        gripper_size=int(task.HAS_GRIPPER_ACTION))
    observables = task.task_observables
    self._state_callables = None
    self._observables = [observables[name] for name in self._names]
    self._reference_states = None
    self._index = 0

  def state(self) -> np.ndarray:
    """The compared state s now (noise-free)."""
    physics = _composer_environment(self._environment).physics
    return np.concatenate([np.ravel(obs._callable(physics)())   # pylint: disable=protected-access
                           for obs in self._observables])

  def reset(self) -> dm_env.TimeStep:
    """Starts an episode as RSI does; one from a dataset state follows
    that state's episode.

    Returns:
      The first time step.
    """
    timestep = super().reset()
    if self.reference is None:
      self._reference_states = None
      return timestep
    episode, step = self.reference
    observed = self._dataset.episodes[episode].expert_observations
    self._reference_states = np.concatenate(
        [observed[name].reshape(len(observed[name]), -1)
         for name in self._names], axis=1)
    self._index = step
    return timestep

  def step(self, action: np.ndarray) -> dm_env.TimeStep:
    """Steps the environment; with a reference episode the reward mixes in
    the similarity of the state to the reference's next one.

    Args:
      action: the action.

    Returns:
      The next time step.
    """
    timestep = self._environment.step(action)
    if self._reference_states is None or timestep.reward is None:
      return timestep
    self._index = min(self._index + 1, len(self._reference_states) - 1)
    reward = self._reward.reward(timestep.reward, self.state(),
                                 self._reference_states[self._index])
    return timestep._replace(reward=np.asarray(reward, np.float64))


class ActionImitationReward(EnvironmentWrapper):
  """AIR: rewards agreement with the expert's action on the same state.

  Args:
    environment: the environment.
    expert: time step -> the expert's action (None: the task's expert,
      experts.make, without re-planning: Expert.disable_replanning).
    weight: the imitation weight varsigma, in [0, 1].
    scale: the distance scale iota of the arm part of actions.
    gripper_scale: the distance scale of the gripper part.
    position_weight: the arm part's weight beta, in [0, 1].

  Raises:
    ValueError: a weight or scale out of its range.
  """

  def __init__(
      self, environment: dm_env.Environment,
      expert: Optional[Callable[[dm_env.TimeStep], np.ndarray]] = None,
      weight: float = rewards_lib.IMITATION_WEIGHT,
      scale: float = rewards_lib.DISTANCE_SCALE,
      gripper_scale: float = rewards_lib.AIR_GRIPPER_SCALE,
      position_weight: float = rewards_lib.POSITION_WEIGHT):
    super().__init__(environment)
    inner = _composer_environment(environment)
    if expert is None:
      # The advice on a state is the expert's action there, never a detour
      # driven by the agent's replaced actions (experts/replan.py).
      expert = experts_lib.make(inner)
      expert.disable_replanning()
    self._expert = expert
    self._reward = rewards_lib.ImitationReward(
        weight=weight, scale=scale, gripper_scale=gripper_scale,
        position_weight=position_weight,
        gripper_size=int(inner.task.HAS_GRIPPER_ACTION))
    self._timestep = None
    self.last_expert_action = None

  @property
  def expert(self) -> Callable[[dm_env.TimeStep], np.ndarray]:
    """The expert queried on the agent's states."""
    return self._expert

  def reset(self) -> dm_env.TimeStep:
    """Starts an episode of the wrapped environment.

    Returns:
      Its first time step.
    """
    self._timestep = self._environment.reset()
    return self._timestep

  def step(self, action: np.ndarray) -> dm_env.TimeStep:
    """Steps the environment with the agent's action; the reward mixes in
    the similarity of that action (clipped to [-1, 1]) to the expert's on
    the state it was taken in (`last_expert_action`).

    Args:
      action: the agent's action.

    Returns:
      The next time step.

    Raises:
      RuntimeError: step before reset.
    """
    if self._timestep is None:
      raise RuntimeError('step() before reset()')
    expert_action = np.asarray(self._expert(self._timestep), np.float64)
    self.last_expert_action = expert_action
    timestep = self._environment.step(action)
    self._timestep = timestep
    if timestep.reward is None:
      return timestep
    executed = np.clip(np.asarray(action, np.float64), -1.0, 1.0)
    reward = self._reward.reward(timestep.reward, executed, expert_action)
    return timestep._replace(reward=np.asarray(reward, np.float64))


AGENTS = ('sac', 'rsi', 'sir', 'air', 'rsi+air')
NEEDS_DATASET = ('rsi', 'sir', 'rsi+air')
# kwargs of the composed 'rsi+air' that go to RSI (the rest go to AIR).
_RSI_KWARGS = ('probability',)


def wrap(environment: dm_env.Environment, agent: str,
         dataset: Optional[dataset_lib.Dataset] = None, seed: int = 0,
         **kwargs: Any) -> dm_env.Environment:
  """The environment for an agent.

  'rsi+air' composes the two wrappers: episodes start from dataset states
  with probability p (kwarg `probability`, default 0.5, as the reference's
  agents did) and the reward is AIR's (the other kwargs).

  Args:
    environment: the environment.
    agent: one of AGENTS ('sac': the environment unchanged).
    dataset: the expert dataset (hrc_suite.experts.dataset.load_dataset),
      needed by NEEDS_DATASET's agents.
    seed: the seed of RSI's draws.
    **kwargs: the wrapper's other arguments.

  Returns:
    The wrapped environment.

  Raises:
    ValueError: an unknown agent, or no dataset for one that needs it.
  """
  if agent not in AGENTS:
    raise ValueError(f'Unknown agent {agent!r}: expected one of '
                     f'{", ".join(AGENTS)}')
  if agent == 'sac':
    return environment
  if agent == 'air':
    return ActionImitationReward(environment, **kwargs)
  if dataset is None:
    raise ValueError(f'agent {agent!r} needs an expert dataset (collect one '
                     'with python -m agents.collect_expert)')
  if agent == 'rsi':
    return ReferenceStateInitialization(environment, dataset, seed=seed,
                                        **kwargs)
  if agent == 'rsi+air':
    rsi_kwargs = {name: kwargs.pop(name) for name in _RSI_KWARGS
                  if name in kwargs}
    starts = ReferenceStateInitialization(environment, dataset, seed=seed,
                                          **rsi_kwargs)
    return ActionImitationReward(starts, **kwargs)
  return StateImitationReward(environment, dataset, seed=seed, **kwargs)
