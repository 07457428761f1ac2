"""The broad phase of collision prevention's plan sweep
(collision_prevention/bounds.py): its distance bounds never exceed the
distances, and on plans near the table and near self-collision every
capsule test that hits at a sample of a run is one the broad phase left
unproven (so the sweep decides as before)."""

import numpy as np
import pytest

from hrc_suite import robot_description
from hrc_suite.safety import geometry
from hrc_suite.safety import kernels
from hrc_suite.safety import long_term_plan as ltp
from hrc_suite.safety.collision_prevention import bounds
from hrc_suite.safety.collision_prevention import kernels as collision_kernels
from hrc_suite.safety.collision_prevention import prevention as prevention_lib


def _segments(rng, count):
  """Random segment pairs, with nearly parallel, crossing, touching and
  point segments among them."""
  out = []
  for _ in range(count):
    a0 = rng.uniform(-0.5, 0.5, 3)
    d = rng.normal(size=3) * rng.uniform(0.0, 0.6)
    kind = rng.randint(5)
    if kind == 0:     # Nearly parallel, close.
      b0 = a0 + rng.normal(size=3) * rng.choice([1e-6, 1e-3, 0.05])
      b1 = b0 + d * rng.uniform(-1.5, 1.5) + 1e-7 * rng.normal(size=3)
    elif kind == 1:   # Point segments.
      b0 = a0 + rng.normal(size=3) * 0.1
      b1 = b0.copy()
      d = d * rng.choice([0.0, 1.0])
    elif kind == 2:   # Crossing or touching.
      b0 = a0 + 0.5 * d - rng.normal(size=3) * 0.1
      b1 = 2 * (a0 + 0.5 * d) - b0 + rng.normal(size=3) * 1e-4
    else:
      b0 = rng.uniform(-0.5, 0.5, 3)
      b1 = b0 + rng.normal(size=3) * rng.uniform(0.0, 0.6)
    out.append((a0, a0 + d, b0, b1))
  return out


def _brute_distance(a0, a1, b0, b1, count=400):
  """Smallest distance over dense points of both segments (>= the true
  distance)."""
  s = np.linspace(0.0, 1.0, count)[:, None]
  a = a0 + s * (a1 - a0)
  b = b0 + s * (b1 - b0)
  return np.sqrt(((a[:, None] - b[None]) ** 2).sum(-1)).min()


def test_segment_bound_never_exceeds_the_distance_and_is_tight():
  rng = np.random.RandomState(0)
  gaps = []
  for a0, a1, b0, b1 in _segments(rng, 600):
    bound = bounds.segment_lower_bound(a0, a1, b0, b1)
    distance = float(geometry.segment_distance(a0, a1, b0, b1))
    assert bound <= _brute_distance(a0, a1, b0, b1) + 1e-12
    assert bound <= distance + 1e-12
    gaps.append(distance - bound)
  # Tight (an exact distance, up to round-off) for most pairs.
  assert np.median(gaps) < 1e-12
  assert np.mean(np.array(gaps) < 1e-9) > 0.9


def test_box_bound_never_exceeds_the_distance():
  rng = np.random.RandomState(1)
  lo, hi = np.array([0.2, -0.4, 0.0]), np.array([0.9, 0.4, 0.05])
  equal = 0
  for a0, a1, _, _ in _segments(rng, 600):
    a0, a1 = a0 + (0.5, 0.0, 0.1), a1 + (0.5, 0.0, 0.1)
    bound = bounds.box_lower_bound(a0, a1, lo, hi)
    distance = float(geometry.segment_box_distance(a0, a1, lo, hi))
    assert bound <= distance + 1e-12
    equal += abs(bound - distance) < 1e-12
  assert equal > 100    # Exact above the table top, for instance.


def _tool(description):
  start = description.flange_translation
  end = start + description.flange_rotation @ np.array([0.0, 0.0, 0.12])
  return start, end, 0.045


def _near_starts(prevention, rng, count, clearance=0.03):
  """Free configurations with a capsule within `clearance` of the table or
  of another capsule (half of each, as far as found)."""
  description = prevention.description
  limits = description.limits
  table = prevention.box_names.index('table')
  near = {'table': [], 'self': []}
  for _ in range(200):
    q = rng.uniform(limits.q_min, limits.q_max, (200, description.dof))
    boxes, pairs = prevention.penetrations(q)
    free = ~prevention.in_collision(q)
    depth_table = boxes[:, table].max(-1)
    depth_pairs = pairs.max(-1) if pairs.shape[1] else np.full(len(q), -1)
    near['table'] += list(q[free & (depth_table > -clearance)])
    near['self'] += list(q[free & (depth_pairs > -clearance)])
    if min(len(v) for v in near.values()) >= count // 2:
      break
  return near['table'][:count // 2] + near['self'][:count // 2]


def _plans(prevention, rng, count):
  """Long-term plans from moving starts near the table or near
  self-collision to goals around them (the cases where the broad phase
  must leave tests unproven)."""
  description = prevention.description
  limits = description.limits
  plans = []
  for q in _near_starts(prevention, rng, count):
    dq = rng.uniform(-0.4, 0.4, description.dof) * limits.v_max
    goal = q + rng.uniform(-0.5, 0.5, description.dof)
    try:
      plans.append(ltp.plan_to_goal(q, dq, np.zeros_like(q), goal, limits,
                                    0.004))
    except ltp.PlanningError:
      continue
  return plans


def _element_hits(prevention, q, capsule_margin, pair_margin):
  """NumPy: which capsule-box tests (S, Bx, L) and pairs (S, P) hit at
  configurations q (S, dof) with margins (the tests of
  CollisionPrevention._colliding_reference, element by element)."""
  p1, p2, r = prevention.reach.capsules(q)
  radius = r + capsule_margin
  lo = np.minimum(p1, p2) - radius[..., None]
  hi = np.maximum(p1, p2) + radius[..., None]
  box_min = prevention.box_min[None, :, None]
  box_max = prevention.box_max[None, :, None]
  overlap = np.all((lo[:, None] <= box_max) & (hi[:, None] >= box_min), -1)
  distance = geometry.capsule_box_distance(p1[:, None], p2[:, None],
                                           radius[:, None], box_min, box_max)
  boxes = (overlap & prevention._box_checked[None]
           & (distance < -prevention._box_allowance[None]))
  i, j = prevention.pairs[:, 0], prevention.pairs[:, 1]
  pairs = geometry.capsule_distance(p1[:, i], p2[:, i], r[i], p1[:, j],
                                    p2[:, j], r[j]) < pair_margin
  return boxes, pairs


@pytest.mark.parametrize('name', ['schunk', 'panda'])
def test_every_hit_is_left_unproven(name):
  """Runs of SWEEP_RUN samples of plans near the table and near
  self-collision: a test that hits (with its margin) at any sample of a
  run is among those `bounds.unproven` leaves for the exact check;
  both proven and unproven runs, and hits, occur."""
  description = robot_description.load(name)
  prevention = prevention_lib.CollisionPrevention(
      description, tool_capsule=_tool(description), tool_table_allowance=0.01)
  rng = np.random.RandomState(2)
  run = prevention_lib.SWEEP_RUN
  count_l, count_b = prevention.num_capsules, len(prevention.box_names)
  fixed, points = prevention.reach.kernel_model
  proven = unproven_runs = hits = 0
  for plan in _plans(prevention, rng, 24):
    _, _, q, reach = collision_kernels.sweep_samples(
        prevention_lib._polynomial(plan), prevention.levers,
        prevention.max_step)
    capsule_margin = prevention_lib._lever_sum(reach, prevention.levers)
    pair_margin = prevention_lib._lever_sum(reach, prevention._pair_levers)
    box_hits, pair_hits = _element_hits(prevention, q, capsule_margin,
                                        pair_margin)
    motion = np.empty((1, description.dof))
    for first in range(0, len(q), run):
      stop = min(first + run, len(q))
      centre = (first + stop) // 2
      collision_kernels.run_motion(q, reach, first, stop, centre, motion)
      ends = kernels._endpoints(kernels._frames(q[centre:centre + 1], fixed),
                                points, prevention.reach.kernel_frames)
      box_todo = np.empty(count_b * count_l, dtype=np.int64)
      pair_todo = np.empty(len(prevention.pairs), dtype=np.int64)
      boxes, count = bounds.unproven(
          ends[0], prevention_lib._lever_sum(motion, prevention.levers)[0],
          prevention_lib._lever_sum(motion, prevention._pair_levers)[0],
          prevention.reach.kernel_radii, prevention.box_min, prevention.box_max,
          prevention._box_checked, prevention._box_allowance,
          prevention._kernel_pairs, box_todo, pair_todo)
      box_open = np.zeros(count_b * count_l, dtype=bool)
      box_open[box_todo[:boxes]] = True
      pair_open = np.zeros(len(prevention.pairs), dtype=bool)
      pair_open[pair_todo[:count]] = True
      run_boxes = box_hits[first:stop].any(0).ravel()
      run_pairs = pair_hits[first:stop].any(0)
      assert not np.any(run_boxes & ~box_open)
      assert not np.any(run_pairs & ~pair_open)
      hits += run_boxes.sum() + run_pairs.sum()
      if boxes or count:
        unproven_runs += 1
      else:
        proven += 1
  assert proven > 100 and unproven_runs > 20 and hits > 20


@pytest.mark.parametrize('name', ['schunk', 'panda', 'ur5e'])
def test_sweep_decides_as_the_reference_near_contact(name):
  """planned_paths_free with the compiled sweep (broad phase included)
  accepts exactly the goals the NumPy reference accepts, from moving
  starts near the table and near self-collision (some goals beyond the
  joint limits); both outcomes occur."""
  import types
  description = robot_description.load(name)
  kwargs = dict(tool_capsule=_tool(description), tool_table_allowance=0.01)
  prevention = prevention_lib.CollisionPrevention(description, **kwargs)
  reference = prevention_lib.CollisionPrevention(description,
                                                 compiled=False, **kwargs)
  limits = description.limits
  rng = np.random.RandomState(3)
  decided = []
  for q in _near_starts(prevention, rng, 30):
    moving = types.SimpleNamespace(
        q=q, dq=rng.uniform(-0.4, 0.4, description.dof) * limits.v_max,
        ddq=np.zeros_like(q), s=0.0, limits=limits, cycle_time=0.004)
    # Some goals beyond the joint limits (not within: rejected).
    goals = q + rng.uniform(-0.5, 0.5, (3, description.dof))
    fast = prevention.planned_paths_free(goals, moving)
    assert np.array_equal(fast, reference.planned_paths_free(goals, moving))
    decided += fast.tolist()
  assert 0.1 < np.mean(decided) < 0.9
