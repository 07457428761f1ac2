"""Tests for motion synthesis."""

import numpy as np
import pytest

from hrc_suite.human import body
from hrc_suite.human import clip as clip_lib
from hrc_suite.human import synthesis
from hrc_suite.motion_tools import synthetic_library


def test_minimum_jerk_profile():
  s = np.linspace(0, 1, 1001)
  p = synthesis.minimum_jerk(s)
  assert p[0] == 0 and p[-1] == 1
  v = np.gradient(p, s)
  assert v[0] == pytest.approx(0, abs=1e-2) and v[-1] == pytest.approx(
      0, abs=1e-2)
  assert v.max() == pytest.approx(synthesis.MIN_JERK_PEAK_RATIO, rel=1e-3)


@pytest.mark.parametrize('task', clip_lib.MOTION_TASKS)
def test_synthesis_is_deterministic(task):
  a = synthetic_library.synthesise(task, 1)
  b = synthetic_library.synthesise(task, 1)
  c = synthetic_library.synthesise(task, 2)
  np.testing.assert_array_equal(a.positions, b.positions)
  assert a.keyframes == b.keyframes and a.metadata == b.metadata
  assert a.positions.shape != c.positions.shape or not np.array_equal(
      a.positions, c.positions)


def test_script_reach_hits_target_at_end_of_move():
  rs = np.random.RandomState(0)
  script = synthesis.Script(body.proportional_body(1.7), rs, 'x', 'other')
  target = np.array([0.45, -0.1, 1.1])
  script.reach(1, target)
  script.hold(0.5)
  clip = script.render(fps=50)
  hand = clip.positions[-1, clip_lib.keypoints.KEYPOINT_INDEX['right_hand']]
  # Idle drift and sway move the hand by at most a couple of centimetres.
  assert np.linalg.norm(hand - target) < 0.03


def test_unknown_task_is_rejected():
  with pytest.raises(ValueError, match='juggling'):
    synthetic_library.synthesise('juggling', 0)


def test_idle_phases_use_the_task_events(library_events):
  assert library_events['stacking'] == (clip_lib.Event.second_cube_placed,
                                        clip_lib.Event.fourth_cube_placed)
  for task, events in library_events.items():
    clip = synthetic_library.synthesise(task, 0)
    assert tuple(p.event for p in clip.idle_phases) == events


def _moving_clip(speeds, fast_phases=(), keyframe=50, fps=25.0):
  """100 still frames; the left hand moves at speeds[i] m/s over interval i
  (frame i -> i + 1) for the intervals given."""
  positions = np.zeros((100, clip_lib.keypoints.NUM_KEYPOINTS, 3))
  hand = clip_lib.keypoints.KEYPOINT_INDEX['left_hand']
  steps = np.zeros(99)
  for i, v in speeds.items():
    steps[i] = v / fps
  positions[1:, hand, 0] = np.cumsum(steps)
  return clip_lib.Clip(
      name='moving', task='other', fps=fps,
      positions=positions.astype(np.float32), keyframes=(keyframe,),
      fast_phases=fast_phases)


def _with_idle(clip, amplitudes, speeds):
  phase = clip_lib.IdlePhase(keyframe=0, event='go',
                             amplitudes=np.array(amplitudes),
                             speeds=np.array(speeds))
  return clip.replace(idle_phases=(phase,))


def test_idle_speed_bound_is_window_speed_times_peak_rate():
  # Keyframe at 2 s; 1 m/s over frames 40-44, 5 m/s in a fast phase 60-63.
  base = _moving_clip({i: 1.0 for i in range(40, 44)}
                      | {i: 5.0 for i in range(60, 63)},
                      fast_phases=((60, 63),))
  # u = 0.4 s -> window 2 s +- 0.532 s = frames 36.7-63.3: sees the move,
  # not the fast phase. Peak rate (0.5 + 0.2) x 1.1**3.
  clip = _with_idle(base, [0.3, 0.1], [0.5, 0.2])
  phase = clip.idle_phases[0]
  assert synthesis.idle_window(phase) == pytest.approx(0.4 * 1.331)
  assert synthesis.idle_max_rate(phase) == pytest.approx(0.7 * 1.331)
  assert synthesis.idle_window_speed(clip, phase) == pytest.approx(1.0,
                                                                   rel=1e-3)
  assert synthesis.idle_speed_bound(clip, phase) == pytest.approx(
      0.7 * 1.331, rel=1e-3)
  # u = 0.14 s -> frames 45.3-54.7 (plus one frame): the move is outside.
  narrow = _with_idle(base, [0.1, 0.04], [0.5, 0.2])
  assert synthesis.idle_speed_bound(narrow, narrow.idle_phases[0]) == 0.0
  # Without the fast phase the blow counts.
  unmarked = _with_idle(base.replace(fast_phases=()), [0.3, 0.1], [0.5, 0.2])
  assert synthesis.idle_window_speed(
      unmarked, unmarked.idle_phases[0]) == pytest.approx(5.0, rel=1e-3)


def test_fit_idle_phases_slows_only_what_exceeds_the_limit():
  base = _moving_clip({i: 1.0 for i in range(40, 44)})
  calm = _with_idle(base, [0.3, 0.1], [0.3, 0.1])
  assert synthesis.fit_idle_phases(calm).idle_phases[0].speeds.tolist() == (
      [0.3, 0.1])
  brisk = _with_idle(base, [2.0, 1.0], [1.5, 0.5])   # bound 2.66 m/s
  fitted = synthesis.fit_idle_phases(brisk)
  phase = fitted.idle_phases[0]
  bound = synthesis.idle_speed_bound(fitted, phase)
  assert synthesis.IDLE_SPEED_LIMIT - 0.01 < bound <= (
      synthesis.IDLE_SPEED_LIMIT)
  np.testing.assert_allclose(phase.speeds / [1.5, 0.5], phase.speeds[0] / 1.5,
                             rtol=1e-2)
  np.testing.assert_array_equal(phase.amplitudes, [2.0, 1.0])
  assert fitted.metadata['idle_speed_scales'][0] == pytest.approx(
      1.9 / 2.662, rel=1e-3)


def test_fit_idle_phases_rejects_jitter_and_too_fast_clips():
  base = _moving_clip({i: 1.0 for i in range(40, 44)})
  # The reference's handover values: a 0.007 s sine at 70 Hz.
  jitter = _with_idle(base, [2.7, 0.007], [1.0, 3.1])
  with pytest.raises(ValueError, match='Hz'):
    synthesis.fit_idle_phases(jitter)
  fast = _with_idle(_moving_clip({i: 4.0 for i in range(40, 44)}),
                    [2.0, 1.0], [1.5, 0.5])
  with pytest.raises(ValueError, match='hold still longer'):
    synthesis.fit_idle_phases(fast)


def test_shipped_scripts_need_no_idle_slowing():
  # The authored idle values fit every synthesised clip as they are.
  for task in ('handover_robot_to_human', 'hammering', 'stacking'):
    clip = synthetic_library.synthesise(task, 0)
    assert clip.metadata['idle_speed_scales'] == [1.0] * len(
        clip.idle_phases)
    for phase in clip.idle_phases:
      assert synthesis.idle_speed_bound(clip, phase) <= (
          synthesis.IDLE_SPEED_LIMIT)
      assert synthesis.idle_max_hz(phase) <= synthesis.MAX_IDLE_HZ
