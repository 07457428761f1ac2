"""SAC learner: one jit-compiled update of critics, policy and temperature.

Per gradient step on a batch (s, a, r, d, s') (Haarnoja et al. 2018):

* critic: y = c r + gamma d (min_j Q'_j(s', a') - alpha log pi(a'|s')) with
  a' ~ pi(.|s'), target critics Q' and reward scale c (r is the reward less
  beta x the step's cost where the config's cost_penalty beta > 0);
  loss = mean_j 0.5 (Q_j(s, a) - y)^2;
* policy: loss = alpha log pi(a~|s) - min_j Q_j(s, a~), a~ ~ pi(.|s)
  reparameterised, with the critics before this step's critic update;
* temperature: loss = alpha (-log pi(a~|s) - H_target) with the entropy
  estimate held fixed, so alpha falls while the entropy is above target;
* targets: Q' <- (1 - tau) Q' + tau Q.

alpha is the temperature before this step's update in all three losses. All
of it, and several steps at once (`update_steps`, a lax.scan), is one XLA
computation.
"""

import collections
import collections.abc
import functools
import threading
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple

import jax
import jax.numpy as jnp
import numpy as np
import optax

from agents import checkpoint_files
from agents import config as config_lib
from agents import replay
from agents.sac import networks as networks_lib

TrainingState = collections.namedtuple('TrainingState', [
    'policy_params', 'q_params', 'target_q_params', 'log_temperature',
    'policy_optimizer_state', 'q_optimizer_state',
    'temperature_optimizer_state', 'key', 'steps'])

METRIC_NAMES = ('critic_loss', 'actor_loss', 'temperature_loss',
                'temperature', 'entropy', 'q_values', 'target_q_values')


def _optimizer(config):
  adam = optax.adam(config.learning_rate)
  if config.max_grad_norm is None:
    return adam
  return optax.chain(optax.clip_by_global_norm(config.max_grad_norm), adam)


def polyak_average(target: Any, online: Any, tau: float) -> Any:
  """Target parameters moved towards the online ones, leaf by leaf.

  Args:
    target: the target parameters (a pytree).
    online: the online parameters, of target's structure.
    tau: the step towards the online ones, in [0, 1].

  Returns:
    (1 - tau) target + tau online.
  """
  return jax.tree_util.tree_map(
      lambda t, o: (1.0 - tau) * t + tau * o, target, online)


def _to_floats(metrics):
  """{name: float} of a dict of device scalars (one transfer)."""
  return {name: float(value)
          for name, value in jax.device_get(metrics).items()}


class UpdateMetrics(collections.abc.Mapping):
  """An update's metrics as floats, fetched from the device when first read.

  JAX dispatches the update asynchronously: reading its metrics at once
  would wait for it, leaving it unread lets it run while the caller (the
  environment loop) steps the environment.

  Args:
    device_metrics: {name: device scalar} of an update.
  """

  def __init__(self, device_metrics: Mapping[str, jax.Array]):
    self._names = tuple(device_metrics)
    self._device = device_metrics
    self._floats = None

  def _values(self):
    if self._floats is None:
      self._floats = _to_floats(self._device)
      self._device = None
    return self._floats

  def __getitem__(self, name):
    return self._values()[name]

  def __iter__(self):
    return iter(self._names)

  def __len__(self):
    return len(self._names)


class UpdateFunctions:
  """Pure SAC maths for one (networks, config, action size).

  `compiled_update_functions` caches its jitted functions, so learners of
  the same networks and config share compilations.

  Args:
    networks: the policy and critics.
    config: SAC's hyperparameters.
    action_size: the action's size (the entropy target's).
  """

  def __init__(self, networks: networks_lib.SACNetworks,
               config: config_lib.SACConfig, action_size: int):
    self.networks = networks
    self.config = config
    self.target_entropy = config.entropy_target(action_size)
    self.policy_optimizer = _optimizer(config)
    self.q_optimizer = _optimizer(config)
    self.temperature_optimizer = _optimizer(config)

  def initial_state(self, policy_params: Any, q_params: Any,
                    key: jax.Array) -> TrainingState:
    """The training state before the first step.

    Args:
      policy_params: the policy's initial parameters.
      q_params: the critics' initial parameters (copied to the targets).
      key: the updates' JAX random key.

    Returns:
      The state: optimizers initialised, initial_temperature, 0 steps.
    """
    log_temperature = jnp.log(jnp.asarray(self.config.initial_temperature,
                                          jnp.float32))
    return TrainingState(
        policy_params=policy_params,
        q_params=q_params,
        target_q_params=jax.tree_util.tree_map(jnp.copy, q_params),
        log_temperature=log_temperature,
        policy_optimizer_state=self.policy_optimizer.init(policy_params),
        q_optimizer_state=self.q_optimizer.init(q_params),
        temperature_optimizer_state=self.temperature_optimizer.init(
            log_temperature),
        key=key,
        steps=jnp.zeros((), jnp.int32))

  def critic_loss(self, q_params: Any, state: TrainingState,
                  batch: replay.Transition, temperature: jax.Array,
                  key: jax.Array) -> Tuple[jax.Array, Tuple[jax.Array,
                                                             jax.Array]]:
    """The critics' loss (module doc).

    Args:
      q_params: the critics' parameters (differentiated).
      state: the training state (policy and target critics).
      batch: the transitions.
      temperature: alpha.
      key: for the next actions' samples.

    Returns:
      (loss, (q values (batch, 2), targets (batch,))).
    """
    networks = self.networks
    next_mean, next_log_std = networks.policy_apply(
        state.policy_params, batch.next_observation)
    next_action, next_log_prob = networks.sample(key, next_mean,
                                                 next_log_std)
    next_q = networks.q_apply(state.target_q_params, batch.next_observation,
                              next_action)
    next_value = jnp.min(next_q, axis=-1) - temperature * next_log_prob
    reward = batch.reward
    if self.config.cost_penalty:
      reward = reward - self.config.cost_penalty * batch.cost
    target = jax.lax.stop_gradient(
        self.config.reward_scale * reward
        + self.config.discount * batch.discount * next_value)
    q = networks.q_apply(q_params, batch.observation, batch.action)
    loss = 0.5 * jnp.mean(jnp.square(q - target[:, None]))
    return loss, (q, target)

  def actor_loss(self, policy_params: Any, state: TrainingState,
                 batch: replay.Transition, temperature: jax.Array,
                 key: jax.Array) -> Tuple[jax.Array, jax.Array]:
    """The policy's loss (module doc).

    Args:
      policy_params: the policy's parameters (differentiated).
      state: the training state (critics).
      batch: the transitions.
      temperature: alpha.
      key: for the actions' samples.

    Returns:
      (loss, log probabilities (batch,) of the sampled actions).
    """
    networks = self.networks
    mean, log_std = networks.policy_apply(policy_params, batch.observation)
    action, log_prob = networks.sample(key, mean, log_std)
    q = networks.q_apply(state.q_params, batch.observation, action)
    loss = jnp.mean(temperature * log_prob - jnp.min(q, axis=-1))
    return loss, log_prob

  def sgd_step(self, state: TrainingState, batch: replay.Transition
               ) -> Tuple[TrainingState, Dict[str, jax.Array]]:
    """One gradient step.

    Args:
      state: the training state.
      batch: the transitions, (batch, ...) per field.

    Returns:
      (the next state, {metric name: device scalar}).
    """
    key, critic_key, actor_key = jax.random.split(state.key, 3)
    temperature = jnp.exp(state.log_temperature)

    (critic_loss, (q, target)), q_grads = jax.value_and_grad(
        self.critic_loss, has_aux=True)(state.q_params, state, batch,
                                        temperature, critic_key)
    (actor_loss, log_prob), policy_grads = jax.value_and_grad(
        self.actor_loss, has_aux=True)(state.policy_params, state, batch,
                                       temperature, actor_key)
    entropy = -jnp.mean(log_prob)
    entropy_gap = jax.lax.stop_gradient(entropy - self.target_entropy)
    temperature_loss, temperature_grad = jax.value_and_grad(
        lambda log_temperature: jnp.exp(log_temperature) * entropy_gap)(
            state.log_temperature)

    q_updates, q_optimizer_state = self.q_optimizer.update(
        q_grads, state.q_optimizer_state, state.q_params)
    q_params = optax.apply_updates(state.q_params, q_updates)
    policy_updates, policy_optimizer_state = self.policy_optimizer.update(
        policy_grads, state.policy_optimizer_state, state.policy_params)
    policy_params = optax.apply_updates(state.policy_params, policy_updates)
    temperature_update, temperature_optimizer_state = (
        self.temperature_optimizer.update(
            temperature_grad, state.temperature_optimizer_state,
            state.log_temperature))
    log_temperature = optax.apply_updates(state.log_temperature,
                                          temperature_update)
    target_q_params = polyak_average(state.target_q_params, q_params,
                                     self.config.tau)

    new_state = TrainingState(
        policy_params=policy_params,
        q_params=q_params,
        target_q_params=target_q_params,
        log_temperature=log_temperature,
        policy_optimizer_state=policy_optimizer_state,
        q_optimizer_state=q_optimizer_state,
        temperature_optimizer_state=temperature_optimizer_state,
        key=key,
        steps=state.steps + 1)
    metrics = {
        'critic_loss': critic_loss,
        'actor_loss': actor_loss,
        'temperature_loss': temperature_loss,
        'temperature': temperature,
        'entropy': entropy,
        'q_values': jnp.mean(q),
        'target_q_values': jnp.mean(target),
    }
    return new_state, metrics

  def sgd_steps(self, state: TrainingState, batches: replay.Transition
                ) -> Tuple[TrainingState, Dict[str, jax.Array]]:
    """Several steps in one lax.scan.

    Args:
      state: the training state.
      batches: the transitions, (steps, batch, ...) per field.

    Returns:
      (the state after the steps, metrics averaged over the steps).
    """
    state, metrics = jax.lax.scan(self.sgd_step, state, batches)
    return state, jax.tree_util.tree_map(jnp.mean, metrics)


CompiledUpdate = collections.namedtuple(
    'CompiledUpdate', ['initial_state', 'sgd_step', 'sgd_steps'])


@functools.lru_cache(maxsize=None)
def compiled_update_functions(networks: networks_lib.SACNetworks,
                              config: config_lib.SACConfig, action_size: int,
                              functions_class: Optional[type] = None
                              ) -> CompiledUpdate:
  """Jitted (initial_state, sgd_step, sgd_steps), shared across learners.

  No buffer donation: actors and policies keep reading the parameters of a
  state while the next one is computed.

  Args:
    networks: the policy and critics.
    config: the hyperparameters (hashable: the cache's key).
    action_size: the action's size.
    functions_class: the class holding the maths (default SAC's
      `UpdateFunctions`; a subclass for a variant of SAC's losses).

  Returns:
    The jitted functions.
  """
  functions = (functions_class or UpdateFunctions)(networks, config,
                                                   action_size)
  return CompiledUpdate(jax.jit(functions.initial_state),
                        jax.jit(functions.sgd_step),
                        jax.jit(functions.sgd_steps))


class SACLearner:
  """Holds the TrainingState and applies jit-compiled SAC updates.

  Args:
    networks: the policy and critics, of these sizes.
    config: the hyperparameters.
    observation_size: the flat observation's size.
    action_size: the action's size.
    seed: seeds the initial parameters and the updates' random key.

  Raises:
    ValueError: networks built for other sizes.
  """

  # The maths (a subclass of UpdateFunctions for a variant of SAC).
  FUNCTIONS_CLASS = UpdateFunctions

  def __init__(self, networks: networks_lib.SACNetworks,
               config: config_lib.SACConfig, observation_size: int,
               action_size: int, seed: int):
    if (networks.observation_size != observation_size
        or networks.action_size != action_size):
      raise ValueError(
          f'Networks built for observation_size {networks.observation_size}'
          f' and action_size {networks.action_size}, learner given '
          f'{observation_size} and {action_size}')
    self._observation_size = int(observation_size)
    self._action_size = int(action_size)
    self._functions = compiled_update_functions(
        networks, config, self._action_size, self.FUNCTIONS_CLASS)
    random_state = np.random.RandomState(seed)
    self._state = self._initial_state(networks, random_state,
                                      jax.random.PRNGKey(seed))

  def _initial_state(self, networks, random_state, key):
    policy_params = networks.policy_init(random_state)
    q_params = networks.q_init(random_state)
    return self._functions.initial_state(policy_params, q_params, key)

  # Public interface.

  def _check_batch(self, batch, leading):
    sizes = {'observation': self._observation_size,
             'action': self._action_size,
             'next_observation': self._observation_size}
    for field in batch._fields:
      value = getattr(batch, field)
      rank = leading + (1 if field in sizes else 0)
      if np.ndim(value) != rank or (
          field in sizes and np.shape(value)[-1] != sizes[field]):
        expected = ('(steps, batch' if leading == 2 else '(batch') + (
            f', {sizes[field]})' if field in sizes else ')')
        raise ValueError(f'Batch {field} has shape {np.shape(value)}, '
                         f'expected {expected}')

  def update(self, batch: replay.Transition) -> UpdateMetrics:
    """One gradient step, dispatched asynchronously.

    Args:
      batch: the transitions, (batch, ...) per field.

    Returns:
      The step's metrics.

    Raises:
      ValueError: fields of the wrong shapes.
    """
    self._check_batch(batch, leading=1)
    self._state, metrics = self._functions.sgd_step(self._state, batch)
    return UpdateMetrics(metrics)

  def update_steps(self, batches: replay.Transition) -> UpdateMetrics:
    """len(batches.reward) gradient steps in one compiled loop.

    Args:
      batches: the transitions, (steps, batch, ...) per field.

    Returns:
      The metrics averaged over the steps.

    Raises:
      ValueError: fields of the wrong shapes.
    """
    self._check_batch(batches, leading=2)
    self._state, metrics = self._functions.sgd_steps(self._state, batches)
    return UpdateMetrics(metrics)

  def compile_in_background(self, batches: replay.Transition
                            ) -> threading.Thread:
    """Compiles the update for batches shaped like `batches` on a daemon
    thread, leaving the state alone. XLA compiles outside the GIL, so the
    caller steps its environment in the meantime instead of waiting at its
    first update.

    Args:
      batches: leading axes (batch,) as `update` takes them, or (steps,
        batch) as `update_steps`.

    Returns:
      The thread.

    Raises:
      ValueError: fields of the wrong shapes.
    """
    fused = np.ndim(batches.reward) == 2
    self._check_batch(batches, leading=2 if fused else 1)
    function = (self._functions.sgd_steps if fused
                else self._functions.sgd_step)
    state = self._state
    thread = threading.Thread(
        target=lambda: jax.block_until_ready(function(state, batches)),
        name='compile_update', daemon=True)
    thread.start()
    return thread

  def get_variables(self, names: Sequence[str]) -> List[Any]:
    """Acme's variable source.

    Args:
      names: variable names; 'policy' is the policy parameters.

    Returns:
      The value of each name.

    Raises:
      ValueError: another name.
    """
    values = []
    for name in names:
      if name != 'policy':
        raise ValueError(f'Unknown variable {name!r}: the learner serves '
                         "'policy'")
      values.append(self._state.policy_params)
    return values

  @property
  def policy_params(self) -> Any:
    """The policy's current parameters."""
    return self._state.policy_params

  @property
  def training_state(self) -> TrainingState:
    """The whole training state."""
    return self._state

  @property
  def steps(self) -> int:
    """Gradient steps taken."""
    return int(self._state.steps)

  @property
  def temperature(self) -> float:
    """The current temperature alpha."""
    return float(np.exp(np.asarray(self._state.log_temperature)))

  def state(self) -> Dict[str, np.ndarray]:
    """{path: NumPy array} of the whole TrainingState (for .npz)."""
    return checkpoint_files.flatten_to_arrays(self._state._asdict())

  def restore(self, arrays: Mapping[str, np.ndarray]) -> None:
    """Restores a `state()` exactly.

    Args:
      arrays: of `state()`.

    Raises:
      ValueError: arrays missing or of other shapes or dtypes.
    """
    restored = checkpoint_files.unflatten_from_arrays(self._state._asdict(),
                                                     arrays)
    self._state = type(self._state)(**restored)
