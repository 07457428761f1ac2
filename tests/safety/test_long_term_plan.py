"""Long-term plan: Ruckig to rest, exact sampling, single index offset (B1).

docs/shield_maths.md, sections 1, 2 and 10 (B1).
"""

import dataclasses
import re

import numpy as np
import pytest
import ruckig

from hrc_suite import robot_description
from hrc_suite.safety import long_term_plan as ltp

import safety_references

CYCLE = 0.004


@pytest.fixture(scope='module')
def panda():
  return robot_description.load('panda')


def _random_plan(description, rng, start_time=0.0):
  limits = description.limits
  q0 = np.clip(description.q_home + rng.uniform(-0.5, 0.5, description.dof),
               limits.q_min + 0.05, limits.q_max - 0.05)
  dq0 = rng.uniform(-0.3, 0.3, description.dof)
  ddq0 = rng.uniform(-0.5, 0.5, description.dof)
  goal = np.clip(q0 + rng.uniform(-1.0, 1.0, description.dof),
                 limits.q_min + 0.1, limits.q_max - 0.1)
  return q0, dq0, ddq0, goal, ltp.plan_to_goal(q0, dq0, ddq0, goal, limits,
                                               CYCLE, start_time)


@pytest.mark.parametrize('name', robot_description.ROBOT_NAMES)
def test_plan_reaches_goal_at_rest_within_limits(name):
  description = robot_description.load(name)
  limits = description.limits
  rng = np.random.RandomState(0)
  for _ in range(5):
    q0, dq0, ddq0, goal, plan = _random_plan(description, rng)
    np.testing.assert_allclose(plan.q[0], q0, atol=1e-12)
    np.testing.assert_allclose(plan.dq[0], dq0, atol=1e-12)
    np.testing.assert_allclose(plan.ddq[0], ddq0, atol=1e-12)
    np.testing.assert_allclose(plan.goal, goal, atol=1e-9)
    assert np.all(plan.dq[-1] == 0) and np.all(plan.ddq[-1] == 0)
    assert np.all(np.abs(plan.dq) <= limits.v_max + 1e-9)
    assert np.all(np.abs(plan.ddq) <= limits.a_max_ltt + 1e-9)
    assert np.all(np.abs(plan.dddq) <= limits.j_max_ltt + 1e-9)
    # Synchronised: every joint arrives at the end (none earlier by > 1 cycle
    # unless it does not move at all).
    moving = np.abs(goal - q0) > 0.05
    last_motion = np.array([np.nonzero(np.abs(plan.dq[:, i]) > 1e-9)[0].max()
                            for i in np.nonzero(moving)[0]])
    assert np.all(last_motion >= plan.num_samples - 3)


def test_samples_match_ruckig(panda):
  rng = np.random.RandomState(1)
  q0, dq0, ddq0, goal, plan = _random_plan(panda, rng)
  otg = ruckig.Ruckig(panda.dof)
  request = ruckig.InputParameter(panda.dof)
  request.current_position = q0
  request.current_velocity = dq0
  request.current_acceleration = ddq0
  request.target_position = goal
  request.max_velocity = panda.limits.v_max
  request.max_acceleration = panda.limits.a_max_ltt
  request.max_jerk = panda.limits.j_max_ltt
  trajectory = ruckig.Trajectory(panda.dof)
  otg.calculate(request, trajectory)
  for k in range(0, plan.num_samples - 1, 11):
    position, velocity, acceleration = trajectory.at_time(k * CYCLE)
    np.testing.assert_allclose(plan.q[k], position, atol=1e-10)
    np.testing.assert_allclose(plan.dq[k], velocity, atol=1e-10)
    np.testing.assert_allclose(plan.ddq[k], acceleration, atol=1e-10)


def test_single_index_offset_b1(panda):
  """A plan started at cycle 100 looks ahead 1/10/50/99 samples correctly."""
  rng = np.random.RandomState(2)
  start = 100 * CYCLE
  *_, plan = _random_plan(panda, rng, start_time=start)
  assert plan.num_samples > 100
  for ahead in (1, 10, 50, 99):
    q, dq, ddq, dddq = plan.evaluate(start + ahead * CYCLE)
    np.testing.assert_allclose(q, plan.q[ahead], atol=1e-12)
    np.testing.assert_allclose(dq, plan.dq[ahead], atol=1e-12)
  # Positions along the plan really differ (the defect returned the start).
  assert np.linalg.norm(plan.evaluate(start + 99 * CYCLE)[0] - plan.q[0]) > 0.01


def test_taylor_and_chain_rule(panda):
  rng = np.random.RandomState(3)
  *_, plan = _random_plan(panda, rng, start_time=0.3)
  s = 0.3 + 37.4 * CYCLE
  s_dot, s_ddot, jerk = 0.6, -2.0, 30.0
  k, tau = 37, 0.4 * CYCLE
  v = plan.dq[k] + tau * plan.ddq[k] + tau ** 2 / 2 * plan.dddq[k]
  a = plan.ddq[k] + tau * plan.dddq[k]
  q_expected = (plan.q[k] + tau * plan.dq[k] + tau ** 2 / 2 * plan.ddq[k]
                + tau ** 3 / 6 * plan.dddq[k])
  q, dq, ddq, dddq = plan.evaluate(s, s_dot, s_ddot, jerk)
  np.testing.assert_allclose(q, q_expected, atol=1e-12)
  np.testing.assert_allclose(dq, v * s_dot, atol=1e-12)
  np.testing.assert_allclose(ddq, v * s_ddot + a * s_dot ** 2, atol=1e-12)
  np.testing.assert_allclose(
      dddq, plan.dddq[k] * s_dot ** 3 + 3 * a * s_ddot * s_dot + v * jerk,
      atol=1e-10)
  # Batched forms agree with the scalar one.
  batch = plan.evaluate(np.array([s, s]), np.array([s_dot] * 2),
                        np.array([s_ddot] * 2), np.array([jerk] * 2))
  for scalar, batched in zip((q, dq, ddq, dddq), batch):
    np.testing.assert_allclose(batched[1], scalar, atol=1e-12)
  np.testing.assert_allclose(plan.positions(np.array([s]))[0], q, atol=1e-12)
  # Past the end the goal is held at rest.
  q_end, dq_end, _, _ = plan.evaluate(plan.end_time + 1.0, 1.0, 0.0, 0.0)
  np.testing.assert_allclose(q_end, plan.goal)
  assert np.all(dq_end == 0)


def test_goal_is_clamped_inside_limits(panda):
  limits = panda.limits
  goal = limits.q_max + 1.0
  plan = ltp.plan_to_goal(panda.q_home, np.zeros(7), np.zeros(7), goal,
                          limits, CYCLE)
  np.testing.assert_allclose(plan.goal, limits.q_max - ltp.GOAL_LIMIT_MARGIN)


def test_start_state_checks(panda):
  limits = panda.limits
  q0, zeros = panda.q_home, np.zeros(7)
  too_fast = zeros.copy()
  too_fast[2] = 1.5
  with pytest.raises(ltp.PlanningError, match=r'dq0.*\[2\]'):
    ltp.plan_to_goal(q0, too_fast, zeros, q0, limits, CYCLE)
  hard = zeros.copy()
  hard[4] = 3.0
  with pytest.raises(ltp.PlanningError, match=r'a_max_ltt.*\[4\]'):
    ltp.plan_to_goal(q0, zeros, hard, q0, limits, CYCLE)
  # Velocity 0.99 still accelerating at 1.9: would overshoot v_max = 1.
  fast = zeros.copy()
  fast[0], hard_small = 0.99, zeros.copy()
  hard_small[0] = 1.9
  with pytest.raises(ltp.PlanningError, match='ramping'):
    ltp.plan_to_goal(q0, fast, hard_small, q0, limits, CYCLE)
  outside = q0.copy()
  outside[1] = limits.q_max[1] + 0.1
  with pytest.raises(ltp.PlanningError, match='q0 above q_max'):
    ltp.plan_to_goal(outside, zeros, zeros, q0, limits, CYCLE)
  with pytest.raises(ValueError, match=r'q_goal must have shape \(7,\)'):
    ltp.plan_to_goal(q0, zeros, zeros, np.zeros(6), limits, CYCLE)
  with pytest.raises(ValueError, match='finite'):
    ltp.plan_to_goal(q0, zeros, zeros, np.full(7, np.nan), limits, CYCLE)


def test_overshooting_past_a_limit_is_refused(panda):
  limits = panda.limits
  q0 = panda.q_home.copy()
  q0[0] = limits.q_max[0] - 0.05
  dq0 = np.zeros(7)
  dq0[0] = 1.0   # Cannot stop within 0.05 rad at a_ltt = 2, j_ltt = 15.
  with pytest.raises(ltp.PlanningError, match='leave the joint limits'):
    ltp.plan_to_goal(q0, dq0, np.zeros(7), q0, limits, CYCLE)


def test_at_rest_plan(panda):
  plan = ltp.LongTermPlan.at_rest(panda.q_home, CYCLE, start_time=2.0)
  assert plan.num_samples == 1 and plan.end_time == 2.0
  q, dq, ddq, dddq = plan.evaluate(5.0, 1.0, 3.0, 10.0)
  np.testing.assert_allclose(q, panda.q_home)
  assert not np.any(dq) and not np.any(ddq) and not np.any(dddq)


def test_a_ruckig_synchronisation_failure_is_a_planning_error():
  # A Schunk state met during SAC training on reach/dense: Ruckig 0.19
  # raises RuckigError ("error in step 2 in dof: 2 for t sync") on this
  # valid input, which crashed collision prevention before it became a
  # PlanningError (collision prevention then refuses the goal).
  limits = robot_description.load('schunk').limits
  dof = len(limits.q_min)
  uniform = lambda value: np.full(dof, float(value))
  limits = dataclasses.replace(limits, v_max=uniform(1), a_max_ltt=uniform(2),
                               j_max_ltt=uniform(15))
  # Exact values (hex): the logged state moved by a few ulps.
  q0, dq0, ddq0, goal = ([float.fromhex(x) for x in row] for row in (
      ['-0x1.71f093442d328p-1', '0x1.0fdfd50766d24p+0',
       '-0x1.b1846134b51a4p-2', '0x1.64bdeaf1730cep-14',
       '-0x1.8fded5c528b76p+0', '-0x1.71f66c55df05ap-1'],
      ['-0x1.3e7d507d10a75p-3', '0x1.20117b101dc4cp-2',
       '0x1.5169604a8866dp-1', '-0x1.94a6d6ceacc8ep-13',
       '-0x1.2beb8735d8eeap-1', '-0x1.3e0696a11c99ap-3'],
      ['0x0.0p+0', '0x0.0p+0', '-0x1.b21298d9dd536p+0', '0x0.0p+0',
       '-0x1.10f1a0a4487dbp-2', '0x0.0p+0'],
      ['-0x1.8d4755605f346p-1', '0x1.2611972f769eap+0',
       '-0x1.2d74775e9b20ap-2', '-0x1.476c7d6c83800p-23',
       '-0x1.b2b8114ce50d0p+0', '-0x1.8d447fe0d9836p-1']))
  try:
    plan = ltp.plan_to_goal(q0, dq0, ddq0, goal, limits, 0.004)
  except ltp.PlanningError as e:
    assert 'Ruckig failed' in str(e)
  else:   # A Ruckig that solves it must reach the goal at rest.
    np.testing.assert_allclose(plan.q[-1], goal, atol=1e-6)


@pytest.mark.parametrize('seed', range(4))
def test_compiled_sampling_is_the_numpy_reference_bit_for_bit(panda, seed):
  """plan_kernels.sample_pieces against sample_pieces_reference: every
  sample of random plans (moving starts), in chunks and past the end."""
  rng = np.random.RandomState(10 + seed)
  plan = _random_plan(panda, rng)[-1]
  count = plan.num_samples
  for first, stop in ((0, count), (3, min(count, 70)), (count - 1, count + 5)):
    out = np.full((stop + 2, 4, plan.dof), np.nan)
    ltp.plan_kernels.sample_pieces(*plan._pieces, first, stop, out)
    reference = safety_references.sample_pieces(*plan._pieces, first, stop)
    assert np.array_equal(out[first:stop], reference)
    # Only those rows are written.
    assert np.isnan(out[:first]).all() and np.isnan(out[stop:]).all()
  assert np.all(reference[-5:, 0] == plan.goal)   # At rest at the goal.


def test_compiled_start_check_agrees_with_the_numpy_conditions(panda):
  """plan_kernels.start_state_ok (check_start_state's fast path) against
  the conditions of docs/shield_maths.md, 1 in NumPy, and check_start_state
  raises exactly where they fail: random states at and beyond every limit."""
  limits = panda.limits
  slack = ltp._LIMIT_SLACK
  rng = np.random.RandomState(4)
  outcomes = []
  for _ in range(400):
    q0 = rng.uniform(limits.q_min - 0.05, limits.q_max + 0.05)
    dq0 = rng.uniform(-1.1, 1.1, panda.dof) * limits.v_max
    ddq0 = rng.uniform(-1.1, 1.1, panda.dof) * limits.a_max_ltt
    keep = rng.rand(3, panda.dof) < 0.8    # Mostly within: both outcomes.
    q0 = np.where(keep[0], np.clip(q0, limits.q_min, limits.q_max), q0)
    dq0, ddq0 = np.where(keep[1], 0.3 * dq0, dq0), np.where(keep[2], 0.0,
                                                             ddq0)
    ramped = np.abs(dq0 + ddq0 * np.abs(ddq0) / (2.0 * limits.j_max_ltt))
    expected = bool(np.all(q0 >= limits.q_min - slack) and
                    np.all(q0 <= limits.q_max + slack) and
                    np.all(np.abs(dq0) <= limits.v_max + slack) and
                    np.all(np.abs(ddq0) <= limits.a_max_ltt + slack) and
                    np.all(ramped <= limits.v_max + slack))
    ok = ltp.plan_kernels.start_state_ok(
        q0, dq0, ddq0, limits.q_min, limits.q_max, limits.v_max,
        limits.a_max_ltt, limits.j_max_ltt, slack)
    assert ok == expected
    try:
      ltp.check_start_state(q0, dq0, ddq0, limits)
      raised = False
    except ltp.PlanningError:
      raised = True
    assert raised == (not expected)
    outcomes.append(ok)
  assert set(outcomes) == {True, False}


def test_piece_table_lists_each_joints_pieces_in_time_order():
  """plan_kernels.piece_table against the rows written out in Python:
  random profiles, some joints with one or two brake pieces (Ruckig
  gives them only for starts check_start_state rejects, so plans never
  exercise them), zero-duration pieces, padding and the joint shifts."""
  rng = np.random.RandomState(6)
  size = ltp.plan_kernels.PROFILE_SIZE
  for _ in range(50):
    dof = rng.randint(1, 8)
    profiles = rng.normal(size=(dof, size))
    profiles[:, :7] = rng.uniform(0.0, 0.3, (dof, 7)) * (rng.rand(dof, 7)
                                                         < 0.8)
    brakes = np.zeros((0, 5, 2))
    if rng.rand() < 0.7:
      brakes = rng.normal(size=(dof, 5, 2))
      brakes[:, 0] = rng.uniform(0.0, 0.2, (dof, 2)) * (rng.rand(dof, 2)
                                                        < 0.5)
    duration = float(profiles[:, :7].sum(1).max() + 0.1)
    rows = []
    for i in range(dof):
      joint, time = [], 0.0
      for k in range(2 if len(brakes) else 0):
        if brakes[i, 0, k] > 0.0:
          joint.append([time] + list(brakes[i, 1:, k]))
          time += brakes[i, 0, k]
      for k in range(7):
        joint.append([time, profiles[i, 7 + k], profiles[i, 15 + k],
                      profiles[i, 23 + k], profiles[i, 31 + k]])
        time += profiles[i, k]
      rows.append(joint)
    count = max(len(joint) for joint in rows)
    expected = np.full((dof, count, 5), duration + 0.5)
    for i, joint in enumerate(rows):
      expected[i, :len(joint)] = joint
    expected = expected.reshape(dof * count, 5)
    shift = np.arange(dof) * (duration + 1.0)
    table, starts, joint_shift = ltp.plan_kernels.piece_table(
        profiles, brakes, duration)
    assert np.array_equal(table, expected)
    assert np.array_equal(joint_shift, shift)
    assert np.array_equal(starts, expected[:, 0] + np.repeat(shift, count))
    assert np.all(np.diff(starts) >= 0.0)


def test_compiled_input_check_agrees_with_the_checks_one_by_one(panda):
  """plan_kernels.plan_inputs_ok (plan_to_goal's fast path) passes exactly
  the inputs that pass _check_vector, clamp_goal and check_start_state,
  with clamp_goal's goal bit for bit: random states, some not finite,
  some beyond the limits; plan_to_goal raises the checks' own errors."""
  limits = panda.limits
  rng = np.random.RandomState(5)
  outcomes = []
  for _ in range(400):
    q0 = rng.uniform(limits.q_min - 0.02, limits.q_max + 0.02)
    dq0 = rng.uniform(-1.05, 1.05, panda.dof) * limits.v_max
    ddq0 = rng.uniform(-0.5, 0.5, panda.dof) * limits.a_max_ltt
    q_goal = rng.uniform(limits.q_min - 0.3, limits.q_max + 0.3)
    vectors = [q0, dq0, ddq0, q_goal]
    if rng.rand() < 0.2:
      vectors[rng.randint(4)][rng.randint(panda.dof)] = rng.choice(
          [np.nan, np.inf, -np.inf])
    try:
      for name, x in zip(('q0', 'dq0', 'ddq0'), vectors):
        ltp._check_vector(name, x, panda.dof)
      expected_goal = ltp.clamp_goal(q_goal, limits)
      ltp.check_start_state(q0, dq0, ddq0, limits)
      expected = None
    except ValueError as e:   # PlanningError included.
      expected = e
    goal = np.empty(panda.dof)
    ok = ltp.plan_kernels.plan_inputs_ok(
        *vectors, limits.q_min, limits.q_max, limits.v_max,
        limits.a_max_ltt, limits.j_max_ltt, ltp._LIMIT_SLACK,
        ltp.GOAL_LIMIT_MARGIN, goal)
    assert ok == (expected is None)
    if ok:
      assert np.array_equal(goal, expected_goal)
    else:
      with pytest.raises(type(expected), match=re.escape(str(expected))):
        ltp.plan_to_goal(q0, dq0, ddq0, q_goal, limits, 0.004)
    outcomes.append(ok)
  assert 0.2 < np.mean(outcomes) < 0.8


def test_clamp_goal_is_numpys_clip_bit_for_bit(panda):
  """clamp_goal's compiled fast path gives np.clip's goal (margin inside
  the limits) bit for bit, for goals inside, beyond and on the clamped
  bounds, and converts other inputs; a goal not finite or of the wrong
  shape is refused with the bad value named."""
  limits = panda.limits
  low = limits.q_min + ltp.GOAL_LIMIT_MARGIN
  high = limits.q_max - ltp.GOAL_LIMIT_MARGIN
  rng = np.random.RandomState(8)
  goals = [rng.uniform(limits.q_min - 0.5, limits.q_max + 0.5)
           for _ in range(200)] + [low.copy(), high.copy(), limits.q_min,
                                   limits.q_max]
  for goal in goals:
    expected = np.clip(goal, low, high)
    assert ltp.clamp_goal(goal, limits).tobytes() == expected.tobytes()
    assert (ltp.clamp_goal(goal.tolist(), limits).tobytes()
            == expected.tobytes())
    strided = np.stack([goal, goal], axis=1)[:, 0]
    assert ltp.clamp_goal(strided, limits).tobytes() == expected.tobytes()
  bad = panda.q_home.copy()
  bad[3] = np.nan
  with pytest.raises(ValueError, match='q_goal must be finite'):
    ltp.clamp_goal(bad, limits)
  with pytest.raises(ValueError, match=r'q_goal must have shape \(7,\)'):
    ltp.clamp_goal(np.zeros(6), limits)


def test_plan_kernels_warm_up_compiles_what_plan_to_goal_calls(panda):
  from hrc_suite.safety import plan_kernels   # pylint: disable=g-import-not-at-top
  plan_kernels.warm_up()
  dispatchers = {name: getattr(plan_kernels, name)
                 for name in dir(plan_kernels)
                 if hasattr(getattr(plan_kernels, name), 'signatures')}
  before = {name: len(f.signatures) for name, f in dispatchers.items()}
  rng = np.random.RandomState(5)
  for _ in range(5):
    plan = _random_plan(panda, rng)[-1]
    plan.q, plan.positions(np.array([0.01, 0.02]))
  assert {name: len(f.signatures)
          for name, f in dispatchers.items()} == before


def test_recent_plans_are_reused_and_recent_false_plans_afresh(panda):
  """Collision prevention's plan of a goal is the shield's next candidate:
  the same inputs give the same plan object; recent=False (the shield's
  re-plans from a braking command) plans afresh, to the same samples, and
  leaves the recent plans as they were."""
  rng = np.random.RandomState(3)
  q0, dq0, ddq0, goal, plan = _random_plan(panda, rng, start_time=0.5)
  limits = panda.limits
  again = ltp.plan_to_goal(q0, dq0, ddq0, goal, limits, CYCLE, 0.5)
  assert again is plan
  fresh = ltp.plan_to_goal(q0, dq0, ddq0, goal, limits, CYCLE, 0.5,
                           recent=False)
  assert fresh is not plan
  np.testing.assert_array_equal(fresh._all(), plan._all())
  assert ltp.plan_to_goal(q0, dq0, ddq0, goal, limits, CYCLE, 0.5) is plan
  # Another start time is another plan.
  later = ltp.plan_to_goal(q0, dq0, ddq0, goal, limits, CYCLE, 0.6)
  assert later is not plan and later.start_time == 0.6


def test_inputs_of_other_types_and_layouts_give_the_same_plan(panda):
  """Inputs that are not contiguous float64 vectors (a strided view, float32,
  lists) are converted: the same samples as from float64 copies."""
  rng = np.random.RandomState(4)
  q0, dq0, ddq0, goal, plan = _random_plan(panda, rng)
  rows = np.stack([q0, dq0, ddq0, goal], axis=1)   # Columns are strided.
  assert rows[:, 0].strides != (8,)
  strided = ltp.plan_to_goal(rows[:, 0], rows[:, 1], rows[:, 2], rows[:, 3],
                             panda.limits, CYCLE, recent=False)
  np.testing.assert_array_equal(strided._all(), plan._all())
  lists = ltp.plan_to_goal(q0.tolist(), dq0.tolist(), ddq0.tolist(),
                           goal.tolist(), panda.limits, CYCLE, recent=False)
  np.testing.assert_array_equal(lists._all(), plan._all())
  single = ltp.plan_to_goal(*(x.astype(np.float32) for x in (q0, dq0, ddq0)),
                            goal, panda.limits, CYCLE, recent=False)
  expected = ltp.plan_to_goal(
      *(x.astype(np.float32).astype(float) for x in (q0, dq0, ddq0)), goal,
      panda.limits, CYCLE, recent=False)
  np.testing.assert_array_equal(single._all(), expected._all())
