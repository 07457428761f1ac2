"""The stacking task: reset/step, the human's cubes, rewards, snapshots and
an oracle that stacks all four cubes."""

import types
import unittest

from dm_env import test_utils
import numpy as np
import pytest

from hrc_suite import layout
from hrc_suite import suite
from hrc_suite.control import ik as ik_lib
from hrc_suite.human import clip as clip_lib
from hrc_suite.human import keypoints
from hrc_suite.tasks.runtime import actions
from hrc_suite.tasks.runtime import metrics
from hrc_suite.tasks import stacking

import checks   # tests/tasks/checks.py

ROBOTS = ('panda', 'schunk')
SPACES = ('joint', 'cartesian')
SECOND_PLACED = clip_lib.Event.second_cube_placed
IDENTITY = np.array([1.0, 0.0, 0.0, 0.0])


def _env(robot='panda', space='cartesian', seed=0, **kwargs):
  kwargs.setdefault('time_limit', 1.0)
  return suite.load('stacking', 'default', task_kwargs={
      'robot': robot, 'action_space': space, **kwargs},
                    environment_kwargs={'random_state': seed})


def _still(env):
  """Zero arm motion, gripper open."""
  action = np.zeros(env.action_spec().shape)
  action[-1] = -1.0
  return action


@pytest.mark.parametrize('robot', ROBOTS)
@pytest.mark.parametrize('space', SPACES)
def test_reset_and_step(robot, space):
  env = _env(robot, space, observations='full')
  timestep = env.reset()
  assert timestep.observation['eef_to_cubes'].shape == (4, 3)
  assert timestep.observation['cube_quaternions'].shape == (4, 4)
  assert env.task.reward_range == (
      stacking.REWARD_TOPPLED + env.task.collision_reward,
      stacking.REWARD_SUCCESS)
  assert len(checks.run_random_episode(env, timestep)) == 10


def test_paper_observations_and_defaults():
  env = _env()
  observation = env.reset().observation
  assert sorted(observation) == sorted(
      stacking.Stacking.OBSERVATION_PRESETS['paper'])
  task = env.task
  np.testing.assert_allclose(
      observation['eef_to_cubes'],
      np.array([c.position(env.physics) for c in task.cubes])
      - task.robot.tcp_pose(env.physics)[0], atol=1e-12)
  task = stacking.Stacking()
  assert task.shield_mode == 'ssm' and task.horizon == 3000
  assert task.reward_delay == 0   # the human's retreat delays success
  assert stacking.Stacking.HUMAN_PLACEMENT_RANGE == (0.02, 0.1, 0.1)
  assert ('stacking', 'default') in suite.tasks_with_tag('assembly')


@pytest.mark.parametrize('robot', ROBOTS)
def test_cubes_start_where_the_human_and_the_robot_take_them(robot):
  env = _env(robot, seed=4)
  task = env.task
  solver = ik_lib.InverseKinematics(task.kinematics)
  q_home = task.robot.description.q_home
  for _ in range(3):
    env.reset()
    targets = task.player.targets_world
    positions = np.array([c.position(env.physics) for c in task.cubes])
    for i in stacking.HUMAN_CUBES:
      np.testing.assert_allclose(positions[i], targets[f'cube_{i + 1}_pick'],
                                 atol=1e-6)
    for i in stacking.ROBOT_CUBES:
      assert positions[i][2] == pytest.approx(
          layout.TABLE_TOP_Z + task.cubes[i].size / 2)
      grasp = solver.solve(positions[i] + (0, 0, 0.01), q_home,
                           actions.GRIPPER_YAW)
      assert grasp.success
      assert not task.collision_checker.in_collision(grasp.q)
    # The robot's cubes lie clear of the stack and of each other.
    stack = targets['stack_base'][:2]
    for i in stacking.ROBOT_CUBES:
      assert np.linalg.norm(positions[i][:2] - stack) >= (
          stacking.STACK_CLEARANCE)
    assert np.linalg.norm(positions[1][:2] - positions[3][:2]) >= (
        stacking.CUBE_SPACING)


def _human_puts_down_cube_1(env, steps=150):
  task = env.task
  for _ in range(steps):
    env.step(_still(env))
    if task._human_state[0] == stacking.RELEASED:
      return True
  return False


def test_the_human_carries_cube_1_to_the_stack():
  env = _env(time_limit=20.0, seed=2)
  env.reset()
  task = env.task
  place = task.player.targets_world['cube_1_place']
  assert _human_puts_down_cube_1(env)
  for _ in range(5):
    env.step(_still(env))
  cube = task.cubes[0].position(env.physics)
  assert np.linalg.norm(cube[:2] - place[:2]) < stacking.RELEASE_REACH
  assert cube[2] == pytest.approx(place[2], abs=0.005)   # on the table
  assert task.stacked[0] and task.human.holding(task.cubes[0].body) is None
  # The stack's axis is where cube 1 stands.
  np.testing.assert_allclose(task.slots[1][:2], cube[:2], atol=1e-3)
  # Then the person waits for the robot's cube (and keeps waiting).
  waits = 0
  for _ in range(100):
    env.step(_still(env))
    waits += task.player.waiting_for == SECOND_PLACED
  assert waits > 50 and task.player.waiting_for == SECOND_PLACED


def test_the_human_takes_cube_3_only_after_putting_cube_1_down():
  # Seed 3 (Panda): the clip's cube 3 lies within reach of the hand that
  # picks up cube 1; the person still carries one cube at a time.
  env = _env(time_limit=20.0, seed=3)
  env.reset()
  task = env.task
  pick = task.cubes[2].position(env.physics)
  while task._human_state[0] != stacking.RELEASED:
    env.step(_still(env))
    if task._human_state[0] == stacking.HELD:
      assert task._human_state[2] == stacking.ON_TABLE
  np.testing.assert_allclose(task.cubes[2].position(env.physics), pick,
                             atol=1e-3)


@pytest.mark.parametrize('seed', (2, 9))
def test_the_human_sets_a_cube_down_upright_and_at_rest(seed):
  env = _env(time_limit=20.0, seed=seed)
  env.reset()
  task = env.task
  tilts = []
  while task._human_state[0] != stacking.RELEASED:
    env.step(_still(env))
    if task._human_state[0] == stacking.HELD:
      tilts.append(np.abs(task.cubes[0].quaternion(env.physics)[1:3]).max())
  assert max(tilts) > 0.02   # The hand tilts the cube it carries ...
  quaternion = task.cubes[0].quaternion(env.physics)
  assert np.abs(quaternion[1:3]).max() < 1e-3   # ... and sets it down level,
  velocity = env.physics.bind(task.cubes[0].body).cvel
  assert np.abs(velocity).max() < 0.05   # at rest (a step of settling).


def test_toppled_stack_ends_the_episode_with_minus_ten():
  env = _env(time_limit=20.0, seed=2, reward_delay=0)
  env.reset()
  task = env.task
  assert _human_puts_down_cube_1(env)
  env.step(_still(env))
  assert task.stacked[0]
  cube = task.cubes[0].position(env.physics)
  task.cubes[0].set_pose(env.physics, cube + (0.1, 0.0, 0.0), IDENTITY)
  timestep = env.step(_still(env))
  assert timestep.last() and timestep.discount == 0.0
  assert timestep.reward == stacking.REWARD_TOPPLED


def _build_stack(env):
  """Cube 1 put down by the human, then 2-4 set on it (privileged)."""
  task = env.task
  assert _human_puts_down_cube_1(env)
  while task.player.waiting_for != SECOND_PLACED:   # hands back
    env.step(_still(env))
  base = task.cubes[0].position(env.physics)
  for i in (1, 2, 3):
    task.cubes[i].set_pose(env.physics, base + (0, 0, i * task.cubes[i].size),
                           IDENTITY)
  task._human_state[2] = stacking.RELEASED


def test_rewards_of_the_reference():
  env = _env(time_limit=30.0, seed=2, reward_delay=0)
  env.reset()
  task = env.task
  assert env.step(_still(env)).reward == stacking.REWARD_OTHERWISE
  _build_stack(env)
  # The TCP is far from the stack: complete, released, withdrawn; success
  # waits for the end of the human's clip.
  timestep = env.step(_still(env))
  assert task.step_metrics['stack_height'] == 4
  assert timestep.reward == stacking.REWARD_FOURTH_PLACED
  assert task.step_metrics['success'] == 0.0 and not timestep.last()


def test_fourth_cube_held_in_place_pays_one():
  env = _env(time_limit=30.0, seed=2, reward_delay=0, done_at_success=False)
  env.reset()
  task = env.task
  _build_stack(env)
  task._gripped[:] = False
  # Pretend the gripper still holds cube 4 (the grasp check is physics).
  task._gripper.is_grasping = lambda physics, body: (
      body is task.cubes[3].body)
  timestep = env.step(_still(env))
  assert task.step_metrics['success'] == 0.0
  assert timestep.reward == stacking.REWARD_FOURTH_PLACED


@pytest.mark.parametrize('space', SPACES)
def test_same_seed_same_observations(space):
  checks.assert_same_seed_same_episode(
      lambda: _env(seed=3, space=space, observations='full', time_limit=3.0))


@pytest.mark.parametrize('space', SPACES)
def test_snapshot_while_the_human_holds_a_cube(space):
  env = _env(seed=2, space=space, observations='full', time_limit=20.0)
  env.reset()
  while env.task._human_state[0] != stacking.HELD:
    env.step(_still(env))
  checks.assert_snapshot_restores(
      env, lambda: _env(seed=99, space=space, observations='full',
                        time_limit=20.0), replay=8)


class StackingOracle:
  """Privileged: fetch cube 2 (then 4), park until the cube below is
  stacked and the human's hands are CLEAR of the stack, put it on slowly
  (SSM lets a slow robot come closer), withdraw."""

  HOVER = 0.12        # m above the goal while travelling
  SLOW = 0.2          # action scale near the human
  NEAR = 0.6          # m, robot-human distance below which to go slowly
  CLEAR = 0.35        # m, hands from the stack's axis
  HANDS = keypoints.index(['left_hand', 'right_hand'])

  def __init__(self, env):
    self._env = env
    self._phase, self._cube, self._timer = 'fetch', 1, 0
    self._lift = None

  def __call__(self, timestep):
    del timestep
    task, physics = self._env.task, self._env.physics
    tcp = task.robot.tcp_pose(physics)[0]
    cube = task.cubes[self._cube].position(physics)
    slot = task.slots[self._cube]
    grip, slow = 1.0, False
    phase = self._phase
    if phase == 'fetch':
      goal, grip = cube + (0, 0, self.HOVER), -1.0
      if np.linalg.norm(goal - tcp) < 0.02:
        self._phase = 'descend'
    elif phase == 'descend':
      goal, grip = cube + (0, 0, 0.01), -1.0
      if np.linalg.norm(goal - tcp) < 0.01:
        self._phase, self._timer = 'close', 0
    elif phase == 'close':
      goal = cube + (0, 0, 0.01)
      self._timer += 1
      if self._timer > 5:
        self._phase = 'park'
        self._lift = np.append(cube[:2], slot[2] + self.HOVER)
    elif phase == 'park':
      goal = self._lift
      hands = task.human.keypoint_positions(physics)[self.HANDS]
      clear = np.min(np.linalg.norm(hands[:, :2] - slot[:2], axis=1))
      if (np.linalg.norm(goal - tcp) < 0.03 and task.stacked[self._cube - 1]
          and clear > self.CLEAR):
        self._phase = 'over'
    elif phase == 'over':
      goal, slow = slot + (0, 0, self.HOVER), True
      if np.linalg.norm(goal - tcp) < 0.02:
        self._phase = 'put'
    elif phase == 'put':
      goal, slow = slot + (0, 0, 0.01), True
      if np.linalg.norm(goal - tcp) < 0.008:
        self._phase, self._timer = 'open', 0
    elif phase == 'open':
      goal, grip, slow = slot + (0, 0, 0.01), -1.0, True
      self._timer += 1
      if self._timer > 5:
        self._phase = 'up'
    elif phase == 'up':
      goal, grip, slow = slot + (0, 0, self.HOVER), -1.0, True
      if np.linalg.norm(goal - tcp) < 0.03:
        self._phase = 'back'
    elif phase == 'back':
      goal = np.array([0.45, 0.0, task.slots[3][2] + self.HOVER])
      grip = -1.0
      if np.linalg.norm(goal - tcp) < 0.03 and self._cube == 1:
        self._phase, self._cube = 'fetch', 3
    near = task.step_metrics.get('min_human_distance', 1.0) < self.NEAR
    limit = self.SLOW if (slow or near) else 1.0
    arm = np.clip((goal - tcp) / actions.CARTESIAN_STEP, -limit, limit)
    return np.append(arm, grip)


@pytest.mark.slow
def test_oracle_stacks_the_cubes():
  successes = 0
  for seed in (2, 3, 0, 1):
    env = _env('panda', seed=seed, time_limit=120.0)
    result = metrics.run_episode(env, StackingOracle(env))
    assert result['contacts_human_critical'] == 0
    if result['success']:
      successes += 1
      assert env.task.stacked.all()
      assert result['cubes_placed'] == 4
      # Success came with the end of the human's clip (the retreat).
      assert env.task.clip_ended and env.task.clips_completed >= 1
      break
  assert successes >= 1


class StackingSpecTest(test_utils.EnvironmentTestMixin, unittest.TestCase):
  """dm_env conformance (specs, reset, step, discounts) on the full observation."""

  def make_object_under_test(self):
    return _env('schunk', 'cartesian', observations='full', time_limit=1.0)


@pytest.mark.parametrize('stack', [(0.47, 0.29), (0.47, -0.29), (0.5, 0.0),
                                   (0.7, 0.4), (0.4, -0.22)])
def test_robot_cubes_find_room_beside_any_stack(stack):
  """Wherever a person puts the stack on the robot's half (held-out
  recordings included), both robot cubes get a spot clear of it."""
  task = types.SimpleNamespace(_size=0.05)
  for seed in range(5):
    rs = np.random.RandomState(seed)
    taken = [np.array(stack)]
    for side in (1.0, -1.0):
      spot = stacking.Stacking._robot_cube_spot(task, rs, side, taken)
      assert np.all(np.linalg.norm(np.array(taken) - spot[:2], axis=1)
                    >= [stacking.STACK_CLEARANCE]
                    + [stacking.CUBE_SPACING] * (len(taken) - 1))
      taken.append(spot[:2])
