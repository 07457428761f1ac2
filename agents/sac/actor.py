"""SAC actor: picks actions from flat observations with the current policy.

Actions live in [-1, 1] (the tanh-Gaussian's range); agents/action_scaler.py
maps them to and from a bounded dm_env action spec.
"""

from typing import Any, Sequence, Tuple

import jax
import numpy as np

from agents import variable_utils
from agents.sac import networks as networks_lib

# A policy's layers: (kernel, bias) pairs of float32 NumPy arrays.
Layers = Tuple[Tuple[np.ndarray, np.ndarray], ...]


def numpy_policy(params: Any) -> Layers:
  """The policy's layers as float32 NumPy (kernel, bias) pairs, input first.

  Args:
    params: `networks.GaussianPolicy` parameters (flax: an MLP of Dense
      layers, ReLU between them, a last layer giving mean and log std).

  Returns:
    The layers.

  Raises:
    ValueError: params of another structure.
  """
  try:
    mlp = params['params']['MLP_0']
    names = sorted(mlp, key=lambda name: int(name.rsplit('_', 1)[1]))
    return tuple((np.asarray(mlp[name]['kernel'], np.float32),
                  np.asarray(mlp[name]['bias'], np.float32))
                 for name in names)
  except (KeyError, TypeError, ValueError, IndexError) as e:
    structure = jax.tree_util.tree_structure(params)
    raise ValueError(f'Expected GaussianPolicy params (params/MLP_0/Dense_i/'
                     f'kernel, bias), got {structure}') from e


def policy_mean_log_std(layers: Sequence[Tuple[np.ndarray, np.ndarray]],
                        observation: np.ndarray
                        ) -> Tuple[np.ndarray, np.ndarray]:
  """The policy's Gaussian in NumPy: the same maths as
  `networks.GaussianPolicy` (float32).

  Args:
    layers: of `numpy_policy`.
    observation: (..., observation_size) float32.

  Returns:
    (mean, log std clipped to [LOG_STD_MIN, LOG_STD_MAX]), each
    (..., action_size).
  """
  x = observation
  for kernel, bias in layers[:-1]:
    x = np.maximum(x @ kernel + bias, 0.0)
  kernel, bias = layers[-1]
  mean, log_std = np.split(x @ kernel + bias, 2, axis=-1)
  return mean, np.clip(log_std, networks_lib.LOG_STD_MIN,
                       networks_lib.LOG_STD_MAX)


class SACActor:
  """Samples (or, in evaluation, takes tanh(mean)) actions in [-1, 1].

  The policy runs in NumPy on the host, not as a JAX computation: JAX
  executes a device's computations in order, so a jitted action would wait
  for the learner call in flight (docs/benchmarks.md, "SAC training
  throughput"). A one-observation forward pass of the small MLP costs tens
  of microseconds this way.

  Args:
    networks: `SACNetworks`.
    variables: the policy parameters' holder (agents/variable_utils.py:
      `.params`), read at every action; they are copied to NumPy when a
      different params object comes back.
    seed: int seed of the sampling noise (a np.random.RandomState).
    evaluation: deterministic actions tanh(mean) instead of samples.
  """

  def __init__(self, networks: networks_lib.SACNetworks,
               variables: variable_utils.VariableClient, seed: int,
               evaluation: bool = False):
    self._variables = variables
    self.random_state = np.random.RandomState(seed)
    self.evaluation = bool(evaluation)
    self._observation_size = networks.observation_size
    self._source = None   # The params object `_layers` were copied from.
    self._layers = None

  def _current_layers(self):
    params = self._variables.params
    if params is not self._source:
      self._layers = numpy_policy(params)
      self._source = params
    return self._layers

  def select_action(self, observation: np.ndarray) -> np.ndarray:
    """The action for a flat observation.

    Args:
      observation: (observation_size,).

    Returns:
      (action_size,) float64 in [-1, 1].

    Raises:
      ValueError: an observation of another shape.
    """
    observation = np.asarray(observation, np.float32)
    if observation.shape != (self._observation_size,):
      raise ValueError(f'Observation vector has shape {observation.shape}, '
                       f'expected ({self._observation_size},)')
    mean, log_std = policy_mean_log_std(self._current_layers(), observation)
    if self.evaluation:
      pre_squash = mean
    else:
      noise = self.random_state.standard_normal(mean.shape)
      pre_squash = mean + np.exp(log_std) * noise.astype(np.float32)
    return np.clip(np.tanh(pre_squash.astype(np.float64)), -1.0, 1.0)
