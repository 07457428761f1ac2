"""SAC actor: picks actions from flat observations with the current policy.

Actions live in [-1, 1] (the tanh-Gaussian's range); `ActionScaler` maps
them to and from a bounded dm_env action spec.
"""

import functools

import jax
import jax.numpy as jnp
import numpy as np


class ActionScaler:
  """Affine map between [-1, 1]^n and a bounded 1-D action spec."""

  def __init__(self, action_spec):
    minimum = getattr(action_spec, 'minimum', None)
    maximum = getattr(action_spec, 'maximum', None)
    if minimum is None or maximum is None or len(action_spec.shape) != 1:
      raise ValueError(f'Expected a bounded 1-D action spec, got '
                       f'{action_spec!r}')
    shape = action_spec.shape
    self._minimum = np.broadcast_to(np.asarray(minimum, np.float64), shape)
    self._maximum = np.broadcast_to(np.asarray(maximum, np.float64), shape)
    if not (np.all(np.isfinite(self._minimum))
            and np.all(np.isfinite(self._maximum))
            and np.all(self._maximum > self._minimum)):
      raise ValueError(f'Action bounds must be finite with maximum > minimum,'
                       f' got minimum {self._minimum} and maximum '
                       f'{self._maximum}')
    self._identity = bool(np.all(self._minimum == -1.0)
                          and np.all(self._maximum == 1.0))
    self._half_range = 0.5 * (self._maximum - self._minimum)
    self._centre = 0.5 * (self._maximum + self._minimum)

  @property
  def size(self):
    return self._minimum.shape[0]

  @property
  def minimum(self):
    return self._minimum.copy()

  @property
  def maximum(self):
    return self._maximum.copy()

  def to_environment(self, normalised):
    """float64 environment action of a [-1, 1] action."""
    normalised = np.clip(np.asarray(normalised, np.float64), -1.0, 1.0)
    if self._identity:
      return normalised
    return self._centre + self._half_range * normalised

  def to_normalised(self, action):
    """[-1, 1] action of an environment action (clipped to the bounds)."""
    action = np.asarray(action, np.float64)
    if action.shape != self._minimum.shape:
      raise ValueError(f'Action has shape {action.shape}, expected '
                       f'{self._minimum.shape}')
    if not self._identity:
      action = (action - self._centre) / self._half_range
    return np.clip(action, -1.0, 1.0)


@functools.lru_cache(maxsize=None)
def _compiled_policy(networks):
  """Jitted (sample, mode) functions, shared by the actors of `networks`."""

  def sample(params, key, observation):
    key, sample_key = jax.random.split(key)
    mean, log_std = networks.policy_apply(params, observation[None])
    action, _ = networks.sample(sample_key, mean, log_std)
    return action[0], key

  def mode(params, observation):
    mean, _ = networks.policy_apply(params, observation[None])
    return networks.deterministic_action(mean)[0]

  return jax.jit(sample), jax.jit(mode)


class SACActor:
  """Samples (or, in evaluation, takes tanh(mean)) actions in [-1, 1].

  Args:
    networks: `SACNetworks`.
    variable_source: callable returning the current policy params (e.g. the
      learner's `policy_params`), read at every action as Acme's variable
      client would be after each update.
    seed: int seed of the sampling key.
    evaluation: deterministic actions tanh(mean) instead of samples.
  """

  def __init__(self, networks, variable_source, seed, evaluation=False):
    self._networks = networks
    self._variable_source = variable_source
    self._key = jax.random.PRNGKey(seed)
    self.evaluation = bool(evaluation)
    self._observation_size = networks.observation_size

    self._sample, self._mode = _compiled_policy(networks)

  def select_action(self, observation):
    """float64 (action_size,) action in [-1, 1] of a flat observation."""
    observation = np.asarray(observation, np.float32)
    if observation.shape != (self._observation_size,):
      raise ValueError(f'Observation vector has shape {observation.shape}, '
                       f'expected ({self._observation_size},)')
    params = self._variable_source()
    if self.evaluation:
      action = self._mode(params, observation)
    else:
      action, self._key = self._sample(params, self._key, observation)
    return np.clip(np.asarray(action, np.float64), -1.0, 1.0)

  @property
  def key(self):
    """The sampling key as a NumPy array (for checkpoints)."""
    return np.array(self._key, copy=True)

  @key.setter
  def key(self, value):
    value = np.asarray(value)
    expected = np.asarray(self._key)
    if value.shape != expected.shape or value.dtype != expected.dtype:
      raise ValueError(f'Actor key has shape {value.shape} and dtype '
                       f'{value.dtype}, expected {expected.shape} and '
                       f'{expected.dtype}')
    self._key = jnp.asarray(value)
