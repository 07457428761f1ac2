"""Tests of agents/sac/networks.py."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import stats

from agents.sac import networks


def test_log_prob_matches_the_numerical_density_of_tanh_gaussian():
  mean, log_std = jnp.array([[0.3]]), jnp.array([[np.log(0.7)]])
  actions = np.linspace(-0.98, 0.98, 41)
  width = 1e-4
  # P(a <= A < a + h) from the Gaussian CDF of atanh(A), divided by h.
  cdf = lambda a: stats.norm.cdf(np.arctanh(a), loc=0.3, scale=0.7)
  numerical = (cdf(actions + width / 2) - cdf(actions - width / 2)) / width
  analytic = np.exp(np.asarray(networks.tanh_gaussian_log_prob(
      jnp.asarray(actions[:, None], jnp.float32), mean, log_std)))
  np.testing.assert_allclose(analytic, numerical, rtol=2e-3)


def test_density_integrates_to_one_and_factorises():
  mean = jnp.array([[-1.2, 0.4]])
  log_std = jnp.array([[np.log(0.5), np.log(1.5)]])
  grid = np.linspace(-1, 1, 20001)[1:-1]
  for axis in range(2):
    log_prob = networks.tanh_gaussian_log_prob(
        jnp.asarray(grid[:, None], jnp.float32), mean[:, axis:axis + 1],
        log_std[:, axis:axis + 1])
    assert abs(np.trapezoid(np.exp(np.asarray(log_prob)), grid) - 1) < 2e-3
  pairs = np.random.RandomState(0).uniform(-0.99, 0.99, (50, 2))
  joint = networks.tanh_gaussian_log_prob(jnp.asarray(pairs, jnp.float32),
                                          mean, log_std)
  marginals = sum(networks.tanh_gaussian_log_prob(
      jnp.asarray(pairs[:, i:i + 1], jnp.float32), mean[:, i:i + 1],
      log_std[:, i:i + 1]) for i in range(2))
  np.testing.assert_allclose(joint, marginals, rtol=1e-5, atol=1e-5)


def test_sampled_log_prob_is_the_log_prob_of_the_sample():
  mean = jnp.zeros((1000, 3)) + jnp.array([0.2, -0.5, 1.0])
  log_std = jnp.full((1000, 3), np.log(0.3))
  actions, log_prob = networks.sample_tanh_gaussian(jax.random.PRNGKey(0),
                                                    mean, log_std)
  assert np.all(np.abs(actions) < 1)
  np.testing.assert_allclose(
      log_prob, networks.tanh_gaussian_log_prob(actions, mean, log_std),
      rtol=1e-3, atol=1e-3)
  # The samples' pre-squash mean is the Gaussian's mean.
  np.testing.assert_allclose(np.mean(np.arctanh(np.asarray(actions)), 0),
                             [0.2, -0.5, 1.0], atol=0.03)


def test_squash_jacobian_is_stable_for_large_inputs():
  u = jnp.array([-50.0, -5.0, 0.0, 5.0, 50.0])
  jacobian = networks.squash_log_jacobian(u)
  assert np.all(np.isfinite(jacobian))
  np.testing.assert_allclose(jacobian[1:4],
                             np.log(1 - np.tanh([-5.0, 0.0, 5.0]) ** 2),
                             rtol=1e-4)
  np.testing.assert_allclose(jacobian[0], 2 * (np.log(2) - 50), rtol=1e-6)


def test_policy_and_critic_shapes_and_deterministic_action():
  nets = networks.make_networks(5, 2, (32, 32))
  policy_params = nets.policy_init(np.random.RandomState(0))
  q_params = nets.q_init(np.random.RandomState(1))
  observations = jnp.asarray(np.random.RandomState(2).randn(7, 5),
                             jnp.float32)
  mean, log_std = nets.policy_apply(policy_params, observations)
  assert mean.shape == (7, 2) and log_std.shape == (7, 2)
  np.testing.assert_array_equal(nets.deterministic_action(mean),
                                jnp.tanh(mean))
  q = nets.q_apply(q_params, observations, jnp.zeros((7, 2)))
  assert q.shape == (7, 2)
  assert not np.allclose(q[:, 0], q[:, 1])   # Two independent critics.
  # Huge inputs saturate the log standard deviation at its bounds.
  _, huge_log_std = nets.policy_apply(policy_params, 1e6 * observations)
  assert np.all(huge_log_std >= networks.LOG_STD_MIN)
  assert np.all(huge_log_std <= networks.LOG_STD_MAX)
  assert np.any(np.isin(np.asarray(huge_log_std),
                        [networks.LOG_STD_MIN, networks.LOG_STD_MAX]))


def test_init_follows_lecun_normal_and_the_seed():
  nets = networks.make_networks(400, 2, (300,))
  params = nets.policy_init(np.random.RandomState(0))
  kernel = np.asarray(params['params']['MLP_0']['Dense_0']['kernel'])
  assert kernel.shape == (400, 300)
  np.testing.assert_allclose(kernel.std(), np.sqrt(1 / 400), rtol=0.02)
  assert np.abs(kernel).max() <= 2 * np.sqrt(1 / 400) / 0.8796 + 1e-6
  assert not np.any(params['params']['MLP_0']['Dense_0']['bias'])
  again = nets.policy_init(np.random.RandomState(0))
  np.testing.assert_array_equal(
      again['params']['MLP_0']['Dense_0']['kernel'], kernel)
  with pytest.raises(TypeError, match='RandomState'):
    nets.policy_init(0)


def test_bad_sizes_are_rejected():
  with pytest.raises(ValueError, match='action_size=0'):
    networks.make_networks(3, 0)
  with pytest.raises(ValueError, match='hidden_sizes'):
    networks.make_networks(3, 1, ())
