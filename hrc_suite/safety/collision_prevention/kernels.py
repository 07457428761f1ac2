"""Compiled (numba) kernels of collision prevention's path checks.

`colliding` computes what prevention.CollisionPrevention's NumPy
reference (`_colliding_reference`) computes: the collision flags of
configurations against the workcell's boxes and of the checked capsule
pairs, with the same margins and escape masks. Forward kinematics are the
shield's kernels (`safety_kernels._frames`, `safety_kernels._endpoints`,
hrc_suite/safety/kernels.py); the capsule-box distance is
geometry.segment_box_distance's candidate scheme, the same operations in
the same order (`segment_box_distance`); capsule pairs use
`safety_kernels.segment_distance`. A configuration stops at its first hit.

`planned_path_collides` is collision prevention's whole sweep of one
long-term plan (`CollisionPrevention._planned_sweep`, the reference) in
one call, its arguments in named groups (`PlanPolynomial`,
`SweepSettings`, `RobotCapsules`, `CollisionTests`): the plan's
per-cycle Taylor polynomial sampled from its samples
(LongTermPlan.nominal), the margins of its motion bound, the checks and
their refinement, the same operations in the same order, so that it
rejects exactly the plans the reference rejects. A conservative broad
phase (`bounds`, docs/safety.md) skips, for runs of samples, only the
capsule tests it proves cannot hit at any of them. Same compilation
settings as `safety_kernels` (cache, IEEE arithmetic).
"""

import math
import typing

import numpy as np

from hrc_suite.safety import kernels as safety_kernels
from hrc_suite.safety.collision_prevention import bounds

_jit = safety_kernels._jit
_inline = safety_kernels._inline


class PlanPolynomial(typing.NamedTuple):
  """A long-term plan's per-cycle Taylor polynomial (LongTermPlan.nominal;
  collision_prevention._polynomial)."""
  coefficients: np.ndarray   # (N, 4, dof) q, dq, ddq, jerk per cycle
  start_time: float          # s, plan time of sample 0
  inverse_cycle: float       # 1/s
  cycle: float               # s
  cycle2: float              # cycle ** 2
  cycle3: float              # cycle ** 3
  last: int                  # N - 1


class SweepSettings(typing.NamedTuple):
  """How a plan is swept (collision_prevention's constants and levers)."""
  levers: np.ndarray        # (dof, L) capsule motion per joint motion
  pair_levers: np.ndarray   # (dof, P) relative motion of each pair
  max_step: float           # m, largest capsule motion between samples
  offsets: np.ndarray       # (R,) sub-sample positions in half widths
  levels: int               # refinement levels
  run: int                  # samples per run of the broad phase


class RobotCapsules(typing.NamedTuple):
  """The robot's capsule model (robot_reach.RobotReach's kernel model)."""
  fixed: np.ndarray         # (dof, 3, 4) fixed joint transforms
  points: np.ndarray        # (L, 2, 4) capsule ends in their frames
  frame_index: np.ndarray   # (L,) int64 each capsule's frame
  radii: np.ndarray         # (L,)


class CollisionTests(typing.NamedTuple):
  """The tests of a configuration: capsules against the workcell's boxes,
  and the checked capsule pairs."""
  box_min: np.ndarray         # (Bx, 3)
  box_max: np.ndarray         # (Bx, 3)
  box_checked: np.ndarray     # (Bx, L) bool
  box_allowance: np.ndarray   # (Bx, L) m of allowed penetration
  pairs: np.ndarray           # (P, 2) int64


@_jit
def _clip(x, low, high):
  return min(max(x, low), high)


@_jit
def _point_box_squared(p0, p1, p2, lo, hi):
  """Squared distance of a point to box (lo, hi) (3,) (0 inside)."""
  total = 0.0
  for r, x in ((0, p0), (1, p1), (2, p2)):
    gap = max(max(lo[r] - x, x - hi[r]), 0.0)
    total += gap * gap
  return total


@_jit
def segment_box_distance(a, b, lo, hi):
  """Distance of segment [a, b] (3,) to the box (lo, hi) (0 when touching):
  geometry.segment_box_distance for one segment and one box."""
  d = np.empty(3)
  for r in range(3):
    d[r] = b[r] - a[r]
  breaks = np.empty(8)
  for r in range(3):
    moving = d[r] != 0.0
    breaks[r] = _clip((lo[r] - a[r]) / d[r], 0.0, 1.0) if moving else 0.0
    breaks[3 + r] = _clip((hi[r] - a[r]) / d[r], 0.0, 1.0) if moving else 0.0
  breaks[6] = 0.0
  breaks[7] = 1.0
  breaks.sort()
  best = np.inf
  for i in range(8):
    x = breaks[i]
    best = min(best, _point_box_squared(a[0] + x * d[0], a[1] + x * d[1],
                                        a[2] + x * d[2], lo, hi))
  for i in range(7):
    low, high = breaks[i], breaks[i + 1]
    mid = 0.5 * (low + high)
    num = 0.0
    den = 0.0
    for r in range(3):
      x = a[r] + mid * d[r]
      if x < lo[r]:
        num += d[r] * (a[r] - lo[r])
        den += d[r] * d[r]
      elif x > hi[r]:
        num += d[r] * (a[r] - hi[r])
        den += d[r] * d[r]
    stationary = -num / den if den > 0 else mid
    x = _clip(stationary, low, high)
    best = min(best, _point_box_squared(a[0] + x * d[0], a[1] + x * d[1],
                                        a[2] + x * d[2], lo, hi))
  return math.sqrt(best)


@_jit
def _box_hit(ends, n, l, b, radius, box_min, box_max, box_allowance):
  """Whether capsule l of configuration n (radius grown by its margin)
  hits box b: its bounding box overlaps, and its distance is below minus
  the allowance."""
  for r in range(3):
    low = min(ends[n, l, 0, r], ends[n, l, 1, r]) - radius
    high = max(ends[n, l, 0, r], ends[n, l, 1, r]) + radius
    if low > box_max[b, r] or high < box_min[b, r]:
      return False
  distance = segment_box_distance(ends[n, l, 0], ends[n, l, 1], box_min[b],
                                  box_max[b]) - radius
  return distance < -box_allowance[b, l]


@_jit
def _pair_hit(ends, n, p, radii, pairs, pair_margin):
  """Whether pair p of configuration n is closer than its margin."""
  i, j = pairs[p, 0], pairs[p, 1]
  a0, a1 = ends[n, i, 0], ends[n, i, 1]
  b0, b1 = ends[n, j, 0], ends[n, j, 1]
  distance = safety_kernels.segment_distance(
      a0[0], a0[1], a0[2], b0[0], b0[1], b0[2],
      a1[0] - a0[0], a1[1] - a0[1], a1[2] - a0[2],
      b1[0] - b0[0], b1[1] - b0[1], b1[2] - b0[2]) - radii[i] - radii[j]
  return distance < pair_margin[n, p]


@_jit
def _hit(ends, n, radii, capsule_margin, pair_margin, box_min, box_max,
         box_checked, box_allowance, pairs, ignore_boxes, ignore_pairs):
  """Whether configuration n (capsule ends (N, L, 2, 3)) collides: the
  test of `colliding` for one configuration."""
  count_l = radii.shape[0]
  masked_boxes = ignore_boxes.shape[0] > 0
  masked_pairs = ignore_pairs.shape[0] > 0
  for b in range(box_min.shape[0]):
    for l in range(count_l):
      if not box_checked[b, l] or (masked_boxes and ignore_boxes[n, b, l]):
        continue
      if _box_hit(ends, n, l, b, radii[l] + capsule_margin[n, l], box_min,
                  box_max, box_allowance):
        return True
  for p in range(pairs.shape[0]):
    if masked_pairs and ignore_pairs[n, p]:
      continue
    if _pair_hit(ends, n, p, radii, pairs, pair_margin):
      return True
  return False


@_jit
def _hit_some(ends, n, radii, capsule_margin, pair_margin, box_min,
              box_max, box_allowance, pairs, box_todo, boxes, pair_todo,
              count):
  """`_hit` restricted to the tests box_todo[:boxes] (flat b * L + l) and
  pair_todo[:count] (the others proven not to hit: bounds)."""
  count_l = radii.shape[0]
  for k in range(boxes):
    b, l = box_todo[k] // count_l, box_todo[k] % count_l
    if _box_hit(ends, n, l, b, radii[l] + capsule_margin[n, l], box_min,
                box_max, box_allowance):
      return True
  for k in range(count):
    if _pair_hit(ends, n, pair_todo[k], radii, pairs, pair_margin):
      return True
  return False


@_jit
def colliding(q, fixed, points, frame_index, radii, capsule_margin,
              pair_margin, box_min, box_max, box_checked, box_allowance,
              pairs, ignore_boxes, ignore_pairs):
  """Collision flags (N,) of configurations q (N, dof).

  Capsules (radii (L,)) are inflated by capsule_margin (N, L) against the
  boxes (box_min, box_max (Bx, 3); box_checked, box_allowance (Bx, L));
  pairs (P, 2) need a clearance of pair_margin (N, P). ignore_boxes (N, Bx,
  L) and ignore_pairs (N, P) leave elements out; pass shape (0, ...) for
  none."""
  ends = safety_kernels._endpoints(safety_kernels._frames(q, fixed),
                                   points, frame_index)
  hit = np.zeros(q.shape[0], dtype=np.bool_)
  for n in range(q.shape[0]):
    hit[n] = _hit(ends, n, radii, capsule_margin, pair_margin, box_min,
                  box_max, box_checked, box_allowance, pairs, ignore_boxes,
                  ignore_pairs)
  return hit


@_jit
def _lever_sum(x, levers, column):
  """sum_k x[k] levers[k, column], joint by joint in order (as
  collision_prevention._lever_sum)."""
  total = x[0] * levers[0, column]
  for k in range(1, x.shape[0]):
    total = total + x[k] * levers[k, column]
  return total


@_jit
def _plan_point(plan, s, half, row, q, reach):
  """The plan's Taylor polynomial (PlanPolynomial) at plan time s
  (LongTermPlan.nominal) into q[row], and the reach of its motion within
  `half` of s into reach[row] (the motion bound of planned_paths_free's
  `evaluate`, whose lever sums are the margins: `_margins`)."""
  coefficients = plan.coefficients
  dof = coefficients.shape[2]
  k = math.floor((s - plan.start_time) * plan.inverse_cycle)
  k = int(min(max(k, 0.0), float(plan.last)))
  tau = s - plan.start_time - k * plan.cycle
  for d in range(dof):
    c0, c1 = coefficients[k, 0, d], coefficients[k, 1, d]
    c2, j = coefficients[k, 2, d], coefficients[k, 3, d]
    a = c2 + tau * j
    v = c1 + tau * (c2 + 0.5 * tau * j)
    q[row, d] = c0 + tau * (c1 + tau * (0.5 * c2 + tau * j / 6.0))
    reach[row, d] = half * (abs(v) + half * (abs(a) / 2
                                             + half * abs(j) / 6))


@_jit
def _margins(reach, row, levers, pair_levers, capsule_margin, pair_margin,
             out):
  """Capsule and pair margins of reach[row] into row `out`."""
  for l in range(levers.shape[1]):
    capsule_margin[out, l] = _lever_sum(reach[row], levers, l)
  for p in range(pair_levers.shape[1]):
    pair_margin[out, p] = _lever_sum(reach[row], pair_levers, p)


@_jit
def _cycle_pieces(plan, levers, max_step):
  """Samples per plan cycle (planned_paths_free's `pieces`): the motion
  over a whole cycle of the plan (PlanPolynomial) bounded from the
  cycle's sample, over max_step.

  A cycle whose travel moves no capsule more than max_step even with each
  joint's largest lever needs one sample without the per-capsule sums:
  floating-point products and sums of non-negative numbers are monotone,
  so every capsule's computed sum is at most that one."""
  coefficients, start_time, inverse_cycle = (plan.coefficients,
                                             plan.start_time,
                                             plan.inverse_cycle)
  cycle, cycle2, cycle3, last = (plan.cycle, plan.cycle2, plan.cycle3,
                                 plan.last)
  count = last + 1
  dof = coefficients.shape[2]
  pieces = np.empty(count, dtype=np.int64)
  travel = np.empty(dof)
  widest = np.zeros((dof, 1))
  for d in range(dof):
    for l in range(levers.shape[1]):
      widest[d, 0] = max(widest[d, 0], levers[d, l])
  for i in range(count):
    s = start_time + cycle * i
    k = math.floor((s - start_time) * inverse_cycle)
    k = int(min(max(k, 0.0), float(last)))
    tau = s - start_time - k * cycle
    for d in range(dof):
      c2, j = coefficients[k, 2, d], coefficients[k, 3, d]
      v = abs(coefficients[k, 1, d] + tau * (c2 + 0.5 * tau * j))
      a = abs(c2 + tau * j)
      travel[d] = v * cycle + a * cycle2 / 2 + abs(j) * cycle3 / 6
    if math.ceil(_lever_sum(travel, widest, 0) / max_step) <= 1.0:
      pieces[i] = 1
      continue
    largest = -np.inf
    for l in range(levers.shape[1]):
      largest = max(largest, _lever_sum(travel, levers, l))
    pieces[i] = int(max(1.0, math.ceil(largest / max_step)))
  return pieces


@_jit
def sweep_samples(plan, levers, max_step):
  """The plan sweep's base samples of a PlanPolynomial: (plan times (S,),
  half widths (S,), configurations q (S, dof), reach (S, dof)
  (`_plan_point`)), each cycle cut into `_cycle_pieces` samples."""
  dof = plan.coefficients.shape[2]
  start_time, cycle = plan.start_time, plan.cycle
  pieces = _cycle_pieces(plan, levers, max_step)
  total = 0
  for i in range(pieces.shape[0]):
    total += pieces[i]
  params = np.empty(total)
  halves = np.empty(total)
  n = 0
  for i in range(pieces.shape[0]):
    width = cycle / pieces[i]
    for w in range(pieces[i]):
      params[n] = start_time + i * cycle + (w + 0.5) * width
      halves[n] = 0.5 * width
      n += 1
  q = np.empty((total, dof))
  reach = np.empty((total, dof))
  for n in range(total):
    _plan_point(plan, params[n], halves[n], n, q, reach)
  return params, halves, q, reach


@_jit
def run_motion(q, reach, first, stop, centre, motion):
  """m = D + R of bounds for the samples [first, stop) around sample
  `centre` into motion[0] (dof,): the largest joint displacement from
  the centre plus the largest reach."""
  for d in range(q.shape[1]):
    spread = 0.0
    largest = 0.0
    for n in range(first, stop):
      spread = max(spread, abs(q[n, d] - q[centre, d]))
      largest = max(largest, reach[n, d])
    motion[0, d] = spread + largest


@_inline
def _sweep_test_arrays(sweep, rows):
  """The capsule and pair counts (L, P) of a sweep (SweepSettings) and
  the arrays of its `_hit` calls: zero capsule margins (rows, L) and pair
  margins (rows, P), the tests without margins, and empty box and pair
  masks (nothing ignored)."""
  count_l = sweep.levers.shape[1]
  count_p = sweep.pair_levers.shape[1]
  return (count_l, count_p, np.zeros((rows, count_l)),
          np.zeros((rows, count_p)), np.zeros((0, 0, 0), dtype=np.bool_),
          np.zeros((0, 0), dtype=np.bool_))


@_jit
def _refine_collides(plan, sweep, robot, tests, base_ends, base_s,
                     base_half):
  """Whether a base sample (plan time base_s, half width base_half, ends
  base_ends (1, L, 2, 3)) that hits with its margins collides: a hit
  without margins does; else its len(offsets) sub-samples are checked
  with their margins, `levels` times, and at the last level a hit with
  margins collides. Depth first, with an early exit. plan:
  PlanPolynomial, sweep: SweepSettings, robot: RobotCapsules, tests:
  CollisionTests."""
  levers, pair_levers = sweep.levers, sweep.pair_levers
  offsets, levels = sweep.offsets, sweep.levels
  fixed, points, frame_index, radii = (robot.fixed, robot.points,
                                       robot.frame_index, robot.radii)
  box_min, box_max, box_checked, box_allowance, pairs = (
      tests.box_min, tests.box_max, tests.box_checked, tests.box_allowance,
      tests.pairs)
  dof = plan.coefficients.shape[2]
  count_l, count_p, zero_l, zero_p, no_boxes, no_pairs = _sweep_test_arrays(
      sweep, 1)
  # Refinement stack: (path parameter, half width, level).
  width = offsets.shape[0]
  stack_s = np.empty(levels * width + 1)
  stack_h = np.empty(levels * width + 1)
  stack_level = np.empty(levels * width + 1, dtype=np.int64)
  one_q = np.empty((1, dof))
  one_reach = np.empty((1, dof))
  one_capsule = np.empty((1, count_l))
  one_pair = np.empty((1, count_p))
  stack_s[0], stack_h[0], stack_level[0] = base_s, base_half, 0
  top = 1
  first = True
  while top > 0:
    top -= 1
    s, half, level = stack_s[top], stack_h[top], stack_level[top]
    if first:    # The base sample, already known to hit.
      sample_ends = base_ends
      first = False
    else:
      _plan_point(plan, s, half, 0, one_q, one_reach)
      _margins(one_reach, 0, levers, pair_levers, one_capsule, one_pair, 0)
      sample_ends = safety_kernels._endpoints(
          safety_kernels._frames(one_q, fixed), points, frame_index)
      if not _hit(sample_ends, 0, radii, one_capsule, one_pair, box_min,
                  box_max, box_checked, box_allowance, pairs, no_boxes,
                  no_pairs):
        continue
    if level == levels:
      return True
    if _hit(sample_ends, 0, radii, zero_l, zero_p, box_min, box_max,
            box_checked, box_allowance, pairs, no_boxes, no_pairs):
      return True
    for o in range(width):
      stack_s[top] = s + offsets[o] * half
      stack_h[top] = half / width
      stack_level[top] = level + 1
      top += 1
  return False


@_jit
def planned_path_collides(start, plan, sweep, robot, tests):
  """Whether a plan (PlanPolynomial: samples (N, 4, dof) one cycle apart
  from start_time) from configuration start (1, dof) collides: 1 if it
  does, 0 if not, -1 if the start itself collides (not swept: the escape
  rule's reference sweep decides then). collision_prevention.
  planned_paths_free's sweep for a start not in collision, in one call,
  with the SweepSettings `sweep`, the robot's RobotCapsules and the
  CollisionTests. Each cycle is cut into samples moving no capsule point
  more than max_step; a sample colliding with its margins is checked
  exactly (a hit: the path collides) and else refined into len(offsets)
  sub-samples, `levels` times; at the last level a hit with margins
  collides (`_refine_collides`). A path collides iff some sample of the
  refinement tree does, as in the reference's level-by-level sweep; here
  all samples are checked exactly before any is refined (an early exit
  at the first hit without margins, and most colliding plans have one).

  Broad phase: runs of `run` samples are checked at their centre sample
  first (bounds.unproven); only the tests it cannot prove free are
  done at each sample of the run, so the same samples hit.

  The groups are the plain tuples of their fields (safety_kernels.as_fields:
  called for every goal checked)."""
  plan, sweep = PlanPolynomial(*plan), SweepSettings(*sweep)
  robot, tests = RobotCapsules(*robot), CollisionTests(*tests)
  levers, pair_levers = sweep.levers, sweep.pair_levers
  levels, run = sweep.levels, sweep.run
  fixed, points, frame_index, radii = (robot.fixed, robot.points,
                                       robot.frame_index, robot.radii)
  box_min, box_max, box_checked, box_allowance, pairs = (
      tests.box_min, tests.box_max, tests.box_checked, tests.box_allowance,
      tests.pairs)
  dof = plan.coefficients.shape[2]
  count_l, count_p, zero_l, zero_p, no_boxes, no_pairs = _sweep_test_arrays(
      sweep, run)
  ends = safety_kernels._endpoints(safety_kernels._frames(start, fixed),
                                   points, frame_index)
  if _hit(ends, 0, radii, zero_l, zero_p, box_min, box_max, box_checked,
          box_allowance, pairs, no_boxes, no_pairs):
    return -1
  params, halves, q, reach = sweep_samples(plan, levers, sweep.max_step)
  total = params.shape[0]
  motion = np.empty((1, dof))
  capsule_motion = np.empty((1, count_l))
  pair_motion = np.empty((1, count_p))
  box_todo = np.empty(box_min.shape[0] * count_l, dtype=np.int64)
  pair_todo = np.empty(count_p, dtype=np.int64)
  capsule_margin = np.empty((run, count_l))
  pair_margin = np.empty((run, count_p))
  # Samples hitting with their margins but not without: refined after
  # the sweep (a hit without margins ends it first).
  pending = np.empty(total, dtype=np.int64)
  num_pending = 0
  for first in range(0, total, run):
    stop = min(first + run, total)
    centre = (first + stop) // 2
    run_motion(q, reach, first, stop, centre, motion)
    _margins(motion, 0, levers, pair_levers, capsule_motion, pair_motion, 0)
    ends = safety_kernels._endpoints(
        safety_kernels._frames(q[centre:centre + 1], fixed), points,
        frame_index)
    boxes, count = bounds.unproven(
        ends[0], capsule_motion[0], pair_motion[0], radii, box_min, box_max,
        box_checked, box_allowance, pairs, box_todo, pair_todo)
    if boxes == 0 and count == 0:
      continue
    ends = safety_kernels._endpoints(
        safety_kernels._frames(q[first:stop], fixed), points, frame_index)
    for n in range(first, stop):
      _margins(reach, n, levers, pair_levers, capsule_margin, pair_margin,
               n - first)
      if not _hit_some(ends, n - first, radii, capsule_margin, pair_margin,
                       box_min, box_max, box_allowance, pairs, box_todo,
                       boxes, pair_todo, count):
        continue
      if levels == 0 or _hit(ends, n - first, radii, zero_l, zero_p,
                             box_min, box_max, box_checked, box_allowance,
                             pairs, no_boxes, no_pairs):
        return 1
      pending[num_pending] = n
      num_pending += 1
  for k in range(num_pending):
    n = pending[k]
    ends = safety_kernels._endpoints(
        safety_kernels._frames(q[n:n + 1], fixed), points, frame_index)
    if _refine_collides(plan, sweep, robot, tests, ends, params[n],
                        halves[n]):
      return 1
  return 0


@_jit
def within_limits(q, q_min, q_max):
  """Flags (N,): configurations q (N, dof) within [q_min, q_max] (dof,)
  (CollisionPrevention._within)."""
  out = np.empty(q.shape[0], dtype=np.bool_)
  for n in range(q.shape[0]):
    inside = True
    for d in range(q.shape[1]):
      if not (q[n, d] >= q_min[d] and q[n, d] <= q_max[d]):
        inside = False
    out[n] = inside
  return out


_warm = False


def warm_up():
  """Compiles (or loads from the cache) `colliding` (with and without
  escape masks), `planned_path_collides` and `within_limits` for the
  argument types collision prevention passes."""
  global _warm
  if _warm:
    return
  dof, count_l, count_x, count_p = 2, 2, 1, 1
  floats = np.zeros
  masks = ((np.zeros((0, 0, 0), dtype=bool), np.zeros((0, 0), dtype=bool)),
           (np.zeros((1, count_x, count_l), dtype=bool),
            np.zeros((1, count_p), dtype=bool)))
  for boxes, pairs in masks:
    colliding(floats((1, dof)), floats((dof, 3, 4)),
              floats((count_l, 2, 4)), np.zeros(count_l, dtype=np.int64),
              floats(count_l), floats((1, count_l)), floats((1, count_p)),
              floats((count_x, 3)), floats((count_x, 3)),
              np.ones((count_x, count_l), dtype=bool),
              floats((count_x, count_l)),
              np.zeros((count_p, 2), dtype=np.int64), boxes, pairs)
  planned_path_collides(floats((1, dof)), *safety_kernels.as_fields((
      PlanPolynomial(floats((2, 4, dof)), 0.0, 1.0, 1.0, 1.0, 1.0, 1),
      SweepSettings(floats((dof, count_l)), floats((dof, count_p)), 1.0,
                    floats(2), 1, 1),
      RobotCapsules(floats((dof, 3, 4)), floats((count_l, 2, 4)),
                    np.zeros(count_l, dtype=np.int64), floats(count_l)),
      CollisionTests(floats((count_x, 3)), floats((count_x, 3)),
                     np.ones((count_x, count_l), dtype=bool),
                     floats((count_x, count_l)),
                     np.zeros((count_p, 2), dtype=np.int64)))))
  limit = floats(dof)
  limit.flags.writeable = False   # JointLimits' arrays are read-only.
  within_limits(floats((1, dof)), limit, limit)
  _warm = True
