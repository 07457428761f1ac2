"""The lifting task: spec conformance, the starting grasp, reset/step in
both action spaces, rewards, failure, determinism and snapshots."""

import unittest

from dm_env import test_utils
import numpy as np
import pytest

from hrc_suite import suite
from hrc_suite.human import keypoints
from hrc_suite.tasks import lifting
from hrc_suite.tasks.runtime import metrics

import checks    # tests/tasks/checks.py
import oracles   # tests/tasks/oracles.py

ROBOTS = ('panda', 'schunk')
SPACES = ('cartesian', 'joint')


def _env(robot='panda', space='cartesian', seed=0, **kwargs):
  kwargs.setdefault('time_limit', 2.0)
  return suite.load('lifting', 'default', task_kwargs={
      'robot': robot, 'action_space': space, **kwargs},
                    environment_kwargs={'random_state': seed})


def _hold_still(env):
  """Arm still, gripper closed."""
  action = np.zeros(env.action_spec().shape)
  action[-1] = 1.0
  return action


class LiftingSpecTest(test_utils.EnvironmentTestMixin, unittest.TestCase):

  def make_object_under_test(self):
    return _env('schunk', 'cartesian', observations='full', time_limit=1.0)


@pytest.mark.parametrize('robot', ROBOTS)
@pytest.mark.parametrize('space', SPACES)
def test_starts_grasped_and_steps(robot, space):
  env = _env(robot, space)
  timestep = env.reset()
  assert list(timestep.observation) == ['board_quaternion', 'head_distance',
                                        'eef_to_hands']
  assert timestep.observation['eef_to_hands'].shape == (2, 3)
  task, physics = env.task, env.physics
  assert task.step_metrics == {} and env.physics.time() == 0.0
  assert task._gripped
  tcp = task.robot.tcp_pose(physics)[0]
  grip = physics.bind(task.board.robot_grip_site).xpos
  assert np.linalg.norm(tcp - grip) < 0.01
  assert task.board.tilt(physics) < 0.01
  low, high = task.reward_range
  steps = 0
  while not timestep.last():
    timestep = env.step(_hold_still(env))
    steps += 1
    assert low <= timestep.reward <= high
  # Before the person comes to the board: gripped and level, reward ~ +1.
  assert steps == 20
  assert task.episode_metrics['return'] > 19.0


@pytest.mark.parametrize('robot', ROBOTS)
def test_robot_can_lift_the_handle_from_its_grip(robot):
  # Cartesian steps straight up from the starting grip, through the task's
  # own action space, stay collision-free for LIFT_CHECK. Unshifted, the
  # Schunk's grip less than 0.44 m ahead of the world origin folded its
  # elbow against its upper arm within 0.1 m of rising.
  env = _env(robot)
  task = env.task
  space = task._action_space
  for seed in range(4):
    env.random_state.seed(seed)
    env.reset()
    q = task.robot.joint_positions(env.physics).copy()
    rise = 0.0
    while rise < lifting.LIFT_CHECK - 1e-9:
      q, ok = space.goal(q, np.array([0.0, 0.0, 0.2]), q)
      assert ok and not task.collision_checker.in_collision(q), (seed, rise)
      rise += 0.2 * space.step


def test_squeezes_the_handle_with_the_lifting_grip_force():
  env = _env('schunk', 'cartesian')
  env.reset()
  gripper = env.task.gripper
  assert gripper.grip_force == lifting.GRIP_FORCE == 100.0
  env.step(_hold_still(env))
  force = -env.physics.bind(gripper.actuator).force
  assert force == pytest.approx(lifting.GRIP_FORCE, rel=0.05)


def test_cartesian_actions_keep_the_grip_yaw():
  env = _env('panda', 'cartesian')
  env.reset()
  action = np.array([0.0, 0.0, 0.3, 1.0])
  for _ in range(3):
    env.step(action)
  rotation = env.physics.bind(env.task.robot.tcp_site).xmat.reshape(3, 3)
  assert abs(abs(rotation[1, 0]) - 1.0) < 0.05   # x along world +-y.
  assert env.task.step_metrics['board_gripped'] == 1.0


def test_letting_go_fails_with_minus_ten():
  env = _env('panda', 'joint', time_limit=5.0)
  env.reset()
  action = np.zeros(env.action_spec().shape)
  action[-1] = -1.0   # Open.
  rewards = []
  timestep = env.step(action)
  rewards.append(timestep.reward)
  while not timestep.last():
    timestep = env.step(action)
    rewards.append(timestep.reward)
  assert timestep.discount == 0.0
  assert rewards[-1] == lifting.FAILURE_REWARD
  assert len(rewards) <= lifting.MAX_RELEASED_STEPS + 3
  assert env.task.episode_metrics['success'] == 0.0


def test_person_takes_the_board_with_both_hands():
  env = _env('panda', 'joint', time_limit=4.0)
  timestep = env.reset()
  task = env.task
  held = False
  while not timestep.last():
    timestep = env.step(_hold_still(env))
    held |= task.holding_hand is not None
  assert held
  active = [env.physics.data.eq_active[env.physics.bind(w).element_id]
            for w in task._welds.values()]
  assert all(active) or task.holding_hand is None


# Small arm motions with the gripper closed keep the board held.
_GENTLE = dict(scale=0.3, gripper=1.0)


@pytest.mark.parametrize('space', SPACES)
def test_same_seed_same_episode(space):
  checks.assert_same_seed_same_episode(
      lambda: _env('panda', space, seed=4, observations='full'), **_GENTLE)


def test_snapshot_restore_is_bit_exact_while_holding():
  env = _env('panda', 'joint', observations='full', time_limit=6.0)
  env.reset()
  task = env.task
  for _ in range(22):   # The person holds the board by then.
    env.step(_hold_still(env))
  assert task.holding_hand is not None
  checks.assert_snapshot_restores(
      env, lambda: _env('panda', 'joint', seed=5, observations='full',
                        time_limit=6.0), replay=6, diverge=3, **_GENTLE)
  assert task.holding_hand is not None


def test_registered_with_tags():
  assert ('lifting', 'default') in suite.ALL_TASKS
  assert ('lifting', 'default') in suite.tasks_with_tag('dense')
  assert ('lifting', 'default') not in suite.tasks_with_tag('delayed')


def _oracle(env):
  """Privileged follower: while the person holds the board, the TCP keeps
  the offset it had from the midpoint of their hands when they took it
  (plus LOOKAHEAD s of the hands' velocity), gripper closed."""
  task = env.task
  driver = oracles.WaypointDriver(env, yaw=lifting.GRIP_YAW)
  hands = np.array(keypoints.index(('left_hand', 'right_hand')))
  lookahead = 0.15   # s, about the robot's lag behind its goal
  state = {}

  def policy(timestep):
    physics = env.physics
    if timestep.first():
      state.clear()
    if task.holding_hand is None:
      state.pop('offset', None)
      return _hold_still(env)
    middle = task.human.keypoint_positions(physics)[hands].mean(axis=0)
    if 'offset' not in state:
      state['offset'] = task.robot.tcp_pose(physics)[0] - middle
    velocity = task.player.velocities[hands].mean(axis=0)
    return driver.action(middle + lookahead * velocity + state['offset'], 1.0)

  return policy


def test_oracle_completes_a_lift():
  env = _env('panda', 'joint', seed=1, time_limit=30.0)
  result = metrics.run_episode(env, _oracle(env))
  assert result['success'] == 1.0 and result['lifts'] == 1
  assert result['contacts_human_critical'] == 0
  # Level enough all along: every step paid more than half the +1.
  assert result['return'] > 0.5 * result['steps']


@pytest.mark.slow
@pytest.mark.parametrize('robot,space', [('panda', 'cartesian'),
                                         ('schunk', 'joint')])
def test_oracle_succeeds_in_a_few_seeds(robot, space):
  successes = 0
  for seed in range(3):
    env = _env(robot, space, seed=seed, time_limit=30.0)
    result = metrics.run_episode(env, _oracle(env))
    assert result['contacts_human_critical'] == 0
    successes += int(result['success'])
  assert successes >= 1
