"""Shield step: construction, read-outs, slices, plan adoption, modes."""

import dataclasses
import json
import math

import numpy as np
import pytest

from hrc_suite import robot_description
from hrc_suite.human import keypoints
from hrc_suite.safety import geometry
from hrc_suite.safety import long_term_plan as ltp
from hrc_suite.safety.shield import benchmark as shield_benchmark
from hrc_suite.safety.shield import human_reach as human_reach_lib
from hrc_suite.safety.shield import shield as shield_lib
from hrc_suite.safety.shield import verification

import safety_references
import shield_harness as harness

CYCLE = shield_lib.DEFAULT_CYCLE_TIME


@pytest.fixture(scope='module')
def panda():
  return robot_description.load('panda')


def _shield(description, **kwargs):
  return shield_lib.Shield(description,
                           tool_capsule=harness.tool_capsule(description),
                           **kwargs)


def _goal(description, shift=0.8):
  goal = description.q_home.copy()
  goal[0] += shift
  return goal


def _human_near(shield):
  """A person whose right hand is 0.35 m in front of the gripper."""
  _, p2, _ = shield.robot.capsules(shield.q)
  body = harness.place(harness.STANDING, 0.0, 0.0, math.pi)
  hand = keypoints.KEYPOINT_INDEX['right_hand']
  return body + (p2[-1] + np.array([0.35, 0.0, 0.0]) - body[hand])


def _blocking_human(shield):
  """A person whose torso is on the robot's second link."""
  p1, p2, _ = shield.robot.capsules(shield.q)
  body = harness.place(harness.STANDING, 0.0, 0.0, 0.0)
  return body + 0.5 * (p1[1] + p2[1]) - body[keypoints.KEYPOINT_INDEX['torso']]


def test_bad_arguments_are_named(panda):
  with pytest.raises(ValueError, match="Unknown shield mode 'fast': "
                     "expected one of 'ssm', 'pfl', 'off'"):
    shield_lib.Shield(panda, mode='fast')
  with pytest.raises(ValueError, match='cycle_time'):
    shield_lib.Shield(panda, cycle_time=0.0)
  with pytest.raises(ValueError, match='v_safe'):
    shield_lib.Shield(panda, v_safe=-1.0)
  shield = shield_lib.Shield(panda)
  with pytest.raises(ValueError, match='outside the joint limits'):
    shield.reset(panda.limits.q_max + 0.1)
  with pytest.raises(ValueError, match=r'7 finite joint positions'):
    shield.reset(np.zeros(6))
  with pytest.raises(ValueError, match=r'q_goal must have shape \(7,\)'):
    shield.new_goal(np.zeros(3))
  with pytest.raises(ValueError, match='keypoints'):
    shield.step(np.zeros((3, 3)), 0.0)


def test_the_description_by_name_path_or_object(panda):
  by_path = shield_lib.Shield(robot_description.ROBOTS_DIR / 'panda.json')
  by_name = shield_lib.Shield('panda')
  assert by_path.description.name == by_name.description.name == panda.name
  with pytest.raises(TypeError, match='robot_description: expected a '
                     'RobotDescription, a robot name or a description file '
                     'path, got 7'):
    shield_lib.Shield(7)


def test_starts_at_rest_and_defaults(panda):
  shield = shield_lib.Shield(panda)
  np.testing.assert_array_equal(shield.q, panda.q_home)
  assert not shield.dq.any()
  assert not shield.is_safe   # Nothing verified yet.
  assert shield_lib.Shield(panda, mode='off').is_safe
  assert shield.v_safe == panda.shield.v_safe == 0.05
  assert shield_lib.Shield('schunk').v_safe == 0.05   # suite default
  assert shield_lib.Shield(panda, v_safe=0.2).v_safe == 0.2


def test_without_human_the_plan_is_followed(panda):
  shield = _shield(panda)
  shield.new_goal(_goal(panda))
  for i in range(50):
    shield.step(None, i * CYCLE)
    assert shield.is_safe and not shield.intervened
  assert shield.human_reach_capsules is None
  assert shield.min_distance == np.inf
  assert np.abs(shield.dq).max() > 0.05


def test_read_outs(panda):
  shield = _shield(panda)
  shield.new_goal(_goal(panda))
  far = harness.far_away()(0.0)
  for i in range(60):
    shield.step(far, i * CYCLE)
  previous = shield.q.copy()
  human = _human_near(shield)
  shield.step(human, 60 * CYCLE)
  robot = shield.robot_reach_capsules
  num_capsules = panda.dof + 1
  k = robot[2].shape[0]
  assert robot[0].shape == (k, num_capsules, 3)
  assert robot[2].shape == (k, num_capsules)
  human_reach = shield.human_reach_capsules
  assert human_reach[0].shape == (1, k, shield.human.num_bodies, 3)
  # Slices (docs/shield_maths.md, 6): the current step (fix L4), then 20 ms
  # slices of the failsafe.
  assert k >= 2
  # The first slice encloses the robot at the previous and the new command.
  for q in (previous, shield.q):
    p1, p2, r = shield.robot.capsules(q)
    assert np.all(geometry.capsule_contains_capsule(
        robot[0][0], robot[1][0], robot[2][0], p1, p2, r, 1e-9))
  # Distances and speeds are the real-size ones at the command.
  r1, r2, rr = shield.robot.capsules(shield.q)
  h1, h2, hr = shield.human.body_capsules(human)
  expected = geometry.capsule_distance(r1[:, None], r2[:, None], rr[:, None],
                                       h1[None], h2[None], hr[None]).min()
  assert shield.min_distance == pytest.approx(expected)
  assert shield.max_cartesian_speed == pytest.approx(
      shield.robot.surface_speeds(shield.q, shield.dq).max())
  assert shield.max_cartesian_speed > 0.01
  # The reach distance is below the real one (reach sets are larger).
  assert shield.reach_distance <= shield.min_distance


@pytest.mark.parametrize('robot', robot_description.ROBOT_NAMES)
def test_min_distance_kernel_agrees_with_numpy(robot):
  description = robot_description.load(robot)
  shield = _shield(description)
  rng = np.random.RandomState(0)
  limits = description.limits
  body = harness.place(harness.STANDING, 0.0, 0.0, math.pi)
  overlapping = 0
  for _ in range(50):
    q = rng.uniform(limits.q_min, limits.q_max)
    shield.reset(q, 0.0)
    # A person's torso from on the robot's wrist to 1.2 m from it.
    _, p2, _ = shield.robot.capsules(q)
    offset = p2[-1] + rng.uniform(-1.2, 1.2, 3)
    human = body + offset - body[keypoints.KEYPOINT_INDEX['torso']]
    shield.step(human, 0.0)
    expected = safety_references.min_distance(shield)
    assert shield.min_distance == pytest.approx(expected, abs=1e-12)
    overlapping += expected < 0
  assert 0 < overlapping < 50


def test_slices_cover_the_failsafe(panda):
  shield = _shield(panda)
  shield.new_goal(_goal(panda, 1.5))
  human = harness.place(harness.STANDING, 1.2, 0.0, math.pi)
  for i in range(100):
    shield.step(human, i * CYCLE)
  assert shield.is_safe and shield.s_dot == pytest.approx(1.0)
  failsafe = shield.state.verified
  interval = panda.shield.reachability_interval_cycles * CYCLE
  k = shield.robot_reach_capsules[2].shape[0]
  assert k == 1 + math.ceil(failsafe.end_time() / interval - 1e-9)
  # The last slice ends at the end of the failsafe, at rest on the plan.
  s_end, s_dot_end, _ = failsafe.final()
  assert s_dot_end == 0.0
  q_end = shield.plan.evaluate(s_end)[0]
  p1, p2, r = shield.robot.capsules(q_end)
  robot = shield.robot_reach_capsules
  assert np.all(geometry.capsule_contains_capsule(
      robot[0][-1], robot[1][-1], robot[2][-1], p1, p2, r, 1e-9))


def test_new_plan_waits_for_verification_b4(panda):
  shield = _shield(panda)
  shield.new_goal(_goal(panda))
  far = harness.far_away()(0.0)
  t = 0.0
  for _ in range(40):
    shield.step(far, t)
    t += CYCLE
  old_plan = shield.plan
  blocking = _blocking_human(shield)
  new_goal = panda.q_home.copy()
  new_goal[1] -= 0.5
  shield.new_goal(new_goal)
  for _ in range(60):
    shield.step(blocking, t)
    t += CYCLE
    assert not shield.is_safe and shield.intervened
    # Still braking along the old, verified plan.
    assert shield.plan is old_plan and shield.goal_pending
    np.testing.assert_allclose(shield.q, old_plan.evaluate(shield.s)[0],
                               atol=1e-12)
  assert not np.abs(shield.dq).any()
  # The human leaves: the new plan verifies, is adopted and followed.
  for _ in range(5):
    shield.step(far, t)
    t += CYCLE
  assert shield.is_safe and not shield.goal_pending
  assert shield.plan is not old_plan
  np.testing.assert_allclose(shield.plan.goal, new_goal)


def test_a_plan_made_from_the_command_is_the_first_candidate(panda):
  """new_goal(q_goal, plan): a plan made from the shield's command to the
  goal (collision prevention's) is adopted as it is, not made again, and
  the robot moves exactly as when the shield plans itself; a plan from
  another command, to another goal or with other limits is not used."""
  goal = panda.q_home.copy()
  goal[1] -= 0.4
  given, t = _moving(panda)
  own, _ = _moving(panda)
  plan = ltp.plan_to_goal(given.q, given.dq, given.ddq, goal, panda.limits,
                          CYCLE, given.s, recent=False)
  given.new_goal(goal, plan)
  own.new_goal(goal)
  for i in range(40):
    given.step(None, t + i * CYCLE)
    own.step(None, t + i * CYCLE)
    assert given.q.tobytes() == own.q.tobytes()
    assert given.dq.tobytes() == own.dq.tobytes()
  assert given.plan is plan and own.plan is not plan
  # Plans the shield would not make now are made again instead.
  other_goal = goal.copy()
  other_goal[0] += 0.1
  wider = dataclasses.replace(panda.limits, v_max=panda.limits.v_max * 2.0)
  for state, to, limits in (('moved', goal, panda.limits),
                            ('now', other_goal, panda.limits),
                            ('now', goal, wider)):
    shield, t = _moving(panda)
    before = (shield.q, shield.dq, shield.ddq, shield.s)
    shield.step(None, t)
    q, dq, ddq, s = before if state == 'moved' else (
        shield.q, shield.dq, shield.ddq, shield.s)
    stale = ltp.plan_to_goal(q, dq, ddq, to, limits, CYCLE, s, recent=False)
    shield.new_goal(goal, stale)
    shield.step(None, t + CYCLE)
    assert shield.plan is not stale
    np.testing.assert_allclose(shield.plan.goal, goal)


def test_a_robot_stopped_next_to_a_person_starts_again(panda,
                                                       monkeypatch):
  """A new plan from rest that does not verify at path velocity 1 (its
  braking horizon reaches the person's reachable set) starts at 0 and
  accelerates along the path, as a stopped plan resumes; without that the
  robot never moves away from a person standing 0.1 m from the gripper."""
  def run(rest_start):
    shield = _shield(panda)
    _, p2, _ = shield.robot.capsules(shield.q)
    body = harness.place(harness.STANDING, 0.0, 0.0, math.pi)
    hand = keypoints.KEYPOINT_INDEX['right_hand']
    person = body + (p2[-1] + np.array([0.3, 0.0, 0.0]) - body[hand])
    goal = panda.q_home.copy()
    goal[1] -= 0.4   # Back, away from the person.
    with monkeypatch.context() as patch:
      if not rest_start:
        patch.setattr(shield_lib.Shield, '_at_rest', lambda self, command: False)
      return harness.simulate(shield, lambda t: person, 1.0,
                              first_goal=goal)
  stuck, started = run(False), run(True)
  assert 0.05 < stuck.min_clearance < 0.15
  assert not stuck.safe.any() and np.abs(stuck.q - stuck.q[0]).max() == 0
  assert started.safe.any()
  assert np.abs(started.q[-1] - started.q[0]).max() > 0.05   # rad
  assert not started.violations


def test_off_mode_follows_the_plan_and_reports(panda):
  shield = _shield(panda, mode='off')
  shield.new_goal(_goal(panda))
  blocking = None
  for i in range(80):
    if i == 20:
      blocking = _blocking_human(shield)
    shield.step(blocking, i * CYCLE)
    assert not shield.intervened
    if blocking is not None:
      assert not shield.is_safe
      assert shield.first_unsafe_interval == 0
      assert shield.min_distance < 0
  assert shield.s_dot == pytest.approx(1.0)


def test_old_measurements_age(panda):
  """Without new measurements the human's reachable set keeps growing."""
  shield = _shield(panda)
  human = harness.place(harness.STANDING, 1.4, 0.0, math.pi)
  shield.step(human, 0.0)
  t = CYCLE
  while shield.is_safe:
    shield.step(None, t)
    t += CYCLE
    assert t < 2.0, 'an ageing measurement never became unsafe'
  # The person could have walked 2 m/s * age into the robot: about 0.6 m.
  assert 0.15 < t < 0.8


def test_same_inputs_same_outputs(panda):
  outputs = []
  for _ in range(2):
    shield = _shield(panda, mode='pfl')
    human = harness.hand_attack(np.array([0.5, 0.0, 1.2]), start=0.05)
    rng = np.random.RandomState(5)
    run = harness.simulate(shield, human, 0.6, check=False,
                           goal=harness.random_goals(panda, rng))
    outputs.append((run.q, run.dq, run.ddq, run.safe))
  for a, b in zip(*outputs):
    np.testing.assert_array_equal(a, b)


def test_pfl_moves_slowly_where_ssm_stops(panda):
  speeds = {}
  for mode in ('ssm', 'pfl'):
    shield = _shield(panda, mode=mode)
    shield.new_goal(_goal(panda, 2.0))
    blocking = _blocking_human(shield)
    for i in range(150):
      shield.step(blocking, i * CYCLE)
    speeds[mode] = shield.max_cartesian_speed
  assert speeds['ssm'] == 0.0
  assert 0.005 < speeds['pfl'] <= panda.shield.v_safe


def test_broad_phase_is_conservative(panda):
  """When the broad phase alone declares a cycle safe, the maximal-velocity
  (VEL) model's reach capsules really miss the robot's in every slice."""
  shield = _shield(panda, use_combined_model=False)
  human = harness.walk_in(speed=1.0, stop_x=0.5)
  rng = np.random.RandomState(4)
  goals = harness.random_goals(panda, rng)
  decided = 0
  for i in range(400):
    if i % 12 == 0:
      shield.new_goal(goals())
    shield.step(human(i * CYCLE), i * CYCLE)
    if shield.is_safe and (   # Decided by a broad phase.
        shield.state.verification.reach_distance is not None):
      decided += 1
      robot = shield.robot_reach_capsules
      c1, c2, r = shield.human_reach_capsules
      vel = human_reach_lib.VEL
      safe, _, distance = verification.ssm_verdict(
          robot, (c1[vel:vel + 1], c2[vel:vel + 1], r[vel:vel + 1]))
      assert safe and distance >= shield.reach_distance - 1e-9
  assert decided > 50


def test_benchmark_runs_and_the_close_scene_intervenes():
  rows = shield_benchmark.main(['--robots', 'panda', '--cycles', '120'])
  scenes = {row[1]: row for row in rows}
  assert set(scenes) == set(shield_benchmark.SCENES)
  for _, _, median, p95, _, cpu_median, cpu_p95 in rows:
    assert 0 < median <= p95 and 0 < cpu_median <= cpu_p95
  assert scenes['close'][4] > 0 and scenes['far'][4] == 0


# ------------------------------------------------- tracking and resync


def _moving(description, cycles=60):
  """A shield moving towards a goal (no human), and its next cycle time."""
  shield = _shield(description)
  shield.new_goal(_goal(description))
  for i in range(cycles):
    shield.step(None, i * CYCLE)
  assert np.abs(shield.dq).max() > 0.1
  return shield, cycles * CYCLE


def test_tracking_tolerance_is_the_secure_radius(panda):
  shield = _shield(panda)
  assert shield.tracking_tolerance == shield.robot.secure_radius == 0.02
  assert shield.tracking_error(shield.q) == 0.0
  assert shield.tracking_bound(shield.q) == 0.0
  for check in (shield.tracking_error, shield.tracking_bound):
    with pytest.raises(ValueError, match=r'7 joint positions'):
      check(np.zeros(6))
    with pytest.raises(ValueError, match=r'7 joint positions'):
      check(shield.q, np.zeros(3))


def _axis_points(shield, q, count=11):
  """Points along every capsule axis (links and tool) at q, (L * count, 3)."""
  p1, p2, _ = shield.robot.capsules(q)
  t = np.linspace(0.0, 1.0, count)[:, None, None]
  return ((1.0 - t) * p1 + t * p2).reshape(-1, 3)


@pytest.mark.parametrize('name', robot_description.ROBOT_NAMES)
def test_tracking_error_and_its_bound(name):
  """tracking_error is how far the capsule axes moved (their ends move
  farthest), tracking_bound is never below it, for random poses and joint
  errors up to 0.3 rad; the bound is within a factor 2 for some pose of
  each joint (not vacuous)."""
  description = robot_description.load(name)
  shield = _shield(description)
  rng = np.random.RandomState(0)
  limits = description.limits
  for _ in range(200):
    q = rng.uniform(limits.q_min, limits.q_max)
    error = rng.uniform(-0.3, 0.3, description.dof) * (
        rng.uniform(size=description.dof) < 0.5)
    moved = np.linalg.norm(_axis_points(shield, q + error)
                           - _axis_points(shield, q), axis=1).max()
    exact = shield.tracking_error(q + error, q)
    assert exact == pytest.approx(moved, rel=1e-12, abs=1e-15)
    # The kernel (both paths of the task use it) and the NumPy version.
    assert exact == pytest.approx(
        safety_references.tracking_error(shield, q + error, q), rel=1e-12,
        abs=1e-15)
    assert exact <= shield.tracking_bound(q + error, q) + 1e-12
  # Every joint but the last (the tool turns about its own axis).
  best = np.zeros(description.dof - 1)
  for _ in range(100):
    q = rng.uniform(limits.q_min, limits.q_max)
    for joint in range(description.dof - 1):
      error = np.zeros(description.dof)
      error[joint] = 0.01
      best[joint] = max(best[joint], shield.tracking_error(q + error, q)
                        / shield.tracking_bound(q + error, q))
  assert np.all(best >= 0.5), best


def test_resync_restarts_at_rest_at_the_measured_pose(panda):
  """A person pushed the moving robot 0.3 rad off its command: the shield
  stands still where the robot is, keeps the goal and resumes from there,
  not from the stale command."""
  shield, t = _moving(panda)
  stale = shield.q.copy()
  goal = shield.goal.copy()
  measured = stale + np.array([0.0, 0.3, 0.0, -0.2, 0.0, 0.0, 0.0])
  assert shield.tracking_error(measured) > shield.tracking_tolerance
  shield.resync(measured)
  np.testing.assert_array_equal(shield.q, measured)
  assert not shield.dq.any() and not shield.ddq.any()
  np.testing.assert_array_equal(shield.goal, goal)
  assert shield.goal_pending
  assert shield.s_dot == 0.0 and shield.max_cartesian_speed == 0.0
  # The next command starts at the measured pose (one cycle from rest).
  q, dq, _ = shield.step(None, t)
  assert np.abs(q - measured).max() < 1e-4
  assert np.abs(q - stale).max() > 0.29
  for i in range(1, 1500):
    shield.step(None, t + i * CYCLE)
  np.testing.assert_allclose(shield.q, goal, atol=1e-9)   # Goal reached.
  assert not shield.dq.any()


def test_resync_with_a_person_in_contact_keeps_the_robot_still(panda):
  shield, t = _moving(panda)
  blocking = _blocking_human(shield)
  measured = shield.q + 0.2
  shield.resync(measured)
  for i in range(50):
    q, dq, _ = shield.step(blocking, t + i * CYCLE)
    np.testing.assert_array_equal(q, measured)
    assert not dq.any() and not shield.is_safe


def test_resync_clips_to_the_limits_and_checks_its_input(panda):
  shield = _shield(panda)
  outside = panda.q_home.copy()
  outside[0] = panda.limits.q_max[0] + 0.05
  shield.resync(outside)
  assert shield.q[0] == panda.limits.q_max[0]
  assert not shield.goal_pending   # No goal was given: none to keep.
  with pytest.raises(ValueError, match=r'7 finite joint positions'):
    shield.resync(np.zeros(6))
  bad = panda.q_home.copy()
  bad[2] = np.nan
  with pytest.raises(ValueError, match=r'7 finite joint positions'):
    shield.resync(bad)


@pytest.mark.parametrize('mode', ['ssm', 'pfl', 'off'])
def test_resync_snapshots_continue_bit_for_bit(panda, mode):
  """A snapshot taken right after a resync (through JSON) restores a shield
  whose commands and verdicts continue exactly."""
  shield = _shield(panda, mode=mode)
  shield.new_goal(_goal(panda))
  human = harness.walk_in(speed=1.0, stop_x=0.6)
  for i in range(40):
    shield.step(human(i * CYCLE), i * CYCLE)
  shield.resync(shield.q + 0.05)
  state = shield.get_state()
  restored = _shield(panda, mode=mode)
  restored.set_state(json.loads(json.dumps(
      {k: v.tolist() if isinstance(v, np.ndarray) else v
       for k, v in state.items()})))
  for i in range(40, 120):
    t = i * CYCLE
    if i == 80:
      for s in (shield, restored):
        s.new_goal(_goal(panda, -0.5))
    outputs = [s.step(human(t), t) for s in (shield, restored)]
    for a, b in zip(*outputs):
      np.testing.assert_array_equal(a, b)
    assert shield.is_safe == restored.is_safe
    assert shield.intervened == restored.intervened
