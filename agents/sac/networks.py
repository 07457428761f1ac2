"""SAC networks: a tanh-Gaussian policy and twin Q critics (flax.linen).

The policy maps an observation to the mean and log standard deviation of a
diagonal Gaussian over pre-squash actions u; the action is a = tanh(u), in
(-1, 1). Its log density follows from the change of variables:

  log pi(a|s) = sum_i [log N(u_i; mu_i, sigma_i) - log(1 - tanh(u_i)^2)],

with log(1 - tanh(u)^2) = 2 (log 2 - u - softplus(-2u)), exact and stable
for large |u|. The log standard deviation is clipped to [LOG_STD_MIN,
LOG_STD_MAX] (Haarnoja et al.'s reference implementation; the gradient is
zero outside). The deterministic action is tanh(mu).

Parameters are initialised in NumPy from a np.random.RandomState with flax's
default distributions (kernels LeCun normal: a normal truncated to two
standard deviations, scaled to variance 1 / fan_in; biases zero): the same
distribution as `module.init`, without compiling JAX's random bit generator
(seconds of XLA compilation per network on a loaded 2-core machine).

The critics are two independent MLPs on [observation, action], each with a
scalar output; `q_apply` returns them stacked on a last axis of size 2.
"""

import dataclasses
import functools
import math
from typing import Any, Callable, Sequence, Tuple

import flax
import flax.linen as nn
import jax
import jax.numpy as jnp
import numpy as np

# Bounds of the policy's log standard deviation (Haarnoja et al. 2018,
# softlearning's GaussianPolicy: SCALE_DIAG_MIN_MAX = (-20, 2)).
LOG_STD_MIN = -20.0
LOG_STD_MAX = 2.0
_HALF_LOG_TWO_PI = 0.5 * math.log(2.0 * math.pi)
_LOG_TWO = math.log(2.0)
# flax.linen.initializers.lecun_normal: a standard normal truncated to
# [-2, 2] has standard deviation 0.87962566103423978 (flax's constant),
# divided out so the kernel's variance is 1 / fan_in.
TRUNCATION = 2.0
TRUNCATED_NORMAL_STD = 0.87962566103423978


class MLP(nn.Module):
  """ReLU multilayer perceptron with a linear output layer."""
  hidden_sizes: Sequence[int]
  output_size: int

  @nn.compact
  def __call__(self, inputs: jnp.ndarray) -> jnp.ndarray:
    """The output layer's values.

    Args:
      inputs: (..., input size).

    Returns:
      (..., output_size).
    """
    x = inputs
    for size in self.hidden_sizes:
      x = nn.relu(nn.Dense(size)(x))
    return nn.Dense(self.output_size)(x)


class GaussianPolicy(nn.Module):
  """Observation -> (mean, log_std) of the pre-squash Gaussian."""
  hidden_sizes: Sequence[int]
  action_size: int

  @nn.compact
  def __call__(self, observation: jnp.ndarray
               ) -> Tuple[jnp.ndarray, jnp.ndarray]:
    """The pre-squash Gaussian of an observation.

    Args:
      observation: (..., observation size).

    Returns:
      (mean, log_std clipped to [LOG_STD_MIN, LOG_STD_MAX]), each
      (..., action_size).
    """
    out = MLP(self.hidden_sizes, 2 * self.action_size)(observation)
    mean, log_std = jnp.split(out, 2, axis=-1)
    return mean, jnp.clip(log_std, LOG_STD_MIN, LOG_STD_MAX)


class TwinCritic(nn.Module):
  """(observation, action) -> (..., 2) values of two independent critics."""
  hidden_sizes: Sequence[int]

  @nn.compact
  def __call__(self, observation: jnp.ndarray,
               action: jnp.ndarray) -> jnp.ndarray:
    """Both critics' values.

    Args:
      observation: (..., observation size).
      action: (..., action size).

    Returns:
      (..., 2).
    """
    inputs = jnp.concatenate([observation, action], axis=-1)
    q1 = MLP(self.hidden_sizes, 1, name='critic_0')(inputs)
    q2 = MLP(self.hidden_sizes, 1, name='critic_1')(inputs)
    return jnp.concatenate([q1, q2], axis=-1)


def _truncated_normal(random_state, shape):
  """Standard normal samples redrawn until within [-2, 2]."""
  values = random_state.standard_normal(shape)
  outside = np.abs(values) > TRUNCATION
  while np.any(outside):
    values[outside] = random_state.standard_normal(int(outside.sum()))
    outside = np.abs(values) > TRUNCATION
  return values


def init_params(module: nn.Module, random_state: np.random.RandomState,
                example_inputs: Sequence[jnp.ndarray]) -> Any:
  """Params of `module` drawn from flax's default initialisers in NumPy.

  Args:
    module: the flax module.
    random_state: the draws' random numbers.
    example_inputs: arrays of the module's input shapes.

  Returns:
    The params, as `module.init` shapes them.

  Raises:
    TypeError: a random_state that is not a np.random.RandomState.
    ValueError: a parameter that is neither a kernel nor a bias.
  """
  if not isinstance(random_state, np.random.RandomState):
    raise TypeError('random_state must be a np.random.RandomState, got '
                    f'{type(random_state).__name__}')
  shapes = jax.eval_shape(module.init, jax.random.PRNGKey(0),
                          *example_inputs)
  flat = flax.traverse_util.flatten_dict(flax.core.unfreeze(shapes))
  params = {}
  for path in sorted(flat):
    leaf = flat[path]
    if path[-1] == 'kernel':
      fan_in = int(np.prod(leaf.shape[:-1]))
      std = np.sqrt(1.0 / fan_in) / TRUNCATED_NORMAL_STD
      value = std * _truncated_normal(random_state, leaf.shape)
    elif path[-1] == 'bias':
      value = np.zeros(leaf.shape)
    else:
      raise ValueError(f'No initialiser for parameter {"/".join(path)}')
    params[path] = jnp.asarray(value, leaf.dtype)
  return flax.traverse_util.unflatten_dict(params)


def squash_log_jacobian(pre_squash: jnp.ndarray) -> jnp.ndarray:
  """log |d tanh(u)/du| = log(1 - tanh(u)^2), elementwise and stable.

  Args:
    pre_squash: u.

  Returns:
    The log Jacobian, u's shape.
  """
  return 2.0 * (_LOG_TWO - pre_squash - jax.nn.softplus(-2.0 * pre_squash))


def gaussian_log_prob(pre_squash: jnp.ndarray, mean: jnp.ndarray,
                      log_std: jnp.ndarray) -> jnp.ndarray:
  """Sum over the last axis of the diagonal Gaussian log density.

  Args:
    pre_squash: (..., n) points u.
    mean: (..., n).
    log_std: (..., n).

  Returns:
    (...,) log densities.
  """
  z = (pre_squash - mean) * jnp.exp(-log_std)
  return jnp.sum(-0.5 * z * z - log_std - _HALF_LOG_TWO_PI, axis=-1)


def tanh_gaussian_log_prob_of_pre_squash(pre_squash: jnp.ndarray,
                                         mean: jnp.ndarray,
                                         log_std: jnp.ndarray) -> jnp.ndarray:
  """log pi(tanh(u)) for pre-squash samples u (the sampler's path).

  Args:
    pre_squash: (..., n) samples u.
    mean: (..., n).
    log_std: (..., n).

  Returns:
    (...,) log densities.
  """
  return (gaussian_log_prob(pre_squash, mean, log_std)
          - jnp.sum(squash_log_jacobian(pre_squash), axis=-1))


def tanh_gaussian_log_prob(action: jnp.ndarray, mean: jnp.ndarray,
                           log_std: jnp.ndarray,
                           epsilon: float = 1e-6) -> jnp.ndarray:
  """log pi(a) of actions a in (-1, 1).

  Args:
    action: (..., n) actions; |a| is clipped to 1 - epsilon.
    mean: (..., n) of the pre-squash Gaussian.
    log_std: (..., n).
    epsilon: the clipping margin.

  Returns:
    (...,) log densities.
  """
  action = jnp.clip(action, -1.0 + epsilon, 1.0 - epsilon)
  return tanh_gaussian_log_prob_of_pre_squash(jnp.arctanh(action), mean,
                                              log_std)


def sample_tanh_gaussian(key: jax.Array, mean: jnp.ndarray,
                         log_std: jnp.ndarray
                         ) -> Tuple[jnp.ndarray, jnp.ndarray]:
  """One reparameterised sample per row.

  Args:
    key: a JAX random key.
    mean: (..., n) of the pre-squash Gaussian.
    log_std: (..., n).

  Returns:
    (action (..., n) in (-1, 1), log_prob (...,)).
  """
  noise = jax.random.normal(key, mean.shape, mean.dtype)
  pre_squash = mean + jnp.exp(log_std) * noise
  return (jnp.tanh(pre_squash),
          tanh_gaussian_log_prob_of_pre_squash(pre_squash, mean, log_std))


def deterministic_action(mean: jnp.ndarray) -> jnp.ndarray:
  """The policy's mode-like action tanh(mean) used for evaluation.

  Args:
    mean: (..., n) of the pre-squash Gaussian.

  Returns:
    (..., n) actions.
  """
  return jnp.tanh(mean)


@dataclasses.dataclass(frozen=True)
class SACNetworks:
  """Init/apply functions of the policy and the twin critic.

  policy_init(random_state) -> params; policy_apply(params, obs) -> (mean,
  log_std); q_init(random_state) -> params; q_apply(params, obs, action) -> (..., 2);
  sample(key, mean, log_std) -> (action, log_prob); log_prob(action, mean,
  log_std); deterministic_action(mean).
  """
  observation_size: int
  action_size: int
  hidden_sizes: tuple
  policy_init: Callable
  policy_apply: Callable
  q_init: Callable
  q_apply: Callable
  sample: Callable = sample_tanh_gaussian
  log_prob: Callable = tanh_gaussian_log_prob
  deterministic_action: Callable = deterministic_action


def make_networks(observation_size: int, action_size: int,
                  hidden_sizes: Sequence[int] = (256, 256)) -> SACNetworks:
  """SACNetworks for flat float32 observations and actions in [-1, 1].

  Equal arguments give the same (immutable) object, so compiled functions
  keyed on it are shared.

  Args:
    observation_size: an integer >= 1.
    action_size: an integer >= 1.
    hidden_sizes: the MLPs' hidden layer sizes, integers >= 1.

  Returns:
    The networks.

  Raises:
    ValueError: sizes that are not integers >= 1.
  """
  for name, value in (('observation_size', observation_size),
                      ('action_size', action_size)):
    if isinstance(value, bool) or int(value) != value or value < 1:
      raise ValueError(f'{name}={value!r}: expected an integer >= 1')
  hidden = tuple(hidden_sizes)
  if not hidden or any(int(h) != h or h < 1 for h in hidden):
    raise ValueError(f'hidden_sizes={hidden_sizes!r}: expected a non-empty '
                     'sequence of integers >= 1')
  return _make_networks(int(observation_size), int(action_size),
                        tuple(int(h) for h in hidden))


@functools.lru_cache(maxsize=None)
def _make_networks(observation_size, action_size, hidden_sizes):
  policy = GaussianPolicy(hidden_sizes, int(action_size))
  critic = TwinCritic(hidden_sizes)
  dummy_observation = jnp.zeros((1, int(observation_size)), jnp.float32)
  dummy_action = jnp.zeros((1, int(action_size)), jnp.float32)
  return SACNetworks(
      observation_size=int(observation_size),
      action_size=int(action_size),
      hidden_sizes=hidden_sizes,
      policy_init=functools.partial(init_params, policy,
                                    example_inputs=(dummy_observation,)),
      policy_apply=policy.apply,
      q_init=functools.partial(init_params, critic,
                               example_inputs=(dummy_observation,
                                               dummy_action)),
      q_apply=critic.apply,
  )
