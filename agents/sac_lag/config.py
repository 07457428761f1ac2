"""SAC-Lagrangian's hyperparameters: SAC's plus the constraint's.

The design choices published SAC-Lagrangian versions differ on, and the
ones made here, are in docs/safe_rl.md.
"""

import dataclasses
import math
from typing import Any, Dict, Optional, Tuple

from agents import config as config_lib

AGGREGATES = ('max', 'mean')
MULTIPLIER_UPDATES = ('gradient', 'pid')


@dataclasses.dataclass(frozen=True)
class SACLagrangianConfig(config_lib.SACConfig):
  """`agents.config.SACConfig`'s fields and the constraint's.

  Attributes:
    cost_limit: d >= 0, the per-episode cost the policy may incur (the sum
      of the steps' costs, agents/adders.py).
    cost_scale: factor on costs in the cost critics' target; None: the
      reward_scale, so that lambda prices a unit of cost in units of
      reward, as SAC's cost_penalty does (docs/safe_rl.md).
    cost_critic_aggregate: how the twin cost critics combine, in their
      target and in the policy loss: 'max' (pessimistic: the larger cost
      estimate) or 'mean'.
    multiplier_update: 'gradient' (projected gradient ascent on the dual:
      lambda += multiplier_learning_rate (J_c - d)) or 'pid' (Stooke et al.
      2020's PID Lagrangian with gains pid_gains), after each finished
      training episode with its cost J_c.
    initial_multiplier: lambda at the start (>= 0).
    multiplier_learning_rate: step size of the 'gradient' update.
    max_multiplier: lambda stays in [0, max_multiplier].
    pid_gains: (K_P, K_I, K_D) of the 'pid' update, each >= 0.
    normalise_actor_loss: divide the policy loss by 1 + lambda, so its
      scale stays that of one critic as lambda grows.
  """
  cost_limit: float = 1.0
  cost_scale: Optional[float] = None
  cost_critic_aggregate: str = 'max'
  multiplier_update: str = 'gradient'
  initial_multiplier: float = 0.0
  multiplier_learning_rate: float = 0.01
  max_multiplier: float = 100.0
  pid_gains: Tuple[float, float, float] = (0.1, 0.01, 0.01)
  normalise_actor_loss: bool = True

  def __post_init__(self):
    super().__post_init__()
    object.__setattr__(self, 'pid_gains', tuple(self.pid_gains))

    def check(condition, name, expected):
      config_lib._check(condition, name, getattr(self, name), expected,   # pylint: disable=protected-access
                        config_name='SACLagrangianConfig')

    def finite(value):
      return isinstance(value, (int, float)) and math.isfinite(value)

    check(self.cost_penalty == 0, 'cost_penalty',
          '0 (SAC-Lagrangian constrains the cost instead of penalising it)')
    check(finite(self.cost_limit) and self.cost_limit >= 0, 'cost_limit',
          'a finite number >= 0')
    check(self.cost_scale is None or (finite(self.cost_scale)
                                      and self.cost_scale > 0),
          'cost_scale', 'None or a finite number > 0')
    check(self.cost_critic_aggregate in AGGREGATES, 'cost_critic_aggregate',
          f'one of {AGGREGATES}')
    check(self.multiplier_update in MULTIPLIER_UPDATES, 'multiplier_update',
          f'one of {MULTIPLIER_UPDATES}')
    check(finite(self.max_multiplier) and self.max_multiplier > 0,
          'max_multiplier', 'a finite number > 0')
    check(finite(self.initial_multiplier)
          and 0 <= self.initial_multiplier <= self.max_multiplier,
          'initial_multiplier', 'in [0, max_multiplier]')
    check(finite(self.multiplier_learning_rate)
          and self.multiplier_learning_rate > 0, 'multiplier_learning_rate',
          'a finite number > 0')
    check(len(self.pid_gains) == 3 and all(
        finite(g) and g >= 0 for g in self.pid_gains), 'pid_gains',
          'three finite numbers >= 0 (K_P, K_I, K_D)')
    check(isinstance(self.normalise_actor_loss, bool), 'normalise_actor_loss',
          'True or False')

  def cost_factor(self) -> float:
    """The factor on costs in the cost critics' target."""
    return float(self.reward_scale if self.cost_scale is None
                 else self.cost_scale)

  def to_dict(self) -> Dict[str, Any]:
    """The fields as JSON values (pid_gains a list)."""
    values = super().to_dict()
    values['pid_gains'] = list(self.pid_gains)
    return values


def from_sac_config(sac_config: config_lib.SACConfig,
                    **overrides: Any) -> SACLagrangianConfig:
  """The SAC-Lagrangian config with a SAC config's fields and overrides.

  Args:
    sac_config: SAC's config (its cost_penalty must be 0).
    **overrides: fields of SACLagrangianConfig.

  Returns:
    The config.

  Raises:
    ValueError: a field's bad value.
  """
  values = dataclasses.asdict(sac_config)
  values.update(overrides)
  return SACLagrangianConfig(**values)
