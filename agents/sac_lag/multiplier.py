"""The Lagrange multiplier of a per-episode cost limit, updated per episode.

The constrained problem max_pi J_r(pi) s.t. J_c(pi) <= d has the
Lagrangian L(pi, lambda) = J_r(pi) - lambda (J_c(pi) - d), lambda >= 0; the
policy ascends it in pi, the multiplier descends it in lambda, i.e. rises
while the measured cost J_c exceeds the limit d and falls while it is below.
After each finished training episode with cost J_c (e = J_c - d):

* 'gradient': lambda <- clip(lambda + eta e, 0, lambda_max);
* 'pid' (Stooke, Achiam and Abbeel 2020, "Responsive Safety in
  Reinforcement Learning by PID Lagrangian Methods", Algorithm 2):
  I <- max(0, I + e); D = max(0, J_c - J_c,previous);
  lambda <- clip(K_P e + K_I I + K_D D, 0, lambda_max). The integral alone
  is the gradient update with eta = K_I; the proportional and derivative
  terms damp its overshoot. I starts at lambda_0 / K_I (so lambda starts
  at lambda_0 where K_I > 0).

All in float64 NumPy on the host: a few operations per episode, exact and
part of the learner's checkpoint.
"""

from typing import Dict, Mapping

import numpy as np

from agents.sac_lag import config as config_lib


class LagrangeMultiplier:
  """lambda and its update rule's memory.

  Args:
    config: `agents.sac_lag.config.SACLagrangianConfig`.
  """

  def __init__(self, config: config_lib.SACLagrangianConfig):
    self._config = config
    self._value = float(config.initial_multiplier)
    ki = config.pid_gains[1]
    self._integral = self._value / ki if ki > 0 else 0.0
    self._previous_cost = None
    self._updates = 0

  @property
  def value(self) -> float:
    """The current lambda."""
    return self._value

  def update(self, episode_cost: float) -> float:
    """Updates lambda after a finished episode.

    Args:
      episode_cost: the episode's cost J_c.

    Returns:
      The new lambda.

    Raises:
      ValueError: a cost that is not finite.
    """
    cost = float(episode_cost)
    if not np.isfinite(cost):
      raise ValueError(f'episode cost {episode_cost!r}: expected a finite '
                       'number')
    config = self._config
    error = cost - config.cost_limit
    if config.multiplier_update == 'gradient':
      value = self._value + config.multiplier_learning_rate * error
    else:
      kp, ki, kd = config.pid_gains
      self._integral = max(0.0, self._integral + error)
      previous = cost if self._previous_cost is None else self._previous_cost
      value = (kp * error + ki * self._integral
               + kd * max(0.0, cost - previous))
    self._previous_cost = cost
    self._value = float(np.clip(value, 0.0, config.max_multiplier))
    self._updates += 1
    return self._value

  def state(self) -> Dict[str, np.ndarray]:
    """{name: array} for a checkpoint."""
    return {'value': np.float64(self._value),
            'integral': np.float64(self._integral),
            'previous_cost': np.float64(np.nan if self._previous_cost is None
                                        else self._previous_cost),
            'updates': np.int64(self._updates)}

  def restore(self, arrays: Mapping[str, np.ndarray]) -> None:
    """Restores a `state()`.

    Args:
      arrays: of `state()`.

    Raises:
      ValueError: entries missing.
    """
    missing = sorted({'value', 'integral', 'previous_cost', 'updates'}
                     - set(arrays))
    if missing:
      raise ValueError(f'Multiplier state lacks {missing}')
    self._value = float(arrays['value'])
    self._integral = float(arrays['integral'])
    previous = float(arrays['previous_cost'])
    self._previous_cost = None if np.isnan(previous) else previous
    self._updates = int(arrays['updates'])
