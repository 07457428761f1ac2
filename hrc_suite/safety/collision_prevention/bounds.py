"""Conservative broad phase of collision prevention's plan sweep.

`kernels.planned_path_collides` checks each sample n of a plan: a
capsule l hits a box b if its bounding box, grown by its radius rho_l and
margin cm_nl, overlaps the box and its computed axis distance d_nl to the
box has d_nl - rho_l - cm_nl < -alpha_bl (alpha: allowed penetration); a
pair (i, j) hits if its computed axis distance d_np has d_np - rho_i -
rho_j < pm_np. A sample that hits is refined; one that does not is done.

`unproven` proves, for a run of samples C with a centre sample c, which
of these tests cannot hit at any sample of C, from one forward kinematics
at c (docs/safety.md, "Collision prevention's broad phase"):

* Motion. Every point of capsule l moves at most sum_k lever_kl |dq_k|
  for a joint step dq, and capsule j in capsule i's frame at most
  sum_k pair_lever_kp |dq_k| (collision_prevention._setup_levers,
  _setup_pairs). With D_k = max_n |q_nk - q_ck| and R_k = max_n r_nk
  (r_n: the reach whose lever sums are sample n's margins, so cm_nl <=
  sum_k lever_kl R_k), m = D + R, M_l = sum_k lever_kl m_k and P_p =
  sum_k pair_lever_kp m_k bound both a sample's displacement from c and
  its margin.
* Boxes. The distance of a segment to an axis-aligned box is at least
  that of the segment's bounding box, G_bl = |max(lo - hi_seg, lo_seg -
  hi, 0)| (lo_seg, hi_seg: the segment's coordinate range at c). If
  G_bl - rho_l - M_l + alpha_bl >= SLACK, then at every n the true axis
  distance is >= G_bl - sum_k lever_kl D_k, so d_nl - rho_l - cm_nl >=
  -alpha_bl: no hit (when the bounding boxes do not even overlap, the
  sample skips the test: no hit either).
* Pairs. For any direction u, the gap between the segments' projections
  onto u over |u| is at most their distance; u from (nearly) closest
  points makes it (nearly) the distance. If that bound B_p - rho_i -
  rho_j - P_p >= SLACK, then d_np - rho_i - rho_j >= pm_np: no hit.

A computed distance is a distance between two points of the segments
(any parameters in [0, 1]), so never below the true one by more than
round-off; SLACK covers every round-off of these sums (float64 on
coordinates of at most metres: below 1e-13 m), and floating-point sums
and products of non-negative numbers are monotone, so the computed
margins obey the same bound. A test not proven is done in full, so the
samples' decisions are those of the full tests.
"""

import math

from hrc_suite.safety import kernels as safety_kernels

_jit = safety_kernels._jit

# Round-off allowance of the bounds (m): a million times the float64
# round-off of distances between points of a few metres (2.2e-16 per
# operation on a few tens of operations).
SLACK = 1e-9
# Squared length below which a segment counts as a point (as
# geometry._DEGENERATE_SQUARED_LENGTH).
_TINY = 1e-24


@_jit
def _clamp01(x):
  return min(max(x, 0.0), 1.0)


@_jit
def _dot(x0, x1, x2, y0, y1, y2):
  return x0 * y0 + x1 * y1 + x2 * y2


@_jit
def segment_lower_bound(a0, a1, b0, b1):
  """A lower bound of the distance of segments [a0, a1] and [b0, b1] (3,):
  their projections' gap on the direction u between (nearly) closest
  points, over |u| (0 if those coincide)."""
  d0, d1, d2 = a1[0] - a0[0], a1[1] - a0[1], a1[2] - a0[2]
  e0, e1, e2 = b1[0] - b0[0], b1[1] - b0[1], b1[2] - b0[2]
  r0, r1, r2 = a0[0] - b0[0], a0[1] - b0[1], a0[2] - b0[2]
  a = _dot(d0, d1, d2, d0, d1, d2)
  e = _dot(e0, e1, e2, e0, e1, e2)
  f = _dot(e0, e1, e2, r0, r1, r2)
  c = _dot(d0, d1, d2, r0, r1, r2)
  s = t = 0.0
  if a <= _TINY:
    t = _clamp01(f / e) if e > _TINY else 0.0
  elif e <= _TINY:
    s = _clamp01(-c / a)
  else:
    b = _dot(d0, d1, d2, e0, e1, e2)
    denom = a * e - b * b
    s = _clamp01((b * f - c * e) / denom) if denom > 0.0 else 0.0
    t = (b * s + f) / e
    if t < 0.0:
      t, s = 0.0, _clamp01(-c / a)
    elif t > 1.0:
      t, s = 1.0, _clamp01((b - c) / a)
  u0, u1, u2 = r0 + s * d0 - t * e0, r1 + s * d1 - t * e1, r2 + s * d2 - t * e2
  norm = math.sqrt(_dot(u0, u1, u2, u0, u1, u2))
  if not norm > 0.0:
    return 0.0
  pa0 = _dot(a0[0], a0[1], a0[2], u0, u1, u2)
  pa1 = _dot(a1[0], a1[1], a1[2], u0, u1, u2)
  pb0 = _dot(b0[0], b0[1], b0[2], u0, u1, u2)
  pb1 = _dot(b1[0], b1[1], b1[2], u0, u1, u2)
  gap = max(min(pa0, pa1) - max(pb0, pb1), min(pb0, pb1) - max(pa0, pa1))
  return max(gap, 0.0) / norm


@_jit
def box_lower_bound(a0, a1, lo, hi):
  """A lower bound of the distance of segment [a0, a1] (3,) to the box
  (lo, hi) (3,): the distance of the segment's bounding box to it."""
  total = 0.0
  for r in range(3):
    gap = max(max(lo[r] - max(a0[r], a1[r]), min(a0[r], a1[r]) - hi[r]),
              0.0)
    total += gap * gap
  return math.sqrt(total)


@_jit
def unproven(ends, capsule_motion, pair_motion, radii, box_min, box_max,
             box_checked, box_allowance, pairs, box_todo, pair_todo):
  """The tests (capsule-box, pair) not proven free over a run of samples:
  ends (L, 2, 3), the capsules at its centre sample; capsule_motion (L,)
  and pair_motion (P,): M and P of the module's docstring. Writes the
  unproven ones as flat indices b * L + l into box_todo and p into
  pair_todo; returns their counts."""
  count_l = radii.shape[0]
  boxes = 0
  for l in range(count_l):
    grown = radii[l] + capsule_motion[l]
    for b in range(box_min.shape[0]):
      if not box_checked[b, l]:
        continue
      gap = box_lower_bound(ends[l, 0], ends[l, 1], box_min[b], box_max[b])
      if not gap - grown + box_allowance[b, l] >= SLACK:
        box_todo[boxes] = b * count_l + l
        boxes += 1
  count = 0
  for p in range(pairs.shape[0]):
    i, j = pairs[p, 0], pairs[p, 1]
    gap = segment_lower_bound(ends[i, 0], ends[i, 1], ends[j, 0], ends[j, 1])
    if not gap - radii[i] - radii[j] - pair_motion[p] >= SLACK:
      pair_todo[count] = p
      count += 1
  return boxes, count

