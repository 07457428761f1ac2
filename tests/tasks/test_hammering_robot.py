"""hammering/robot_hammers: the hammer in the gripper, the plank carried
in, set down, waited over, taken back; success, failure, snapshots; the
reference's recordings (marked `recordings`, tests/conftest.py)."""

import numpy as np
import pytest

from hrc_suite import layout
from hrc_suite import suite
from hrc_suite.human import clip as clip_lib
from hrc_suite.human import keypoints
from hrc_suite.human import recording_cache
from hrc_suite.human import synthesis
from hrc_suite.human import task_motions
from hrc_suite.human import task_targets
from hrc_suite.motion_tools import synthetic_library
from hrc_suite.tasks import hammering_robot
from hrc_suite.tasks.runtime import motions

import checks   # tests/tasks/checks.py


def _env(robot='panda', space='cartesian', seed=0, **kwargs):
  kwargs.setdefault('time_limit', 30.0)
  return suite.load('hammering', 'robot_hammers', task_kwargs={
      'robot': robot, 'action_space': space, 'observations': 'full',
      **kwargs}, environment_kwargs={'random_state': seed})


def _hold(env):
  action = np.zeros(env.action_spec().shape)
  action[-1] = 1.0
  return action


def _until_placed(env, timestep=None):
  timestep = timestep or env.reset()
  while env.task.board_phase != hammering_robot.PLACED:
    assert not timestep.last()
    timestep = env.step(_hold(env))
  return timestep


@pytest.mark.parametrize('robot', ('panda', 'schunk'))
@pytest.mark.parametrize('space', ('cartesian', 'joint'))
def test_starts_with_the_hammer_face_down_in_the_gripper(robot, space):
  env = _env(robot, space)
  timestep = env.reset()
  task, physics = env.task, env.physics
  assert timestep.observation['object_gripped'][0] == 1.0
  hammer = physics.bind(task.hammer.body).xmat.reshape(3, 3)
  np.testing.assert_allclose(hammer[:, 2], [0, 0, 1], atol=0.02)  # face down
  np.testing.assert_allclose(hammer[:, 0], [0, 1, 0], atol=0.02)  # head +y
  # The grip is at the hammer's centre of mass, under the TCP.
  assert np.linalg.norm(timestep.observation['eef_to_object']) < 0.005
  assert task.board_phase == hammering_robot.CARRIED
  assert task.shield_mode == 'pfl'


def test_plank_is_set_down_with_its_handle_at_the_place():
  env = _env(seed=2)
  _until_placed(env)
  task, physics = env.task, env.physics
  clip = task.player.clip
  assert task.player.clip_time >= clip.keyframes[0] / clip.fps
  board = physics.bind(task.board.body)
  rotation = board.xmat.reshape(3, 3)
  handle = board.xpos + rotation[:, 0] * hammering_robot.PLANK_HANDLE_X
  place = task.player.targets_world['board_place']
  np.testing.assert_allclose(handle[:2], place[:2], atol=1e-3)
  assert board.xpos[2] == pytest.approx(
      layout.TABLE_TOP_Z + hammering_robot.PLANK_HALF_SIZE[2], abs=3e-3)
  # The nail points towards the robot and lies within its reach.
  nail = physics.bind(task.board.nail_head_site).xpos
  assert nail[0] < handle[0] - 0.2
  assert 0.3 < nail[0] < 0.75
  # A few steps on the plank rests there (it collides with the table now).
  for _ in range(5):
    env.step(_hold(env))
  np.testing.assert_allclose(physics.bind(task.board.body).xpos, board.xpos,
                             atol=2e-3)


def test_person_waits_until_the_nail_is_in_then_leaves_with_the_plank():
  """Held still, the robot never drives the nail: the person waits past
  their clip's length. Driving it in (set here) fires the event: the
  person takes the plank back, and success comes when the clip ends."""
  env = _env(seed=1, time_limit=60.0)
  timestep = _until_placed(env)
  task = env.task
  length = task.player.clip.duration
  while task.player.episode_time < length + 2.0:
    timestep = env.step(_hold(env))
    assert task.board_phase == hammering_robot.PLACED
    assert timestep.reward == -1.0
  assert task.player.waiting_for == hammering_robot.EVENT
  assert task.episode_metrics['nail_blows'] == 0
  task.board.set_progress(env.physics, 1.0)
  phases = []
  while not timestep.last():
    timestep = env.step(_hold(env))
    phases.append(task.board_phase)
  assert hammering_robot.TAKEN in phases
  assert timestep.reward == 1.0
  assert task.episode_metrics['success'] == 1.0


def test_dropping_the_hammer_fails():
  env = _env(seed=0)
  timestep = env.reset()
  action = _hold(env)
  action[-1] = -1.0
  steps = 0
  while not timestep.last():
    timestep = env.step(action)
    steps += 1
  # The fingers open, the hammer falls: failure DROP_STEPS steps later.
  assert hammering_robot.DROP_STEPS < steps <= hammering_robot.DROP_STEPS + 5
  assert timestep.discount == 0.0
  assert env.task.episode_metrics['success'] == 0.0


@pytest.mark.parametrize('space', ('cartesian', 'joint'))
def test_snapshot_restore_is_bit_exact(space):
  env = _env(seed=5, space=space)
  _until_placed(env)
  checks.assert_snapshot_restores(
      env, lambda: _env(seed=99, space=space))


def test_same_seed_same_episode():
  checks.assert_same_seed_same_episode(lambda: _env(seed=3, time_limit=3.0))


def test_synthetic_clips_stay_within_the_shield_human_model():
  env = _env()
  v_max = env.task.shield.human.config.v_max
  for clip in clip_lib.shipped_library('hammering_board'):
    assert motions.speed_excess(clip, v_max) is None, clip.name
    assert clip.holding_hand in clip_lib.HANDS
    assert clip.targets['board_place'][0] > task_targets.TABLE_EDGE_X


def test_shipped_plank_clips_equal_a_fresh_synthesis():
  shipped = clip_lib.shipped_library('hammering_board')
  assert len(shipped) == task_motions.CLIP_COUNTS['hammering_board']
  fresh = synthetic_library.synthesise('hammering_board', 3)
  assert shipped[3].name == fresh.name
  np.testing.assert_array_equal(shipped[3].positions, fresh.positions)


def test_clip_without_blows_is_refused_for_hammering_default():
  """The rule for hammering/default refuses a person who never strikes
  (here a synthetic plank bearer), naming the clip, target and reason."""
  clip = clip_lib.shipped_library('hammering_board')[0]
  fields = {'keyframes': clip.keyframes, 'idle_phases': clip.idle_phases}
  with pytest.raises(clip_lib.ClipError,
                     match=r"made\.bvh: cannot derive 'strike_grip': the "
                     r'person never strikes.*hammering/robot_hammers'):
    task_targets.derive('hammering', clip.positions, clip.fps, fields,
                        'made.bvh')


@pytest.fixture()
def cache(tmp_path, monkeypatch):
  monkeypatch.setenv(recording_cache.CACHE_ENV, str(tmp_path))


@pytest.mark.recordings
def test_recordings_are_refused_for_hammering_default(cache, recordings_dir):
  del cache
  with pytest.raises(clip_lib.ClipError,
                     match=r"CollaborativeHammering/0\.bvh: cannot derive "
                     r"'strike_grip': the person never strikes: the left "
                     r'hand moves down at most .* m/s.*use '
                     r'hammering/robot_hammers'):
    suite.load('hammering', 'default', task_kwargs={
        'motions': str(recordings_dir), 'outside_human_model': 'allow'})


@pytest.mark.recordings
def test_recordings_play_in_robot_hammers(cache, recordings_dir):
  """Every recording: the plank lands with its nail within reach; the
  person waits for the nail."""
  del cache
  env = _env(motions=str(recordings_dir), outside_human_model='allow')
  clips = env.task.player.clips
  assert len(clips) == 8
  for clip in clips:
    assert clip.task == 'hammering_board' and clip.holding_hand == 'left'
    place = clip.targets['board_place']
    hand = clip.positions[clip.keyframes[0],
                          keypoints.KEYPOINT_INDEX['left_hand']]
    np.testing.assert_allclose(place[:2], hand[:2], atol=1e-3)
    # World x of the nail: station minus the clip x, minus the handle-nail
    # distance along the facing (-x world).
    nail_x = (layout.HUMAN_STATION_ACROSS[0] - place[0]
              - (hammering_robot.PLANK_NAIL_X
                 - hammering_robot.PLANK_HANDLE_X))
    assert 0.45 < nail_x < 0.7, (clip.name, nail_x)
  _until_placed(env)
  assert env.task.player.waiting_for is None or (
      env.task.player.waiting_for == hammering_robot.EVENT)
