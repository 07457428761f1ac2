"""Tests of SAC-Lagrangian (agents/sac_lag/): the multiplier, the config,
the learner, and the agent on a toy task where the constraint binds."""

import jax
import numpy as np
import pytest

from agents import agent as agent_lib
from agents import agent_checkpoint
from agents import builders
from agents import config as config_lib
from agents import replay as replay_lib
from agents import specs
from agents.sac import learning as sac_learning
from agents.sac import networks as networks_lib
from agents.sac_lag import config as lag_config_lib
from agents.sac_lag import learning as lag_learning
from agents.sac_lag import multiplier as multiplier_lib

from toy_tasks import HazardousActions


def _config(**overrides):
  values = dict(hidden_sizes=(32, 32), batch_size=64, min_replay_size=200,
                cost_limit=2.0, multiplier_learning_rate=0.02)
  values.update(overrides)
  return lag_config_lib.SACLagrangianConfig(**values)


def _agent(env, seed=0, **overrides):
  builder = builders.make_builder('sac_lag', _config(**overrides).to_dict())
  return agent_lib.Agent(specs.make_environment_spec(env), builder, seed=seed)


def _train(env, agent, episodes):
  """Trains `episodes` episodes; [(episode cost, multiplier after it)]."""
  history = []
  for _ in range(episodes):
    timestep = env.reset()
    agent.observe_first(timestep)
    cost = 0.0
    while not timestep.last():
      action = agent.select_action(timestep.observation)
      agent.update()
      timestep = env.step(action)
      agent.observe(action, timestep)
      cost += float(timestep.observation['cost'][0])
    history.append((cost, agent.learner.multiplier))
  return history


@pytest.mark.parametrize('rule', ['gradient', 'pid'])
def test_multiplier_rises_above_the_limit_and_falls_below_it(rule):
  config = _config(multiplier_update=rule, initial_multiplier=0.5,
                   pid_gains=(0.05, 0.02, 0.01))
  multiplier = multiplier_lib.LagrangeMultiplier(config)
  values = [multiplier.value]
  for cost in [6.0] * 10 + [0.0] * 40:
    values.append(multiplier.update(cost))
  steps = np.diff(values)
  assert np.all(steps[:10] >= 0) and values[10] > values[0]
  if rule == 'gradient':
    assert np.all(steps[10:] <= 0)
    np.testing.assert_allclose(values[10], 0.5 + 10 * 0.02 * 4.0)
  else:   # The derivative term is gone once the cost stops rising.
    assert np.all(steps[11:] <= 0)
  assert values[-1] < values[10]
  assert min(values) >= 0.0   # Projected onto [0, max].
  assert values[-1] == 0.0


def test_multiplier_is_bounded_and_round_trips():
  config = _config(max_multiplier=1.5, multiplier_update='pid')
  multiplier = multiplier_lib.LagrangeMultiplier(config)
  for _ in range(100):
    multiplier.update(50.0)
  assert multiplier.value == 1.5
  copy = multiplier_lib.LagrangeMultiplier(config)
  copy.restore(multiplier.state())
  assert copy.update(0.0) == multiplier.update(0.0)
  with pytest.raises(ValueError, match='episode cost'):
    multiplier.update(float('nan'))


@pytest.mark.parametrize('field,value', [
    ('cost_limit', -1.0), ('cost_critic_aggregate', 'min'),
    ('multiplier_update', 'adam'), ('initial_multiplier', 200.0),
    ('pid_gains', (0.1, -0.1, 0.0)), ('cost_penalty', 1.0)])
def test_bad_config_values_name_the_field(field, value):
  with pytest.raises(ValueError, match=f'SACLagrangianConfig.{field}='):
    _config(**{field: value})


def test_config_round_trips_and_keeps_sac_fields():
  config = _config(pid_gains=[0.2, 0.1, 0.0])
  assert lag_config_lib.SACLagrangianConfig.from_dict(
      config.to_dict()) == config
  sac = config_lib.quick_config()
  derived = lag_config_lib.from_sac_config(sac, cost_limit=3.0)
  assert derived.reward_scale == sac.reward_scale and derived.cost_limit == 3


def test_agent_without_a_cost_observation_is_refused():
  class NoCost(HazardousActions):

    def observation_spec(self):
      spec = super().observation_spec()
      del spec['cost']
      return spec

  with pytest.raises(ValueError, match="'observations': 'safe_rl'"):
    _agent(NoCost(0))


def test_constrained_agent_learns_to_keep_the_cost_under_the_limit():
  """The multiplier rises while episodes cost more than the limit, the
  policy learns to avoid the costly actions, and the multiplier then
  falls: the dual ascent closes the loop through the learner."""
  env = HazardousActions(0)
  agent = _agent(env, seed=1)
  history = _train(env, agent, 120)
  costs = np.array([cost for cost, _ in history])
  multipliers = np.array([value for _, value in history])
  previous = np.concatenate([[0.0], multipliers[:-1]])
  # Every episode moved the multiplier towards the limit's side (or held
  # it at 0).
  above, below = costs > 2.0, costs < 2.0
  assert np.all(multipliers[above] > previous[above])
  assert np.all((multipliers[below] < previous[below])
                | (multipliers[below] == 0.0))
  assert np.all(multipliers[~above & ~below] == previous[~above & ~below])
  assert costs[:10].mean() > 5.0               # Indifferent at first.
  assert costs[-20:].mean() < 2.0              # Under the limit at the end.
  peak = int(np.argmax(multipliers))
  assert multipliers[-1] < multipliers[peak]   # And the multiplier fell.


def test_checkpoint_restores_the_multiplier_and_cost_critics(tmp_path):
  env = HazardousActions(2)
  agent = _agent(env, seed=3, min_replay_size=50)
  _train(env, agent, 6)
  timestep = env.reset()
  agent.observe_first(timestep)
  for _ in range(7):   # Inside an episode: its cost so far is kept.
    action = agent.select_action(timestep.observation)
    timestep = env.step(action)
    agent.observe(action, timestep)
  agent_checkpoint.save(agent, tmp_path / 'agent')
  restored = _agent(env, seed=9, min_replay_size=50)
  agent_checkpoint.restore(restored, tmp_path / 'agent')
  assert restored.learner.multiplier == agent.learner.multiplier > 0
  assert restored.adder.episode_cost == agent.adder.episode_cost
  for name, value in agent.learner.state().items():
    np.testing.assert_array_equal(restored.learner.state()[name], value,
                                  err_msg=name)
  # A SAC agent cannot read it.
  sac = agent_lib.Agent(specs.make_environment_spec(env),
                        builders.make_builder('sac', {}), seed=0)
  with pytest.raises(ValueError, match="agent='sac_lag'"):
    agent_checkpoint.restore(sac, tmp_path / 'agent')


def _batches(steps, size=32, seed=0):
  random_state = np.random.RandomState(seed)
  observation = random_state.randn(steps, size, 3).astype(np.float32)
  return replay_lib.Transition(
      observation=observation,
      action=random_state.uniform(-1, 1, (steps, size, 2)).astype(
          np.float32),
      reward=observation[..., 0].copy(),
      discount=np.ones((steps, size), np.float32),
      next_observation=random_state.randn(steps, size, 3).astype(
          np.float32),
      cost=(observation[..., 1] > 0).astype(np.float32))


def test_with_lambda_zero_the_policy_and_critics_learn_as_sacs():
  """lambda = 0 leaves SAC's losses: the policy, critics and temperature
  follow SAC's from the same seed; the cost critics learn the cost."""
  sac_config = config_lib.default_config(hidden_sizes=(16, 16))
  lag_config = lag_config_lib.from_sac_config(sac_config, cost_limit=1e6)
  nets = networks_lib.make_networks(3, 2, (16, 16))
  sac = sac_learning.SACLearner(nets, sac_config, 3, 2, seed=4)
  lagrangian = lag_learning.SACLagrangianLearner(nets, lag_config, 3, 2,
                                                 seed=4)
  batches = _batches(40)
  sac.update_steps(batches)
  metrics = lagrangian.update_steps(batches)
  assert lagrangian.multiplier == 0.0 and metrics['multiplier'] == 0.0
  for name in ('policy_params', 'q_params', 'target_q_params',
               'log_temperature'):
    for ours, theirs in zip(
        jax.tree_util.tree_leaves(getattr(lagrangian.training_state, name)),
        jax.tree_util.tree_leaves(getattr(sac.training_state, name))):
      np.testing.assert_allclose(np.asarray(ours), np.asarray(theirs),
                                 rtol=1e-6, atol=1e-7, err_msg=name)
  # Without bootstrapping the cost critics regress the cost itself.
  batches = batches._replace(discount=np.zeros_like(batches.discount))
  first = float(lagrangian.update_steps(batches)['cost_critic_loss'])
  for _ in range(40):
    metrics = lagrangian.update_steps(batches)
  assert float(metrics['cost_critic_loss']) < 0.5 * first


def test_lambda_moves_the_policy_away_from_costly_actions():
  """With a cost on positive first action components and lambda > 0, the
  policy's mean first component falls below SAC's."""
  config = lag_config_lib.SACLagrangianConfig(
      hidden_sizes=(16, 16), initial_multiplier=5.0, cost_limit=0.0)
  nets = networks_lib.make_networks(3, 2, (16, 16))
  sac = sac_learning.SACLearner(
      nets, config_lib.default_config(hidden_sizes=(16, 16)), 3, 2, seed=1)
  lagrangian = lag_learning.SACLagrangianLearner(nets, config, 3, 2, seed=1)
  batches = _batches(40, seed=3)
  batches = batches._replace(
      cost=(batches.action[..., 0] > 0).astype(np.float32),
      reward=np.zeros_like(batches.reward))
  for _ in range(40):
    sac.update_steps(batches)
    lagrangian.update_steps(batches)
  observations = batches.observation.reshape(-1, 3)

  def mean_first_action(learner):
    mean, _ = nets.policy_apply(learner.policy_params, observations)
    return float(np.mean(np.tanh(np.asarray(mean))[:, 0]))

  assert mean_first_action(lagrangian) < mean_first_action(sac) - 0.2
