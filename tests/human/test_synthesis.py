"""Tests for motion synthesis."""

import numpy as np
import pytest

from hrc_suite.human import body
from hrc_suite.human import clip as clip_lib
from hrc_suite.human import synthesis


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
  a = synthesis.synthesise(task, 1)
  b = synthesis.synthesise(task, 1)
  c = synthesis.synthesise(task, 2)
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
    synthesis.synthesise('juggling', 0)


def test_idle_phases_use_the_task_events():
  for task, events in clip_lib.TASK_EVENTS.items():
    clip = synthesis.synthesise(task, 0)
    assert tuple(p.event for p in clip.idle_phases) == events
