"""The reach task: spec conformance, goals, rewards, success by an oracle."""

import dataclasses
import unittest

from dm_env import test_utils
import numpy as np
import pytest

from hrc_suite import layout
from hrc_suite import robot_description
from hrc_suite import suite
from hrc_suite.control import ik as ik_lib
from hrc_suite.tasks.runtime import actions
from hrc_suite.tasks.runtime import metrics
from hrc_suite.tasks import reach

import checks   # tests/tasks/checks.py

ROBOTS = ('panda', 'schunk')
SPACES = ('joint', 'cartesian')


def _env(robot='panda', space='joint', reward='dense', seed=0, **kwargs):
  kwargs.setdefault('time_limit', 2.0)
  return suite.load('reach', reward, task_kwargs={
      'robot': robot, 'action_space': space, **kwargs},
                    environment_kwargs={'random_state': seed})


class ReachSpecTest(test_utils.EnvironmentTestMixin, unittest.TestCase):
  """dm_env conformance (reset, steps, specs) of reach with every
  observation."""

  def make_object_under_test(self):
    return _env('schunk', 'cartesian', observations='full', time_limit=1.0)


class ReachJointSpecTest(test_utils.EnvironmentTestMixin, unittest.TestCase):

  def make_object_under_test(self):
    return _env('panda', 'joint', reward='sparse', time_limit=1.0)


@pytest.mark.parametrize('robot', ROBOTS)
@pytest.mark.parametrize('space', SPACES)
def test_reset_and_step(robot, space):
  env = _env(robot, space, observations='full')
  timestep = env.reset()
  dof = env.task.robot.dof
  expected = {'joint_positions': (dof,), 'goal_difference':
              (dof,) if space == 'joint' else (3,),
              'human_keypoints': (19, 3), 'human_in_eef_frame': (3, 3),
              'goal_joint_difference': (dof,), 'critical_contact': (1,)}
  for name, shape in expected.items():
    assert timestep.observation[name].shape == shape, name
  assert len(checks.run_random_episode(env, timestep)) == 20   # time_limit 2 s at 10 Hz.


def test_paper_observation_is_the_goal_difference():
  for space, size in (('joint', 7), ('cartesian', 3)):
    env = _env(space=space)
    observation = env.reset().observation
    assert list(observation) == ['goal_difference']
    task, physics = env.task, env.physics
    if space == 'joint':
      expected = task.goal_joint_positions - task.robot.joint_positions(
          physics)
    else:
      expected = task.goal_position - task.robot.tcp_pose(physics)[0]
    np.testing.assert_allclose(observation['goal_difference'], expected)
    assert observation['goal_difference'].shape == (size,)


def test_goal_observables_are_consistent():
  env = _env(space='cartesian', observations='full')
  observation = env.reset().observation
  world = observation['goal_position']
  in_eef = observation['goal_in_eef_frame']
  distance = observation['goal_distance'][0]
  assert np.linalg.norm(in_eef) == pytest.approx(distance)
  np.testing.assert_allclose(np.linalg.norm(world - observation[
      'eef_position']), distance)


@pytest.mark.parametrize('robot', ROBOTS)
@pytest.mark.parametrize('space', SPACES)
def test_goals_are_reachable_and_collision_free(robot, space):
  env = _env(robot, space, seed=3)
  task = env.task
  low, high = ik_lib.table_workspace_box(task.kinematics)
  for _ in range(4):
    env.reset()
    q_goal = task.goal_joint_positions
    assert not task.collision_checker.in_collision(q_goal)
    assert task.kinematics.within_limits(q_goal)
    np.testing.assert_allclose(task.kinematics.tcp_pose(q_goal)[:3, 3],
                               task.goal_position, atol=1e-3)
    if space == 'cartesian':
      local = task.goal_position - np.asarray(task.kinematics.base_pose[:3, 3])
      table = -layout.robot_mount(robot).height_above_table
      assert np.all(local >= np.maximum(
          low, [-9, -9, table + reach.GOAL_MIN_HEIGHT]) - 1e-3)
      assert np.all(local <= high + 1e-3)
    # The marker shows the goal.
    np.testing.assert_allclose(
        task._marker.mocap_position(env.physics), task.goal_position)


def _oracle(env):
  """Privileged policy: straight towards the goal at full speed."""
  task = env.task

  def policy(timestep):
    del timestep
    physics = env.physics
    if task.action_space_name == 'joint':
      delta = task.goal_joint_positions - task.robot.joint_positions(physics)
      return np.clip(delta / actions.JOINT_STEP, -1.0, 1.0)
    delta = task.goal_position - task.robot.tcp_pose(physics)[0]
    return np.clip(delta / actions.CARTESIAN_STEP, -1.0, 1.0)

  return policy


@pytest.mark.parametrize('robot', ROBOTS)
@pytest.mark.parametrize('space', SPACES)
def test_oracle_reaches_the_goal(robot, space):
  successes = 0
  for seed in range(3):
    env = _env(robot, space, reward='sparse', seed=seed, time_limit=10.0)
    result = metrics.run_episode(env, _oracle(env))
    if result['success']:
      successes += 1
      # Done at success: the last reward is the success reward.
      assert env.task.step_metrics['reward'] == 1.0
      assert result['steps'] < 100
    assert result['contacts_human_critical'] == 0
  assert successes >= 1


def test_success_thresholds():
  env = _env(space='cartesian', reward='sparse', done_at_success=False)
  env.reset()
  task, physics = env.task, env.physics
  # Put the goal exactly at the TCP, then just outside the threshold.
  tcp = task.robot.tcp_pose(physics)[0]
  task._goal_position = tcp.copy()
  timestep = env.step(np.zeros(3))
  assert timestep.reward == 1.0 and task.step_metrics['success'] == 1.0
  tcp = task.robot.tcp_pose(physics)[0]
  task._goal_position = tcp + [reach.SUCCESS_DISTANCE + 0.01, 0.0, 0.0]
  timestep = env.step(np.zeros(3))
  assert timestep.reward == -1.0 and task.step_metrics['success'] == 0.0


def test_dense_reward_is_minus_tenth_of_distance():
  env = _env(space='cartesian', reward='dense')
  env.reset()
  timestep = env.step(np.zeros(3))
  task = env.task
  distance = np.linalg.norm(task.goal_position -
                            task.robot.tcp_pose(env.physics)[0])
  assert timestep.reward == pytest.approx(-reach.DENSE_SCALE * distance)


def test_done_at_success_is_configurable():
  for done in (True, False):
    env = _env(space='cartesian', reward='sparse', done_at_success=done)
    env.reset()
    env.task._goal_position = env.task.robot.tcp_pose(env.physics)[0]
    timestep = env.step(np.zeros(3))
    assert timestep.last() == done
    if done:
      assert timestep.discount == 0.0


def test_reward_kind_conflicting_with_the_registered_task_raises():
  with pytest.raises(ValueError, match='conflicts'):
    suite.load('reach', 'dense', task_kwargs={'reward': 'sparse'})
  with pytest.raises(ValueError, match="Unknown reward 'shaped'"):
    reach.Reach(reward='shaped')


@pytest.mark.parametrize('robot', robot_description.ROBOT_NAMES)
def test_joint_goal_range_is_one_turn_at_most(robot):
  description = robot_description.load(robot)
  limits = description.limits
  low, high = layout.reach_joint_goal_range(description)
  wide = (limits.q_max - limits.q_min
          > layout.ONE_TURN + layout.ONE_TURN_TOLERANCE)
  # Joints of at most one turn keep their limits (the reference's rule).
  np.testing.assert_array_equal(low[~wide], limits.q_min[~wide])
  np.testing.assert_array_equal(high[~wide], limits.q_max[~wide])
  # Wider ones: one turn, inside the limits, centred on home here.
  np.testing.assert_allclose(high[wide] - low[wide], layout.ONE_TURN)
  np.testing.assert_allclose((low + high)[wide] / 2, description.q_home[wide])
  assert np.all(low >= limits.q_min) and np.all(high <= limits.q_max)
  assert wide.any() == (robot in ('sawyer', 'jaco', 'kinova3', 'ur5e'))


def test_joint_goal_range_shifts_inside_a_near_limit():
  description = robot_description.load('ur5e')
  q_home = description.q_home.copy()
  q_home[0] = description.limits.q_max[0] - 1.0
  moved = dataclasses.replace(description, q_home=q_home)
  low, high = layout.reach_joint_goal_range(moved)
  assert high[0] == description.limits.q_max[0]
  assert low[0] == pytest.approx(high[0] - layout.ONE_TURN)


@pytest.mark.parametrize('robot', ('ur5e', 'kinova3'))
def test_joint_goals_lie_within_one_turn_of_home(robot):
  # Uniform within +-2 pi, goals lay 6-7 rad from home on these joints and
  # the expert did not reach them in the horizon (issue 17).
  env = _env(robot, 'joint', seed=0)
  description = env.task.robot.description
  low, high = layout.reach_joint_goal_range(description)
  limits = description.limits
  wide = limits.q_max - limits.q_min > layout.ONE_TURN + 1e-6
  for _ in range(5):
    env.reset()
    q_goal = env.task.goal_joint_positions
    assert np.all(q_goal >= low) and np.all(q_goal <= high)
    assert np.all(np.abs(q_goal - description.q_home)[wide] <= np.pi + 1e-9)


@pytest.mark.parametrize('robot', ('jaco', 'iiwa'))
@pytest.mark.parametrize('space', SPACES)
def test_goals_keep_the_robot_beside_the_person(robot, space):
  # Without the rule, joint goals of seeds 1 and 8 (Jaco) and 1, 3 and 8
  # (iiwa) put the TCP at y 0.78-0.99 m, into the person (issue 17).
  env = _env(robot, space)
  task = env.task
  for seed in range(10):
    env.random_state.seed(seed)
    env.reset()
    p1, p2, radii = task.collision_checker.reach.capsules(
        task.goal_joint_positions)
    assert np.all(np.maximum(p1[:, 1], p2[:, 1]) + radii
                  <= layout.REACH_GOAL_MAX_Y), seed
