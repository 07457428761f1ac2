"""Ornstein-Uhlenbeck action noise and the noisy expert.

The reference's noisy expert (docs/reference_benchmark.md, Experts)
executes

  a = (1 - w) a_e + w X,     w = 0.02,

where a_e is the expert's action and X an Ornstein-Uhlenbeck process per
action dimension, dX = alpha (mu - X) dt + sigma sqrt(2 alpha) dW. Sampled
every `dt`, the process is exactly the AR(1) recursion

  X_{k+1} = mu + phi (X_k - mu) + sigma sqrt(1 - phi^2) eps_k,
  phi = exp(-alpha dt),  eps_k ~ N(0, 1),

whose stationary law is N(mu, sigma^2) and whose autocorrelation at lag k
is phi^k. One sample is drawn per RL step, so `dt` is the process's own
clock (the reference's 0.01), not the 0.1 s RL step.

What the defaults mean for the executed action (normalised to [-1, 1]):
alpha 0.5 and dt 0.01 give phi = exp(-0.005) = 0.995, a correlation time of
1 / (alpha dt) = 200 samples (RL steps); sigma 0.5 (half the action limit)
weighted by w = 0.02 is a perturbation of standard deviation w sigma = 0.01
of the action range, drifting slowly, plus a 2 % shrink (1 - w) of the
expert's own action. The reference's joint-space reach uses alpha 10
(phi = 0.905, about 10 steps), sigma 0.5 (`REFERENCE_PARAMETERS`).
"""

import math
import numbers
from typing import Any, Optional, Union

from dm_control import composer
import dm_env
import numpy as np

from hrc_suite.experts import base

# Reference parameters (docs/reference_benchmark.md, Experts),
# per action space: OU rate alpha (1/s), stationary std sigma (normalised
# action units: the limit is 1, sigma = half of it), sampling step dt (s).
REFERENCE_PARAMETERS = {
    'cartesian': {'alpha': 0.5, 'sigma': 0.5, 'dt': 0.01},
    'joint': {'alpha': 10.0, 'sigma': 0.5, 'dt': 0.01},
}
DEFAULT_ALPHA = REFERENCE_PARAMETERS['cartesian']['alpha']
DEFAULT_SIGMA = REFERENCE_PARAMETERS['cartesian']['sigma']
DEFAULT_DT = REFERENCE_PARAMETERS['cartesian']['dt']
# Weight of the noise in the executed action, a = (1 - w) a_e + w X
# (reference: a = 0.98 a_e + 0.02 OU).
DEFAULT_WEIGHT = 0.02
# Where X_0 is drawn from: the stationary law N(mu, sigma^2), or mu itself.
STARTS = ('stationary', 'mean')
# Mixed into the per-episode seed so that a NoisyExpert and an environment
# seeded with the same integer draw unrelated streams.
_NOISE_STREAM = 0x4F55   # 'OU'


def _finite(name, value, size, minimum=None, strict=False):
  """`value` broadcast to (size,) floats, each finite and above minimum."""
  try:
    array = np.broadcast_to(np.asarray(value, dtype=np.float64),
                            (size,)).copy()
  except (TypeError, ValueError) as e:
    raise ValueError(f'{name} must be a number or {size} numbers (one per '
                     f'action dimension), got {value!r}') from e
  bad = ~np.isfinite(array)
  if minimum is not None:
    bad |= (array <= minimum) if strict else (array < minimum)
  if bad.any():
    bound = '' if minimum is None else (
        f' and {">" if strict else ">="} {minimum}')
    raise ValueError(f'{name} must be finite{bound}, got {value!r}')
  return array


def random_state_from(
    seed: Union[int, np.random.RandomState]) -> np.random.RandomState:
  """A RandomState from an int seed or a RandomState (used as is).

  Args:
    seed: an integer >= 0 (taken modulo 2**32), or a RandomState.

  Returns:
    The RandomState.

  Raises:
    ValueError: neither.
  """
  if isinstance(seed, np.random.RandomState):
    return seed
  if isinstance(seed, numbers.Integral) and not isinstance(seed, bool) and (
      seed >= 0):
    return np.random.RandomState(int(seed) % 2**32)
  raise ValueError('Expected a seed (an integer >= 0) or an '
                   f'np.random.RandomState, got {seed!r}')


def episode_random_state(seed: int, episode: int) -> np.random.RandomState:
  """The noise stream of episode `episode` of a NoisyExpert seeded `seed`:
  RandomState(SeedSequence((_NOISE_STREAM, seed + episode))).

  Args:
    seed: the NoisyExpert's seed, an integer >= 0.
    episode: the episode's index, an integer >= 0.

  Returns:
    The episode's RandomState.

  Raises:
    ValueError: a seed or episode that is not an integer >= 0.
  """
  for name, value in (('seed', seed), ('episode', episode)):
    if not isinstance(value, numbers.Integral) or isinstance(
        value, bool) or value < 0:
      raise ValueError(f'{name} must be an integer >= 0, got {value!r}')
  sequence = np.random.SeedSequence((_NOISE_STREAM, int(seed) + int(episode)))
  return np.random.RandomState(sequence.generate_state(4))


class OrnsteinUhlenbeckNoise:
  """An exact AR(1) discretisation of an OU process per action dimension."""

  def __init__(self, size: int,
               alpha: Union[float, np.ndarray] = DEFAULT_ALPHA,
               sigma: Union[float, np.ndarray] = DEFAULT_SIGMA,
               dt: float = DEFAULT_DT, mu: Union[float, np.ndarray] = 0.0,
               weight: float = DEFAULT_WEIGHT, start: str = 'stationary'):
    """An OU process; sample it after `reset`.

    Args:
      size: number of action dimensions (a positive integer).
      alpha: mean-reversion rate (1/s), > 0, scalar or per dimension.
      sigma: stationary standard deviation, >= 0, scalar or per dimension.
      dt: time between samples (s), > 0.
      mu: the mean the process reverts to, scalar or per dimension.
      weight: w in [0, 1], the noise's share of the executed action
        (NoisyExpert executes (1 - w) a_e + w X).
      start: 'stationary' (X_0 ~ N(mu, sigma^2), so every sample has the
        stationary law) or 'mean' (X_0 = mu).

    Raises:
      ValueError: a parameter outside its range.
    """
    if not isinstance(size, numbers.Integral) or isinstance(
        size, bool) or size < 1:
      raise ValueError(f'size must be a positive integer (action '
                       f'dimensions), got {size!r}')
    self.size = int(size)
    self.alpha = _finite('alpha', alpha, self.size, 0.0, strict=True)
    self.sigma = _finite('sigma', sigma, self.size, 0.0)
    if not (isinstance(dt, numbers.Real) and math.isfinite(dt) and dt > 0):
      raise ValueError(f'dt must be a positive number (s), got {dt!r}')
    self.dt = float(dt)
    self.mu = _finite('mu', mu, self.size)
    if not (isinstance(weight, numbers.Real) and 0.0 <= weight <= 1.0):
      raise ValueError(f'weight must be a number in [0, 1], got {weight!r}')
    self.weight = float(weight)
    if start not in STARTS:
      raise ValueError(f'Unknown start {start!r}: expected one of '
                       f'{", ".join(map(repr, STARTS))}')
    self.start = start
    self.phi = np.exp(-self.alpha * self.dt)
    self._innovation_std = self.sigma * np.sqrt(1.0 - self.phi**2)
    self._value = None
    self._random_state = None

  @classmethod
  def reference(cls, size: int, action_space: str = 'cartesian',
                **kwargs: Any) -> 'OrnsteinUhlenbeckNoise':
    """The process with the reference's parameters for an action space.

    Args:
      size: number of action dimensions.
      action_space: 'cartesian' or 'joint' (REFERENCE_PARAMETERS).
      **kwargs: parameters of the constructor that override them.

    Returns:
      The process.

    Raises:
      ValueError: an unknown action space.
    """
    if action_space not in REFERENCE_PARAMETERS:
      raise ValueError(f'Unknown action_space {action_space!r}: expected one '
                       f'of {", ".join(map(repr, REFERENCE_PARAMETERS))}')
    return cls(size, **{**REFERENCE_PARAMETERS[action_space], **kwargs})

  @property
  def parameters(self) -> dict[str, Any]:
    """JSON-able parameters (per-dimension values as lists)."""
    return {'size': self.size, 'alpha': self.alpha.tolist(),
            'sigma': self.sigma.tolist(), 'dt': self.dt,
            'mu': self.mu.tolist(), 'weight': self.weight,
            'start': self.start}

  @property
  def stationary_std(self) -> np.ndarray:
    """The stationary standard deviation per dimension (sigma)."""
    return self.sigma.copy()

  def autocorrelation(self, lag: Union[int, np.ndarray]) -> np.ndarray:
    """Theoretical autocorrelation at `lag` samples: phi^lag.

    Args:
      lag: samples apart (an int or an array of them).

    Returns:
      phi^lag per dimension (broadcast with the lags).
    """
    return self.phi**lag

  def reset(self, seed: Union[int, np.random.RandomState]) -> None:
    """Starts a new sequence.

    Args:
      seed: an int or a RandomState (`random_state_from`).
    """
    self._random_state = random_state_from(seed)
    if self.start == 'stationary':
      self._value = self.mu + self.sigma * self._random_state.standard_normal(
          self.size)
    else:
      self._value = self.mu.copy()

  def sample(self) -> np.ndarray:
    """The current value X_k (shape (size,)); advances to X_{k+1}.

    Raises:
      RuntimeError: before `reset`.
    """
    if self._value is None:
      raise RuntimeError('OrnsteinUhlenbeckNoise.sample before reset(seed)')
    value = self._value
    eps = self._random_state.standard_normal(self.size)
    self._value = self.mu + self.phi * (value - self.mu) + (
        self._innovation_std * eps)
    return value.copy()

  def mix(self, expert_action: np.ndarray, noise: np.ndarray) -> np.ndarray:
    """The executed action (unclipped).

    Args:
      expert_action: a_e.
      noise: X, a `sample`.

    Returns:
      (1 - w) expert_action + w noise.
    """
    return (1.0 - self.weight) * expert_action + self.weight * noise


class NoisyExpert:
  """An expert whose actions are mixed with Ornstein-Uhlenbeck noise.

  Called like the expert, `action = noisy(timestep)`. At every first
  timestep the noise restarts from `episode_random_state(seed, k)`, k the
  number of episodes this object has started (0, 1, ...; `set_episode`
  sets it, e.g. to resume a dataset), so episode k is the same whatever
  ran before it. The executed action (1 - w) a_e + w X is clipped to
  [-1, 1]; `last_expert_action` is a_e and `last_noise` X of the last call.

  Args:
    expert: the expert.
    noise: the noise process, of the action's size.
    seed: the noise's seed, an integer >= 0.

  Raises:
    ValueError: a noise of another size than the action, or a bad seed.
  """

  def __init__(self, expert: base.Expert, noise: OrnsteinUhlenbeckNoise,
               seed: int = 0):
    shape = tuple(expert.env.action_spec().shape)
    if shape != (noise.size,):
      raise ValueError(f'The noise has {noise.size} dimensions but the '
                       f'action has shape {shape}')
    self.expert = expert
    self.noise = noise
    episode_random_state(seed, 0)   # Validates the seed.
    self.seed = int(seed)
    self.episode = 0
    self._started = False
    self.last_expert_action: Optional[np.ndarray] = None
    self.last_noise: Optional[np.ndarray] = None

  @property
  def env(self) -> composer.Environment:
    """The expert's environment."""
    return self.expert.env

  @property
  def task(self) -> composer.Task:
    """The expert's task."""
    return self.expert.task

  def set_episode(self, episode: int) -> None:
    """The next first timestep starts episode `episode`.

    Args:
      episode: the episode's index, an integer >= 0.

    Raises:
      ValueError: otherwise.
    """
    episode_random_state(self.seed, episode)   # Validates.
    self.episode = int(episode)
    self._started = False

  def __call__(self, timestep: dm_env.TimeStep) -> np.ndarray:
    """The noisy action at a timestep; the noise restarts at a first one.

    Args:
      timestep: the environment's current timestep.

    Returns:
      (1 - w) a_e + w X, clipped to [-1, 1].

    Raises:
      RuntimeError: a call mid-episode before any first timestep.
    """
    if timestep.first():
      if self._started:
        self.episode += 1
      self._started = True
      self.noise.reset(episode_random_state(self.seed, self.episode))
    elif not self._started:
      raise RuntimeError('NoisyExpert called mid-episode before any first '
                         'timestep: the noise has no seed yet')
    expert_action = self.expert(timestep)
    noise = self.noise.sample()
    self.last_expert_action = expert_action
    self.last_noise = noise
    return np.clip(self.noise.mix(expert_action, noise), -1.0, 1.0)
