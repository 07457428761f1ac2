"""Re-planning (hrc_suite/experts/replan.py): an expert whose actions
collision prevention keeps replacing takes a detour whose first step is
accepted, and only then."""

import numpy as np
import pytest

from hrc_suite import experts
from hrc_suite import suite
from hrc_suite.experts import adversary
from hrc_suite.experts import noise as noise_lib
from hrc_suite.experts import replan
from hrc_suite.human import clip as clip_lib
from hrc_suite.human import keypoints
from hrc_suite.human import recording_cache
from hrc_suite.tasks.runtime import actions


class _Replaced:
  """A task whose step metric action_replacements the test sets; all else
  is the real task's."""

  def __init__(self, task):
    self._task = task
    self.replaced = 0

  @property
  def step_metrics(self):
    return {'action_replacements': self.replaced}

  def __getattr__(self, name):
    return getattr(self._task, name)


def _setup(domain, task, robot, space):
  env = suite.load(domain, task, task_kwargs={
      'robot': robot, 'action_space': space},
                   environment_kwargs={'random_state': 0})
  env.reset()
  stub = _Replaced(env.task)
  return env, stub, replan.Replanner(stub)


def _goal(env, action):
  """The joint goal the task's action space makes of an action now."""
  task = env.task
  q = task.robot.joint_positions(env.physics)
  space = actions.make_action_space(task.action_space_name, task.kinematics,
                                    yaw=task.CARTESIAN_YAW)
  goal, solved = space.goal(q, action[:space.num_arm], q)
  assert solved
  return goal


def _call(replanner, stub, env, action, replaced, first=False):
  stub.replaced = int(replaced)
  return replanner.action(action, env.physics, first)


@pytest.mark.parametrize('domain, task, robot, space', [
    ('stacking', 'default', 'schunk', 'cartesian'),
    ('reach', 'dense', 'panda', 'joint'),
])
def test_detours_only_after_replaced_actions_in_a_row(domain, task, robot,
                                                      space):
  env, stub, replanner = _setup(domain, task, robot, space)
  size = env.action_spec().shape[0]
  expert_action = np.full(size, 0.3)
  assert _call(replanner, stub, env, expert_action, 1, first=True) is (
      expert_action)
  for _ in range(2):
    for _ in range(replan.REPLAN_AFTER - 1):
      assert _call(replanner, stub, env, expert_action, 1) is expert_action
    # One action that went through: the count starts again.
    assert _call(replanner, stub, env, expert_action, 0) is expert_action
  for _ in range(replan.REPLAN_AFTER - 1):
    assert _call(replanner, stub, env, expert_action, 1) is expert_action
  assert not replanner.on_detour
  detour = _call(replanner, stub, env, expert_action, 1)
  assert replanner.on_detour and replanner.detours == 1
  assert detour.shape == expert_action.shape
  assert np.all(np.abs(detour) <= 1.0)
  assert not np.allclose(detour, expert_action)
  if env.task.HAS_GRIPPER_ACTION:
    assert detour[-1] == expert_action[-1]   # The gripper is the expert's.
  # Its first step is one collision prevention lets through.
  assert env.task.collision_checker.planned_paths_free(
      _goal(env, detour)[None], env.task.shield)[0]


def test_detour_ends_after_its_steps_and_the_expert_resumes():
  env, stub, replanner = _setup('stacking', 'default', 'schunk', 'cartesian')
  expert_action = np.array([0.0, 0.0, -1.0, 1.0])
  _call(replanner, stub, env, expert_action, 0, first=True)
  for _ in range(replan.REPLAN_AFTER):
    action = _call(replanner, stub, env, expert_action, 1)
  assert replanner.on_detour
  waypoint = replanner.waypoint
  # The robot does not move here: the detour gives up after its steps.
  for _ in range(replan.DETOUR_STEPS - 1):
    action = _call(replanner, stub, env, expert_action, 0)
    assert action is not expert_action
    np.testing.assert_array_equal(replanner.waypoint, waypoint)
  assert _call(replanner, stub, env, expert_action, 0) is expert_action
  assert not replanner.on_detour
  # A second detour starts its search one direction further.
  for _ in range(replan.REPLAN_AFTER):
    _call(replanner, stub, env, expert_action, 1)
  assert replanner.on_detour and replanner.detours == 2
  assert not np.allclose(replanner.waypoint, waypoint)


def test_the_same_state_gives_the_same_detour():
  detours = []
  for _ in range(2):
    env, stub, replanner = _setup('stacking', 'default', 'schunk',
                                  'cartesian')
    expert_action = np.array([0.2, -0.1, -1.0, -1.0])
    _call(replanner, stub, env, expert_action, 0, first=True)
    for _ in range(replan.REPLAN_AFTER):
      action = _call(replanner, stub, env, expert_action, 1)
    detours.append((action, replanner.waypoint))
  np.testing.assert_array_equal(detours[0][0], detours[1][0])
  np.testing.assert_array_equal(detours[0][1], detours[1][1])


def test_experts_replan_and_the_person_chaser_does_not():
  env = suite.load('stacking', 'default', task_kwargs={'robot': 'panda'},
                   environment_kwargs={'random_state': 0})
  assert isinstance(experts.make(env).replanner, replan.Replanner)
  assert adversary.PersonChaser(env).replanner is None


@pytest.fixture(scope='module')
def stacking_recordings(tmp_path_factory, recordings_dir):
  """{clip name: clip} of the reference's stacking recordings."""
  with pytest.MonkeyPatch.context() as patch:
    patch.setenv(recording_cache.CACHE_ENV,
                 str(tmp_path_factory.mktemp('recordings')))
    return {c.name: c for c in recording_cache.load_task_folder(
        recordings_dir, 'stacking')}


def _noisy_episode(env, replans):
  expert = experts.make(env)
  if not replans:
    expert._replanner = None   # pylint: disable=protected-access
  noise = noise_lib.OrnsteinUhlenbeckNoise.reference(
      env.action_spec().shape[0], env.task.action_space_name)
  noisy = noise_lib.NoisyExpert(expert, noise, seed=0)
  noisy.set_episode(0)
  env.random_state.seed(0)
  timestep, longest, run = env.reset(), 0, 0
  while not timestep.last():
    timestep = env.step(noisy(timestep))
    run = run + 1 if env.task.step_metrics['action_replacements'] else 0
    longest = max(longest, run)
  return env.task.episode_metrics, longest, expert


@pytest.mark.slow
@pytest.mark.recordings
def test_noisy_stacking_expert_folded_into_itself_replans(
    stacking_recordings):
  """CollaborativeStacking_5, Schunk, noisy expert (episode 0): carrying
  cube 2 to its parking point the noise folds the arm until its elbow
  and wrist capsules touch, and every action from there on would fold it
  further: collision prevention replaces each one. Without re-planning
  the arm stands there to the end; with it a detour unfolds the arm and
  the stack is built."""
  env = suite.load('stacking', 'default', task_kwargs={
      'robot': 'schunk', 'time_limit': 70.0, 'outside_human_model': 'allow',
      'motions': [stacking_recordings['CollaborativeStacking_5']]},
                   environment_kwargs={'random_state': 0})
  stuck, stuck_run, _ = _noisy_episode(env, replans=False)
  assert stuck['success'] == 0.0
  assert stuck_run > 10 * replan.REPLAN_AFTER
  done, _, expert = _noisy_episode(env, replans=True)
  assert done['success'] == 1.0
  assert done['action_replacements'] < stuck['action_replacements'] / 5
  assert expert.replanner.detours >= 1
  assert done['contacts_human_critical'] == 0


def _leaning_in(lean):
  """The shipped stacking clip 0 with the person's upper body leaning
  `lean` m further over the table (the torso half as far) all along."""
  clip = clip_lib.shipped_library('stacking')[0]
  index = keypoints.KEYPOINT_INDEX
  upper = [index[name] for name in (
      'chest', 'neck', 'head', 'left_shoulder', 'right_shoulder',
      'left_elbow', 'right_elbow', 'left_wrist', 'right_wrist', 'left_hand',
      'right_hand')]
  positions = clip.positions.astype(np.float64)
  positions[:, upper, 0] += lean
  positions[:, index['torso'], 0] += lean / 2
  return clip.replace(positions=positions.astype(np.float32),
                      name=f'{clip.name}_leaning')


def test_a_person_leaning_in_does_not_hold_the_noisy_stacking_arm():
  """A person leaning 0.15 m further over the table keeps their hands near
  the stack: the Schunk's noisy expert parks its cube towards its raised
  base, folds into itself, and without re-planning has every action
  replaced to the end of the minute. With re-planning no run of replaced
  actions outlasts REPLAN_AFTER (the stack is not built within the minute
  either: the parking aim leads back into the fold)."""
  env = suite.load('stacking', 'default', task_kwargs={
      'robot': 'schunk', 'time_limit': 60.0, 'outside_human_model': 'allow',
      'motions': [_leaning_in(0.15)]},
                   environment_kwargs={'random_state': 0})
  stuck, stuck_run, _ = _noisy_episode(env, replans=False)
  assert stuck_run > 10 * replan.REPLAN_AFTER
  freed, freed_run, expert = _noisy_episode(env, replans=True)
  assert freed_run <= replan.REPLAN_AFTER and expert.replanner.detours >= 1
  assert freed['action_replacements'] < stuck['action_replacements'] / 2
