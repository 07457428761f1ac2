"""Compiled (numba) kernels of collision prevention's path checks.

`colliding` computes what collision_prevention.CollisionPrevention's NumPy
reference (`_colliding_reference`) computes: the collision flags of
configurations against the workcell's boxes and of the checked capsule
pairs, with the same margins and escape masks. Forward kinematics are the
shield's kernels (`kernels._frames`, `kernels._endpoints`); the capsule-box
distance is geometry.segment_box_distance's candidate scheme, the same
operations in the same order (`segment_box_distance`); capsule pairs use
`kernels.segment_distance`. A configuration stops at its first hit. Same
compilation settings as `kernels` (cache, IEEE arithmetic).
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
  count = q.shape[0]
  count_l = radii.shape[0]
  count_b = box_min.shape[0]
  masked_boxes = ignore_boxes.shape[0] > 0
  masked_pairs = ignore_pairs.shape[0] > 0
  hit = np.zeros(count, dtype=np.bool_)
  for n in range(count):
    found = False
    for b in range(count_b):
      if found:
        break
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
          found = True
          break
    if not found:
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
          found = True
          break
    hit[n] = found
  return hit


_warm = False


def warm_up():
  """Compiles (or loads from the cache) `colliding` for the argument types
  collision prevention passes (with and without escape masks)."""
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
  _warm = True
