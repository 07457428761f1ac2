"""Exact distance maths for segments, capsules, balls and boxes.

Everything broadcasts over leading axes (NumPy only). A capsule is the set of
points within radius r of the segment [p1, p2]; p1 == p2 is a ball.

The segment-segment routine computes the closest parameters of the two
infinite lines, clamps, and re-projects onto the other segment (the
clamp-and-reproject scheme of Ericson, "Real-Time Collision Detection",
2005, sec. 5.1.9). Parallel and degenerate (point) segments take explicit
branches, so overlapping parallel segments are exact (defect B3 of the SaRA
shield, docs/shield_maths.md, 10).
"""

import numpy as np

# Squared length below which a segment is treated as a point (m^2): 1e-24
# m^2 is a length of 1e-12 m, far below any geometric tolerance here.
_DEGENERATE_SQUARED_LENGTH = 1e-24
# sin^2 of the angle below which two segments are treated as parallel; the
# closest parameters of the infinite lines are ill-conditioned there and the
# clamp-and-reproject branch is exact instead.
_PARALLEL_SIN_SQUARED = 1e-12
# Distance below which two ball centres coincide (m).
_TINY_DISTANCE = 1e-300


def _dot(x, y):
  return np.vecdot(x, y)


def _clamp01(x):
  return np.minimum(np.maximum(x, 0.0), 1.0)


def closest_parameters(a, b, c, e, f):
  """Closest-point parameters (s, t) in [0, 1] of two segments from their
  dot products: a = d1.d1, b = d1.d2, c = d1.r, e = d2.d2, f = d2.r, with
  d1, d2 the segment directions and r = a0 - b0 (any matching shapes)."""
  a_ok = a > _DEGENERATE_SQUARED_LENGTH
  e_ok = e > _DEGENERATE_SQUARED_LENGTH
  denom = a * e - b * b           # >= 0 (Cauchy-Schwarz), 0 if parallel.
  general = denom > _PARALLEL_SIN_SQUARED * a * e
  # Non-parallel: closest point of the infinite lines, s clamped. Parallel or
  # degenerate: start from s = 0 (any s works, the reprojection fixes it).
  s = np.where(general,
               _clamp01((b * f - c * e) / np.where(general, denom, 1.0)), 0.0)
  # t closest to the point at s; a point segment b gets t = -1, which forces
  # the reprojection below onto t = 0.
  t = np.where(e_ok, (b * s + f) / np.where(e_ok, e, 1.0), -1.0)
  t_clamped = _clamp01(t)
  s_reprojected = _clamp01((b * t_clamped - c) / np.where(a_ok, a, 1.0))
  s = np.where(a_ok & (t != t_clamped), s_reprojected, s)
  return np.where(a_ok, s, 0.0), t_clamped


def segment_closest_parameters(a0, a1, b0, b1):
  """Parameters (s, t) in [0, 1] of the closest points a0 + s (a1 - a0) and
  b0 + t (b1 - b0); arrays broadcast over the leading axes of the inputs.
  """
  d1 = np.subtract(a1, a0)
  d2 = np.subtract(b1, b0)
  r = np.subtract(a0, b0)
  return closest_parameters(_dot(d1, d1), _dot(d1, d2), _dot(d1, r),
                            _dot(d2, d2), _dot(d2, r))


def segment_closest_points(a0, a1, b0, b1):
  """Closest points (p on segment a, q on segment b)."""
  s, t = segment_closest_parameters(a0, a1, b0, b1)
  p = a0 + s[..., None] * np.subtract(a1, a0)
  q = b0 + t[..., None] * np.subtract(b1, b0)
  return p, q


def segment_distance(a0, a1, b0, b1):
  """Minimum distance between segments [a0, a1] and [b0, b1] (..., 3)."""
  s, t = segment_closest_parameters(a0, a1, b0, b1)
  gap = (np.subtract(a0, b0) + s[..., None] * np.subtract(a1, a0)
         - t[..., None] * np.subtract(b1, b0))
  return np.sqrt(_dot(gap, gap))


def point_segment_distance(p, a0, a1):
  """Distance from points p to segments [a0, a1]."""
  d = np.subtract(a1, a0)
  w = np.subtract(p, a0)
  length_sq = _dot(d, d)
  ok = length_sq > _DEGENERATE_SQUARED_LENGTH
  s = np.where(ok, np.clip(_dot(w, d) / np.where(ok, length_sq, 1.0), 0, 1),
               0.0)
  gap = w - s[..., None] * d
  return np.sqrt(_dot(gap, gap))


def capsule_distance(a0, a1, ar, b0, b1, br):
  """Signed distance between capsules; < 0 means they intersect (strictly)."""
  return segment_distance(a0, a1, b0, b1) - ar - br


def capsule_contains_capsule(outer_p1, outer_p2, outer_r, p1, p2, r,
                             tolerance=0.0):
  """True where capsule (p1, p2, r) lies inside the outer capsule.

  A capsule is the convex hull of its two end balls and a capsule is convex,
  so containment of both end balls is exact.
  """
  d1 = point_segment_distance(p1, outer_p1, outer_p2)
  d2 = point_segment_distance(p2, outer_p1, outer_p2)
  return (np.maximum(d1, d2) + r) <= np.asarray(outer_r) + tolerance


def enclosing_ball(c1, r1, c2, r2):
  """Smallest ball enclosing balls (c1, r1) and (c2, r2)
  (docs/shield_maths.md, 8.4).

  With the larger ball i and the smaller j at distance d: if d <= ri - rj
  ball i already encloses j; else the centre lies on the line through both,
  ((ci + cj) + (ri - rj) (ci - cj) / d) / 2, radius (ri + rj + d) / 2.
  Both cases in one expression: lambda = clip((r1 - r2) / d, -1, 1),
  centre = (c1 + c2) / 2 + lambda (c1 - c2) / 2 (lambda = +-1 picks the
  enclosing ball), radius = max(r1, r2, (r1 + r2 + d) / 2).
  """
  c1 = np.asarray(c1, dtype=float)
  c2 = np.asarray(c2, dtype=float)
  r1 = np.asarray(r1, dtype=float)
  r2 = np.asarray(r2, dtype=float)
  delta = c1 - c2
  d = np.sqrt(np.vecdot(delta, delta))
  lam = np.minimum(np.maximum((r1 - r2) / np.maximum(d, _TINY_DISTANCE),
                              -1.0), 1.0)
  centre = c2 + (0.5 + 0.5 * lam)[..., None] * delta
  radius = np.maximum(np.maximum(r1, r2), 0.5 * (r1 + r2 + d))
  return centre, radius


def point_box_distance(p, box_min, box_max):
  """Euclidean distance from points to axis-aligned boxes (0 inside)."""
  outside = np.maximum(np.maximum(np.subtract(box_min, p),
                                  np.subtract(p, box_max)), 0.0)
  return np.sqrt(_dot(outside, outside))


def segment_box_distance(a0, a1, box_min, box_max):
  """Exact distance from segments [a0, a1] to axis-aligned boxes (0 if
  touching or inside).

  Along the segment the squared distance is convex and piecewise quadratic:
  its pieces end where the segment crosses a slab plane (at most 6 crossings)
  and inside a piece the set of violated slab bounds is fixed. The minimum
  is therefore at a crossing, an end, or the clipped stationary point of one
  piece's quadratic; all these candidates are evaluated.
  """
  a0 = np.asarray(a0, dtype=float)
  d = np.asarray(a1, dtype=float) - a0
  box_min = np.asarray(box_min, dtype=float)
  box_max = np.asarray(box_max, dtype=float)
  shape = np.broadcast_shapes(a0.shape, d.shape, box_min.shape, box_max.shape)
  a0, d, box_min, box_max = (np.broadcast_to(x, shape)
                             for x in (a0, d, box_min, box_max))
  moving = d != 0.0
  d_safe = np.where(moving, d, 1.0)
  crossings = np.concatenate([
      np.where(moving, (box_min - a0) / d_safe, 0.0),
      np.where(moving, (box_max - a0) / d_safe, 0.0),
      np.zeros(shape[:-1] + (1,)), np.ones(shape[:-1] + (1,))], axis=-1)
  breaks = np.sort(np.clip(crossings, 0.0, 1.0), axis=-1)       # (..., 8)
  lo, hi = breaks[..., :-1], breaks[..., 1:]                     # (..., 7)
  mid = 0.5 * (lo + hi)
  a0_, d_ = a0[..., None, :], d[..., None, :]
  point = a0_ + mid[..., None] * d_                              # (..., 7, 3)
  lo_b, hi_b = box_min[..., None, :], box_max[..., None, :]
  below, above = point < lo_b, point > hi_b
  bound = np.where(below, lo_b, hi_b)
  active = below | above
  num = np.where(active, d_ * (a0_ - bound), 0.0).sum(axis=-1)
  den = np.where(active, d_ * d_, 0.0).sum(axis=-1)
  stationary = np.where(den > 0, -num / np.where(den > 0, den, 1.0), mid)
  stationary = np.clip(stationary, lo, hi)
  candidates = np.concatenate([breaks, stationary], axis=-1)     # (..., 15)
  points = a0_ + candidates[..., None] * d_
  return point_box_distance(points, lo_b, hi_b).min(axis=-1)


def capsule_box_distance(p1, p2, r, box_min, box_max):
  """Signed distance between capsules and boxes; < 0 means intersecting."""
  return segment_box_distance(p1, p2, box_min, box_max) - r
