"""Real recordings as their tasks' motions: placement, targets, loading.

Uses the real recordings (MIT licensed test data, tests/conftest.py):
those tests are marked `recordings` and skip with a message when the
recordings are absent. The bad-clip tests use clips made here.
"""

import re

import numpy as np
import pytest

from hrc_suite import layout
from hrc_suite.human import bvh_import
from hrc_suite.human import clip as clip_lib
from hrc_suite.human import keypoints
from hrc_suite.human import placement
from hrc_suite.human import recording_cache
from hrc_suite.human import task_targets
from hrc_suite.safety.shield import human_reach
from hrc_suite.tasks.runtime import motions as motions_lib

I = keypoints.KEYPOINT_INDEX
EDGE = placement.TABLE_EDGE_CLEARANCE   # table edge, clip frame x
V_MAX = human_reach.HumanModelConfig.load(None).v_max
# Targets the robot brings an object to or takes one from: over the table.
ROBOT_TARGETS = ('inspection_point', 'handover_point', 'strike_grip', 'nail',
                 'stack_base', 'cube_1_place', 'cube_3_place')


@pytest.fixture(scope='module')
def cache(tmp_path_factory):
  path = tmp_path_factory.mktemp('recording_cache')
  with pytest.MonkeyPatch.context() as patch:
    patch.setenv(recording_cache.CACHE_ENV, str(path))
    yield path


@pytest.fixture(scope='module')
def task_clips(cache, recordings_dir):
  """{folder: (task, clips)} loaded as a task loads `motions=DIR`."""
  del cache
  out = {}
  for folder in sorted(p.name for p in recordings_dir.iterdir()
                       if p.is_dir()):
    task = bvh_import.REFERENCE_FOLDER_TASKS[folder]
    out[folder] = task, recording_cache.load_task_folder(recordings_dir,
                                                         task)
  return out


@pytest.mark.recordings
def test_reference_layout_loads_each_task(task_clips, library_events,
                                          recordings_dir, recording_folder):
  task, clips = task_clips[recording_folder]
  assert len(clips) == len(
      list((recordings_dir / recording_folder).glob('*.bvh')))
  station = {'pick_place': layout.HUMAN_STATION_BESIDE}.get(
      task, layout.HUMAN_STATION_ACROSS)
  # Every task requirement holds (the speed model aside: checked below).
  motions_lib.check_motions(clips, task, library_events[task], station,
                            V_MAX, 'allow')
  for clip in clips:
    assert clip.task == task
    assert set(clip_lib.TASK_TARGETS[task]) <= set(clip.targets)


@pytest.mark.recordings
def test_placement_keeps_people_out_of_the_table(task_clips,
                                                 recording_folder):
  """The pelvis stays 0.10 m or more behind the table's far edge; some hand reaches within 0.1 m of the edge or over it (inspection:
  the head within 1.2 m of the inspection point); targets the robot serves
  lie over the table."""
  task, clips = task_clips[recording_folder]
  # Stations closer to the edge (stacking's) leave less room.
  pelvis_limit = EDGE - 0.1 - placement.STATION_SHIFTS.get(task, 0.0)
  for clip in clips:
    p = clip.positions.astype(np.float64)
    assert p[:, I['pelvis'], 0].max() <= pelvis_limit + 1e-5, clip.name
    if clip.task == 'inspection':
      # The person inspects by looking: the point is within arm's reach
      # (0.9-1.1 m in 2 of the 7 recordings, whose people wait a step
      # back; task_targets.OVER_TABLE keeps the point where robots reach).
      frame = clip.keyframes[clip.idle_phases[0].keyframe]
      distance = np.linalg.norm(clip.targets['inspection_point']
                                - p[frame, I['head']])
      assert distance < 1.2, (clip.name, distance)
    else:
      hands = p[:, [I['left_hand'], I['right_hand']], 0]
      assert hands.max() > EDGE - 0.1, (clip.name, hands.max())
    for name in ROBOT_TARGETS:
      if name in clip.targets:
        assert clip.targets[name][0] > EDGE, (clip.name, name,
                                              clip.targets[name])


@pytest.mark.recordings
def test_handover_people_reach_out_over_the_table(task_clips):
  """The handovers' people step up until the holding hand is
  HANDOVER_REACH ahead of the station at the wait, as far as
  LEAN_ALLOWANCE lets them (bvh_import.REACH_TASKS)."""
  for folder in ('RobotHumanHandover', 'HumanRobotHandover'):
    _, clips = task_clips[folder]
    for clip in clips:
      p = clip.positions.astype(np.float64)
      frame = clip.keyframes[clip.idle_phases[0].keyframe]
      hand = p[frame, I[f'{clip.holding_hand}_hand'], 0]
      stepped = p[frame, I['pelvis'], 0] > 1e-5
      at_limit = p[:, I['pelvis'], 0].max() > placement.LEAN_ALLOWANCE - 1e-5
      assert hand > bvh_import.HANDOVER_REACH - 1e-5 or at_limit, (
          clip.name, hand)
      if stepped:
        assert abs(hand - bvh_import.HANDOVER_REACH) < 1e-5 or at_limit


@pytest.mark.recordings
def test_targets_follow_the_motion(task_clips):
  """Targets come from the hands: the holding hand is at the handover
  point at the presentation keyframe, the board grasps at the hands when
  the person takes the board."""
  _, handovers = task_clips['RobotHumanHandover']
  for clip in handovers:
    frame = clip.keyframes[clip.idle_phases[0].keyframe]
    hand = clip.positions[frame, I[f'{clip.holding_hand}_hand']]
    np.testing.assert_allclose(hand, clip.targets['handover_point'],
                               atol=1e-3)
  _, lifts = task_clips['CollaborativeLifting']
  for clip in lifts:
    first = clip.keyframes[0]
    for side in ('left', 'right'):
      np.testing.assert_allclose(clip.positions[first, I[f'{side}_hand']],
                                 clip.targets[f'board_grasp_{side}'],
                                 atol=1e-3)


@pytest.mark.recordings
def test_stacking_recordings_carry_their_cubes_in(task_clips):
  """The reference's stacking people walk in with both cubes: each pick is
  where a hand holds its cube at the first frame (the task starts it in
  hand), the places are over the table, cube 3 above cube 1, the stack
  under cube 1."""
  _, clips = task_clips['CollaborativeStacking']
  grip = np.array([0.0, 0.0, task_targets.GRIP_ABOVE_CENTRE])
  for clip in clips:
    t = clip.targets
    hands = clip.positions[0, [I['left_hand'], I['right_hand']]]
    for cube in (1, 3):
      held = np.linalg.norm(hands - grip - t[f'cube_{cube}_pick'], axis=1)
      assert held.min() < 1e-3, (clip.name, cube, held)
      assert t[f'cube_{cube}_place'][0] > task_targets.TABLE_EDGE_X
    assert t['cube_3_place'][2] > t['cube_1_place'][2]
    np.testing.assert_allclose(t['stack_base'][:2], t['cube_1_place'][:2])


@pytest.mark.recordings
def test_cache_is_reused_and_keyed_by_content(tmp_path, monkeypatch,
                                              recordings_dir):
  monkeypatch.setenv(recording_cache.CACHE_ENV, str(tmp_path / 'cache'))
  source = tmp_path / 'HumanRobotHandover'
  source.mkdir()
  for name in ('0.bvh', '0_info.json'):
    (source / name).write_bytes((recordings_dir / 'HumanRobotHandover' /
                                 name).read_bytes())
  first = recording_cache.load_task_folder(tmp_path,
                                           'handover_human_to_robot')
  entries = list((tmp_path / 'cache').iterdir())
  assert len(entries) == 1 and len(first) == 1
  again = recording_cache.load_task_folder(tmp_path,
                                           'handover_human_to_robot')
  assert list((tmp_path / 'cache').iterdir()) == entries
  np.testing.assert_array_equal(first[0].positions, again[0].positions)
  # A changed recording is converted afresh.
  info = source / '0_info.json'
  info.write_text(info.read_text().replace('"right"', '"left"'))
  changed = recording_cache.load_task_folder(tmp_path,
                                             'handover_human_to_robot')
  assert len(list((tmp_path / 'cache').iterdir())) == 2
  assert changed[0].holding_hand == 'left'


def test_folder_without_the_task_names_what_it_found(tmp_path):
  (tmp_path / 'Unrelated').mkdir()
  with pytest.raises(clip_lib.ClipError, match='no sub-folder for task '
                     "'stacking'.*CollaborativeStacking.*Unrelated"):
    recording_cache.load_task_folder(tmp_path, 'stacking')


@pytest.mark.recordings
def test_recording_without_derivable_target_names_clip_and_target(
    tmp_path, recordings_dir):
  """A hammering-less 'hammering' recording: no lowest blow point needs a
  window; a stacking recording without its placing hand."""
  source = tmp_path / 'CollaborativeStacking'
  source.mkdir()
  (source / '0.bvh').write_bytes(
      (recordings_dir / 'CollaborativeStacking' / '0.bvh').read_bytes())
  info = (recordings_dir / 'CollaborativeStacking' /
          '0_info.json').read_text()
  (source / '0_info.json').write_text(
      info.replace('"first_placing_hand": "left",', ''))
  with pytest.raises(clip_lib.ClipError,
                     match=r"0\.bvh: cannot derive 'cube_1_place': the clip "
                     'names no first placing hand'):
    recording_cache.load_task_folder(tmp_path, 'stacking', use_cache=False)


# ------------------------------------------------ bad clips, clear errors


def _clip(task='pick_place', **changes):
  positions = np.tile(clip_lib.shipped_library('pick_place')[0].positions[:1],
                      (20, 1, 1))
  clip = clip_lib.Clip(name='made', task=task, fps=25.0, positions=positions)
  return clip.replace(**changes)


def test_clip_over_the_speed_model_is_refused_or_allowed():
  clip = _clip()
  fast = clip.positions.copy()
  fast[10:, I['right_hand'], 0] += 0.2    # 5 m/s for one frame at 25 fps.
  clip = clip.replace(positions=fast)
  station = layout.HUMAN_STATION_BESIDE
  with pytest.raises(clip_lib.ClipError,
                     match=r"clip 'made': right_hand moves at 5\.00 m/s at "
                     r't = 0\.36 s.*outside_human_model'):
    motions_lib.check_motions([clip], 'pick_place', (), station, V_MAX)
  assert motions_lib.check_motions([clip], 'pick_place', (), station, V_MAX,
                                   'allow') == [clip]
  with pytest.raises(ValueError, match="outside_human_model 'maybe'"):
    motions_lib.check_motions([clip], 'pick_place', (), station, V_MAX,
                              'maybe')


def test_clip_outside_the_workcell_is_refused():
  far = _clip().positions.copy()
  far[5:] += np.float32(1e30)
  with pytest.raises(clip_lib.ClipError,
                     match="keypoint 'pelvis' at frame 5 .*outside the "
                     'workcell'):
    motions_lib.check_motions([_clip(positions=far)], 'pick_place', (),
                              layout.HUMAN_STATION_BESIDE, V_MAX)


def test_non_finite_clip_is_refused():
  bad = _clip().positions.copy()
  bad[3, 0, 0] = np.nan
  with pytest.raises(clip_lib.ClipError,
                     match="field 'positions': non-finite value at frame 3"):
    clip_lib.validate(_clip(positions=bad), 'x')


def test_clip_waiting_for_other_events_than_the_tasks_is_refused():
  station = layout.HUMAN_STATION_BESIDE
  taken, placed = clip_lib.Event.object_taken, clip_lib.Event.object_placed
  phases = tuple(clip_lib.IdlePhase(keyframe=k, event=e, amplitudes=[0.2, 0.1],
                                    speeds=[0.1, 0.1])
                 for k, e in enumerate((taken, placed)))
  clip = _clip(keyframes=(5, 10), idle_phases=phases)
  assert motions_lib.check_motions([clip], 'pick_place', (taken, placed),
                                   station, V_MAX) == [clip]
  for events in ((), (placed, taken), (taken,)):
    expected = [str(e) for e in events]
    with pytest.raises(clip_lib.ClipError, match=re.escape(
        f"clip 'made': the task triggers the events {expected} in this "
        "order (its EVENTS), the clip's idle phases wait for "
        "['object_taken', 'object_placed']")):
      motions_lib.check_motions([clip], 'pick_place', events, station, V_MAX)


def test_clip_missing_its_tasks_targets_or_keyframes_is_refused():
  station = layout.HUMAN_STATION_ACROSS
  with pytest.raises(clip_lib.ClipError,
                     match=r"task 'hammering' needs the targets \['nail', "
                     r"'strike_grip'\]; the clip has none"):
    motions_lib.check_motions([_clip()], 'hammering', (), station, V_MAX)
  grasps = {'board_grasp_left': [0.3, 0.2, 0.9],
            'board_grasp_right': [0.3, -0.2, 0.9]}
  with pytest.raises(clip_lib.ClipError,
                     match="task 'lifting' needs at least 2 keyframes"):
    motions_lib.check_motions([_clip(targets=grasps)], 'lifting', (),
                              station, V_MAX)


@pytest.mark.parametrize('content', [b'', b'PK\x03\x04 truncated',
                                     b'not a zip file at all'])
def test_corrupt_npz_names_the_file(tmp_path, content):
  path = clip_lib.save_clip(_clip(), tmp_path)
  path.with_suffix('.npz').write_bytes(content)
  with pytest.raises(clip_lib.ClipError, match=r"made\.npz: field "
                     r"'positions': cannot read"):
    clip_lib.load_clip(path)
