"""SACAgent: flattener + actor + learner + replay, in Acme's agent shape.

  agent = SACAgent(specs.make_environment_spec(env), config, seed=0)
  timestep = env.reset()
  agent.observe_first(timestep)
  while ...:
    action = agent.select_action(timestep.observation)
    timestep = env.step(action)
    agent.observe(action, timestep)
    agent.update()

Bootstrapping uses the environment's discount: 0 at a termination, 1 at a
time-limit truncation (dm_env's convention), times the config's gamma.
Updates start once the replay holds `min_replay_size` transitions; from
then on each observed step adds `updates_per_step` gradient steps to a
credit (fractional ratios accumulate), and `update()` dispatches one
learner call of `fused_steps` gradient steps (one compiled lax.scan on
fused_steps fresh minibatches) whenever the credit holds that many.

Overlap and lag: JAX runs a call asynchronously, so the call dispatched
before an environment step computes while the environment steps. The actor
does not wait for it: it runs the policy in NumPy (a jitted action would
queue behind the call on the device), and each call moves it to the policy
the learner had before that call (the previous call's result, computed in
the meantime). A call's gradient steps therefore reach the actions one call
later, fused_steps / updates_per_step environment steps after its dispatch,
and act until the call after that. A call learns only from transitions
observed before its dispatch: its minibatches are sampled then, from
everything observed so far (up to fused_steps / updates_per_step - 1
transitions more than the same gradient steps would have seen dispatched
one at a time). The policy the actor uses is deterministic (it never
depends on how fast the call ran) and part of a checkpoint; evaluation
(`policy`) uses the learner's latest parameters.

Checkpoints (`save` / `restore`, and `load_policy` for rendering) are a
directory holding agent.json (config, sizes, counters, caller metadata),
learner.npz (TrainingState), replay.npz and agent.npz (the actor's
RandomState and acting policy, replay sampling RandomState, the episode's
last observation, caller arrays).
"""

import collections
import pathlib

import numpy as np

from agents import config as config_lib
from agents import observations
from agents import replay as replay_lib
from agents.sac import actor as actor_lib
from agents.sac import checkpointing
from agents.sac import learning
from agents.sac import networks as networks_lib

CHECKPOINT_FORMAT = 1
_EXTRA_PREFIX = 'extra/'
_ACTING_PREFIX = 'acting_policy/'
# Slack on the update credit, a float sum of updates_per_step, before it
# counts as holding fused_steps gradient steps (0.1 added ten times is
# 0.9999999999999999).
_CREDIT_TOLERANCE = 1e-9

CheckpointExtras = collections.namedtuple('CheckpointExtras',
                                          ['metadata', 'arrays'])


def _seeds(seed, count):
  """`count` independent 31-bit seeds derived from one seed."""
  if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or (
      seed < 0):
    raise ValueError(f'seed={seed!r}: expected an integer >= 0')
  state = np.random.SeedSequence(int(seed)).generate_state(count, np.uint32)
  return [int(s) >> 1 for s in state]


def _random_state_arrays(prefix, random_state):
  """{prefix/field: array} of a np.random.RandomState's state."""
  _, keys, position, has_gauss, cached = random_state.get_state()
  return {f'{prefix}/keys': keys,
          f'{prefix}/position': np.int64(position),
          f'{prefix}/has_gauss': np.int64(has_gauss),
          f'{prefix}/cached_gaussian': np.float64(cached)}


def _restore_random_state(arrays, prefix, random_state):
  """Sets a RandomState to the state `_random_state_arrays` saved."""
  random_state.set_state((
      'MT19937', arrays[f'{prefix}/keys'],
      int(arrays[f'{prefix}/position']),
      int(arrays[f'{prefix}/has_gauss']),
      float(arrays[f'{prefix}/cached_gaussian'])))


class SACAgent:
  """Soft actor-critic agent on a dm_env environment spec."""

  def __init__(self, environment_spec, config=None, seed=0, images='error'):
    self._config = config or config_lib.default_config()
    if not isinstance(self._config, config_lib.SACConfig):
      raise TypeError(f'config must be a SACConfig, got '
                      f'{type(self._config).__name__}')
    learner_seed, actor_seed, replay_seed = _seeds(seed, 3)
    self._seed = int(seed)
    self._images = images
    self._flattener = observations.ObservationFlattener(
        environment_spec.observations, images=images)
    self._scaler = actor_lib.ActionScaler(environment_spec.actions)
    observation_size = self._flattener.size
    action_size = self._scaler.size
    self._networks = networks_lib.make_networks(
        observation_size, action_size, self._config.hidden_sizes)
    self._learner = learning.SACLearner(self._networks, self._config,
                                        observation_size, action_size,
                                        learner_seed)
    self._replay = replay_lib.ReplayBuffer(self._config.replay_capacity,
                                           observation_size, action_size)
    # The policy the actor acts with: the learner's before its last call.
    self._acting_params = self._learner.policy_params
    self._actor = actor_lib.SACActor(self._networks,
                                     lambda: self._acting_params, actor_seed)
    self._sample_random_state = np.random.RandomState(replay_seed)
    self._last_observation = None   # Flat observation before the next action.
    self._flat_cache = (None, None)   # (observation dict, its flat vector).
    self._env_steps = 0
    self._steps_since_update = 0
    self._update_credit = 0.0

  def _policy_params(self):
    return self._learner.policy_params

  def _flatten(self, observation):
    cached_dict, cached_vector = self._flat_cache
    if observation is cached_dict:
      return cached_vector
    vector = self._flattener(observation)
    self._flat_cache = (observation, vector)
    return vector

  # Acme's actor interface.

  def select_action(self, observation):
    """float64 action within the action spec (sampled from the policy)."""
    return self._scaler.to_environment(
        self._actor.select_action(self._flatten(observation)))

  def observe_first(self, timestep):
    self._last_observation = self._flatten(timestep.observation)

  def observe(self, action, next_timestep):
    """Stores (s, a, r, discount, s') for the step that led to next_timestep."""
    if self._last_observation is None:
      raise RuntimeError('observe() called before observe_first() of the '
                         'episode')
    next_observation = self._flatten(next_timestep.observation)
    self._replay.add(self._last_observation,
                     self._scaler.to_normalised(action),
                     np.float32(next_timestep.reward),
                     np.float32(next_timestep.discount), next_observation)
    self._last_observation = (None if next_timestep.last()
                              else next_observation)
    self._env_steps += 1
    self._steps_since_update += 1

  def update(self):
    """Dispatches the learner calls due; the last one's mean metrics (read
    lazily: learning.UpdateMetrics), or None."""
    config = self._config
    if len(self._replay) < max(config.min_replay_size, 1):
      self._steps_since_update = 0
      return None
    self._update_credit += config.updates_per_step * self._steps_since_update
    self._steps_since_update = 0
    calls = int((self._update_credit + _CREDIT_TOLERANCE)
                // config.fused_steps)
    if calls == 0:
      return None
    self._update_credit = max(
        0.0, self._update_credit - calls * config.fused_steps)
    for _ in range(calls):
      metrics = self.learn(config.fused_steps)
    return metrics

  def learn(self, num_steps=1):
    """One learner call of `num_steps` gradient steps on fresh replay
    samples, dispatched asynchronously; its mean metrics. The actor moves
    to the policy from before this call (module docstring)."""
    if len(self._replay) == 0:
      raise ValueError('Cannot learn from an empty replay buffer')
    batch = self._replay.sample(num_steps * self._config.batch_size,
                                self._sample_random_state)
    self._acting_params = self._learner.policy_params
    if num_steps == 1:
      return self._learner.update(batch)
    batches = replay_lib.Transition(*(
        field.reshape((num_steps, self._config.batch_size) + field.shape[1:])
        for field in batch))
    return self._learner.update_steps(batches)

  def compile_update_in_background(self):
    """Starts compiling the learner call `update` makes (fused_steps
    gradient steps on batches of batch_size) on a background thread
    (learning.SACLearner.compile_in_background); returns the thread."""
    config = self._config
    leading = (config.batch_size,)
    if config.fused_steps > 1:
      leading = (config.fused_steps,) + leading
    sizes = {'observation': (self._flattener.size,),
             'action': (self._scaler.size,),
             'next_observation': (self._flattener.size,)}
    batches = replay_lib.Transition(**{
        field: np.zeros(leading + sizes.get(field, ()), np.float32)
        for field in replay_lib.Transition._fields})
    return self._learner.compile_in_background(batches)

  # Evaluation.

  def policy(self, deterministic=True, seed=0):
    """Callable timestep -> action with the agent's current parameters.

    Deterministic: tanh(mean). Otherwise samples with its own RandomState
    seeded by `seed` (the training actor's is left alone).
    """
    actor = actor_lib.SACActor(self._networks, self._policy_params, seed,
                               evaluation=deterministic)
    return _TimestepPolicy(self._flattener, actor, self._scaler)

  # Accessors.

  @property
  def config(self):
    return self._config

  @property
  def learner(self):
    return self._learner

  @property
  def replay(self):
    return self._replay

  @property
  def actor(self):
    return self._actor

  @property
  def flattener(self):
    return self._flattener

  @property
  def acting_policy_params(self):
    """The policy parameters the actor samples with (module docstring)."""
    return self._acting_params

  @property
  def env_steps(self):
    """Transitions observed."""
    return self._env_steps

  # Checkpoints.

  def _description(self):
    return {
        'format': CHECKPOINT_FORMAT,
        'config': self._config.to_dict(),
        'seed': self._seed,
        'images': self._images,
        'observation_keys': list(self._flattener.keys),
        'observation_size': self._flattener.size,
        'action_size': self._scaler.size,
        'action_minimum': self._scaler.minimum.tolist(),
        'action_maximum': self._scaler.maximum.tolist(),
    }

  def save(self, directory, metadata=None, arrays=None):
    """Writes the whole agent to `directory` (replaced atomically).

    metadata: JSON-able dict and arrays: {name: array} of the caller (e.g.
    loop counters, environment RNG state), returned by `restore`.
    """
    description = self._description()
    description['counters'] = {
        'env_steps': self._env_steps,
        'steps_since_update': self._steps_since_update,
        'update_credit': self._update_credit,
        'learner_steps': self._learner.steps,
    }
    description['metadata'] = metadata or {}
    agent_arrays = dict(
        _random_state_arrays('sample_random_state',
                             self._sample_random_state),
        **_random_state_arrays('actor_random_state',
                               self._actor.random_state))
    if self._last_observation is not None:
      agent_arrays['last_observation'] = self._last_observation
    for key, value in learning.flatten_to_arrays(
        self._acting_params).items():
      agent_arrays[_ACTING_PREFIX + key] = value
    for key, value in (arrays or {}).items():
      agent_arrays[_EXTRA_PREFIX + key] = np.asarray(value)
    with checkpointing.atomic_directory(directory) as staging:
      checkpointing.save_json(staging / 'agent.json', description)
      checkpointing.save_arrays(staging / 'learner.npz',
                                self._learner.state())
      checkpointing.save_arrays(staging / 'replay.npz', self._replay.state())
      checkpointing.save_arrays(staging / 'agent.npz', agent_arrays)

  def restore(self, directory):
    """Restores a `save`d agent built with the same spec and config.

    Returns CheckpointExtras(metadata, arrays) given to `save`.
    """
    directory = pathlib.Path(directory)
    description = checkpointing.load_json(directory / 'agent.json')
    description['config'] = config_lib.SACConfig.from_dict(
        description['config']).to_dict()
    expected = self._description()
    for key in ('format', 'config', 'images', 'observation_keys',
                'observation_size', 'action_size', 'action_minimum',
                'action_maximum'):
      if description.get(key) != expected[key]:
        raise ValueError(f'Checkpoint {directory} has {key}='
                         f'{description.get(key)!r}, this agent has '
                         f'{expected[key]!r}')
    agent_arrays = checkpointing.load_arrays(directory / 'agent.npz')
    self._learner.restore(checkpointing.load_arrays(directory /
                                                    'learner.npz'))
    self._replay.restore(checkpointing.load_arrays(directory / 'replay.npz'))
    _restore_random_state(agent_arrays, 'sample_random_state',
                          self._sample_random_state)
    if 'actor_random_state/keys' in agent_arrays:
      _restore_random_state(agent_arrays, 'actor_random_state',
                            self._actor.random_state)
    else:   # Written when the actor sampled with a JAX key: seeded by it.
      self._actor.random_state.seed(
          np.asarray(agent_arrays['actor_key']).astype(np.uint32))
    self._last_observation = agent_arrays.get('last_observation')
    acting = {key[len(_ACTING_PREFIX):]: value
              for key, value in agent_arrays.items()
              if key.startswith(_ACTING_PREFIX)}
    # Checkpoints written before the acting policy was saved act with the
    # learner's.
    self._acting_params = (learning.unflatten_from_arrays(
        self._learner.policy_params, acting) if acting
                           else self._learner.policy_params)
    self._flat_cache = (None, None)
    counters = description['counters']
    self._env_steps = int(counters['env_steps'])
    self._steps_since_update = int(counters['steps_since_update'])
    self._update_credit = float(counters['update_credit'])
    self._seed = description['seed']
    extras = {key[len(_EXTRA_PREFIX):]: value
              for key, value in agent_arrays.items()
              if key.startswith(_EXTRA_PREFIX)}
    return CheckpointExtras(description['metadata'], extras)


class _TimestepPolicy:
  """timestep -> environment action, through a flattener and an actor."""

  def __init__(self, flattener, actor, scaler):
    self._flattener = flattener
    self._actor = actor
    self._scaler = scaler

  def __call__(self, timestep):
    return self._scaler.to_environment(
        self._actor.select_action(self._flattener(timestep.observation)))


def load_policy(directory, environment, deterministic=True, seed=0):
  """timestep -> action callable of a saved agent's policy on `environment`.

  Reads only agent.json and learner.npz's policy parameters; the
  environment must have the observations and actions the agent was trained
  on.
  """
  directory = pathlib.Path(directory)
  description = checkpointing.load_json(directory / 'agent.json')
  if description.get('format') != CHECKPOINT_FORMAT:
    raise ValueError(f'Checkpoint {directory} has format '
                     f'{description.get("format")!r}, expected '
                     f'{CHECKPOINT_FORMAT}')
  flattener = observations.ObservationFlattener(
      environment.observation_spec(), images=description['images'])
  if list(flattener.keys) != description['observation_keys'] or (
      flattener.size != description['observation_size']):
    raise ValueError(
        f'The environment observes {list(flattener.keys)} ({flattener.size} '
        f'values), the checkpoint {directory} was trained on '
        f'{description["observation_keys"]} '
        f'({description["observation_size"]} values)')
  scaler = actor_lib.ActionScaler(environment.action_spec())
  if (scaler.size != description['action_size']
      or scaler.minimum.tolist() != description['action_minimum']
      or scaler.maximum.tolist() != description['action_maximum']):
    raise ValueError(f'The environment action spec {environment.action_spec()}'
                     f' differs from the checkpoint\'s ({directory})')
  config = config_lib.SACConfig.from_dict(description['config'])
  networks = networks_lib.make_networks(flattener.size, scaler.size,
                                        config.hidden_sizes)
  prefix = 'policy_params/'
  arrays = {key[len(prefix):]: value for key, value in
            checkpointing.load_arrays(directory / 'learner.npz').items()
            if key.startswith(prefix)}
  params = learning.unflatten_from_arrays(
      networks.policy_init(np.random.RandomState(0)), arrays)
  actor = actor_lib.SACActor(networks, lambda: params, seed,
                             evaluation=deterministic)
  return _TimestepPolicy(flattener, actor, scaler)
