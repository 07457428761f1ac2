"""compare: statistics on motions with known answers, the report, and one
real folder (the recordings, tests/conftest.py)."""

import math

from absl import flags
import numpy as np
import pytest

from hrc_suite.human import clip as clip_lib
from hrc_suite.human import keypoints
from hrc_suite.human import recording_cache
from hrc_suite.human import synthesis
from hrc_suite.motion_tools import compare

K = keypoints.KEYPOINT_INDEX
STATION = (1.45, 0.0, math.pi)   # layout.HUMAN_STATION_ACROSS
LIMITS = (np.full(keypoints.NUM_KEYPOINTS, 2.0),
          np.full(keypoints.NUM_KEYPOINTS, 50.0))


def _still(seconds, fps):
  """Every keypoint at (0, 0, 1) m, the chest at (0, 0, 1.3) m."""
  frames = int(round(seconds * fps)) + 1
  pos = np.zeros((frames, keypoints.NUM_KEYPOINTS, 3))
  pos[..., 2] = 1.0
  pos[:, K['chest'], 2] = 1.3
  return pos


def _clip(positions, fps, task='reach', **kwargs):
  return clip_lib.Clip(name='test', task=task, fps=fps,
                       positions=positions, **kwargs)


def test_resampling_a_100_fps_clip_keeps_every_fourth_frame():
  pos = np.random.RandomState(0).uniform(-1, 1, (101, 19, 3))
  clip = _clip(pos, 100.0)
  np.testing.assert_allclose(compare.resample(clip), clip.positions[::4],
                             atol=1e-6)


def test_constant_velocity():
  # The left hand moves at 0.5 m/s for 2 s, the right hand rests: pooled
  # over both hands the median speed is halfway, p95 and peak 0.5 m/s, and
  # nothing accelerates.
  pos = _still(2.0, 50.0)
  pos[:, K['left_hand'], 0] += 0.5 * np.arange(len(pos)) / 50.0
  stats = compare.clip_statistics(_clip(pos, 50.0), STATION, LIMITS)
  assert stats['hand_speed_peak'] == pytest.approx(0.5, rel=1e-4)
  assert stats['hand_speed_p95'] == pytest.approx(0.5, rel=1e-4)
  assert stats['hand_speed_median'] == pytest.approx(0.25, rel=1e-4)
  assert stats['hand_accel_peak'] == pytest.approx(0.0, abs=1e-3)
  assert stats['over_v_max'] == 0.0 and stats['over_a_max'] == 0.0
  assert stats['duration'] == pytest.approx(2.0)
  assert math.isnan(stats['idle_speed_peak'])
  assert math.isnan(stats['time_to_event'])


def test_constant_acceleration_survives_the_smoothing():
  # x = a t^2 / 2 at 100 fps: resampled to 25 fps and smoothed, the second
  # difference is a exactly. Interval i's speed a (i + 1/2) / 25 exceeds
  # 2 m/s from i = 33 on: 17 of the 50 intervals.
  a = 1.5
  t = np.arange(201) / 100.0
  pos = _still(2.0, 100.0)
  pos[:, K['left_hand'], 0] += 0.5 * a * t**2
  stats = compare.clip_statistics(_clip(pos, 100.0), STATION, LIMITS)
  assert stats['hand_accel_peak'] == pytest.approx(a, rel=1e-3)
  assert stats['hand_accel_p95'] == pytest.approx(a, rel=1e-3)
  assert stats['hand_speed_peak'] == pytest.approx(a * (2.0 - 0.02),
                                                   rel=1e-4)
  assert stats['over_v_max'] == pytest.approx(100.0 * 17 / 50)
  assert stats['over_a_max'] == 0.0


def test_smoothing_removes_a_single_frame_spike():
  pos = _still(2.0, 25.0)
  pos[25, K['right_hand'], 2] += 0.004   # a 4 mm glitch
  raw = np.linalg.norm(pos[2:] - 2 * pos[1:-1] + pos[:-2], axis=-1)
  accel = compare.accelerations(pos)
  assert raw.max() * 625 == pytest.approx(5.0)
  assert accel.max() == pytest.approx(5.0 / 6)


def test_reach_and_closest_approach_at_the_station():
  # Across the table (x 1.45 m, facing -x) a hand 0.5 m ahead of the
  # station at 1.0 m stands at world (0.95, 0, 1.0): 0.967 m from the base
  # (0, 0, 0.82).
  pos = _still(1.0, 25.0)
  pos[:, K['right_hand']] = (0.5, 0.0, 1.0)
  pos[:, K['left_hand']] = (0.2, 0.3, 1.0)
  stats = compare.clip_statistics(_clip(pos, 25.0), STATION, LIMITS)
  assert stats['reach_forward'] == pytest.approx(0.5)
  assert stats['reach_chest'] == pytest.approx(math.hypot(0.5, 0.3))
  assert stats['closest_to_robot'] == pytest.approx(math.hypot(0.95, 0.18))
  np.testing.assert_allclose(
      compare.world_positions([0.5, 0.2, 1.0], (0.55, 1.05, -math.pi / 2)),
      [0.75, 0.55, 1.0], atol=1e-12)


def test_idle_statistics_cover_the_warp_window_without_fast_phases():
  # An inspection clip waits at 5 s; its warp replays 5 s +- 0.75 x 1.1^3
  # = 4.0-6.0 s. The hand moves at 0.2 m/s within 3-7 s, at 1 m/s outside
  # and 5 m/s in a fast phase at 5.0-5.2 s (left out, like hammer blows).
  fps = 25.0
  pos = _still(10.0, fps)
  velocity = np.where((np.arange(len(pos) - 1) >= 75)
                      & (np.arange(len(pos) - 1) < 175), 0.2, 1.0)
  velocity[125:130] = 5.0
  pos[1:, K['left_hand'], 0] += np.cumsum(velocity) / fps
  phase = clip_lib.IdlePhase(keyframe=0, event='object_presented',
                             amplitudes=[0.6, 0.15], speeds=[0.5, 0.25])
  clip = _clip(pos, fps, task='inspection', keyframes=(125,),
               idle_phases=(phase,), fast_phases=((125, 130),))
  assert compare.idle_windows(clip)[0] == pytest.approx((4.00175, 5.99825))
  stats = compare.clip_statistics(clip, STATION, LIMITS)
  assert stats['idle_speed_peak'] == pytest.approx(0.2, rel=1e-4)
  assert stats['idle_speed_median'] == pytest.approx(0.2, rel=1e-4)
  assert stats['idle_bound'] == pytest.approx(0.2 * 0.75 * 1.1**3, rel=1e-4)
  assert stats['idle_bound'] == pytest.approx(
      synthesis.idle_speed_bound(clip, phase))
  assert stats['time_to_event'] == pytest.approx(5.0)


def test_time_to_event_per_task():
  pos = _still(10.0, 25.0)
  lifting = _clip(pos, 25.0, task='lifting', keyframes=(10, 200))
  assert compare.time_to_event(lifting) == pytest.approx(0.4)
  pick_place = _clip(pos, 25.0, task='pick_place', keyframes=(10, 200))
  assert math.isnan(compare.time_to_event(pick_place))


def _report_rows():
  moving = _still(2.0, 25.0)
  moving[:, K['left_hand'], 0] += 0.4 * np.arange(len(moving)) / 25.0
  real = [_clip(moving, 25.0, task='lifting', keyframes=(0, 50))]
  synthetic = [_clip(_still(2.0, 25.0), 25.0, task='lifting',
                     keyframes=(25, 50))] * 2
  return compare.compare({'lifting': real}, {'lifting': synthetic},
                         stations={'lifting': STATION})


def test_compare_summarises_per_task_and_statistic():
  rows = {r['statistic']: r for r in _report_rows()}
  assert set(rows) == set(compare.UNITS)
  peak = rows['hand_speed_peak']
  assert peak['real'] == pytest.approx((0.4, 0.4, 0.4), rel=1e-4)
  assert peak['synthetic'] == pytest.approx((0.0, 0.0, 0.0))
  assert (peak['real_count'], peak['synthetic_count']) == (1, 2)
  assert compare.verdict(peak) == 'below'
  assert compare.verdict(rows['time_to_event']) == 'above'
  assert compare.verdict(rows['duration']) == 'inside'
  assert compare.verdict(rows['idle_bound']) == ''


def test_report_replaces_only_its_part(tmp_path):
  path = tmp_path / 'doc.md'
  path.write_text('# Doc\n\nhand-written\n\n<!-- compare:begin -->\nold\n'
                  '<!-- compare:end -->\n\nafter\n')
  rows = _report_rows()
  for _ in range(2):
    compare.write_report(rows, path, 'cmd --x', commit='abc1234',
                         host='test machine', date='2026-01-02')
  text = path.read_text()
  assert text.startswith('# Doc\n\nhand-written\n\n<!-- compare:begin -->')
  assert text.endswith('<!-- compare:end -->\n\nafter\n')
  assert text.count('compare:begin') == 1 and 'old' not in text
  assert ('`cmd --x` at commit abc1234 on 2026-01-02 (UTC), test machine'
          in text)
  assert '**lifting** (1 recordings, 2 synthetic clips)' in text
  assert '| hand speed, peak (m/s) | 0.40 (0.40-0.40) | 0.00 (0.00-0.00) ' \
      '| below |' in text
  assert ('| waiting: fastest keypoint as recorded, peak (m/s) | - | - |  |'
          in text)
  new = compare.write_report(rows, tmp_path / 'new.md', 'cmd')
  assert new.read_text().startswith('# Motion library\n\n<!-- compare:')


def test_missing_recordings_folder_is_reported(tmp_path):
  with pytest.raises(FileNotFoundError, match='no task folders'):
    compare.load_recordings(tmp_path)
  with pytest.raises(FileNotFoundError, match='no such folder'):
    compare.load_recordings(tmp_path / 'absent')


@pytest.mark.recordings
def test_command_on_a_real_folder(tmp_path, monkeypatch, recordings_dir):
  monkeypatch.setenv(recording_cache.CACHE_ENV, str(tmp_path / 'cache'))
  recordings = tmp_path / 'recordings'
  recordings.mkdir()
  (recordings / 'ObjectInspection').symlink_to(
      recordings_dir / 'ObjectInspection')
  out = tmp_path / 'doc.md'
  flag_values = flags.FlagValues()
  compare.define_flags(flag_values)
  flag_values(['compare', f'--recordings={recordings}', f'--out={out}'])
  compare.main(['compare'], flag_values)
  text = out.read_text()
  count = len(list((recordings_dir / 'ObjectInspection').glob('*.bvh')))
  assert f'**inspection** ({count} recordings, 8 synthetic clips)' in text
  assert f'--recordings={recordings}' in text
  # The recordings as placed: people at the station, hands below the
  # shield's 2 m/s, waiting for the object after a few seconds.
  real = {r['statistic']: r['real'] for r in compare.compare(
      compare.load_recordings(recordings),
      {'inspection': clip_lib.shipped_library('inspection')})}
  assert 0.5 < real['hand_speed_peak'][2] < 2.0
  assert 0.5 < real['closest_to_robot'][1] < 1.5
  assert 0.0 < real['time_to_event'][1] < 10.0
  assert 0.0 < real['idle_bound'][2] <= synthesis.IDLE_SPEED_LIMIT
