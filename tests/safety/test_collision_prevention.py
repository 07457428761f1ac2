"""Tests for hrc_suite.safety.collision_prevention.prevention (all seven
robots)."""

import dataclasses

import numpy as np
import pytest

from hrc_suite import layout
from hrc_suite import robot_description
from hrc_suite.safety import geometry
from hrc_suite.safety.collision_prevention import prevention as prevention_lib


def _tool(description):
  """A gripper-like capsule: 12 cm along the flange's z, radius 4.5 cm."""
  start = description.flange_translation
  end = start + description.flange_rotation @ np.array([0.0, 0.0, 0.12])
  return start, end, 0.045


def _prevention(name, **kwargs):
  description = robot_description.load(name)
  return description, prevention_lib.CollisionPrevention(
      description, tool_capsule=_tool(description), **kwargs)


def _dense_free(prevention, description, q_start, q_goal, count=1500):
  """Brute force: goal within limits and no collision at `count` samples."""
  limits = description.limits
  if np.any(q_goal < limits.q_min) or np.any(q_goal > limits.q_max):
    return False
  s = np.linspace(0.0, 1.0, count)[1:]
  path = q_start + s[:, None] * (q_goal - q_start)
  return not prevention.in_collision(path).any()


def _static_and_self(prevention, q):
  """Independent exact check of single configurations (N, dof)."""
  p1, p2, r = prevention.reach.capsules(q)
  boxes = prevention_lib.workcell_boxes(
      mount=layout.robot_mount(prevention.description.name))
  hit = np.zeros(len(q), dtype=bool)
  for name, (lo, hi) in boxes.items():
    dist = geometry.capsule_box_distance(p1, p2, r, np.array(lo),
                                         np.array(hi))
    if name == 'pedestal':
      dist[:, 0] = np.inf  # The base-mounted link stands on it.
    hit |= np.any(dist < 0, axis=-1)
  count = len(r)
  for i in range(count):
    for j in range(i + 2, count):
      if (i, j) in prevention.excluded_pairs or (
          i == prevention.dof - 1 and j == count - 1):
        continue
      d = geometry.capsule_distance(p1[:, i], p2[:, i], r[i], p1[:, j],
                                    p2[:, j], r[j])
      hit |= d < 0
  return hit


@pytest.mark.parametrize('name', robot_description.ROBOT_NAMES)
def test_home_is_free_and_exclusions_follow_the_rule(name):
  description, prevention = _prevention(name)
  assert not prevention.in_collision(description.q_home)
  # Excluded pairs overlap at home or at every sampled configuration, or
  # the description exempts them.
  rs = np.random.RandomState(11)
  q = rs.uniform(description.limits.q_min, description.limits.q_max,
                 (300, description.dof))
  p1, p2, r = prevention.reach.capsules(np.vstack([description.q_home, q]))
  for i, j in prevention.excluded_pairs:
    assert j >= i + 2
    if (i, j) in description.self_collision_exempt:
      continue
    d = geometry.capsule_distance(p1[:, i], p2[:, i], r[i], p1[:, j],
                                  p2[:, j], r[j])
    assert d[0] < 0 or np.all(d < 0)
  # Configurations: the class agrees with an independent exact check.
  np.testing.assert_array_equal(prevention.in_collision(q),
                                _static_and_self(prevention, q))


@pytest.mark.parametrize('name', robot_description.ROBOT_NAMES)
def test_never_lets_a_colliding_path_through(name):
  """Property over random goals, against a dense brute-force check."""
  description, prevention = _prevention(name)
  rs = np.random.RandomState(12)
  limits = description.limits
  starts = [description.q_home] * 16
  goals = list(description.q_home + rs.uniform(-0.4, 0.4,
                                               (16, description.dof)))
  for _ in range(14):  # Random free starts, random goals.
    while True:
      q = rs.uniform(limits.q_min, limits.q_max)
      if not prevention.in_collision(q):
        break
    starts.append(q)
    goals.append(rs.uniform(limits.q_min, limits.q_max))
  verdicts = []
  for q_start, q_goal in zip(starts, goals):
    safe = prevention.is_safe(q_start, q_goal)
    dense = _dense_free(prevention, description, q_start, q_goal)
    assert not (safe and not dense), (q_start, q_goal)
    verdicts.append((safe, dense))
  # Non-trivial: both outcomes occur, and it is not much more conservative
  # than the dense check.
  assert {v[0] for v in verdicts} == {True, False}
  conservative = sum(1 for safe, dense in verdicts if dense and not safe)
  assert conservative <= 2


def test_table_pedestal_and_extra_boxes():
  description, prevention = _prevention('panda')
  home = description.q_home
  p1, p2, r = prevention.reach.capsules(home)
  # The tool above the table at home; pushing joint 2 forward drives the
  # arm into the table top.
  down = home.copy()
  down[1] = description.limits.q_max[1]
  assert prevention.in_collision(down)
  assert not prevention.is_safe(home, down)
  # The first link is not checked against its pedestal; the others are.
  assert not prevention._box_checked[prevention.box_names.index('pedestal'),
                                     0]
  assert prevention._box_checked[prevention.box_names.index('pedestal'),
                                 1:].all()
  # An extra box around the gripper's path: a small move through it fails.
  tip = p2[-1]
  box = (tip + [0.05, -0.05, -0.05], tip + [0.15, 0.05, 0.05])
  _, boxed = _prevention('panda', extra_boxes=[box])
  move = home.copy()
  move[1] += 0.25  # Reach forward, towards +x.
  assert prevention.is_safe(home, move)
  assert not boxed.is_safe(home, move)
  with pytest.raises(ValueError, match='extra_boxes'):
    _prevention('panda', extra_boxes=[((0, 0, 1), (0, 0, 0))])


def test_tool_may_touch_the_table_when_allowed():
  # A robot on the default mount (its pedestal top flush with the table).
  description, strict = _prevention('panda')
  _, lenient = _prevention('panda', tool_table_allowance=0.01)
  table = strict.box_names.index('table')
  lo, hi = strict.box_min[table], strict.box_max[table]

  def table_distance(q):
    p1, p2, r = strict.reach.capsules(q)
    return geometry.capsule_box_distance(p1, p2, r, lo, hi)

  def clear_elsewhere(q):  # The pedestal top is flush with the table.
    p1, p2, r = strict.reach.capsules(q)
    others = [geometry.capsule_box_distance(p1, p2, r, strict.box_min[b],
                                            strict.box_max[b])[1:]
              for b in range(len(strict.box_names)) if b != table]
    return np.all(np.array(others) > 0)

  # Lower the tool: move along minus the gradient of its table distance.
  home = description.q_home
  h = 1e-6
  gradient = np.array([(table_distance(home + h * e)[-1] -
                        table_distance(home)[-1]) / h
                       for e in np.eye(description.dof)])
  direction = -gradient / np.linalg.norm(gradient)
  found = 0
  for t in np.linspace(0.0, 1.0, 2001):
    q = home + t * direction
    d = table_distance(q)
    if (-0.008 < d[-1] < -0.001 and np.all(d[:-1] > 0) and
        clear_elsewhere(q)):
      found += 1
      assert strict.in_collision(q)
      assert not lenient.in_collision(q)
    if d[-1] < -0.02:
      assert lenient.in_collision(q)
  assert found > 0


def _joint_action(q_current, scale=0.3):
  return lambda action: q_current + scale * np.asarray(action)


@pytest.mark.parametrize('name', ['panda', 'ur5e', 'sawyer'])
def test_replacement_policies(name):
  description, prevention = _prevention(name)
  q = description.q_home
  to_goal = _joint_action(q, scale=1.0)
  rs = np.random.RandomState(14)
  # An action whose goal collides.
  while True:
    action = rs.uniform(-1, 1, description.dof)
    if not prevention.is_safe(q, to_goal(action)):
      break
  out, goal, replaced, _ = prevention.filter_action(action, q, to_goal,
                                                   'zero')
  assert replaced and np.all(out == 0) and np.all(goal == q)
  # Resample: the first safe sample of the seeded sequence.
  samples = np.random.RandomState(5).uniform(-1, 1, (20, description.dof))
  safe = [prevention.is_safe(q, to_goal(s)) for s in samples]
  assert any(safe), 'test needs a safe sample'
  out, goal, replaced, _ = prevention.filter_action(
      action, q, to_goal, 'resample', random_state=5)
  assert replaced
  np.testing.assert_array_equal(out, samples[safe.index(True)])
  assert prevention.is_safe(q, goal)
  # Closest: the safe sample nearest to the proposed action.
  out, goal, _, _ = prevention.filter_action(action, q, to_goal,
                                             'closest', random_state=5)
  gaps = [np.linalg.norm(s - action) if ok else np.inf
          for s, ok in zip(samples, safe)]
  np.testing.assert_array_equal(out, samples[int(np.argmin(gaps))])
  # Deterministic given the seed.
  again, _, _, _ = prevention.filter_action(action, q, to_goal, 'closest',
                                         random_state=np.random.RandomState(5))
  np.testing.assert_array_equal(out, again)
  # A safe action passes untouched.
  out, goal, replaced, _ = prevention.filter_action(
      samples[safe.index(True)], q, to_goal, 'closest', random_state=5)
  assert not replaced
  assert prevention.num_replacements == 4


def test_no_safe_sample_falls_back_to_zero():
  description, prevention = _prevention('iiwa')
  q = description.q_home
  fails = lambda action: None  # E.g. IK never converges.
  out, goal, replaced, _ = prevention.filter_action(
      np.ones(3), q, fails, 'resample', random_state=0, num_samples=5)
  assert replaced and np.all(out == 0) and np.all(goal == q)
  with pytest.raises(ValueError, match='policy'):
    prevention.filter_action(np.ones(3), q, fails, 'nearest')
  with pytest.raises(ValueError, match='random_state'):
    prevention.filter_action(np.ones(3), q, fails, 'closest')


def test_path_sampling_bounds_the_motion_between_samples():
  description, prevention = _prevention('iiwa')
  rs = np.random.RandomState(15)
  limits = description.limits
  for _ in range(5):
    q0, q1 = rs.uniform(limits.q_min, limits.q_max, (2, description.dof))
    steps = prevention._path_samples(q0, q1)
    s = np.linspace(0.0, 1.0, steps * 20 + 1)
    p1, p2, r = prevention.reach.capsules(q0 + s[:, None] * (q1 - q0))
    # Largest end-point motion within one step (20 sub-samples).
    moved = np.maximum(np.linalg.norm(p1[20:] - p1[:-20], axis=-1),
                       np.linalg.norm(p2[20:] - p2[:-20], axis=-1))
    assert moved.max() <= prevention_lib.DEFAULT_MAX_STEP + 1e-9
  assert layout.TABLE_TOP_Z == prevention.box_max[0, 2]


# -- Escape from a start in collision, and planned paths (Panda) -----------

_LOWER = np.eye(7)[1]   # Panda shoulder: lowers the gripper onto the table.


def _panda_near_table(depth):
  """(description, prevention, q) with the tool `depth` m into the table top
  (negative: above it) by lowering the shoulder from q_home."""
  description, prevention = _prevention('panda')
  home = description.q_home

  def table_depth(t):
    boxes, _ = prevention.penetrations((home + t * _LOWER)[None])
    return boxes[0, prevention.box_names.index('table')].max()

  low, high = 0.0, 0.6
  for _ in range(60):   # Bisection: the depth grows along this direction.
    middle = 0.5 * (low + high)
    low, high = (middle, high) if table_depth(middle) < depth else (low,
                                                                    middle)
  return description, prevention, home + high * _LOWER


def test_start_in_table_escapes_but_may_not_go_deeper():
  description, prevention, q = _panda_near_table(0.003)
  assert prevention.in_collision(q)
  home = description.q_home
  up, deeper = home, q + 0.1 * _LOWER
  sideways = q + 0.3 * np.eye(7)[0]     # Base rotation: stays in contact.
  free = prevention.paths_free(q, np.stack([up, deeper, sideways]))
  assert free.tolist()[:2] == [True, False]
  # Independent check of the sideways verdict: it is accepted only if the
  # table penetration at dense samples never increases until it is free.
  s = np.linspace(0.0, 1.0, 400)
  boxes, _ = prevention.penetrations(q + s[:, None] * (sideways - q))
  depth = boxes[:, prevention.box_names.index('table')].max(-1)
  free_from = np.argmax(depth <= 0) if np.any(depth <= 0) else len(depth)
  monotone = np.all(np.diff(depth[:free_from + 1]) <= 1e-6)
  after = not prevention.in_collision(q + s[free_from:, None]
                                      * (sideways - q)).any()
  assert free[2] == (monotone and after and free_from < len(depth))


@pytest.mark.parametrize('planned', [False, True])
def test_random_actions_get_the_robot_out_of_the_table(planned):
  """The deadlock of pick-and-place: from slightly inside the table, random
  joint-delta actions with 'zero' replacement reach a free configuration
  (before the escape rule every action was replaced for ever). planned:
  checked along the plan of a shield at rest at q."""
  description, prevention, q = _panda_near_table(0.004)
  rs = np.random.RandomState(1)
  depths = []
  for _ in range(40):
    boxes, _ = prevention.penetrations(q[None])
    depths.append(max(boxes.max(), 0.0))
    if not prevention.in_collision(q):
      break
    action = rs.uniform(-1.0, 1.0, 7)
    plan_from = _moving(q, np.zeros(7), description) if planned else None
    q = prevention.filter_action(action, q, lambda a: q + 0.05 * a,
                                 plan_from=plan_from).q_goal
  assert not prevention.in_collision(q)
  assert np.all(np.diff(depths) <= 1e-9)    # Never pushed deeper.
  assert prevention.num_replacements < 40


def _moving(q, dq, description):
  """A shield-like command for planned_paths_free."""
  import types
  return types.SimpleNamespace(q=q, dq=dq, ddq=np.zeros_like(q), s=0.0,
                               limits=description.limits, cycle_time=0.004)


def test_moving_robot_overshoot_into_the_table_is_rejected():
  description, prevention, q = _panda_near_table(-0.0175)   # 1.75 cm above.
  home = description.q_home
  moving = _moving(q, 0.5 * _LOWER, description)   # Shoulder going down.
  # The straight path up is free, the plan up first overshoots downwards.
  assert prevention.paths_free(q, home[None])[0]
  plan = prevention_lib.ltp.plan_to_goal(
      q, moving.dq, moving.ddq, home, description.limits, 0.004)
  dense = plan.nominal(np.linspace(0.0, plan.end_time, 3000))[0]
  assert prevention.in_collision(dense).any()
  assert not prevention.planned_paths_free(home[None], moving)[0]
  # At rest the same goal's plan is the straight path: accepted.
  plan_from_rest = prevention_lib.ltp.plan_to_goal(
      q, np.zeros_like(q), np.zeros_like(q), home, description.limits, 0.004,
      recent=False)
  assert prevention.planned_paths_free(home[None],
                                       _moving(q, 0.0 * _LOWER, description))[0]
  # filter_action with plan_from replaces the action; without, it does not.
  to_goal = lambda a: home
  assert prevention.filter_action(np.ones(1), q, to_goal,
                                  plan_from=moving)[2]
  assert not prevention.filter_action(np.ones(1), q, to_goal)[2]
  # An accepted goal comes with the plan checked (the shield's first
  # candidate): made from plan_from's command; no plan without plan_from.
  resting = _moving(q, 0.0 * _LOWER, description)
  kept = prevention.filter_action(np.ones(1), q, to_goal, plan_from=resting)
  assert not kept.replaced and kept.plan is not None
  goal = prevention_lib.ltp.clamp_goal(home, description.limits)
  assert kept.plan.made_from(np.array([q, resting.dq, resting.ddq]), goal,
                             description.limits, 0.004, 0.0)
  np.testing.assert_array_equal(kept.plan._all(), plan_from_rest._all())
  assert prevention.filter_action(np.ones(1), q, to_goal).plan is None


@pytest.mark.parametrize('name', ['panda', 'ur5e', 'kinova3'])
def test_planned_check_agrees_with_dense_plan_samples(name):
  """Random moving starts and goals: a plan accepted by planned_paths_free
  has no collision at 10 samples per plan cycle."""
  description, prevention = _prevention(name)
  limits = description.limits
  rs = np.random.RandomState(3)
  accepted = 0
  for _ in range(12):
    q = np.clip(description.q_home + rs.uniform(-0.4, 0.4, description.dof),
                limits.q_min + 0.1, limits.q_max - 0.1)
    if prevention.in_collision(q):
      continue
    moving = _moving(q, rs.uniform(-0.4, 0.4) * limits.v_max, description)
    goals = np.clip(q + rs.uniform(-0.6, 0.6, (4, description.dof)),
                    limits.q_min + 0.02, limits.q_max - 0.02)
    free = prevention.planned_paths_free(goals, moving)
    for goal, ok in zip(goals, free):
      if not ok:
        continue
      accepted += 1
      plan = prevention_lib.ltp.plan_to_goal(
          q, moving.dq, moving.ddq, goal, limits, 0.004)
      s = np.linspace(0.0, plan.end_time, 10 * plan.num_samples)
      assert not prevention.in_collision(plan.nominal(s)[0]).any()
  assert accepted > 5


@pytest.mark.parametrize('name', robot_description.ROBOT_NAMES)
def test_compiled_checks_match_the_numpy_reference(name):
  description, prevention = _prevention(name, tool_table_allowance=0.02)
  rs = np.random.RandomState(0)
  count = 3000
  q = rs.uniform(description.limits.q_min, description.limits.q_max,
                 (count, description.dof))
  margins = (rs.uniform(0, 0.05, (count, prevention.num_capsules)),
             rs.uniform(0, 0.05, (count, len(prevention.pairs))))
  masks = (rs.rand(count, len(prevention.box_names),
                   prevention.num_capsules) < 0.3,
           rs.rand(count, len(prevention.pairs)) < 0.3)
  for args in ((), margins, margins + masks, (None, None, masks[0], None)):
    fast = prevention._colliding(q, *args)
    assert np.array_equal(fast, prevention._colliding_reference(q, *args))
    assert 0 < fast.sum() < count   # Both outcomes are exercised.
  reference = prevention_lib.CollisionPrevention(
      description, tool_capsule=_tool(description),
      tool_table_allowance=0.02, compiled=False)
  goals = rs.uniform(description.limits.q_min, description.limits.q_max,
                     (40, description.dof))
  assert np.array_equal(prevention.paths_free(description.q_home, goals),
                        reference.paths_free(description.q_home, goals))


@pytest.mark.parametrize('name', ['panda', 'schunk', 'ur5e', 'kinova3'])
def test_compiled_planned_check_decides_as_the_numpy_reference(name):
  """The compiled sweep of planned paths (collision_prevention/kernels.py)
  rejects exactly the goals the reference rejects: random moving starts
  (free ones, and a few in collision: the escape rule's route) and goals
  around them; both outcomes occur."""
  description, prevention = _prevention(name)
  reference = prevention_lib.CollisionPrevention(
      description, tool_capsule=_tool(description), compiled=False)
  limits = description.limits
  rs = np.random.RandomState(5)
  decisions = {False: [], True: []}    # By start in collision.
  for _ in range(40):
    q = np.clip(description.q_home + rs.uniform(-0.8, 0.8, description.dof),
                limits.q_min + 0.05, limits.q_max - 0.05)
    start_hit = bool(prevention.in_collision(q))
    if start_hit and len(decisions[True]) >= 6:
      continue
    moving = _moving(q, rs.uniform(-0.5, 0.5) * limits.v_max, description)
    goals = np.clip(q + rs.uniform(-0.7, 0.7, (3, description.dof)),
                    limits.q_min, limits.q_max)
    fast = prevention.planned_paths_free(goals, moving)
    assert np.array_equal(fast, reference.planned_paths_free(goals, moving))
    decisions[start_hit].extend(fast.tolist())
  assert set(decisions[False]) == {True, False}
  assert len(decisions[False]) >= 45


def test_compiled_planned_check_refines_as_the_reference(monkeypatch):
  """Plans grazing the table (the Panda's tool 1 cm above it; 20 ms
  cycles and 5 cm steps make the margins large): many samples hit only
  with their margins, so the refinement decides (without it decisions
  change), and the compiled sweep decides as the reference."""
  description, _, q = _panda_near_table(-0.01)
  kwargs = dict(tool_capsule=_tool(description), max_step=0.05)
  prevention = prevention_lib.CollisionPrevention(description, **kwargs)
  reference = prevention_lib.CollisionPrevention(
      description, compiled=False, **kwargs)
  limits = description.limits
  rs = np.random.RandomState(0)
  scale = np.array([1.0, 0.1, 1.0, 0.3, 1.0, 0.3, 1.0])
  cases = []
  for _ in range(20):
    goals = np.clip(q + rs.uniform(-0.3, 0.3, (4, 7)) * scale, limits.q_min,
                    limits.q_max)
    moving = _moving(q, rs.uniform(-0.2, 0.2, 7), description)
    moving.cycle_time = 0.02
    cases.append((goals, moving))
  decided = [prevention.planned_paths_free(*case) for case in cases]
  for case, fast in zip(cases, decided):
    assert np.array_equal(fast, reference.planned_paths_free(*case))
  assert set(np.concatenate(decided).tolist()) == {True, False}
  # The sweep's settings are the module's constants when it is made.
  monkeypatch.setattr(prevention_lib, 'REFINE_LEVELS', 0)
  unrefining = prevention_lib.CollisionPrevention(description, **kwargs)
  unrefined = [unrefining.planned_paths_free(*case) for case in cases]
  assert not np.array_equal(np.concatenate(unrefined),
                            np.concatenate(decided))


def test_sawyer_wrist_pair_exemption():
  """Sawyer: the wrist pair (link5, link7) touches across the gripper-down
  band of q5 (sawyer.json's notes); without the description's exemption it
  flags poses there, with it only that pair is dropped."""
  description, prevention = _prevention('sawyer')
  assert (4, 6) in description.self_collision_exempt
  assert (4, 6) in prevention.excluded_pairs
  bare = prevention_lib.CollisionPrevention(
      dataclasses.replace(description, self_collision_exempt=()),
      tool_capsule=_tool(description))
  assert (4, 6) not in bare.excluded_pairs
  rs = np.random.RandomState(3)
  q = rs.uniform(description.limits.q_min, description.limits.q_max,
                 (2000, description.dof))
  q[:, 5] = rs.uniform(0.4, 1.6, len(q))   # The gripper-down band.
  with_exemption, without = prevention.in_collision(q), bare.in_collision(q)
  assert not np.any(with_exemption & ~without)
  assert np.any(without & ~with_exemption)
