"""The walk-throughs of docs/extending.md done from outside the package: a
shield mode, a task with its expert, a reward, and a robot, each defined
here (the robot's description file written to a temporary folder) and
loaded through `suite.load` and the binaries without editing a file of
hrc_suite.

This module is itself an extension module (hrc_suite/extensions.py): the
binaries' tests name it in HRC_SUITE_EXTENSIONS. Its tasks use domains of
their own, so registering them at import changes no shipped task's list.
"""

import json
import math
import os
import pathlib
import subprocess
import sys

from absl import flags
from dm_control.composer.observation import observable
import numpy as np
import pytest

from hrc_suite import experts
from hrc_suite import extensions
from hrc_suite import layout
from hrc_suite import robot_description
from hrc_suite import suite
from hrc_suite.experts import base as expert_base
from hrc_suite.human import clip as clip_lib
from hrc_suite.human import keypoints
from hrc_suite.human import synthesis
from hrc_suite.safety import shield as shield_lib
from hrc_suite.safety.shield import batch
from hrc_suite.safety.shield import modes
from hrc_suite.tasks.runtime import actions
from hrc_suite.tasks import base
from hrc_suite.tasks.runtime import options
from hrc_suite.tasks import reach

# ------------------------------------------------ a shield mode (step 1)


@modes.register
class SlowPfl(modes.Pfl):
  """PFL at half its speed limit where the person may be touched."""
  name = 'pfl_slow'

  def speed_limit(self, v_safe):
    return 0.5 * super().speed_limit(v_safe)


# ------------------------------------------------------- a task (step 2)

GOAL_SPREAD = 0.3     # rad, goal joints uniform around home
SUCCESS_ERROR = 0.1   # rad, joint error norm at success
GOAL_ATTEMPTS = 100   # samples before giving up on a collision-free goal


@suite.register('joint_pose', 'dense', tags=('coexistence', 'dense', 'ssm'),
                reward='dense')
@suite.register('joint_pose', 'sparse',
                tags=('coexistence', 'sparse', 'ssm'), reward='sparse')
class JointPose(base.HrcTask):
  """Bring the joints to a goal pose near home; a person works beside."""

  MOTIONS = 'reach'                        # a shipped motion library
  HUMAN_STATION = layout.HUMAN_STATION_BESIDE
  DEFAULT_ACTION_SPACE = 'joint'
  REWARDS = ('dense', 'sparse')
  HORIZON = 50
  HAS_GRIPPER_ACTION = False
  OBSERVATION_PRESETS = {'paper': ('pose_error',)}
  TASK_STATE = ('_goal', '_error')         # restored by snapshots

  def _build_task(self):
    self._goal = self._robot.description.q_home.copy()
    self._error = 0.0

  def _initialize_task(self, physics, random_state):
    model = self._kinematics
    for _ in range(GOAL_ATTEMPTS):
      goal = np.clip(self._robot.description.q_home + random_state.uniform(
          -GOAL_SPREAD, GOAL_SPREAD, model.q_min.shape), model.q_min,
                     model.q_max)
      if not self._collision_checker.in_collision(goal):
        break
    else:
      raise RuntimeError('JointPose: no collision-free goal')
    self._goal = goal
    self._error = self._pose_error(physics)

  def _pose_error(self, physics):
    return float(np.linalg.norm(self._goal
                                - physics.data.qpos[self._qpos_index]))

  def _update_task(self, physics):
    self._error = self._pose_error(physics)
    return {'success': float(self._error <= SUCCESS_ERROR),
            'pose_error': self._error}

  def _task_reward(self, physics):
    del physics
    if self.reward_kind == 'sparse':
      return 1.0 if self._error <= SUCCESS_ERROR else 0.0
    return -self._error

  def _task_reward_range(self):
    if self.reward_kind == 'sparse':
      return (0.0, 1.0)
    model = self._kinematics
    return (-float(np.linalg.norm(model.q_max - model.q_min)), 0.0)

  def _task_observables(self):
    return {'pose_error': observable.Generic(
        lambda physics: self._goal - physics.data.qpos[self._qpos_index])}


# ------------------------------------------------ its expert (step 2b)


@experts.register('joint_pose', 'dense', 'sparse', 'wait')
class JointPoseExpert(expert_base.Expert):
  """Steps the joints straight at the goal (actions: JOINT_STEP rad)."""

  OBSERVED = ('pose_error',)

  def action(self, observation):
    return observation['pose_error'] / actions.JOINT_STEP


# ------------------------------- an event of the task's own (step 2c)

POSE_REACHED = 'pose_reached'   # a new event (clip.Event names it nowhere)
WAIT_FRAME = 25                 # the wait starts 1 s into a reach clip
# The sway while waiting: amplitudes in s of clip time and dimensionless
# slopes (hrc_suite/human/clip.py), small enough for the human model.
WAIT_AMPLITUDES = (0.3, 0.1)
WAIT_SPEEDS = (0.2, 0.1)


def waiting_clips():
  """The shipped reach clips, each waiting at WAIT_FRAME for POSE_REACHED."""
  wait = clip_lib.IdlePhase(keyframe=0, event=POSE_REACHED,
                            amplitudes=WAIT_AMPLITUDES, speeds=WAIT_SPEEDS)
  return [clip.replace(keyframes=(WAIT_FRAME,) + clip.keyframes,
                       idle_phases=(wait,))
          for clip in clip_lib.shipped_library('reach')]


@suite.register('joint_pose', 'wait', tags=('coexistence', 'sparse', 'ssm'),
                reward='sparse')
class PoseWait(JointPose):
  """JointPose whose person waits 1 s into their clip until the robot
  holds the goal pose."""

  EVENTS = (POSE_REACHED,)   # what the person's clips wait for, in order

  def __init__(self, motions=None, **kwargs):
    super().__init__(motions=waiting_clips() if motions is None else motions,
                     **kwargs)

  def _human_events(self, physics):
    del physics
    return self.EVENTS if self._error <= SUCCESS_ERROR else ()


# ------------------------------------------------------ a reward (step 3)

SHAPING_SCALE = 0.1   # rad: the reward is exp(-error / SHAPING_SCALE)


@suite.register('shaped_reach', 'exponential',
                tags=('coexistence', 'dense', 'ssm'), reward='exponential')
class ShapedReach(reach.Reach):
  """Reach with a reward in (0, 1], growing towards the goal."""

  REWARDS = reach.Reach.REWARDS + ('exponential',)

  def _task_reward(self, physics):
    if self.reward_kind == 'exponential':
      return math.exp(-self._last_distance / SHAPING_SCALE)
    return super()._task_reward(physics)

  def _task_reward_range(self):
    if self.reward_kind == 'exponential':
      return (0.0, 1.0)
    return super()._task_reward_range()


# ----------------------------------------------------- a robot (step 4)


def write_robot(folder, name='myarm', source='panda'):
  """A description file for robot `name`: a copy of `source`'s, renamed."""
  data = json.loads((robot_description.ROBOTS_DIR
                     / f'{source}.json').read_text())
  data.update(name=name, display_name=f'My arm (a {source} copy)')
  path = pathlib.Path(folder) / f'{name}.json'
  path.write_text(json.dumps(data, indent=1))
  return path


@pytest.fixture
def robot_file(tmp_path):
  path = write_robot(tmp_path)
  yield path
  if 'myarm' in robot_description.names():
    robot_description.unregister('myarm')


# ------------------------------------------------------------- the tests


def _episode(env, policy):
  timestep = env.reset()
  while not timestep.last():
    timestep = env.step(policy(timestep))
  return env.task.episode_metrics


def test_the_task_is_registered_with_its_tags_and_fixed_reward():
  assert ('joint_pose', 'dense') in suite.all_tasks()
  assert ('joint_pose', 'sparse') in suite.tasks_with_tag('sparse')
  assert ('joint_pose', 'dense') not in suite.tasks_with_tag('sparse')
  assert ('joint_pose', 'dense') in experts.registered()
  with pytest.raises(ValueError, match="reward='sparse' conflicts"):
    suite.load('joint_pose', 'dense', task_kwargs={'reward': 'sparse'})
  with pytest.raises(ValueError, match='already registered'):
    suite.register('joint_pose', 'dense')(JointPose)
  # A class constant out of range fails at registration, named.
  assert JointPose.defaults().horizon == 50

  class NoSteps(JointPose):
    HORIZON = 0
  with pytest.raises(ValueError, match='NoSteps.HORIZON: expected an '
                     'integer >= 1, got 0'):
    suite.register('joint_pose', 'no_steps')(NoSteps)
  assert ('joint_pose', 'no_steps') not in suite.all_tasks()


def test_the_task_loads_and_its_expert_solves_it():
  for seed in (0, 1):
    env = suite.load('joint_pose', 'sparse',
                     task_kwargs={'robot': 'panda', 'seed': seed})
    metrics = _episode(env, experts.make(env))
    assert metrics['success'] == 1.0, metrics
    assert metrics['steps'] < JointPose.HORIZON   # Done at success.
    # Without the expert the goal is not reached.
    env = suite.load('joint_pose', 'sparse',
                     task_kwargs={'robot': 'panda', 'seed': seed})
    zero = np.zeros(env.action_spec().shape)
    assert _episode(env, lambda timestep: zero)['success'] == 0.0


def test_a_task_with_an_event_of_its_own():
  assert POSE_REACHED not in list(clip_lib.Event)
  assert suite.task_class('joint_pose', 'wait') is PoseWait
  wait = waiting_clips()[0].idle_phases[0]
  wait_time = WAIT_FRAME / waiting_clips()[0].fps
  clip_times = {}
  for policy in ('expert', 'zero'):
    env = suite.load('joint_pose', 'wait', task_kwargs={
        'robot': 'panda', 'seed': 0, 'done_at_success': False})
    zero = np.zeros(env.action_spec().shape)
    act = experts.make(env) if policy == 'expert' else lambda _: zero
    metrics = _episode(env, act)
    assert metrics['success'] == float(policy == 'expert'), policy
    clip_times[policy] = env.task.player.clip_time
    waiting = env.task.player.waiting_for
    assert waiting == (POSE_REACHED if policy == 'zero' else None), policy
  # Without the pose the person still sways about the wait's keyframe at
  # the end (the wait starts at the first physics step at or after it);
  # with it they went on with their clip.
  sway = synthesis.idle_window(wait) + options.DEFAULT_PHYSICS_TIMESTEP
  assert abs(clip_times['zero'] - wait_time) <= sway
  assert clip_times['expert'] > wait_time + sway
  # Clips that do not wait for the task's events are refused, named.
  with pytest.raises(clip_lib.ClipError, match=r"the task triggers the "
                     r"events \['pose_reached'\] in this order \(its "
                     r"EVENTS\), the clip's idle phases wait for \[\]"):
    suite.load('joint_pose', 'wait', task_kwargs={
        'motions': clip_lib.shipped_library('reach')})

  class BadEvent(PoseWait):
    EVENTS = ('pose reached',)
  with pytest.raises(ValueError, match=r"BadEvent.EVENTS: expected a tuple "
                     r"of event names"):
    suite.register('joint_pose', 'bad_event')(BadEvent)


def test_a_reward_added_to_a_task():
  env = suite.load('shaped_reach', 'exponential', task_kwargs={
      'robot': 'panda', 'seed': 3, 'time_limit': 1.0,
      'collision_reward': 0.0})
  assert env.task.reward_range == (0.0, 1.0)
  random_state = np.random.RandomState(0)
  spec = env.action_spec()
  timestep, rewards = env.reset(), []
  while not timestep.last():
    timestep = env.step(random_state.uniform(-1, 1, spec.shape))
    distance = env.task.step_metrics['goal_distance']
    assert timestep.reward == math.exp(-distance / SHAPING_SCALE)
    rewards.append(timestep.reward)
  assert len(rewards) == 10 and len(set(rewards)) > 1
  # The shipped task's rewards are unchanged.
  dense = suite.load('reach', 'dense', task_kwargs={'robot': 'panda'})
  assert dense.task.REWARDS == ('dense', 'sparse')
  with pytest.raises(ValueError, match="Unknown reward 'exponential'"):
    reach.Reach(reward='exponential')


def test_a_robot_from_one_description_file(robot_file):
  assert 'myarm' not in robot_description.names()
  # By path (registered under its name on first use) ...
  env = suite.load('reach', 'dense', task_kwargs={
      'robot': str(robot_file), 'seed': 5, 'time_limit': 0.5})
  assert env.task.robot.description.name == 'myarm'
  assert 'myarm' in robot_description.names()
  # ... then by name: the same episodes as the robot it copies, bit for bit.
  runs = []
  for robot in ('myarm', 'panda'):
    env = suite.load('reach', 'dense', task_kwargs={
        'robot': robot, 'seed': 5, 'time_limit': 0.5})
    timestep, steps = env.reset(), []
    while not timestep.last():
      timestep = env.step(np.full(env.action_spec().shape, 0.5))
      steps.append((timestep.reward, timestep.observation['goal_difference']))
    runs.append(steps)
  for (r1, o1), (r2, o2) in zip(*runs):
    assert r1 == r2 and np.array_equal(o1, o2)


def test_a_robot_file_must_carry_its_own_name(robot_file, tmp_path):
  other = tmp_path / 'other'
  other.mkdir()
  wrong = other / 'wrong.json'
  wrong.write_text(robot_file.read_text())   # Says 'myarm' inside.
  with pytest.raises(ValueError, match="its name 'myarm' must be the file "
                     "name without .json \\('wrong'\\)"):
    robot_description.register(wrong)
  robot_description.register(robot_file)
  robot_description.register(robot_file)   # Again: the same file.
  with pytest.raises(ValueError, match="robot 'myarm' is already described"):
    robot_description.register(write_robot(other))
  with pytest.raises(ValueError, match="robot 'panda' is already described"):
    robot_description.register(write_robot(other, name='panda'))
  with pytest.raises(ValueError, match="Unknown robot 'yourarm'.*myarm"):
    suite.load('reach', 'dense', task_kwargs={'robot': 'yourarm'})


def _person_above_the_tool(shield, cycles):
  """Keypoints of `cycles` cycles: the whole person 0.35 m above the
  robot's home tool position (contact possible at once), drifting 1 mm."""
  _, p2, _ = shield.robot.capsules(shield.description.q_home)
  point = p2[-1] + np.array([0.0, 0.0, 0.35])
  frames = np.tile(point, (cycles, len(keypoints.KEYPOINT_NAMES), 1))
  return frames + np.linspace(0.0, 1e-3, cycles)[:, None, None]


def _shield_run(mode, compiled, cycles=100, per_call=25):
  """Set-points of a shield moving joint 1 by 1 rad under the person."""
  description = robot_description.load('panda')
  shield = shield_lib.Shield(
      description, mode=mode,
      base_pose=layout.robot_mount('panda').base_pose())
  frames = _person_above_the_tool(shield, cycles)
  times = np.arange(cycles) * shield.cycle_time
  goal = description.q_home.copy()
  goal[0] += 1.0
  shield.new_goal(goal)
  points = np.concatenate([
      batch.step_many(shield, frames[i:i + per_call], times[i:i + per_call],
                      compiled=compiled)[0]
      for i in range(0, cycles, per_call)])
  speeds = [shield.robot.surface_speeds(q, dq).max() for q, dq, _ in points]
  return points, max(speeds), shield


def test_a_shield_mode_in_one_module():
  assert 'pfl_slow' in modes.names() and 'pfl_slow' in suite.tags()
  fast, slow_speed, shield = _shield_run('pfl_slow', compiled=True)
  assert shield.speed_limit == 0.45 * shield.v_safe
  # Its compiled cycles are the readable shield's, bit for bit.
  reference, _, _ = _shield_run('pfl_slow', compiled=False)
  assert np.array_equal(fast, reference)
  # PFL moves faster than the new limit, which the new mode keeps; SSM
  # does not move with the person this close.
  _, pfl_speed, _ = _shield_run('pfl', compiled=True)
  _, ssm_speed, _ = _shield_run('ssm', compiled=True)
  assert ssm_speed == 0.0
  assert 0.0 < slow_speed <= shield.speed_limit < pfl_speed
  # Tasks take it like a shipped mode (contacts are judged as under PFL).
  env = suite.load('joint_pose', 'dense', task_kwargs={
      'robot': 'panda', 'shield': 'pfl_slow', 'time_limit': 0.2})
  assert env.task.shield.mode == 'pfl_slow'
  assert env.task.critical_speed == env.task.shield.v_safe
  with pytest.raises(ValueError, match="Unknown shield 'fast'.*'pfl_slow'"):
    suite.load('joint_pose', 'dense', task_kwargs={'shield': 'fast'})


def test_bad_extension_entries_are_named(monkeypatch):
  monkeypatch.setattr(extensions, '_loaded', set())
  monkeypatch.setenv(extensions.ENV_VAR, 'no_such_module_here')
  with pytest.raises(ImportError, match="HRC_SUITE_EXTENSIONS entry "
                     "'no_such_module_here': cannot import"):
    suite.all_tasks()
  monkeypatch.setenv(extensions.ENV_VAR, 'json:no_function')
  with pytest.raises(ValueError, match="entry 'json:no_function': json has "
                     "no function 'no_function'"):
    modes.names()


def _extension_env():
  """The environment of a binary that loads this module as an extension."""
  module = sys.modules[__name__]
  root = pathlib.Path(module.__file__).resolve().parents[
      __name__.count('.')]
  repository = pathlib.Path(suite.__file__).resolve().parents[1]
  env = dict(os.environ)
  env['PYTHONPATH'] = os.pathsep.join(
      [str(root), str(repository), env.get('PYTHONPATH', '')])
  env[extensions.ENV_VAR] = __name__
  env.setdefault('MUJOCO_GL', 'egl')
  return env


def _run_binary(module, *args):
  return subprocess.run([sys.executable, '-m', module, *args],
                        env=_extension_env(), capture_output=True, text=True,
                        timeout=600, check=False)


def test_the_binaries_take_the_extensions(tmp_path):
  robot = write_robot(tmp_path)
  video = tmp_path / 'episode.gif'
  done = _run_binary('hrc_suite.rendering.episode', '--domain=joint_pose',
                     '--task=dense', f'--robot={robot}', '--shield=pfl_slow',
                     '--policy=expert', '--max_steps=3', '--width=64',
                     '--height=48', f'--out={video}')
  assert done.returncode == 0, done.stderr[-2000:]
  written = json.loads(video.with_suffix('.json').read_text())
  assert (written['domain'], written['task']) == ('joint_pose', 'dense')
  assert written['task_kwargs'] == {'shield': 'pfl_slow'}
  assert written['metrics']['steps'] == 3
  table = tmp_path / 'experts.md'
  done = _run_binary('hrc_suite.experts.evaluate', '--tasks=joint_pose/dense',
                     f'--robots={robot}', '--policies=expert',
                     '--shield=pfl_slow', '--episodes=2', '--progress=false',
                     f'--out={table}')
  assert done.returncode == 0, done.stderr[-2000:]
  assert 'BELOW THE BAR' not in done.stdout
  rows = [line.split(' | ') for line in table.read_text().splitlines()
          if line.startswith('| joint_pose/dense |')]
  assert len(rows) == 1, table.read_text()
  assert rows[0][4:8] == ['pfl_slow', 'joint', '2', '1.00 [1.00, 1.00]']
  picture = tmp_path / 'robot.gif'
  done = _run_binary('hrc_suite.rendering.robot', f'--robot={robot}',
                     f'--out={picture}', '--width=64', '--height=48',
                     '--fps=5')
  assert done.returncode == 0 and picture.stat().st_size > 0, done.stderr
  # Names are checked when the command line is parsed, against the
  # registries (the extension's names are valid, others are not).
  done = _run_binary('hrc_suite.rendering.episode', '--domain=joint_pose',
                     '--task=dense', '--shield=pfl_fast')
  assert done.returncode != 0
  assert "unknown shield mode 'pfl_fast'" in done.stderr
  assert 'pfl_slow' in done.stderr


def test_the_training_flags_take_the_extensions(robot_file):
  from agents import train  # pylint: disable=g-import-not-at-top
  values = flags.FlagValues()
  train.define_flags(values)
  values(['train', '--domain=joint_pose', '--task=sparse',
          f'--robot={robot_file}', '--logdir=unused'])
  assert (values.domain, values.task) == ('joint_pose', 'sparse')
  values = flags.FlagValues()
  train.define_flags(values)
  with pytest.raises(flags.IllegalFlagValueError,
                     match="unknown task 'wave' of domain 'joint_pose'"):
    values(['train', '--domain=joint_pose', '--task=wave',
            '--logdir=unused'])
