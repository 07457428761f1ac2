"""Imitation wrappers: the similarity formulas on hand-computed cases, RSI
restores dataset states, SIR and AIR rewards on real episodes."""

import numpy as np
import pytest

from agents import imitation
from hrc_suite import experts
from hrc_suite import suite
from hrc_suite.experts import dataset as dataset_lib

TASK_KWARGS = {'robot': 'panda', 'action_space': 'cartesian',
               'time_limit': 0.6}


def test_similarity_hand_computed():
  assert imitation.similarity(0.0, 0.1) == 1.0
  assert imitation.similarity(0.1, 0.1) == pytest.approx(0.5)
  assert imitation.similarity(0.2, 0.1) == pytest.approx(2.0 ** -4)
  with pytest.raises(ValueError, match='scale'):
    imitation.similarity(0.1, 0.0)


def test_imitation_reward_hand_computed():
  arm_only = imitation.ImitationReward(weight=0.25, scale=0.1)
  # |(0.06, 0.08)| = 0.1: similarity 1/2.
  assert arm_only.similarity([0.06, 0.08], [0.0, 0.0]) == pytest.approx(0.5)
  assert arm_only.reward(-1.0, [0.06, 0.08], [0, 0]) == pytest.approx(
      0.75 * -1.0 + 0.25 * 0.5)
  with_gripper = imitation.ImitationReward(
      weight=0.25, scale=0.1, gripper_scale=0.5, position_weight=0.7,
      gripper_size=1)
  # Position part 0.1 away (1/2), gripper 0.5 away (1/2), then 1.0 (1/16).
  assert with_gripper.similarity([0.1, 0, 0, 1.0], [0, 0, 0, 0.5]) == (
      pytest.approx(0.5))
  assert with_gripper.similarity([0.1, 0, 0, 1.0], [0, 0, 0, 0.0]) == (
      pytest.approx(0.7 * 0.5 + 0.3 / 16))
  assert with_gripper.reward(2.0, [0, 0, 0, 1], [0, 0, 0, 1]) == (
      pytest.approx(0.75 * 2.0 + 0.25))
  with pytest.raises(ValueError, match='weight'):
    imitation.ImitationReward(weight=1.5)
  with pytest.raises(ValueError, match='shapes'):
    arm_only.similarity([0.0], [0.0, 1.0])


@pytest.fixture(scope='module')
def reach_dataset(tmp_path_factory):
  directory = tmp_path_factory.mktemp('reach_dataset')
  return dataset_lib.collect(directory, 'reach', 'dense', TASK_KWARGS,
                             policy='noisy_expert', episodes=2, seed=3)


def _env(seed=11):
  return suite.load('reach', 'dense', task_kwargs=dict(TASK_KWARGS),
                    environment_kwargs={'random_state': seed})


def test_rsi_restores_dataset_states(reach_dataset):
  env = imitation.ReferenceStateInitialization(_env(), reach_dataset,
                                               probability=1.0, seed=5)
  starts = set()
  for _ in range(4):
    timestep = env.reset()
    assert timestep.first()
    episode, step = env.reference
    starts.add((episode, step))
    recorded = reach_dataset.snapshot(episode, step)
    now = env.task.get_state(env.physics)
    np.testing.assert_array_equal(now['physics'], recorded['physics'])
    # The first observation is the recorded one (no observation noise).
    observed = reach_dataset.episodes[episode].observations
    for name, value in timestep.observation.items():
      np.testing.assert_array_equal(value, observed[name][step])
    # Replaying the recorded action reproduces the recorded next step.
    action = reach_dataset.episodes[episode].actions[step]
    timestep = env.step(action)
    assert timestep.reward == pytest.approx(
        reach_dataset.episodes[episode].rewards[step], abs=0)
  assert len(starts) > 1
  fresh = imitation.ReferenceStateInitialization(_env(), reach_dataset,
                                                 probability=0.0)
  fresh.reset()
  assert fresh.reference is None


def test_rsi_rejects_a_dataset_of_another_setup(reach_dataset):
  other = suite.load('reach', 'dense', task_kwargs={'robot': 'schunk'})
  with pytest.raises(ValueError, match='robot'):
    imitation.ReferenceStateInitialization(other, reach_dataset)
  task = suite.load('pick_place', 'default', task_kwargs={'robot': 'panda'})
  with pytest.raises(ValueError, match='reach/dense'):
    imitation.ReferenceStateInitialization(task, reach_dataset)


def test_sir_reward_follows_the_reference(reach_dataset):
  env = imitation.StateImitationReward(_env(), reach_dataset, seed=2)
  env.reset()
  episode, step = env.reference
  recorded = reach_dataset.episodes[episode]
  # Following the recorded action keeps the state on the reference:
  # similarity 1, reward (1 - 0.25) r_env + 0.25.
  timestep = env.step(recorded.actions[step])
  assert timestep.reward == pytest.approx(
      0.75 * recorded.rewards[step] + 0.25, abs=1e-12)
  # Another action leaves it; the reward is the formula's.
  timestep = env.step(-np.ones(env.action_spec().shape))
  reference = recorded.expert_observations['eef_position'][
      min(step + 2, recorded.num_steps)]
  similarity = imitation.ImitationReward(scale=0.1).similarity(
      env.state(), reference)
  assert similarity < 1.0
  env_reward = (timestep.reward - 0.25 * similarity) / 0.75
  assert env_reward == pytest.approx(env.task.step_metrics['reward'])


def test_air_queries_the_expert_without_replanning():
  # Advice on a state must not depend on how often the agent's actions were
  # replaced (hrc_suite/experts/replan.py): the task's own expert re-plans.
  env = imitation.ActionImitationReward(_env(seed=4))
  assert experts.make(_env(seed=4)).replanner is not None
  assert env.expert.replanner is None


def test_air_rewards_agreeing_with_the_expert():
  env = imitation.ActionImitationReward(_env(seed=4))
  shadow = _env(seed=4)
  expert = experts.make(shadow)
  timestep, shadow_timestep = env.reset(), shadow.reset()
  for k in range(3):
    action = expert(shadow_timestep)
    timestep = env.step(action)
    shadow_timestep = shadow.step(action)
    np.testing.assert_array_equal(env.last_expert_action, action)
    assert timestep.reward == pytest.approx(
        0.75 * shadow_timestep.reward + 0.25, abs=1e-12), k
  # The opposite action: similarity of a distance |2 a~ - ...| < 1.
  expert_action = expert(shadow_timestep)
  timestep = env.step(-expert_action)
  shadow_timestep = shadow.step(-expert_action)
  similarity = imitation.ImitationReward(scale=0.1).similarity(
      -expert_action, expert_action)
  assert timestep.reward == pytest.approx(
      0.75 * shadow_timestep.reward + 0.25 * similarity, abs=1e-12)


def test_rsi_air_starts_from_dataset_states_with_the_air_reward(
    reach_dataset):
  env = imitation.wrap(_env(), 'rsi+air', dataset=reach_dataset, seed=5,
                       probability=1.0, scale=0.5, weight=0.5)
  assert isinstance(env, imitation.ActionImitationReward)
  timestep = env.reset()
  episode, step = env.reference   # RSI's, through the AIR wrapper.
  np.testing.assert_array_equal(
      env.task.get_state(env.physics)['physics'],
      reach_dataset.snapshot(episode, step)['physics'])
  # The expert is asked on the restored state: its action scores 1.
  shadow = _env()
  shadow.reset()
  shadow.task.set_state(shadow.physics, reach_dataset.snapshot(episode, step))
  expert_action = experts.make(shadow)(timestep)
  timestep = env.step(expert_action)
  np.testing.assert_array_equal(env.last_expert_action, expert_action)
  assert timestep.reward == pytest.approx(
      0.5 * env.task.step_metrics['reward'] + 0.5, abs=1e-12)
  # AIR's kwargs stay AIR's; a misspelt one is not swallowed.
  with pytest.raises(TypeError, match='probabilty'):
    imitation.wrap(_env(), 'rsi+air', dataset=reach_dataset,
                   probabilty=0.5)


def test_wrap_names_and_needs():
  env = _env()
  assert imitation.wrap(env, 'sac') is env
  with pytest.raises(ValueError, match='sac, rsi, sir, air, rsi\\+air'):
    imitation.wrap(env, 'bc')
  for agent in ('rsi', 'sir', 'rsi+air'):
    with pytest.raises(ValueError, match='dataset'):
      imitation.wrap(env, agent)
