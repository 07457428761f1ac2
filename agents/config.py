"""Soft actor-critic hyperparameters: a frozen dataclass and named presets.

Three presets:

* `default_config()`: the values of Haarnoja et al. 2018 ("Soft Actor-Critic
  Algorithms and Applications", Table 1: Adam lr 3e-4, two hidden layers of
  256 units, batch 256, tau 0.005, gamma 0.99, one gradient step per
  environment step) with an initial temperature of 1.0 (Acme's SAC default):
  a high temperature explores broadly at first and the automatic tuning
  brings it down within a few thousand updates. Its gradient steps run
  FUSED_STEPS at a time in one compiled call (`SACConfig.fused_steps`).
* `reference_config()`: the Human-Robot Gym paper's SAC (see
  docs/reference_benchmark.md, Training and evaluation): lr 5e-4,
  buffer 1e6, learning starts at 1000 transitions, batch 128, tau 0.005,
  gamma 0.99, 100 gradient steps every 100 environment steps, initial
  temperature 0.2, MLP (64, 64, 64).
* `quick_config()`: the default with small networks (64, 64), rewards
  scaled by 100, an initial temperature of 0.01 and discount 0.95, for
  dense rewards of a few hundredths per step over short episodes
  (reach/dense); the README's quickstart run.

Measured on reach/dense (Schunk, Cartesian, default horizon): overrides
reward_scale=100, initial_temperature=0.01, hidden_sizes=(64, 64) reach
90 % deterministic evaluation success (20 episodes) after 2 x 10^4 steps
with seeds 0 and 1; the default temperature with unscaled rewards showed no
progress within 6000 steps (the entropy bonus swamps -0.1 x distance).
With discount 0.95 instead of 0.99 (reach's episodes end at the goal,
about 15 steps once learnt) success at 2.5 x 10^4 steps was 0.90, 1.00,
1.00 over seeds 0-2, against 0.95, 0.45, 0.85 with 0.99
(docs/benchmarks.md, "Quickstart success by discount").

Seeds are not part of a config: agents take them separately.
"""

import dataclasses
import math
from typing import Any, Dict, Mapping, Optional, Tuple

# Gradient steps per compiled learner call by default: measured on the
# 2-core machine (docs/benchmarks.md, "SAC training throughput"), 8 fused
# steps cost the environment's core 0.13-0.15 ms per gradient step instead
# of 0.5-0.7 ms unfused, and 1.5-1.7 ms of CPU in all instead of 2.0-2.4;
# longer scans save little more and lengthen the actor's policy lag
# (agents/sac/agent.py).
FUSED_STEPS = 8


@dataclasses.dataclass(frozen=True)
class SACConfig:
  """Hyperparameters of `agents.sac.SACAgent` (defaults = `default_config`).

  Attributes:
    learning_rate: Adam step size of the policy, critics and temperature.
    batch_size: transitions per gradient step.
    replay_capacity: transitions the ring buffer holds.
    min_replay_size: transitions in the buffer before learning starts.
    discount: gamma, multiplied by the environment's per-step discount.
    tau: Polyak rate of the target critics (target += tau (online - target)).
    hidden_sizes: units of each hidden layer of the policy and both critics.
    initial_temperature: entropy temperature alpha at the start.
    target_entropy: entropy the temperature tuning aims at; None means
      -action_size (Haarnoja et al. 2018).
    updates_per_step: gradient steps per environment step, the
      update-to-data ratio (may be fractional: the agent accumulates it).
    fused_steps: gradient steps per learner call, fused into one compiled
      lax.scan (amortises dispatch); a call runs once fused_steps steps
      are due, i.e. every fused_steps / updates_per_step environment steps.
    max_grad_norm: clip each gradient to this global norm (None: no clipping).
    reward_scale: factor on rewards in the critic target (Acme's SACConfig
      field; Haarnoja et al. 2018a, Sec. 5.2: SAC is sensitive to the scale of
      rewards against the entropy bonus and to Adam's fixed step sizes on
      the critic, so tasks with small rewards, e.g. reach/dense's -0.1 x
      distance, learn faster with a scale of 10-100).
    cost_penalty: beta >= 0; the critic learns from r - beta x cost, the
      transition's safety cost (agents/adders.py) taken as a reward
      penalty (0: the cost is not read).
  """
  learning_rate: float = 3e-4
  batch_size: int = 256
  replay_capacity: int = 1_000_000
  min_replay_size: int = 1000
  discount: float = 0.99
  tau: float = 0.005
  hidden_sizes: Tuple[int, ...] = (256, 256)
  initial_temperature: float = 1.0
  target_entropy: Optional[float] = None
  updates_per_step: float = 1.0
  fused_steps: int = FUSED_STEPS
  max_grad_norm: Optional[float] = None
  reward_scale: float = 1.0
  cost_penalty: float = 0.0

  def __post_init__(self):
    # Lists (e.g. from JSON) become tuples so the config stays hashable.
    object.__setattr__(self, 'hidden_sizes', tuple(self.hidden_sizes))
    _check(self.learning_rate > 0, 'learning_rate', self.learning_rate, '> 0')
    for name in ('batch_size', 'replay_capacity', 'fused_steps'):
      value = getattr(self, name)
      _check(isinstance(value, int) and value >= 1, name, value,
             'an integer >= 1')
    _check(isinstance(self.min_replay_size, int) and self.min_replay_size >= 0,
           'min_replay_size', self.min_replay_size, 'an integer >= 0')
    _check(0 <= self.discount <= 1, 'discount', self.discount, 'in [0, 1]')
    _check(0 < self.tau <= 1, 'tau', self.tau, 'in (0, 1]')
    _check(len(self.hidden_sizes) >= 1 and all(
        isinstance(h, int) and h >= 1 for h in self.hidden_sizes),
           'hidden_sizes', self.hidden_sizes,
           'a non-empty tuple of integers >= 1')
    _check(self.initial_temperature > 0, 'initial_temperature',
           self.initial_temperature, '> 0')
    _check(self.target_entropy is None or math.isfinite(self.target_entropy),
           'target_entropy', self.target_entropy, 'None or a finite number')
    _check(self.updates_per_step >= 0, 'updates_per_step',
           self.updates_per_step, '>= 0')
    _check(self.max_grad_norm is None or self.max_grad_norm > 0,
           'max_grad_norm', self.max_grad_norm, 'None or > 0')
    _check(self.reward_scale > 0 and math.isfinite(self.reward_scale),
           'reward_scale', self.reward_scale, 'a finite number > 0')
    _check(self.cost_penalty >= 0 and math.isfinite(self.cost_penalty),
           'cost_penalty', self.cost_penalty, 'a finite number >= 0')

  def entropy_target(self, action_size: int) -> float:
    """The entropy the temperature tuning aims at.

    Args:
      action_size: the action's size.

    Returns:
      `target_entropy`, or -action_size when it is None.
    """
    if self.target_entropy is None:
      return -float(action_size)
    return float(self.target_entropy)

  def to_dict(self) -> Dict[str, Any]:
    """JSON-ready dict (`SACConfig.from_dict` rebuilds the config)."""
    values = dataclasses.asdict(self)
    values['hidden_sizes'] = list(self.hidden_sizes)
    return values

  @classmethod
  def from_dict(cls, values: Mapping[str, Any]) -> 'SACConfig':
    """The config of a `to_dict` dict.

    A dict with update_every instead of fused_steps (environment steps
    between bursts of updates_per_step * update_every gradient steps, run
    as one call) has it become fused_steps.

    Args:
      values: the fields.

    Returns:
      The config.

    Raises:
      ValueError: both update_every and fused_steps, a burst that is not
        an integer >= 1, or a field's bad value.
    """
    values = dict(values)
    if 'update_every' in values:
      if 'fused_steps' in values:
        raise ValueError(f'SAC config {values!r} has both update_every and '
                         'fused_steps: expected one of them')
      burst = values.pop('update_every') * values.get('updates_per_step', 1.0)
      if burst != int(burst) or burst < 1:
        raise ValueError(
            f'SAC config {values!r}: update_every times updates_per_step is '
            f'{burst!r} gradient steps per burst, expected an integer >= 1 '
            '(fused_steps)')
      values['fused_steps'] = int(burst)
    return cls(**values)


def _check(condition, name, value, expected, config_name='SACConfig'):
  if not condition:
    raise ValueError(f'{config_name}.{name}={value!r}: expected {expected}')


def default_config(**overrides: Any) -> SACConfig:
  """Sensible SAC defaults (Haarnoja et al. 2018, Table 1).

  Args:
    **overrides: SACConfig fields.

  Returns:
    The config.

  Raises:
    ValueError: a field's bad value.
  """
  return SACConfig(**overrides)


def reference_config(**overrides: Any) -> SACConfig:
  """The Human-Robot Gym paper's SAC hyperparameters.

  Args:
    **overrides: SACConfig fields.

  Returns:
    The config.

  Raises:
    ValueError: a field's bad value.
  """
  values = dict(
      learning_rate=5e-4,
      batch_size=128,
      replay_capacity=1_000_000,
      min_replay_size=1000,
      discount=0.99,
      tau=0.005,
      hidden_sizes=(64, 64, 64),
      initial_temperature=0.2,
      target_entropy=None,
      updates_per_step=1.0,
      fused_steps=100,
  )
  values.update(overrides)
  return SACConfig(**values)


def quick_config(**overrides: Any) -> SACConfig:
  """The default with (64, 64) networks, rewards x 100, temperature 0.01
  at first and discount 0.95: learns reach/dense (Schunk, Cartesian)
  within 2-2.5 x 10^4 steps (module docstring; docs/benchmarks.md,
  "Quickstart success by discount").

  Args:
    **overrides: SACConfig fields.

  Returns:
    The config.

  Raises:
    ValueError: a field's bad value.
  """
  values = dict(hidden_sizes=(64, 64), reward_scale=100.0,
                initial_temperature=0.01, discount=0.95)
  values.update(overrides)
  return SACConfig(**values)


CONFIGS = {'default': default_config, 'reference': reference_config,
           'quick': quick_config}


def config_from_name(name: str, **overrides: Any) -> SACConfig:
  """A preset with overrides.

  Args:
    name: a key of CONFIGS.
    **overrides: SACConfig fields.

  Returns:
    The config.

  Raises:
    ValueError: an unknown name or field, or a field's bad value.
  """
  if name not in CONFIGS:
    raise ValueError(f'Unknown SAC config {name!r}: expected one of '
                     f'{", ".join(CONFIGS)}')
  fields = {field.name for field in dataclasses.fields(SACConfig)}
  unknown = sorted(set(overrides) - fields)
  if unknown:
    raise ValueError(f'Unknown SACConfig fields {unknown}: expected some of '
                     f'{", ".join(sorted(fields))}')
  return CONFIGS[name](**overrides)
