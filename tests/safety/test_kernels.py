"""The compiled kernels against their NumPy references (random inputs)."""

import numpy as np
import pytest

from hrc_suite import robot_description
from hrc_suite.safety import geometry
from hrc_suite.safety import kernels
from hrc_suite.safety import long_term_plan as ltp
from hrc_suite.safety import robot_reach
from hrc_suite.safety.shield import human_reach
from hrc_suite.safety.shield import shield as shield_lib
from hrc_suite.safety.shield import speed_kernels
from hrc_suite.safety.shield import verification

import safety_references

TOOL = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.12), 0.06)


def _special_segments(rng):
  """Segment pairs (a0, a1, b0, b1) in the cases with explicit branches:
  parallel (overlapping, disjoint, anti-parallel), collinear, nearly
  parallel, point segments, identical segments."""
  out = []
  for _ in range(40):
    a0 = rng.uniform(-1, 1, 3)
    d = rng.normal(size=3)
    offset = rng.normal(size=3) * rng.choice([0.0, 1e-9, 0.3])
    shift = rng.uniform(-2, 2)
    b0 = a0 + shift * d + offset
    out.append((a0, a0 + d, b0, b0 + rng.uniform(-2, 2) * d))   # Parallel.
    out.append((a0, a0 + d, b0, b0 + d + 1e-8 * rng.normal(size=3)))
    out.append((a0, a0, b0, b0 + d))                             # Point a.
    out.append((a0, a0 + d, b0, b0.copy()))                      # Point b.
    out.append((a0, a0.copy(), b0, b0.copy()))                   # Two points.
    out.append((a0, a0 + d, a0.copy(), a0 + d))                  # Same.
  return out


def test_segment_distance_matches_geometry_including_b3_cases():
  rng = np.random.RandomState(0)
  pairs = _special_segments(rng) + [
      tuple(rng.uniform(-1, 1, (4, 3))) for _ in range(2000)]
  a0, a1, b0, b1 = (np.array(x) for x in zip(*pairs))
  expected = geometry.segment_distance(a0, a1, b0, b1)
  got = np.array([kernels.segment_distance(*p0, *q0, *(p1 - p0), *(q1 - q0))
                  for p0, p1, q0, q1 in zip(a0, a1, b0, b1)])
  np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12)
  # The overlapping parallel case of defect B3 (docs/shield_maths.md, 10):
  # distance 1, not more.
  assert kernels.segment_distance(0, 0, 0, 1, 1, 0, 2, 0, 0, 2, 0,
                                  0) == pytest.approx(1.0, abs=1e-15)


def _random_capsules(rng, k, l, m, b, spread):
  rc1 = rng.uniform(-spread, spread, (k, l, 3))
  rc2 = rc1 + rng.normal(0, 0.3, (k, l, 3))
  rr = rng.uniform(0, 0.2, (k, l))
  hc1 = rng.uniform(-spread, spread, (m, k, b, 3))
  hc2 = hc1 + rng.normal(0, 0.3, (m, k, b, 3))
  hr = rng.uniform(0, 0.2, (m, k, b))
  kind = rng.randint(4)
  if kind == 1:     # Ball bodies (degenerate segments).
    hc2 = hc1.copy()
  elif kind == 2:   # Bodies parallel to a robot capsule.
    hc2 = hc1 + (rc2 - rc1)[None, :, :1] * rng.uniform(-2, 2)
  elif kind == 3:   # Robot capsules collapsed to balls.
    rc2 = rc1.copy()
  return (rc1, rc2, rr), (hc1, hc2, hr)


def test_ssm_verdict_kernels_match_reference():
  rng = np.random.RandomState(1)
  verdicts = set()
  for i in range(400):
    shape = (rng.randint(1, 9), rng.randint(1, 9), rng.choice([1, 3]),
             rng.randint(1, 14))
    robot, human = _random_capsules(rng, *shape, spread=rng.choice([1, 3]))
    expected = verification.ssm_verdict(robot, human)
    safe, first, distance = verification.ssm_verdict(robot, human,
                                                     compiled=True)
    assert (safe, first) == expected[:2]
    assert distance == pytest.approx(expected[2], abs=1e-12)
    assert verification.first_unsafe_interval(robot, human) == expected[1]
    np.testing.assert_allclose(
        kernels.ssm_clearances(*robot, *human),
        verification.clearances(robot, human), rtol=0, atol=1e-12)
    verdicts.add(safe)
  assert verdicts == {True, False}   # Both outcomes were exercised.


def test_ssm_kernel_on_the_b3_and_touching_cases():
  # Overlapping parallel capsules intersect (B3); touching ones do not.
  robot = tuple(np.array(x, dtype=float)[None, None] for x in (
      (0, 0, 0), (2, 0, 0), 0.5))
  human = tuple(np.array(x, dtype=float)[None, None, None] for x in (
      (1, 1, 0), (3, 1, 0), 0.55))
  assert verification.first_unsafe_interval(robot, human) == 0
  touching = (human[0], human[1], np.full((1, 1, 1), 0.5))
  assert verification.first_unsafe_interval(robot, touching) == -1
  assert verification.ssm_verdict(robot, touching, compiled=True)[2] == 0.0


@pytest.mark.parametrize('name', robot_description.ROBOT_NAMES)
@pytest.mark.parametrize('tool', [None, TOOL])
def test_robot_reach_and_surface_speeds_match_reference(name, tool):
  description = robot_description.load(name)
  robot = robot_reach.RobotReach(description, tool_capsule=tool,
                                 base_pose=(0.1, -0.2, 0.7, 0.1, 0.2, 0.3))
  rng = np.random.RandomState(2)
  for _ in range(20):
    k = rng.randint(1, 12)
    q = rng.uniform(description.limits.q_min, description.limits.q_max,
                    (k + 1, description.dof))
    s = np.cumsum(rng.uniform(0, 0.05, k + 1))
    for got, expected in zip(robot.reach_capsules(q, s),
                             robot.reach_capsules(q, s, compiled=False)):
      np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12)
    dq = rng.uniform(-1, 1, (2, k + 1, description.dof))
    np.testing.assert_allclose(
        robot.surface_speeds(q, dq),
        robot.surface_speeds(q, dq, compiled=False), rtol=0, atol=1e-12)


@pytest.mark.parametrize('combined', [True, False])
@pytest.mark.parametrize('kalman', [True, False])
def test_human_reach_capsules_match_reference(combined, kalman):
  human = human_reach.HumanReach(use_kalman_filter=kalman,
                                 use_combined_model=combined)
  rng = np.random.RandomState(3)
  points = rng.uniform(-1, 1, (human.num_keypoints, 3))
  for i in range(30):
    # Mostly slow motions; every fifth sample a jump faster than v_max.
    step = 0.3 if i % 5 == 4 else 0.005
    points = points + rng.normal(0, step, points.shape)
    human.measure(points, 0.004 * i)
    t_edges = np.concatenate([[0.0], np.cumsum(rng.uniform(0, 0.03, 11))])
    got = human.reach_capsules(0.004 * i + 0.002, t_edges)
    expected = human.reach_capsules(0.004 * i + 0.002, t_edges,
                                    compiled=False)
    for x, y in zip(got, expected):
      assert x.shape == y.shape
      # Relative: speeds of the jumps reach ~100 m/s (radii of metres).
      np.testing.assert_allclose(x, y, rtol=1e-13, atol=1e-12)


def test_shield_broad_phases_match_reference():
  shield = shield_lib.Shield('panda', tool_capsule=TOOL)
  rng = np.random.RandomState(4)
  human = shield.human
  base = rng.uniform(-1, 1, (human.num_keypoints, 3))
  for i in range(20):
    human.measure(base + rng.normal(0, 0.01 * (1 + i % 3), base.shape),
                  0.004 * i)
    now = 0.004 * i + 0.001
    horizon = rng.uniform(0, 0.3)
    config = human.config
    age = (now - human.last_measurement_time + config.delay
           + horizon)
    terms = shield.terms
    centre, radius, gap = kernels.horizon_balls(
        human.positions, human.velocities, terms.human_v_max,
        terms.body_ends, terms.half_thickness, age,
        config.measurement_error_pos, terms.base)
    ref_centre, ref_radius = safety_references.horizon_balls(shield, now,
                                                             horizon)
    np.testing.assert_allclose(centre, ref_centre, rtol=0, atol=1e-12)
    np.testing.assert_allclose(radius, ref_radius, rtol=0, atol=1e-12)
    assert gap == pytest.approx(
        (np.linalg.norm(ref_centre - terms.base, axis=1)
         - ref_radius).min(), abs=1e-12)
    q = rng.uniform(-1, 1, (6, 7))
    capsules = shield.robot.reach_capsules(q, np.arange(6) * 0.02)
    # The reference's |a|^2 + |b|^2 - 2 a.b form loses ~1e-15 m.
    assert kernels.balls_capsules_distance(
        centre, radius, *capsules) - shield_lib._BROAD_PHASE_SLACK == (
            pytest.approx(
            safety_references.balls_capsules_distance(
                centre, radius, capsules), abs=1e-12))


@pytest.mark.parametrize('name', robot_description.ROBOT_NAMES)
@pytest.mark.parametrize('tool', [None, TOOL])
def test_swept_balls_gap_bounds_the_reach_capsules_test(name, tool):
  """The bound from one forward kinematics (docs/shield_maths.md, 5.3)
  never exceeds balls_capsules_distance on the reach capsules, so it
  settles only cycles that test settles; without motion it is that test
  up to the curvature term and its round-off allowance."""
  description = robot_description.load(name)
  robot = robot_reach.RobotReach(description, tool_capsule=tool,
                                 base_pose=(0.1, -0.2, 0.7, 0.1, 0.2, 0.3))
  limits = description.limits
  rng = np.random.RandomState(5)
  fixed, points = robot.kernel_model
  rest = (points, robot.kernel_frames, robot.kernel_alpha,
          robot.kernel_static, robot.kernel_levers,
          robot.kernel_half_lengths)

  def gap(q, s, centre, radius, stop=-np.inf):
    frames = kernels._frames(q[:1], fixed)[0]   # One forward kinematics.
    return kernels.swept_balls_gap(q, s, frames, *rest, centre, radius, stop)

  positive = 0
  for trial in range(300):
    k = rng.randint(1, 10)
    start = rng.uniform(limits.q_min, limits.q_max)
    # Paths of a shield cycle (steps of up to ~0.1 rad between edges)
    # and, every third trial, wild ones.
    scale = 1.0 if trial % 3 == 0 else 0.1
    q = start + np.cumsum(rng.uniform(-scale, scale,
                                      (k + 1, description.dof)), axis=0)
    q[0] = start
    s = np.cumsum(rng.uniform(0, 0.05, k + 1))
    centre = rng.uniform(-1.5, 1.5, (rng.randint(1, 15), 3))
    radius = rng.uniform(0.0, 0.4, centre.shape[0])
    bound = gap(q, s, centre, radius)
    test = kernels.balls_capsules_distance(centre, radius,
                                           *robot.reach_capsules(q, s))
    assert bound <= test
    positive += bound > 0.0
    # Stopped at the first pair at or below 0: the same verdict, and the
    # same bound where it is positive.
    early = gap(q, s, centre, radius, 0.0)
    assert early == bound if bound > 0.0 else early <= 0.0
  assert positive > 30   # Not a vacuous bound.
  # Placed just outside the reach capsules' ball that lies farthest from
  # the link's midpoint at q[0], a point is within 1 mm of the test's
  # bound: the bound must not be above (it is, without its radius terms).
  for _ in range(100):
    k = rng.randint(1, 10)
    start = rng.uniform(limits.q_min, limits.q_max)
    q = start + np.cumsum(rng.uniform(-0.1, 0.1, (k + 1, description.dof)),
                          axis=0)
    q[0] = start
    s = np.cumsum(rng.uniform(0, 0.05, k + 1))
    c1, c2, r = robot.reach_capsules(q, s)
    middle = 0.5 * (c1 + c2)
    ball = 0.5 * np.linalg.norm(c2 - c1, axis=-1) + r
    p1, p2, _ = robot.capsules(q[0])
    offset = middle - 0.5 * (p1 + p2)
    far = np.unravel_index(
        np.argmax(np.linalg.norm(offset, axis=-1) + ball), ball.shape)
    direction = offset[far] / max(np.linalg.norm(offset[far]), 1e-12)
    point = (middle[far] + direction * (ball[far] + 1e-3))[None]
    assert (gap(q, s, point, np.zeros(1))
            <= kernels.balls_capsules_distance(point, np.zeros(1), c1, c2,
                                               r))
  still = np.repeat(start[None], 3, axis=0)
  s = np.array([0.0, 0.02, 0.04])
  bound = gap(still, s, centre, radius)
  test = kernels.balls_capsules_distance(centre, radius,
                                         *robot.reach_capsules(still, s))
  curvature = 0.02 ** 2 / 8 * robot.alpha.max()
  assert test - curvature - 1e-8 <= bound <= test


@pytest.mark.parametrize('name', robot_description.ROBOT_NAMES)
def test_joint_levers_bound_the_motion_of_capsule_end_points(name):
  """A step of one joint moves every capsule end point by at most its
  lever times the step (RobotReach.joint_levers), and the bound is
  reached: the levers are not loose everywhere."""
  description = robot_description.load(name)
  robot = robot_reach.RobotReach(description, tool_capsule=TOOL)
  levers = robot.joint_levers()
  np.testing.assert_allclose(   # Collision prevention's (surfaces).
      robot.joint_levers(with_radius=True),
      np.where(np.arange(description.dof)[:, None] <= robot.frame_index,
               levers + robot.radii, 0.0), rtol=1e-15, atol=0)
  rng = np.random.RandomState(7)
  worst = 0.0
  for _ in range(1500):
    q = rng.uniform(description.limits.q_min, description.limits.q_max)
    joint = rng.randint(description.dof)
    step = np.zeros(description.dof)
    step[joint] = rng.uniform(-1e-3, 1e-3)
    a1, a2, _ = robot.capsules(q)
    b1, b2, _ = robot.capsules(q + step)
    moved = np.maximum(np.linalg.norm(b1 - a1, axis=-1),
                       np.linalg.norm(b2 - a2, axis=-1))
    bound = levers[joint] * abs(step[joint])
    assert np.all(moved <= bound * (1 + 1e-9) + 1e-15)
    worst = max(worst, float((moved / np.maximum(bound, 1e-300)).max()))
  assert worst > 0.99


def test_plan_positions_match_reference():
  description = robot_description.load('iiwa')
  plan = ltp.plan_to_goal(description.q_home, np.zeros(7), np.zeros(7),
                          description.q_home + 0.8, description.limits,
                          0.004, start_time=0.37)
  rng = np.random.RandomState(5)
  # Before the start, inside, and past the end (clamped to the samples).
  s = np.concatenate([[0.0, 0.37, plan.end_time, plan.end_time + 1.0],
                      rng.uniform(0.3, plan.end_time + 0.1, 50)])
  np.testing.assert_allclose(plan.positions(s),
                             safety_references.plan_positions(plan, s),
                             rtol=0, atol=1e-12)
  out = np.full((len(s) + 1, 7), np.nan)
  plan.positions(s, out=out, first=1)
  assert np.all(np.isnan(out[0]))
  np.testing.assert_allclose(out[1:],
                             safety_references.plan_positions(plan, s),
                             rtol=0, atol=1e-12)


def test_shield_reach_distance_is_the_reference_clearance():
  shield = shield_lib.Shield('panda', tool_capsule=TOOL)
  _, p2, _ = shield.robot.capsules(shield.description.q_home)
  shield.new_goal(shield.description.q_home + 0.3)
  rng = np.random.RandomState(6)
  checked = 0
  for i in range(60):
    points = np.tile(p2[-1] + (0.35, 0.0, 0.0), (shield.human.num_keypoints,
                                                 1))
    shield.step(points + rng.normal(0, 0.01, points.shape), 0.004 * i)
    if shield.state.verification.reach_distance is None:   # The exact check.
      robot, human = shield.robot_reach_capsules, shield.human_reach_capsules
      safe, first, distance = verification.ssm_verdict(robot, human)
      assert shield.first_unsafe_interval == first
      assert shield.reach_distance == pytest.approx(distance, abs=1e-12)
      checked += 1
  assert checked > 0


def test_pfl_speed_tables_match_reference():
  rng = np.random.RandomState(7)
  for count in (1, 2, 6, 7, 8, 50, 300):
    speeds = rng.uniform(0, 2, (count, 8))
    for got, expected in zip(shield_lib.pfl_speed_tables(speeds),
                             shield_lib.pfl_speed_tables(speeds,
                                                         compiled=False)):
      np.testing.assert_array_equal(got, expected)


@pytest.mark.parametrize('name', robot_description.ROBOT_NAMES)
@pytest.mark.parametrize('tool', [None, TOOL])
def test_plan_speed_tables_equal_tables_of_surface_speeds(name, tool):
  description = robot_description.load(name)
  robot = robot_reach.RobotReach(description, tool_capsule=tool,
                                 base_pose=(0.1, -0.2, 0.7, 0.1, 0.2, 0.3))
  limits = description.limits
  rotations = robot.kernel_model[0][:, :, :3]   # Rigid frames (the bound).
  np.testing.assert_allclose(rotations @ rotations.transpose(0, 2, 1),
                             np.broadcast_to(np.eye(3), rotations.shape),
                             rtol=0, atol=1e-12)
  rng = np.random.RandomState(3)
  for _ in range(5):
    goal = np.clip(description.q_home + rng.uniform(-1, 1, description.dof),
                   limits.q_min, limits.q_max)
    plan = ltp.plan_to_goal(description.q_home, np.zeros(description.dof),
                            np.zeros(description.dof), goal, limits, 0.004)
    expected = shield_lib.pfl_speed_tables(
        robot.surface_speeds(plan.q, plan.dq))
    got = speed_kernels.plan_speed_tables(
        plan._all(), *robot.kernel_model, robot.kernel_frames,
        robot.kernel_radii, shield_lib.PFL_WINDOW)
    for got_table, expected_table in zip(got, expected):
      np.testing.assert_array_equal(got_table, expected_table)
  # Random states: each capsule is the fastest somewhere (the skipped
  # capsules' bound is exercised).
  samples = rng.uniform(-3, 3, (400, 4, description.dof))
  samples[:, 0] = rng.uniform(limits.q_min, limits.q_max,
                              (400, description.dof))
  speeds = robot.surface_speeds(samples[:, 0], samples[:, 1])
  assert len(set(speeds.argmax(axis=1).tolist())) > 1
  for got_table, expected_table in zip(
      speed_kernels.plan_speed_tables(
          samples, *robot.kernel_model, robot.kernel_frames,
          robot.kernel_radii, shield_lib.PFL_WINDOW),
      shield_lib.pfl_speed_tables(speeds)):
    np.testing.assert_array_equal(got_table, expected_table)


@pytest.mark.parametrize('count', [
    1, speed_kernels.BLOCK - 1, speed_kernels.BLOCK, speed_kernels.BLOCK + 1,
    3 * speed_kernels.BLOCK + 5])
def test_plan_speed_tables_across_block_edges(count):
  # Samples are computed a block at a time: every length, a partial last
  # block included, gives the tables of the speeds one sample at a time.
  description = robot_description.load('panda')
  robot = robot_reach.RobotReach(description, tool_capsule=TOOL)
  limits = description.limits
  rng = np.random.RandomState(count)
  samples = rng.uniform(-2, 2, (count, 4, description.dof))
  samples[:, 0] = rng.uniform(limits.q_min, limits.q_max,
                              (count, description.dof))
  expected = shield_lib.pfl_speed_tables(
      robot.surface_speeds(samples[:, 0], samples[:, 1]))
  got = speed_kernels.plan_speed_tables(
      samples, *robot.kernel_model, robot.kernel_frames,
      robot.kernel_radii, shield_lib.PFL_WINDOW)
  for got_table, expected_table in zip(got, expected):
    assert got_table.tobytes() == expected_table.tobytes()


def test_warm_up_compiles_every_signature_the_shield_uses():
  kernels.warm_up()
  speed_kernels.warm_up()
  dispatchers = {f'{module.__name__}.{name}': getattr(module, name)
                 for module in (kernels, speed_kernels)
                 for name in dir(module)
                 if hasattr(getattr(module, name), 'signatures')}
  before = {name: len(f.signatures) for name, f in dispatchers.items()}
  _, p2, _ = shield_lib.Shield('ur5e').robot.capsules(
      robot_description.load('ur5e').q_home)
  for mode, kalman in (('ssm', False), ('pfl', True)):
    shield = shield_lib.Shield('ur5e', mode=mode, tool_capsule=TOOL,
                               use_kalman_filter=kalman)
    shield.new_goal(shield.description.q_home + 0.4)
    points = np.tile(p2[-1] + (0.3, 0.0, 0.0),
                     (shield.human.num_keypoints, 1))
    for i in range(40):
      shield.step(points + 0.001 * i, 0.004 * i)
      assert np.isfinite(shield.max_cartesian_speed)
      shield.reach_distance, shield.min_distance
  assert {name: len(f.signatures)
          for name, f in dispatchers.items()} == before
