"""Exact distance maths for segments, capsules, balls and boxes.

Everything broadcasts over leading axes (NumPy only). A capsule is the set of
points within radius r of the segment [p1, p2]; p1 == p2 is a ball.

The segment-segment routine computes the closest parameters of the two
infinite lines, clamps, and re-projects onto the other segment (the
clamp-and-reproject scheme of Ericson, "Real-Time Collision Detection",
2005, sec. 5.1.9). Parallel and degenerate (point) segments take explicit
branches, so overlapping parallel segments are exact (defect B3 of the SaRA
shield, shield-spec section 9).
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


def segment_closest_parameters(a0, a1, b0, b1):
  """Parameters (s, t) in [0, 1] of the closest points a0 + s (a1 - a0), ...

  Returns arrays broadcast over the leading axes of the inputs.
  """
  d1 = np.subtract(a1, a0)
  d2 = np.subtract(b1, b0)
  r = np.subtract(a0, b0)
  a = _dot(d1, d1)
  e = _dot(d2, d2)
  b = _dot(d1, d2)
  c = _dot(d1, r)
  f = _dot(d2, r)
  a_ok = a > _DEGENERATE_SQUARED_LENGTH
  e_ok = e > _DEGENERATE_SQUARED_LENGTH
  a_safe = np.where(a_ok, a, 1.0)
  e_safe = np.where(e_ok, e, 1.0)
  denom = a * e - b * b
  general = a_ok & e_ok & (denom > _PARALLEL_SIN_SQUARED * a * e)
  # Non-parallel: closest point of the infinite lines, s clamped. Parallel or
  # degenerate: start from s = 0 (any s works, the reprojection fixes it).
  s = np.where(general,
               np.clip((b * f - c * e) / np.where(general, denom, 1.0),
                       0.0, 1.0), 0.0)
  # t closest to the point at s; a point segment b gets t = -1, which forces
  # the reprojection below onto t = 0.
  t = np.where(e_ok, (b * s + f) / e_safe, -1.0)
  t_clamped = np.clip(t, 0.0, 1.0)
  s_reprojected = np.clip((b * t_clamped - c) / a_safe, 0.0, 1.0)
  s = np.where(a_ok, np.where(t != t_clamped, s_reprojected, s), 0.0)
  return s, t_clamped


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
  """Smallest ball enclosing balls (c1, r1) and (c2, r2) (shield-spec 4.4).

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


# Golden-section iterations for segment-box distance: the bracket shrinks by
# 0.618 per step, 0.618^64 ~ 4e-14 of the segment length.
_GOLDEN_ITERATIONS = 64
_INV_GOLDEN = (np.sqrt(5.0) - 1.0) / 2.0


def segment_box_distance(a0, a1, box_min, box_max):
  """Distance from segments [a0, a1] to axis-aligned boxes (0 if touching).

  The distance of a point to a convex set is convex, so along the segment it
  is a convex function of the parameter; golden-section search finds its
  minimum to ~1e-13 of the segment length (plus endpoints checked exactly).
  """
  a0 = np.asarray(a0, dtype=float)
  d = np.asarray(a1, dtype=float) - a0
  box_min = np.asarray(box_min, dtype=float)
  box_max = np.asarray(box_max, dtype=float)
  shape = np.broadcast_shapes(a0.shape[:-1], d.shape[:-1], box_min.shape[:-1],
                              box_max.shape[:-1])
  lo = np.zeros(shape)
  hi = np.ones(shape)

  def dist(t):
    return point_box_distance(a0 + t[..., None] * d, box_min, box_max)

  x1 = hi - _INV_GOLDEN * (hi - lo)
  x2 = lo + _INV_GOLDEN * (hi - lo)
  f1, f2 = dist(x1), dist(x2)
  for _ in range(_GOLDEN_ITERATIONS):
    left = f1 <= f2  # Minimum in [lo, x2].
    hi = np.where(left, x2, hi)
    lo = np.where(left, lo, x1)
    new_x1 = hi - _INV_GOLDEN * (hi - lo)
    new_x2 = lo + _INV_GOLDEN * (hi - lo)
    x1n = np.where(left, new_x1, x2)
    x2n = np.where(left, x1, new_x2)
    f1n = np.where(left, dist(new_x1), f2)
    f2n = np.where(left, f1, dist(new_x2))
    x1, x2, f1, f2 = x1n, x2n, f1n, f2n
  best = np.minimum(np.minimum(f1, f2),
                    np.minimum(dist(np.zeros(shape)), dist(np.ones(shape))))
  return best


def capsule_box_distance(p1, p2, r, box_min, box_max):
  """Signed distance between capsules and boxes; < 0 means intersecting."""
  return segment_box_distance(p1, p2, box_min, box_max) - r
