"""Pick and place: spec conformance, scene sampling, rewards, snapshots and
success by a scripted oracle."""

import unittest

from dm_env import test_utils
import numpy as np
import pytest

from hrc_suite import layout
from hrc_suite import suite
from hrc_suite.control import ik as ik_lib
from hrc_suite.entities import robot as robot_lib
from hrc_suite.tasks.runtime import actions
from hrc_suite.tasks.runtime import metrics
from hrc_suite.tasks import pick_place

import checks   # tests/tasks/checks.py

ROBOTS = ('panda', 'schunk')
SPACES = ('cartesian', 'joint')
CUBE_REST_Z = layout.TABLE_TOP_Z + 0.02
ORACLE_HOVER = 0.2   # m above the cube (the reference expert's hover)


def _env(robot='panda', space='cartesian', variant='default', seed=0,
         **kwargs):
  kwargs.setdefault('time_limit', 2.0)
  return suite.load('pick_place', variant, task_kwargs={
      'robot': robot, 'action_space': space, **kwargs},
                    environment_kwargs={'random_state': seed})


class Oracle:
  """Privileged state machine (reads the cube and target positions): hover
  above the cube, descend, close, lift, carry above the target, descend."""

  def __init__(self, env, hover=ORACLE_HOVER):
    self.env, self.task, self.hover = env, env.task, hover
    self.ik = ik_lib.InverseKinematics(self.task.kinematics)
    self.phase, self.closing = 'hover', 0
    self.highest_cube = -np.inf   # m, the cube's highest centre seen.

  def _tcp(self):
    return self.task.robot.tcp_pose(self.env.physics)[0]

  def _action(self, target, gripper):
    task, physics = self.task, self.env.physics
    if task.action_space_name == 'cartesian':
      arm = np.clip((target - self._tcp()) / actions.CARTESIAN_STEP, -1, 1)
    else:
      q = task.robot.joint_positions(physics)
      # Aim at most one Cartesian step ahead: IK stays near q.
      tcp = self._tcp()
      delta = target - tcp
      norm = np.linalg.norm(delta)
      if norm > actions.CARTESIAN_STEP:
        delta *= actions.CARTESIAN_STEP / norm
      result = self.ik.solve(tcp + delta, q, actions.GRIPPER_YAW)
      arm = np.clip((result.q - q) / actions.JOINT_STEP, -1, 1)
    return np.append(arm, gripper)

  def __call__(self, timestep):
    del timestep
    task, physics = self.task, self.env.physics
    cube, target = task.object_position(physics), task.target_position
    self.highest_cube = max(self.highest_cube, cube[2])
    tcp = self._tcp()
    hover = self.hover
    grasp = cube + (0.0, 0.0, pick_place.GRASP_TCP_ABOVE_CENTRE)
    if self.phase == 'hover':
      goal = cube + (0.0, 0.0, hover)
      if np.linalg.norm(goal - tcp) < 0.02:
        self.phase = 'descend'
      return self._action(goal, -1.0)
    if self.phase == 'descend':
      if np.linalg.norm(grasp - tcp) < 0.008:
        self.phase = 'close'
      return self._action(grasp, -1.0)
    if self.phase == 'close':
      self.closing += 1
      if self.closing >= 4:
        self.phase = 'lift'
      return self._action(grasp, 1.0)
    if self.phase == 'lift':
      goal = np.append(tcp[:2], target[2] + hover)
      if abs(goal[2] - tcp[2]) < 0.03:
        self.phase = 'carry'
      return self._action(goal, 1.0)
    goal = target + (0.0, 0.0, pick_place.GRASP_TCP_ABOVE_CENTRE + 0.02)
    if self.phase == 'carry':
      goal = target + (0.0, 0.0, hover)
      if np.linalg.norm(goal - tcp) < 0.03:
        self.phase = 'place'
    return self._action(goal, 1.0)


# ------------------------------------------------------------- conformance


class PickPlaceSpecTest(test_utils.EnvironmentTestMixin, unittest.TestCase):
  """dm_env conformance with every observation (Schunk, Cartesian)."""

  def make_object_under_test(self):
    return _env('schunk', 'cartesian', observations='full', time_limit=1.0)


class PickPlaceCloseSpecTest(test_utils.EnvironmentTestMixin,
                             unittest.TestCase):

  def make_object_under_test(self):
    return _env('panda', 'joint', variant='close', time_limit=1.0)


def test_registered_with_tags():
  assert ('pick_place', 'default') in suite.ALL_TASKS
  assert ('pick_place', 'close') in suite.ALL_TASKS
  for tag in ('coexistence', 'sparse', 'ssm'):
    assert ('pick_place', 'close') in suite.tasks_with_tag(tag)
  with pytest.raises(ValueError, match="Unknown reward 'dense'"):
    _env(reward='dense')
  with pytest.raises(ValueError, match='expected one of close, default'):
    _env(variant='far')


@pytest.mark.parametrize('robot', ROBOTS)
@pytest.mark.parametrize('space', SPACES)
def test_reset_and_step(robot, space):
  env = _env(robot, space, observations='full')
  timestep = env.reset()
  dof = env.task.robot.dof
  expected = {'joint_positions': (dof,), 'object_gripped': (1,),
              'eef_to_object': (3,), 'eef_to_target': (3,),
              'object_quaternion': (4,), 'target_distance': (1,),
              'human_distances': (3,), 'gripper_aperture': (1,)}
  for name, shape in expected.items():
    assert timestep.observation[name].shape == shape, name
  assert env.action_spec().shape == ((4,) if space == 'cartesian'
                                     else (dof + 1,))
  assert env.task.reward_range == (-1.0 + env.task.collision_reward, 1.0)
  assert len(checks.run_random_episode(env, timestep)) == 20   # time_limit 2 s at 10 Hz.


def test_horizon_and_defaults():
  task = pick_place.PickPlace()
  assert task.horizon == 1000
  assert task.shield_mode == 'ssm' and task.reward_delay == 0
  assert task.action_space_name == 'cartesian' and task.done_at_success


# ------------------------------------------------------------------- scene


@pytest.mark.parametrize('robot', robot_lib.ROBOTS)
def test_cube_and_target_on_either_side_within_reach(robot):
  env = _env(robot, seed=4)
  task = env.task
  solver = ik_lib.InverseKinematics(task.kinematics)
  q_home = task.robot.description.q_home
  sides = set()
  for _ in range(6):
    env.reset()
    cube = task.object_position(env.physics)
    target = task.target_position
    assert cube[2] == pytest.approx(CUBE_REST_Z, abs=1e-3)
    assert target[2] == pytest.approx(CUBE_REST_Z)
    assert np.sign(cube[1]) == -np.sign(target[1])
    sides.add(np.sign(cube[1]))
    for point in (cube, target):
      local = point - task.kinematics.base_pose[:3, 3]
      assert task.region_x[0] <= local[0] <= task.region_x[1]
      assert (pick_place.REGION_ABS_Y[0] <= abs(local[1])
              <= pick_place.REGION_ABS_Y[1])
      yaw = actions.GRIPPER_YAW
      above = solver.solve(point + (0, 0, pick_place.APPROACH_HEIGHT),
                           q_home, yaw)
      grasp = solver.solve(point + (0, 0, pick_place.GRASP_TCP_ABOVE_CENTRE),
                           above.q, yaw)
      assert above.success and grasp.success
      assert not task.collision_checker.in_collision(grasp.q)
    assert np.linalg.norm(cube - target) > pick_place.SUCCESS_DISTANCE
    # The cube rests: a step later it has not moved.
    env.step(np.array([0.0, 0.0, 0.0, -1.0]))
    np.testing.assert_allclose(task.object_position(env.physics), cube,
                               atol=1e-3)
  assert sides == {-1.0, 1.0}


def test_collision_prevention_lets_fingertips_reach_the_cube_not_the_table():
  task = pick_place.PickPlace(robot='panda')
  solver = ik_lib.InverseKinematics(task.kinematics)
  q_home = task.robot.description.q_home
  point = np.array([0.4, 0.0, layout.TABLE_TOP_Z])
  # The TCP is 1 cm above the fingertips. At the grasp height (the
  # Cartesian workspace floor) the goal is allowed; fingertips closer to
  # the table than TABLE_CLEARANCE are not.
  grasp = point + (0, 0, 0.02 + pick_place.GRASP_TCP_ABOVE_CENTRE)
  low = point + (0, 0, 0.01 + pick_place.TABLE_CLEARANCE - 0.003)
  ok = solver.solve(grasp, q_home, actions.GRIPPER_YAW)
  too_low = solver.solve(low, ok.q, actions.GRIPPER_YAW)
  assert ok.success and too_low.success
  assert not task.collision_checker.in_collision(ok.q)
  assert task.collision_checker.in_collision(too_low.q)
  # The base's default (no tool-table contact) would forbid the grasp.
  assert task.tool_table_allowance > 0.04


def test_close_variant_moves_the_person_towards_the_robot():
  placements = {}
  for variant in ('default', 'close'):
    env = _env(variant=variant, seed=1)
    env.reset()
    placements[variant] = np.array(env.task.player.placement)
  np.testing.assert_allclose(placements['default'] - placements['close'],
                             [0.0, pick_place.CLOSE_STATION_SHIFT, 0.0])
  assert placements['default'][1] == layout.HUMAN_STATION_BESIDE[1]


# ------------------------------------------------------------- observations


def test_paper_observations_match_privileged_state():
  env = _env()
  observation = env.reset().observation
  assert list(observation) == ['gripper_aperture', 'human_distances',
                               'object_gripped', 'eef_to_object',
                               'eef_to_target']
  task, physics = env.task, env.physics
  tcp = task.robot.tcp_pose(physics)[0]
  np.testing.assert_allclose(observation['eef_to_object'],
                             task.object_position(physics) - tcp)
  np.testing.assert_allclose(observation['eef_to_target'],
                             task.target_position - tcp)
  assert observation['object_gripped'][0] == 0.0
  assert observation['gripper_aperture'][0] > 0.9   # Starts open.
  assert np.all(observation['human_distances'] > 0.3)


def test_full_observations_are_consistent():
  env = _env(observations='full')
  observation = env.reset().observation
  for name in ('object', 'target'):
    in_eef = observation[f'{name}_in_eef_frame']
    assert np.linalg.norm(in_eef) == pytest.approx(
        observation[f'{name}_distance'][0])
  np.testing.assert_allclose(observation['object_position'],
                             env.task.object_position(env.physics))
  assert observation['object_at_target'][0] == 0.0
  # The cube's own observables, by the task's names.
  cube = env.task.cube.observables
  assert env.task.task_observables['object_position'] is cube.position
  assert env.task.task_observables['object_quaternion'] is cube.quaternion


# ------------------------------------------------------------------ rewards


def test_sparse_rewards_and_success_threshold():
  env = _env(done_at_success=False, time_limit=5.0)
  env.reset()
  task, physics = env.task, env.physics
  open_hand = np.array([0.0, 0.0, 0.0, -1.0])
  assert env.step(open_hand).reward == pick_place.REWARD_OTHERWISE
  # The cube just outside, then inside the success distance.
  outside = task.target_position + (pick_place.SUCCESS_DISTANCE + 0.01, 0, 0)
  task.cube.set_pose(physics, position=outside)
  timestep = env.step(open_hand)
  assert timestep.reward == -1.0 and task.step_metrics['success'] == 0.0
  task.cube.set_pose(physics, position=task.target_position + (0.05, 0, 0))
  timestep = env.step(open_hand)
  assert timestep.reward == 1.0 and task.step_metrics['success'] == 1.0
  assert timestep.observation is not None and not timestep.last()
  assert task.episode_metrics['object_at_target_steps'] == 1


# --------------------------------------------------- determinism, snapshots


@pytest.mark.parametrize('space', SPACES)
def test_same_seed_same_episode(space):
  targets = []

  def make_env():
    env = _env('schunk', space, seed=7, observations='full')
    targets.append(env.task)
    return env

  checks.assert_same_seed_same_episode(make_env)
  np.testing.assert_array_equal(targets[0].target_position,
                                targets[1].target_position)


def test_snapshot_with_the_cube_in_the_gripper_replays_bit_exactly():
  env = _env('panda', seed=2, observations='full', time_limit=20.0,
             done_at_success=False)
  timestep = env.reset()
  oracle = Oracle(env)
  while oracle.phase != 'lift':
    timestep = env.step(oracle(timestep))
  timestep = env.step(oracle(timestep))
  assert env.task.step_metrics['gripped_steps'] == 1
  assert timestep.observation['object_gripped'][0] == 1.0
  assert timestep.reward == pick_place.REWARD_GRIPPED
  checks.assert_snapshot_restores(
      env, lambda: _env('panda', seed=99, observations='full',
                        time_limit=20.0, done_at_success=False), replay=8)


# ------------------------------------------------------------------ oracle


@pytest.mark.parametrize('variant', ('default', 'close'))
@pytest.mark.parametrize('robot', ROBOTS)
@pytest.mark.parametrize('space', SPACES)
def test_oracle_picks_and_places(robot, space, variant):
  successes = 0
  for seed in range(3):
    env = _env(robot, space, variant=variant, seed=seed, time_limit=15.0)
    oracle = Oracle(env)
    result = metrics.run_episode(env, oracle)
    assert result['contacts_human_critical'] == 0
    if result['success']:
      successes += 1
      assert result['grasps'] >= 1 and result['gripped_steps'] >= 1
      # Done at success: the last reward is the success reward, and the
      # cube was carried (gripped) on the way.
      assert env.task.step_metrics['reward'] == pick_place.REWARD_SUCCESS
      assert env.task.step_metrics['gripped_steps'] == 1
      # Carried through physics: lifted well off the table.
      assert oracle.highest_cube > CUBE_REST_Z + 0.1
      break   # Reachable; further seeds would only cost time.
  assert successes >= 1
