"""Tests for the motion clip format: validation, save/load round trip."""

import json

import numpy as np
import pytest

from hrc_suite.human import clip as clip_lib
from hrc_suite.human import keypoints


def make_clip(name='walk', num_frames=50, fps=100.0, **changes):
  rng = np.random.RandomState(0)
  base = rng.uniform(-0.5, 1.5, size=(keypoints.NUM_KEYPOINTS, 3))
  drift = np.linspace(0.0, 0.3, num_frames)[:, None, None] * np.array(
      [1.0, 0.0, 0.0])
  fields = dict(
      name=name, task='handover_human_to_robot', fps=fps,
      positions=(base[None] + drift).astype(np.float32),
      keyframes=(10, 30),
      idle_phases=(clip_lib.IdlePhase(
          keyframe=0, event='object_taken',
          amplitudes=np.array([2.7, 0.007]), speeds=np.array([1.0, 3.1])),),
      holding_hand='right', placing_hand=None,
      targets={'handover_point': np.array([0.5, -0.1, 1.1])},
      fast_phases=((40, 45),),
      metadata={'source': 'test', 'seed': 3})
  fields.update(changes)
  return clip_lib.Clip(**fields)


def test_valid_clip_passes_and_has_duration():
  clip = clip_lib.validate(make_clip())
  assert clip.num_frames == 50
  assert clip.duration == pytest.approx(0.49)
  assert clip.keyframe_time(1) == pytest.approx(0.3)


def test_round_trip_is_exact(tmp_path):
  clip = make_clip()
  json_path = clip_lib.save_clip(clip, tmp_path)
  assert json_path == tmp_path / 'walk.json'
  assert (tmp_path / 'walk.npz').is_file()
  for path in (json_path, tmp_path / 'walk.npz', tmp_path / 'walk'):
    loaded = clip_lib.load_clip(path)
    assert loaded.name == clip.name and loaded.task == clip.task
    assert loaded.fps == clip.fps
    np.testing.assert_array_equal(loaded.positions, clip.positions)
    assert loaded.positions.dtype == np.float32
    assert loaded.keyframes == clip.keyframes
    assert loaded.fast_phases == clip.fast_phases
    assert loaded.holding_hand == 'right' and loaded.placing_hand is None
    np.testing.assert_array_equal(loaded.targets['handover_point'],
                                  clip.targets['handover_point'])
    (phase,) = loaded.idle_phases
    assert phase.event == 'object_taken' and phase.keyframe == 0
    np.testing.assert_array_equal(phase.amplitudes, [2.7, 0.007])
    np.testing.assert_array_equal(phase.speeds, [1.0, 3.1])
    assert phase.amplitude_std_factor == 1.1
    assert loaded.metadata == clip.metadata


def test_npz_holds_no_objects(tmp_path):
  clip_lib.save_clip(make_clip(), tmp_path)
  with np.load(tmp_path / 'walk.npz', allow_pickle=False) as npz:
    assert list(npz.keys()) == ['positions']


@pytest.mark.parametrize('changes, field', [
    (dict(name='a/b'), 'name'),
    (dict(task='dancing'), 'task'),
    (dict(fps=0.0), 'fps'),
    (dict(positions=np.zeros((50, 3, 3), np.float32)), 'positions'),
    (dict(positions=np.zeros((1, keypoints.NUM_KEYPOINTS, 3))), 'positions'),
    (dict(positions=np.full((50, keypoints.NUM_KEYPOINTS, 3), np.nan)),
     'positions'),
    (dict(keyframes=(30, 10)), 'keyframes'),
    (dict(keyframes=(10, 50)), 'keyframes'),
    (dict(keyframes=(10.5, 30)), 'keyframes'),
    (dict(holding_hand='middle'), 'holding_hand'),
    (dict(placing_hand='LEFT'), 'placing_hand'),
    (dict(targets={'p': np.zeros(2)}), "targets['p']"),
    (dict(fast_phases=((45, 40),)), 'fast_phases[0]'),
    (dict(fast_phases=((40, 60),)), 'fast_phases[0]'),
    (dict(metadata={'bad': object()}), 'metadata'),
])
def test_validation_names_the_field(changes, field):
  with pytest.raises(clip_lib.ClipError) as info:
    clip_lib.validate(make_clip(**changes), source='my_clip.json')
  assert 'my_clip.json' in str(info.value)
  assert repr(field) in str(info.value)


@pytest.mark.parametrize('phase_changes, field', [
    (dict(keyframe=2), 'idle_phases[0].keyframe'),
    (dict(event='not an event'), 'idle_phases[0].event'),
    (dict(amplitudes=np.array([1.0])), 'idle_phases[0].amplitudes'),
    (dict(amplitudes=np.array([1.0, -1.0])), 'idle_phases[0].amplitudes'),
    (dict(speeds=np.array([1.0, 2.0, 3.0])), 'idle_phases[0].speeds'),
    (dict(speed_std_factor=0.9), 'idle_phases[0].speed_std_factor'),
])
def test_idle_phase_validation(phase_changes, field):
  fields = dict(keyframe=0, event='object_taken',
                amplitudes=np.array([1.0, 0.1]), speeds=np.array([1.0, 3.0]))
  fields.update(phase_changes)
  clip = make_clip(idle_phases=(clip_lib.IdlePhase(**fields),))
  with pytest.raises(clip_lib.ClipError, match=repr(field).replace('[', r'\[')):
    clip_lib.validate(clip)


def test_idle_phases_must_be_in_keyframe_order():
  phases = tuple(clip_lib.IdlePhase(k, event, [1.0, 0.1], [1.0, 3.0])
                 for k, event in ((1, 'object_taken'), (0, 'object_placed')))
  with pytest.raises(clip_lib.ClipError, match='keyframe order'):
    clip_lib.validate(make_clip(idle_phases=phases))
  # Any identifier-like event is fine for clips of no benchmark task.
  clip_lib.validate(make_clip(task='other', idle_phases=(
      clip_lib.IdlePhase(0, 'door_opened', [1.0, 0.1], [1.0, 3.0]),)))


def test_load_reports_file_and_field(tmp_path):
  clip_lib.save_clip(make_clip(), tmp_path)
  path = tmp_path / 'walk.json'
  data = json.loads(path.read_text())
  data['keyframes'] = [10, 99]
  path.write_text(json.dumps(data))
  with pytest.raises(clip_lib.ClipError, match=r'walk\.json.*keyframes'):
    clip_lib.load_clip(path)
  del data['fps']
  path.write_text(json.dumps(data))
  with pytest.raises(clip_lib.ClipError, match=r"walk\.json.*'fps'.*missing"):
    clip_lib.load_clip(path)
  path.write_text('{not json')
  with pytest.raises(clip_lib.ClipError, match='not valid JSON'):
    clip_lib.load_clip(path)


def test_load_rejects_frame_count_mismatch_and_missing_npz(tmp_path):
  clip_lib.save_clip(make_clip(), tmp_path)
  path = tmp_path / 'walk.json'
  data = json.loads(path.read_text())
  data['num_frames'] = 49
  path.write_text(json.dumps(data))
  with pytest.raises(clip_lib.ClipError, match='num_frames'):
    clip_lib.load_clip(path)
  (tmp_path / 'walk.npz').unlink()
  with pytest.raises(clip_lib.ClipError, match=r'walk\.npz.*missing'):
    clip_lib.load_clip(path)


def test_load_folder_sorted_and_errors(tmp_path):
  for name in ('b', 'a', 'c'):
    clip_lib.save_clip(make_clip(name=name), tmp_path)
  assert [c.name for c in clip_lib.load_folder(tmp_path)] == ['a', 'b', 'c']
  (tmp_path / 'empty').mkdir()
  with pytest.raises(clip_lib.ClipError, match='no clips'):
    clip_lib.load_folder(tmp_path / 'empty')
  (tmp_path / 'b.npz').unlink()
  with pytest.raises(clip_lib.ClipError, match=r'b\.npz'):
    clip_lib.load_folder(tmp_path)
  with pytest.raises(clip_lib.ClipError, match='not a folder'):
    clip_lib.load_folder(tmp_path / 'missing')


def test_shipped_library_unknown_task_lists_valid_ones():
  with pytest.raises(ValueError, match='handover_robot_to_human'):
    clip_lib.shipped_library('juggling')


def test_speed_violations_skip_fast_phases():
  clip = make_clip(fast_phases=())
  positions = clip.positions.copy()
  positions[20:, 0, 0] += 0.05   # a 5 m/s jump between frames 19 and 20.
  positions[42:, 1, 1] += 0.05   # another between frames 41 and 42.
  clip = clip.replace(positions=positions)
  assert clip_lib.speed_violations(clip).tolist() == [19, 41]
  clip = clip.replace(fast_phases=((40, 45),))
  assert clip_lib.speed_violations(clip).tolist() == [19]
  speeds = clip_lib.keypoint_speeds(clip)
  assert speeds.shape == (49, keypoints.NUM_KEYPOINTS)
  # The jump adds to the steady drift of 0.3 m over 49 frames along x.
  assert speeds[19, 0] == pytest.approx((0.05 + 0.3 / 49) * 100, rel=1e-4)
  assert speeds[18, 0] == pytest.approx(0.3 / 49 * 100, rel=1e-4)
