"""Path profiles (4, B6), bounds (3), advance (2) of docs/shield_maths.md."""

import numpy as np
import pytest

from hrc_suite.safety.shield import path as path_lib

CYCLE = 0.004


def _integrate_schedule(profile):
  """Velocity and acceleration at the end of the schedule, no clipping."""
  v, a, start = profile.s_dot, profile.s_ddot, 0.0
  for end, jerk in zip(profile.phase_ends, profile.phase_jerks):
    d = end - start
    v += a * d + 0.5 * jerk * d * d
    a += jerk * d
    start = end
  return v, a


def _peak_acceleration(profile):
  a, start, peak = profile.s_ddot, 0.0, abs(profile.s_ddot)
  for end, jerk in zip(profile.phase_ends, profile.phase_jerks):
    a += jerk * (end - start)
    start = end
    peak = max(peak, abs(a))
  return peak


def test_profile_grid_ends_at_target():
  """The original's grid (docs/shield_maths.md, 4): v in [0, 1], a in [-8,
  8), target in [0, 1], A=10, J=100."""
  for v in np.linspace(0.0, 1.0, 11):
    for a in np.arange(-8.0, 8.0, 0.5):
      for target in np.linspace(0.0, 1.0, 11):
        profile = path_lib.plan_profile(0.0, v, a, target, 10.0, 100.0, CYCLE)
        assert profile is not None, (v, a, target)
        v_end, a_end = _integrate_schedule(profile)
        assert abs(v_end - target) < 1e-6, (v, a, target, profile)
        assert abs(a_end) < 1e-2, (v, a, target, profile)
        # Bounds hold for the rounded schedule, and durations are whole cycles.
        assert _peak_acceleration(profile) <= 10.0 + 1e-9
        assert max(abs(j) for j in profile.phase_jerks) <= 100.0 * (1 + 1e-9)
        cycles = np.array(profile.phase_ends) / CYCLE
        np.testing.assert_allclose(cycles, np.round(cycles), atol=1e-6)


def test_consistent_threshold_b6():
  """The original's threshold let v=0.25, a=+-4, A=5, J=100 peak at 5.625."""
  for a in (4.0, -4.0):
    for target in (0.0, 1.0):
      profile = path_lib.plan_profile(0.0, 0.25, a, target, 5.0, 100.0, CYCLE)
      assert _peak_acceleration(profile) <= 5.0 + 1e-9
      sampled = profile.sample(np.arange(0, 400) * 1e-3)
      assert max(abs(x) for x in sampled[2]) <= 5.0 + 1e-9


def test_profile_refuses_impossible_requests():
  assert path_lib.plan_profile(0.0, 0.5, 6.0, 0.0, 5.0, 100.0, CYCLE) is None
  assert path_lib.plan_profile(0.0, 0.5, 0.0, 0.0, -1.0, 100.0, CYCLE) is None


def test_already_at_target_coasts_one_cycle():
  profile = path_lib.plan_profile(1.0, 1.0, 0.0, 1.0, 10.0, 100.0, CYCLE)
  assert profile.end_time() == pytest.approx(CYCLE)
  profile.advance(CYCLE)
  assert profile.s == pytest.approx(1.0 + CYCLE)
  assert profile.s_dot == pytest.approx(1.0)


def test_path_limits_examples():
  """docs/shield_maths.md, 3: Panda-like limits a=10, j=400, a_ltt=2,
  j_ltt=15."""
  a_max, j_max = [10.0] * 7, [400.0] * 7
  a_ltt, j_ltt = [2.0] * 7, [15.0] * 7
  acc, jerk = path_lib.path_limits([0.0] * 7, a_max, j_max, a_ltt, j_ltt, 0.2)
  assert acc == pytest.approx(20.0, rel=1e-6)
  assert jerk == pytest.approx(662.5, rel=1e-6)
  moving = [1.0] + [0.0] * 6
  acc, jerk = path_lib.path_limits(moving, a_max, j_max, a_ltt, j_ltt, 0.2)
  assert acc == pytest.approx(8.0 / 1.4, rel=1e-6)
  assert jerk == pytest.approx((400.0 - 3 * 2 * 8.0 / 1.4 - 15.0) / 1.4,
                               rel=1e-6)
  # The unit test of the original uses j_ltt = 10.
  acc, jerk = path_lib.path_limits([0.0], [10.0], [400.0], [2.0], [10.0], 0.2)
  assert jerk == pytest.approx((400.0 - 120.0 - 10.0) / 0.4, rel=1e-6)


def test_advance_matches_sample_and_never_reverses():
  rng = np.random.RandomState(3)
  for _ in range(200):
    v, a = rng.uniform(0, 1), rng.uniform(-8, 8)
    profile = path_lib.plan_profile(0.0, v, a, rng.uniform(0, 1), 10.0,
                                    100.0, CYCLE)
    times = np.arange(80) * CYCLE
    s, s_dot, s_ddot, _ = profile.sample(times)
    walker = profile.copy()
    for i in range(len(times)):
      assert walker.s == pytest.approx(s[i], abs=1e-12)
      assert walker.s_dot == pytest.approx(s_dot[i], abs=1e-9)
      assert walker.s_ddot == pytest.approx(s_ddot[i], abs=1e-7)
      walker.advance(CYCLE)
    assert np.all(np.diff(s) >= -1e-15)
    assert min(s_dot) >= 0.0


def test_stop_when_velocity_would_turn_negative():
  # At rest with a large braking acceleration: the path must not go back.
  path = path_lib.Path(2.0, 0.01, -5.0, 0.0, (0.1, 0.1, 0.1), (0.0, 0.0, 0.0))
  path.advance(0.05)
  assert path.s_dot == 0.0 and path.s_ddot == 0.0 and path.jerk == 0.0
  assert path.s == pytest.approx(2.0 + 0.01 ** 2 / (2 * 5.0))
  path.advance(1.0)
  assert path.s == pytest.approx(2.0 + 0.01 ** 2 / (2 * 5.0))


def test_after_schedule_path_coasts():
  profile = path_lib.plan_profile(0.0, 0.2, 0.0, 0.6, 10.0, 100.0, CYCLE)
  end = profile.end_time()
  s_end, v_end, a_end = profile.final()
  profile.advance(end + 0.1)
  assert profile.s_ddot == 0.0 and profile.jerk == 0.0
  assert profile.s_dot == pytest.approx(0.6)
  assert profile.s == pytest.approx(s_end + 0.1 * v_end)


def test_max_s_dot_finds_interior_peak():
  # Positive acceleration then braking: the peak is inside the first phase.
  profile = path_lib.plan_profile(0.0, 0.5, 6.0, 0.0, 10.0, 100.0, CYCLE)
  dense = profile.sample(np.linspace(0.0, profile.end_time(), 5001))[1]
  assert profile.max_s_dot() == pytest.approx(max(dense), abs=1e-6)
  later = profile.sample(np.linspace(0.05, profile.end_time(), 5001))[1]
  assert profile.max_s_dot(0.05) == pytest.approx(max(later), abs=1e-6)


def test_bad_schedule_is_refused():
  with pytest.raises(ValueError, match='non-decreasing'):
    path_lib.Path(0, 0, 0, 0, (0.2, 0.1, 0.3), (0, 0, 0))
