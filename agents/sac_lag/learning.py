"""SAC-Lagrangian learner: SAC's update with cost critics and a multiplier.

Per gradient step on a batch (s, a, r, d, s', c), besides SAC's critic,
temperature and target updates (agents/sac/learning.py):

* cost critics (twin, with Polyak targets like the reward critics):
  y_c = k c + gamma d agg_j Q'_c,j(s', a'), a' ~ pi(.|s') (no entropy
  term: the entropy is the reward's bonus, not a cost), k the config's
  cost_factor() (by default the reward scale);
  loss = mean_j 0.5 (Q_c,j(s, a) - y_c)^2;
* policy: loss = [alpha log pi(a~|s) - min_j Q_j(s, a~)
  + lambda agg_j Q_c,j(s, a~)] / (1 + lambda) (the division where
  normalise_actor_loss), with the critics before this step's updates;

agg is max (pessimistic) or mean over the twins (cost_critic_aggregate).
lambda is an input of the step, held in the training state and set by the
multiplier's update after each finished episode (agents/sac_lag/
multiplier.py), never by a gradient step.
"""

import collections
from typing import Any, Dict, Mapping, Tuple

import jax
import jax.numpy as jnp
import numpy as np
import optax

from agents import replay
from agents.sac import learning as sac_learning
from agents.sac import networks as networks_lib
from agents.sac_lag import config as config_lib
from agents.sac_lag import multiplier as multiplier_lib

LagrangianTrainingState = collections.namedtuple(
    'LagrangianTrainingState', sac_learning.TrainingState._fields + (
        'cost_q_params', 'target_cost_q_params', 'cost_q_optimizer_state',
        'multiplier'))

# Folded into a step's key for the cost critics' next-action sample, a
# stream apart from SAC's three.
_COST_KEY_DATA = 1
_MULTIPLIER_PREFIX = 'multiplier_controller/'


class LagrangianUpdateFunctions(sac_learning.UpdateFunctions):
  """SAC's maths with cost critics and lambda in the policy loss.

  Args:
    networks: the policy and critics (the cost critics share q_apply).
    config: the hyperparameters.
    action_size: the action's size.
  """

  def __init__(self, networks: networks_lib.SACNetworks,
               config: config_lib.SACLagrangianConfig, action_size: int):
    super().__init__(networks, config, action_size)
    self.cost_q_optimizer = sac_learning._optimizer(config)   # pylint: disable=protected-access

  def initial_state(self, policy_params: Any, q_params: Any,
                    cost_q_params: Any, key: jax.Array
                    ) -> LagrangianTrainingState:
    """The training state before the first step.

    Args:
      policy_params: the policy's initial parameters.
      q_params: the reward critics' initial parameters.
      cost_q_params: the cost critics' initial parameters.
      key: the updates' JAX random key.

    Returns:
      SAC's initial state with the cost critics, their targets and
      optimizer, and lambda = initial_multiplier.
    """
    sac_state = super().initial_state(policy_params, q_params, key)
    return LagrangianTrainingState(
        *sac_state,
        cost_q_params=cost_q_params,
        target_cost_q_params=jax.tree_util.tree_map(jnp.copy, cost_q_params),
        cost_q_optimizer_state=self.cost_q_optimizer.init(cost_q_params),
        multiplier=jnp.asarray(self.config.initial_multiplier, jnp.float32))

  def aggregate(self, cost_q: jax.Array) -> jax.Array:
    """The twin cost critics combined (cost_critic_aggregate).

    Args:
      cost_q: (..., 2) the two cost critics' values.

    Returns:
      (...,) their max or mean.
    """
    if self.config.cost_critic_aggregate == 'max':
      return jnp.max(cost_q, axis=-1)
    return jnp.mean(cost_q, axis=-1)

  def cost_critic_loss(self, cost_q_params: Any,
                       state: LagrangianTrainingState,
                       batch: replay.Transition, key: jax.Array
                       ) -> Tuple[jax.Array, jax.Array]:
    """The cost critics' loss (module doc).

    Args:
      cost_q_params: the cost critics' parameters (differentiated).
      state: the training state (policy and target cost critics).
      batch: the transitions.
      key: for the next actions' samples.

    Returns:
      (loss, cost critic values (batch, 2)).
    """
    networks = self.networks
    next_mean, next_log_std = networks.policy_apply(
        state.policy_params, batch.next_observation)
    next_action, _ = networks.sample(key, next_mean, next_log_std)
    next_cost = self.aggregate(networks.q_apply(
        state.target_cost_q_params, batch.next_observation, next_action))
    target = jax.lax.stop_gradient(
        self.config.cost_factor() * batch.cost
        + self.config.discount * batch.discount * next_cost)
    cost_q = networks.q_apply(cost_q_params, batch.observation, batch.action)
    loss = 0.5 * jnp.mean(jnp.square(cost_q - target[:, None]))
    return loss, cost_q

  def actor_loss(self, policy_params: Any, state: LagrangianTrainingState,
                 batch: replay.Transition, temperature: jax.Array,
                 key: jax.Array) -> Tuple[jax.Array, jax.Array]:
    """The policy's loss with lambda's cost term (module doc).

    Args:
      policy_params: the policy's parameters (differentiated).
      state: the training state (critics, lambda).
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
    cost_q = self.aggregate(networks.q_apply(state.cost_q_params,
                                             batch.observation, action))
    multiplier = jax.lax.stop_gradient(state.multiplier)
    loss = jnp.mean(temperature * log_prob - jnp.min(q, axis=-1)
                    + multiplier * cost_q)
    if self.config.normalise_actor_loss:
      loss = loss / (1.0 + multiplier)
    return loss, log_prob

  def sgd_step(self, state: LagrangianTrainingState,
               batch: replay.Transition
               ) -> Tuple[LagrangianTrainingState, Dict[str, jax.Array]]:
    """One gradient step.

    Args:
      state: the training state.
      batch: the transitions, (batch, ...) per field.

    Returns:
      (the next state, {metric name: device scalar}).
    """
    cost_key = jax.random.fold_in(state.key, _COST_KEY_DATA)
    (cost_loss, cost_q), cost_grads = jax.value_and_grad(
        self.cost_critic_loss, has_aux=True)(state.cost_q_params, state,
                                             batch, cost_key)
    sac_state, metrics = super().sgd_step(state, batch)
    updates, cost_q_optimizer_state = self.cost_q_optimizer.update(
        cost_grads, state.cost_q_optimizer_state, state.cost_q_params)
    cost_q_params = optax.apply_updates(state.cost_q_params, updates)
    target_cost_q_params = sac_learning.polyak_average(
        state.target_cost_q_params, cost_q_params, self.config.tau)
    new_state = LagrangianTrainingState(
        *sac_state,
        cost_q_params=cost_q_params,
        target_cost_q_params=target_cost_q_params,
        cost_q_optimizer_state=cost_q_optimizer_state,
        multiplier=state.multiplier)
    metrics = dict(metrics, cost_critic_loss=cost_loss,
                   cost_q_values=jnp.mean(cost_q),
                   multiplier=state.multiplier)
    return new_state, metrics


class SACLagrangianLearner(sac_learning.SACLearner):
  """SACLearner with cost critics and a Lagrange multiplier.

  `observe_episode_cost(cost)` updates the multiplier after a finished
  training episode (the agent's adder calls it).

  Args:
    networks: the policy and critics, of these sizes.
    config: the hyperparameters.
    observation_size: the flat observation's size.
    action_size: the action's size.
    seed: seeds the initial parameters and the updates' random key.

  Raises:
    ValueError: networks built for other sizes.
  """

  FUNCTIONS_CLASS = LagrangianUpdateFunctions

  def __init__(self, networks: networks_lib.SACNetworks,
               config: config_lib.SACLagrangianConfig, observation_size: int,
               action_size: int, seed: int):
    self._multiplier = multiplier_lib.LagrangeMultiplier(config)
    super().__init__(networks, config, observation_size, action_size, seed)

  def _initial_state(self, networks, random_state, key):
    policy_params = networks.policy_init(random_state)
    q_params = networks.q_init(random_state)
    cost_q_params = networks.q_init(random_state)
    return self._functions.initial_state(policy_params, q_params,
                                         cost_q_params, key)

  def observe_episode_cost(self, cost: float) -> None:
    """Updates lambda with a finished episode's cost.

    Args:
      cost: the episode's summed cost.

    Raises:
      ValueError: a cost that is not finite.
    """
    value = self._multiplier.update(cost)
    self._state = self._state._replace(
        multiplier=jnp.asarray(np.float32(value)))

  @property
  def multiplier(self) -> float:
    """The current lambda."""
    return self._multiplier.value

  def state(self) -> Dict[str, np.ndarray]:
    """{path: NumPy array} of the training state and the multiplier's."""
    arrays = super().state()
    for key, value in self._multiplier.state().items():
      arrays[_MULTIPLIER_PREFIX + key] = value
    return arrays

  def restore(self, arrays: Mapping[str, np.ndarray]) -> None:
    """Restores a `state()` exactly.

    Args:
      arrays: of `state()`.

    Raises:
      ValueError: arrays missing or of other shapes or dtypes.
    """
    controller = {key[len(_MULTIPLIER_PREFIX):]: value
                  for key, value in arrays.items()
                  if key.startswith(_MULTIPLIER_PREFIX)}
    super().restore({key: value for key, value in arrays.items()
                     if not key.startswith(_MULTIPLIER_PREFIX)})
    self._multiplier.restore(controller)
