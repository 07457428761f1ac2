"""Compiled (numba) kernels of collision prevention's path checks.

`colliding` computes what collision_prevention.CollisionPrevention's NumPy
reference (`_colliding_reference`) computes: the collision flags of
configurations against the workcell's boxes and of the checked capsule
pairs, with the same margins and escape masks. Forward kinematics are the
shield's kernels (`kernels._frames`, `kernels._endpoints`); the capsule-box
distance is geometry.segment_box_distance's candidate scheme, the same
operations in the same order (`segment_box_distance`); capsule pairs use
`kernels.segment_distance`. A configuration stops at its first hit.

`planned_path_collides` is collision prevention's whole sweep of one
long-term plan (`CollisionPrevention._planned_sweep`, the reference) in
one call: the plan's per-cycle Taylor polynomial sampled from its samples
(LongTermPlan.nominal), the margins of its motion bound, the checks and
their refinement, the same operations in the same order, so that it
rejects exactly the plans the reference rejects. Same compilation
settings as `kernels` (cache, IEEE arithmetic).
"""

import math

import numpy as np

from hrc_suite.safety import kernels

_jit = kernels._jit


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
      radius = radii[l] + capsule_margin[n, l]
      outside = False
      for r in range(3):
        low = min(ends[n, l, 0, r], ends[n, l, 1, r]) - radius
        high = max(ends[n, l, 0, r], ends[n, l, 1, r]) + radius
        if low > box_max[b, r] or high < box_min[b, r]:
          outside = True
      if outside:
        continue
      distance = segment_box_distance(ends[n, l, 0], ends[n, l, 1],
                                      box_min[b], box_max[b]) - radius
      if distance < -box_allowance[b, l]:
        return True
  for p in range(pairs.shape[0]):
    if masked_pairs and ignore_pairs[n, p]:
      continue
    i, j = pairs[p, 0], pairs[p, 1]
    a0, a1 = ends[n, i, 0], ends[n, i, 1]
    b0, b1 = ends[n, j, 0], ends[n, j, 1]
    distance = kernels.segment_distance(
        a0[0], a0[1], a0[2], b0[0], b0[1], b0[2],
        a1[0] - a0[0], a1[1] - a0[1], a1[2] - a0[2],
        b1[0] - b0[0], b1[1] - b0[1], b1[2] - b0[2]) - radii[i] - radii[j]
    if distance < pair_margin[n, p]:
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
  ends = kernels._endpoints(kernels._frames(q, fixed), points,
                            frame_index)
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
def _plan_sample(coefficients, start_time, inverse_cycle, cycle, last, s,
                 half, levers, pair_levers, row, q, capsule_margin,
                 pair_margin):
  """The plan's Taylor polynomial at plan time s (LongTermPlan.nominal)
  into q[row], and the margins covering it within `half` of s (the
  motion bound of planned_paths_free's `evaluate`) into the margin rows."""
  dof = coefficients.shape[2]
  k = math.floor((s - start_time) * inverse_cycle)
  k = int(min(max(k, 0.0), float(last)))
  tau = s - start_time - k * cycle
  reach = np.empty(dof)
  for d in range(dof):
    c0, c1 = coefficients[k, 0, d], coefficients[k, 1, d]
    c2, j = coefficients[k, 2, d], coefficients[k, 3, d]
    a = c2 + tau * j
    v = c1 + tau * (c2 + 0.5 * tau * j)
    q[row, d] = c0 + tau * (c1 + tau * (0.5 * c2 + tau * j / 6.0))
    reach[d] = half * (abs(v) + half * (abs(a) / 2 + half * abs(j) / 6))
  for l in range(levers.shape[1]):
    capsule_margin[row, l] = _lever_sum(reach, levers, l)
  for p in range(pair_levers.shape[1]):
    pair_margin[row, p] = _lever_sum(reach, pair_levers, p)


@_jit
def _cycle_pieces(coefficients, start_time, inverse_cycle, cycle, cycle2,
                  cycle3, last, levers, max_step):
  """Samples per plan cycle (planned_paths_free's `pieces`): the motion
  over a whole cycle bounded from the cycle's sample, over max_step."""
  count = last + 1
  dof = coefficients.shape[2]
  pieces = np.empty(count, dtype=np.int64)
  travel = np.empty(dof)
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
    largest = -np.inf
    for l in range(levers.shape[1]):
      largest = max(largest, _lever_sum(travel, levers, l))
    pieces[i] = int(max(1.0, math.ceil(largest / max_step)))
  return pieces


@_jit
def planned_path_collides(coefficients, start_time, inverse_cycle, cycle,
                          cycle2, cycle3, last, levers, pair_levers,
                          max_step, offsets, levels, fixed, points,
                          frame_index, radii, box_min, box_max, box_checked,
                          box_allowance, pairs):
  """Whether a plan (samples (N, 4, dof) one cycle apart from start_time)
  collides: collision_prevention.planned_paths_free's sweep for a start
  not in collision, in one call. Each cycle is cut into samples moving no
  capsule point more than max_step (cycle2, cycle3: cycle**2, cycle**3);
  a sample colliding with its margins is checked exactly (a hit: the
  path collides) and else refined into len(offsets) sub-samples, `levels`
  times; at the last level a hit with margins collides. Depth first with
  an early exit: the reference's level-by-level sweep flags the same
  paths (a path collides iff some sample of the refinement tree does)."""
  dof = coefficients.shape[2]
  count_l = levers.shape[1]
  count_p = pair_levers.shape[1]
  no_boxes = np.zeros((0, 0, 0), dtype=np.bool_)
  no_pairs = np.zeros((0, 0), dtype=np.bool_)
  pieces = _cycle_pieces(coefficients, start_time, inverse_cycle, cycle,
                         cycle2, cycle3, last, levers, max_step)
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
  capsule_margin = np.empty((total, count_l))
  pair_margin = np.empty((total, count_p))
  for n in range(total):
    _plan_sample(coefficients, start_time, inverse_cycle, cycle, last,
                 params[n], halves[n], levers, pair_levers, n, q,
                 capsule_margin, pair_margin)
  ends = kernels._endpoints(kernels._frames(q, fixed), points, frame_index)
  zero_l = np.zeros((1, count_l))
  zero_p = np.zeros((1, count_p))
  # Refinement stack: (path parameter, half width, level).
  width = offsets.shape[0]
  stack_s = np.empty(levels * width + 1)
  stack_h = np.empty(levels * width + 1)
  stack_level = np.empty(levels * width + 1, dtype=np.int64)
  one_q = np.empty((1, dof))
  one_capsule = np.empty((1, count_l))
  one_pair = np.empty((1, count_p))
  for n in range(total):
    if not _hit(ends, n, radii, capsule_margin, pair_margin, box_min,
                box_max, box_checked, box_allowance, pairs, no_boxes,
                no_pairs):
      continue
    top = 0
    stack_s[0], stack_h[0], stack_level[0] = params[n], halves[n], 0
    top = 1
    first = True
    while top > 0:
      top -= 1
      s, half, level = stack_s[top], stack_h[top], stack_level[top]
      if first:    # The base sample, already known to hit.
        sample_ends = ends[n:n + 1]
        first = False
      else:
        _plan_sample(coefficients, start_time, inverse_cycle, cycle, last,
                     s, half, levers, pair_levers, 0, one_q, one_capsule,
                     one_pair)
        sample_ends = kernels._endpoints(kernels._frames(one_q, fixed),
                                         points, frame_index)
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


_warm = False


def warm_up():
  """Compiles (or loads from the cache) `colliding` (with and without
  escape masks) and `planned_path_collides` for the argument types
  collision prevention passes."""
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
  planned_path_collides(
      floats((2, 4, dof)), 0.0, 1.0, 1.0, 1.0, 1.0, 1,
      floats((dof, count_l)), floats((dof, count_p)), 1.0, floats(2), 1,
      floats((dof, 3, 4)), floats((count_l, 2, 4)),
      np.zeros(count_l, dtype=np.int64), floats(count_l),
      floats((count_x, 3)), floats((count_x, 3)),
      np.ones((count_x, count_l), dtype=bool), floats((count_x, count_l)),
      np.zeros((count_p, 2), dtype=np.int64))
  _warm = True
