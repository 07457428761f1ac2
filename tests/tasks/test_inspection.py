"""The inspection task: spec conformance, reset/step in both action spaces,
rewards, determinism, snapshots and success by a scripted oracle."""

import unittest

from dm_env import test_utils
import numpy as np
import pytest

from hrc_suite import layout
from hrc_suite import suite
from hrc_suite.tasks.runtime import actions
from hrc_suite.tasks import inspection
from hrc_suite.tasks.runtime import metrics

import checks    # tests/tasks/checks.py
import oracles   # tests/tasks/oracles.py

ROBOTS = ('panda', 'schunk')
SPACES = ('cartesian', 'joint')


def _env(robot='panda', space='cartesian', seed=0, **kwargs):
  kwargs.setdefault('time_limit', 2.0)
  return suite.load('inspection', 'default', task_kwargs={
      'robot': robot, 'action_space': space, **kwargs},
                    environment_kwargs={'random_state': seed})


class InspectionSpecTest(test_utils.EnvironmentTestMixin, unittest.TestCase):

  def make_object_under_test(self):
    return _env('schunk', 'cartesian', observations='full', time_limit=1.0)


@pytest.mark.parametrize('robot', ROBOTS)
@pytest.mark.parametrize('space', SPACES)
def test_reset_and_step(robot, space):
  env = _env(robot, space)
  timestep = env.reset()
  assert list(timestep.observation) == list(
      inspection.Inspection.OBSERVATION_PRESETS['paper'])
  assert timestep.observation['eef_to_target'].shape == (3,)
  task = env.task
  # The cube rests on the table in reach; the target is within the
  # Cartesian workspace box, at most the clip's point.
  cube = task.cube.position(env.physics)
  assert cube[2] == pytest.approx(0.84, abs=2e-3)
  assert task.kinematics.within_limits(task.robot.joint_positions(
      env.physics))
  low, high = actions.workspace_box(task.kinematics)
  assert np.all(task.target_position >= low - 1e-9)
  assert np.all(task.target_position <= high + 1e-9)
  low_r, high_r = task.reward_range
  rs = np.random.RandomState(0)
  steps = 0
  while not timestep.last():
    timestep = env.step(rs.uniform(-1, 1, env.action_spec().shape))
    steps += 1
    assert low_r <= timestep.reward <= high_r
    assert timestep.reward in (-1.0, -0.25) or timestep.reward <= -10
  assert steps == 20


def test_target_is_the_clip_point_when_reachable():
  env = _env('sawyer')
  env.reset()
  task = env.task
  point = task.player.targets_world['inspection_point']
  # Where a held cube's centre reaches the clip's point: no projection.
  if task._reachable(np.asarray(point), task.robot.description.q_home):
    np.testing.assert_allclose(task.target_position, point)
  # The Schunk's target is moved towards its home TCP.
  env = _env('schunk')
  env.reset()
  point = env.task.player.targets_world['inspection_point']
  home = env.task.kinematics.tcp_pose(
      env.task.robot.description.q_home)[:3, 3]
  target = env.task.target_position
  assert np.linalg.norm(target - home) < np.linalg.norm(point - home)
  cross = np.cross(point - home, target - home)
  assert np.linalg.norm(cross) < 1e-9


def test_layout_fits_a_point_into_reach():
  point, home = np.array([1.0, 0.0, 1.0]), np.array([0.0, 0.0, 1.0])
  np.testing.assert_array_equal(
      layout.fit_into_reach(point, home, lambda p: True), point)
  # Reached only from x <= 0.5: the first of the 21 points (steps of 0.05).
  fitted = layout.fit_into_reach(point, home, lambda p: p[0] <= 0.5)
  np.testing.assert_allclose(fitted, [0.5, 0.0, 1.0])
  np.testing.assert_array_equal(
      layout.fit_into_reach(point, home, lambda p: False), home)


@pytest.mark.parametrize('space', SPACES)
def test_same_seed_same_episode(space):
  checks.assert_same_seed_same_episode(
      lambda: _env('panda', space, seed=4, observations='full'))


def test_snapshot_restore_is_bit_exact():
  env = _env('panda', 'cartesian', observations='full', time_limit=5.0)
  env.reset()
  checks.rollout(env, checks.random_actions(env, 5, seed=2))
  checks.assert_snapshot_restores(
      env, lambda: _env('panda', 'cartesian', seed=7, observations='full',
                        time_limit=5.0), replay=8)


def _oracle(env):
  """Privileged pick-and-present: hover, descend, close, lift, carry to the
  target and hold the cube there."""
  task = env.task
  driver = oracles.WaypointDriver(env)
  state = {}

  def policy(timestep):
    if timestep.first():
      state.clear()
      state['phase'] = 'hover'
    grasp = task.cube.position(env.physics) + (
        0, 0, inspection.GRASP_TCP_ABOVE_CENTRE)
    tcp = driver.tcp()
    phase = state['phase']
    if phase == 'hover':
      above = grasp + (0, 0, 0.1)
      if np.linalg.norm(tcp - above) < 0.01:
        state['phase'] = 'descend'
      return driver.action(above, -1)
    if phase == 'descend':
      if np.linalg.norm(tcp - grasp) < 0.006:
        state['phase'], state['closing'] = 'close', 0
        state['lift'] = grasp + (0, 0, 0.1)
      return driver.action(grasp, -1)
    if phase == 'close':
      state['closing'] += 1
      if state['closing'] > 5:
        state['phase'] = 'lift'
      return driver.action(grasp, 1)
    if phase == 'lift':
      if tcp[2] > state['lift'][2] - 0.02:
        state['phase'] = 'carry'
      return driver.action(state['lift'], 1)
    return driver.action(task.target_position, 1)

  return policy


@pytest.mark.slow
@pytest.mark.parametrize('robot', ROBOTS)
@pytest.mark.parametrize('space', SPACES)
def test_oracle_succeeds(robot, space):
  successes = 0
  for seed in range(2):
    env = _env(robot, space, seed=seed, time_limit=60.0)
    result = metrics.run_episode(env, _oracle(env))
    assert result['contacts_human_critical'] == 0
    if result['success']:
      successes += 1
      assert result['presentations'] == 1
      # Done at success: the last reward is the success reward.
      assert env.task.step_metrics['reward'] == inspection.SUCCESS_REWARD
  assert successes >= 1


def test_oracle_succeeds_once_fast():
  env = _env('schunk', 'cartesian', seed=0, time_limit=60.0)
  result = metrics.run_episode(env, _oracle(env))
  assert result['success'] == 1.0 and result['presentations'] == 1


def test_registered_with_tags():
  assert ('inspection', 'default') in suite.ALL_TASKS
  for tag in ('object_handling', 'sparse', 'delayed'):
    assert ('inspection', 'default') in suite.tasks_with_tag(tag)
