"""Compiled (numba) kernels of the shield's per-cycle geometry.

Each kernel computes exactly what a readable NumPy function computes (the
reference, tested against it on random inputs to 1e-12):
* `segment_distance`: geometry.closest_parameters / capsule distance, same
  operations in the same order (parallel and point segments included, B3
  of docs/shield_maths.md, 10);
* `ssm_first_unsafe` / `ssm_clearances`: verification.ssm_verdict, the
  first with an early exit at the first unsafe interval;
* `robot_reach`: robot_reach.RobotReach.reach_capsules (batched FK, chord
  capsules, curvature and secure radius);
* `surface_speeds`: robot_reach.RobotReach.surface_speeds;
* `human_velocity_capsules`: the velocity model (COMBINED or ACCEL) of
  human_reach.HumanReach.reach_capsules;
* `horizon_balls`, `balls_capsules_distance`: the shield's broad
  phases (shield.path_check.PathCheck.verify; their references:
  tests/safety/safety_references.py); `swept_balls_gap`, a lower
  bound of the second from one forward kinematics (its own reference is
  the bound it must stay below, tested);
* `plan_positions`: LongTermPlan.positions (its reference:
  tests/safety/safety_references.py);
* `speed_tables`: shield.pfl_tables.pfl_speed_tables(compiled=False)
  (the same from a plan's samples in one pass:
  speed_kernels.plan_speed_tables).

Compiled with cache=True (the machine code is stored in __pycache__ and
reloaded by later processes) and fastmath=False (IEEE arithmetic, no
reassociation: the results match the NumPy reference). Callers pass
C-contiguous float64 arrays so every kernel has one signature, which
`warm_up` compiles once per process.
"""

import math

import numba
import numpy as np

# Same constants as geometry (kept in one place there; re-read here so the
# kernels compile them in as literals).
from hrc_suite.safety.geometry import _DEGENERATE_SQUARED_LENGTH
from hrc_suite.safety.geometry import _PARALLEL_SIN_SQUARED
from hrc_suite.safety.geometry import _TINY_DISTANCE

_jit = numba.njit(cache=True, fastmath=False, nogil=True)
# Helpers of the kernels below, inlined into them (numba IR).
_inline = numba.njit(cache=True, fastmath=False, nogil=True, inline='always')

# Speeds below this (m/s) have no direction (human_reach._MIN_SPEED).
_MIN_SPEED = 1e-12


def as_fields(group):
  """A named group of kernel arguments (a typing.NamedTuple, named tuples
  inside it too) as plain tuples of its fields, the form in which the
  kernels called every RL step take their groups: numba's dispatcher
  types a plain tuple in C, a named tuple with Python work each call
  (docs/architecture.md, "Kernels and their references"). The kernel
  names it again (`Group(*fields)`)."""
  return tuple(as_fields(value) if isinstance(value, tuple) else value
               for value in group)


@_jit
def _clamp01(x):
  return min(max(x, 0.0), 1.0)


@_jit
def segment_distance(p0, p1, p2, q0, q1, q2, d0, d1, d2, e0, e1, e2):
  """Distance between segments p + s d and q + t e (s, t in [0, 1]), as
  geometry.segment_distance computes it (closest_parameters, then the
  gap p - q + s d - t e)."""
  a = d0 * d0 + d1 * d1 + d2 * d2
  e = e0 * e0 + e1 * e1 + e2 * e2
  r0, r1, r2 = p0 - q0, p1 - q1, p2 - q2
  b = d0 * e0 + d1 * e1 + d2 * e2
  c = d0 * r0 + d1 * r1 + d2 * r2
  f = e0 * r0 + e1 * r1 + e2 * r2
  a_ok = a > _DEGENERATE_SQUARED_LENGTH
  e_ok = e > _DEGENERATE_SQUARED_LENGTH
  denom = a * e - b * b
  if denom > _PARALLEL_SIN_SQUARED * a * e:
    s = _clamp01((b * f - c * e) / denom)
  else:
    s = 0.0
  t = (b * s + f) / e if e_ok else -1.0
  t_clamped = _clamp01(t)
  if a_ok:
    if t != t_clamped:
      s = _clamp01((b * t_clamped - c) / a)
  else:
    s = 0.0
  r0 += s * d0
  r1 += s * d1
  r2 += s * d2
  r0 -= t_clamped * e0
  r1 -= t_clamped * e1
  r2 -= t_clamped * e2
  return math.sqrt(r0 * r0 + r1 * r1 + r2 * r2)


@_jit
def _pair_distance(rc1, rc2, rr, k, l, hc1, hc2, hr, m, b):
  """Signed distance of robot capsule (k, l) and human capsule (m, k, b)."""
  return (segment_distance(
      rc1[k, l, 0], rc1[k, l, 1], rc1[k, l, 2],
      hc1[m, k, b, 0], hc1[m, k, b, 1], hc1[m, k, b, 2],
      rc2[k, l, 0] - rc1[k, l, 0], rc2[k, l, 1] - rc1[k, l, 1],
      rc2[k, l, 2] - rc1[k, l, 2],
      hc2[m, k, b, 0] - hc1[m, k, b, 0], hc2[m, k, b, 1] - hc1[m, k, b, 1],
      hc2[m, k, b, 2] - hc1[m, k, b, 2]) - rr[k, l] - hr[m, k, b])


@_jit
def _bounding_balls(c1, c2, r):
  """Balls around capsules (..., 3), (...): midpoints (n, 3) and radii (n,)
  = half length + radius, flattened over the leading axes."""
  count = r.size
  start = c1.reshape(count, 3)
  end = c2.reshape(count, 3)
  radius = r.reshape(count)
  middle = np.empty((count, 3))
  reach = np.empty(count)
  for i in range(count):
    x0 = end[i, 0] - start[i, 0]
    x1 = end[i, 1] - start[i, 1]
    x2 = end[i, 2] - start[i, 2]
    for j in range(3):
      middle[i, j] = 0.5 * (start[i, j] + end[i, j])
    reach[i] = 0.5 * math.sqrt(x0 * x0 + x1 * x1 + x2 * x2) + radius[i]
  return middle, reach


# Subtracted from the broad phase's lower bounds (m): covers their round-off
# (~1e-16 m), so a pair is only skipped when it surely cannot intersect.
_BOUND_SLACK = 1e-9


@_jit
def _lower_bound(r_mid, r_reach, i, h_mid, h_reach, j):
  """Lower bound of the signed distance of capsules i and j from their
  bounding balls (verification's broad phase), minus _BOUND_SLACK."""
  g0 = r_mid[i, 0] - h_mid[j, 0]
  g1 = r_mid[i, 1] - h_mid[j, 1]
  g2 = r_mid[i, 2] - h_mid[j, 2]
  return (math.sqrt(g0 * g0 + g1 * g1 + g2 * g2) - r_reach[i] - h_reach[j]
          - _BOUND_SLACK)


@_jit
def ssm_clearances(rc1, rc2, rr, hc1, hc2, hr):
  """Exact minimum signed distance (M, K) per human model and interval
  (verification.clearances): pairs whose lower bound cannot beat the best
  distance so far are skipped."""
  count_m, count_k, count_b = hr.shape
  count_l = rr.shape[1]
  r_mid, r_reach = _bounding_balls(rc1, rc2, rr)
  h_mid, h_reach = _bounding_balls(hc1, hc2, hr)
  out = np.empty((count_m, count_k))
  for m in range(count_m):
    for k in range(count_k):
      best = np.inf
      for l in range(count_l):
        for b in range(count_b):
          if _lower_bound(r_mid, r_reach, k * count_l + l, h_mid, h_reach,
                          (m * count_k + k) * count_b + b) < best:
            d = _pair_distance(rc1, rc2, rr, k, l, hc1, hc2, hr, m, b)
            if d < best:
              best = d
      out[m, k] = best
  return out


@_jit
def ssm_first_unsafe(rc1, rc2, rr, hc1, hc2, hr):
  """First interval in which every human model meets a robot capsule
  (strictly: signed distance < 0), or -1: ssm_verdict's verdict, stopping
  at the first unsafe interval and at the first hit of each model."""
  count_m, count_k, count_b = hr.shape
  count_l = rr.shape[1]
  r_mid, r_reach = _bounding_balls(rc1, rc2, rr)
  h_mid, h_reach = _bounding_balls(hc1, hc2, hr)
  for k in range(count_k):
    all_hit = True
    for m in range(count_m):
      hit = False
      for l in range(count_l):
        for b in range(count_b):
          if _lower_bound(r_mid, r_reach, k * count_l + l, h_mid, h_reach,
                          (m * count_k + k) * count_b + b) < 0.0:
            if _pair_distance(rc1, rc2, rr, k, l, hc1, hc2, hr, m,
                              b) < 0.0:
              hit = True
              break
        if hit:
          break
      if not hit:
        all_hit = False
        break
    if all_hit:
      return k
  return -1


@_inline
def _chain(q, fixed, out):
  """Link frames (dof, 3, 4) (top rows of the 4x4 transforms) of one
  configuration q (dof,) into out; fixed (dof, 3, 4) are the fixed
  transforms A_i (base folded into A_0). A_i Rz(q_i) has the columns
  c F0 + s F1, c F1 - s F0, F2, F3 of A_i = [F0 F1 F2 F3] (the
  reference's rest + c cos + s sin term by term, without its zero terms);
  frames chain by products of affine 3x4 transforms, the running frame
  kept in scalars."""
  p00 = p01 = p02 = p03 = p10 = p11 = p12 = p13 = 0.0
  p20 = p21 = p22 = p23 = 0.0
  for i in range(q.shape[0]):
    c = math.cos(q[i])
    s = math.sin(q[i])
    f = fixed[i]
    l00 = c * f[0, 0] + s * f[0, 1]
    l01 = c * f[0, 1] - s * f[0, 0]
    l10 = c * f[1, 0] + s * f[1, 1]
    l11 = c * f[1, 1] - s * f[1, 0]
    l20 = c * f[2, 0] + s * f[2, 1]
    l21 = c * f[2, 1] - s * f[2, 0]
    l02, l03 = f[0, 2], f[0, 3]
    l12, l13 = f[1, 2], f[1, 3]
    l22, l23 = f[2, 2], f[2, 3]
    if i == 0:
      p00, p01, p02, p03 = l00, l01, l02, l03
      p10, p11, p12, p13 = l10, l11, l12, l13
      p20, p21, p22, p23 = l20, l21, l22, l23
    else:
      p00, p01, p02, p03 = (
          p00 * l00 + p01 * l10 + p02 * l20,
          p00 * l01 + p01 * l11 + p02 * l21,
          p00 * l02 + p01 * l12 + p02 * l22,
          p00 * l03 + p01 * l13 + p02 * l23 + p03)
      p10, p11, p12, p13 = (
          p10 * l00 + p11 * l10 + p12 * l20,
          p10 * l01 + p11 * l11 + p12 * l21,
          p10 * l02 + p11 * l12 + p12 * l22,
          p10 * l03 + p11 * l13 + p12 * l23 + p13)
      p20, p21, p22, p23 = (
          p20 * l00 + p21 * l10 + p22 * l20,
          p20 * l01 + p21 * l11 + p22 * l21,
          p20 * l02 + p21 * l12 + p22 * l22,
          p20 * l03 + p21 * l13 + p22 * l23 + p23)
    o = out[i]
    o[0, 0], o[0, 1], o[0, 2], o[0, 3] = p00, p01, p02, p03
    o[1, 0], o[1, 1], o[1, 2], o[1, 3] = p10, p11, p12, p13
    o[2, 0], o[2, 1], o[2, 2], o[2, 3] = p20, p21, p22, p23
  return out


@_jit
def _frames(q, fixed):
  """Link frames (N, dof, 3, 4) for q (N, dof) (`_chain` of each)."""
  count, dof = q.shape
  out = np.empty((count, dof, 3, 4))
  for n in range(count):
    _chain(q[n], fixed, out[n])
  return out


@_inline
def _world(frame, point, r):
  """Coordinate r of a point (3+,) given in a frame (3, 4), in the world."""
  return (frame[r, 0] * point[0] + frame[r, 1] * point[1]
          + frame[r, 2] * point[2] + frame[r, 3])


@_jit
def _endpoints(frames, points, frame_index):
  """Capsule end points (N, L, 2, 3) in the world."""
  count = frames.shape[0]
  count_l = points.shape[0]
  out = np.empty((count, count_l, 2, 3))
  for n in range(count):
    for l in range(count_l):
      f = frame_index[l]
      for j in range(2):
        for r in range(3):
          out[n, l, j, r] = _world(frames[n, f], points[l, j], r)
  return out


@_jit
def robot_reach(q_edges, s_edges, fixed, points, frame_index, alpha,
                static_radius):
  """Reach capsules c1, c2 (K, L, 3), r (K, L) over the K intervals between
  configurations q_edges (K+1, dof) at path positions s_edges (K+1,)."""
  return reach_from_frames(_frames(q_edges, fixed), s_edges, points,
                           frame_index, alpha, static_radius)


@_jit
def reach_from_frames(frames, s_edges, points, frame_index, alpha,
                      static_radius):
  """robot_reach from the edges' link frames (K+1, dof, 3, 4) (`_chain`
  of each edge's configuration)."""
  ends = _endpoints(frames, points, frame_index)
  count_k = frames.shape[0] - 1
  count_l = points.shape[0]
  c1 = np.empty((count_k, count_l, 3))
  c2 = np.empty((count_k, count_l, 3))
  radius = np.empty((count_k, count_l))
  for k in range(count_k):
    ds = s_edges[k + 1] - s_edges[k]
    curvature = ds * ds * 0.125
    for l in range(count_l):
      longest = 0.0
      for j in range(2):
        chord_sq = 0.0
        for r in range(3):
          start = ends[k, l, j, r]
          end = ends[k + 1, l, j, r]
          middle = 0.5 * (start + end)
          if j == 0:
            c1[k, l, r] = middle
          else:
            c2[k, l, r] = middle
          chord = end - start
          chord_sq += chord * chord
        longest = max(longest, chord_sq)
      radius[k, l] = (0.5 * math.sqrt(longest) + curvature * alpha[l]
                      + static_radius[l])
  return c1, c2, radius


@_inline
def _spins(frames, dq, omega, offset):
  """One sample's w_i = sum_{k<=i} dq_k z_k and U_i = sum_{k<=i} dq_k
  z_k x o_k into omega, offset (dof, 3); frames (dof, 3, 4) (`_chain`)."""
  w0 = w1 = w2 = u0 = u1 = u2 = 0.0
  for i in range(dq.shape[0]):
    z0 = frames[i, 0, 2] * dq[i]
    z1 = frames[i, 1, 2] * dq[i]
    z2 = frames[i, 2, 2] * dq[i]
    o0, o1, o2 = frames[i, 0, 3], frames[i, 1, 3], frames[i, 2, 3]
    w0 += z0
    w1 += z1
    w2 += z2
    u0 += z1 * o2 - z2 * o1
    u1 += z2 * o0 - z0 * o2
    u2 += z0 * o1 - z1 * o0
    omega[i, 0], omega[i, 1], omega[i, 2] = w0, w1, w2
    offset[i, 0], offset[i, 1], offset[i, 2] = u0, u1, u2


@_inline
def _capsule_speed(frames, omega, offset, points, radii, l, f):
  """surface_speeds of capsule l (on frame f) of one sample (`_spins`)."""
  a0, a1, a2 = omega[f, 0], omega[f, 1], omega[f, 2]
  best = 0.0
  for j in range(2):
    p0 = _world(frames[f], points[l, j], 0)   # The end (_endpoints).
    p1 = _world(frames[f], points[l, j], 1)
    p2 = _world(frames[f], points[l, j], 2)
    v0 = a1 * p2 - a2 * p1 - offset[f, 0]
    v1 = a2 * p0 - a0 * p2 - offset[f, 1]
    v2 = a0 * p1 - a1 * p0 - offset[f, 2]
    best = max(best, v0 * v0 + v1 * v1 + v2 * v2)
  return (math.sqrt(best)
          + math.sqrt(a0 * a0 + a1 * a1 + a2 * a2) * radii[l])


@_jit
def surface_speeds(q, dq, fixed, points, frame_index, radii):
  """Upper bounds (N, L) of the capsules' surface speeds at (q, dq) (N,
  dof): |w x p - U| at both ends (maximum) plus |w| r."""
  count, dof = q.shape
  out = np.empty((count, points.shape[0]))
  frames = np.empty((dof, 3, 4))
  omega = np.empty((dof, 3))
  offset = np.empty((dof, 3))
  for n in range(count):
    _chain(q[n], fixed, frames)
    _spins(frames, dq[n], omega, offset)
    for l in range(points.shape[0]):
      out[n, l] = _capsule_speed(frames, omega, offset, points, radii, l,
                                 frame_index[l])
  return out


@_jit
def human_velocity_capsules(positions, velocities, v_max, a_max, t,
                            error_pos, error_vel, ends, half_thickness,
                            combined):
  """Velocity-model body capsules c1, c2 (K, B, 3), r (K, B) over the K
  intervals between prediction times t (K+1,): per keypoint the COMBINED
  (combined=True) or ACCEL ball at each time, the smallest ball enclosing
  the balls at both ends of an interval, and per body the capsule between
  its end keypoints' balls with the larger radius plus half its thickness.
  error_vel (N,) is the velocity error of each keypoint."""
  count_n = positions.shape[0]
  count_t = t.shape[0]
  centre = np.empty((count_t, count_n, 3))
  radius = np.empty((count_t, count_n))
  for n in range(count_n):
    vx, vy, vz = velocities[n, 0], velocities[n, 1], velocities[n, 2]
    speed = math.sqrt(vx * vx + vy * vy + vz * vz)
    scale = max(speed, _MIN_SPEED)
    direction = (vx / scale, vy / scale, vz / scale)
    vm, am = v_max[n], a_max[n]
    for i in range(count_t):
      ti = t[i]
      if combined:
        t_up = min((vm - speed) / am, ti)
        t_m = min(vm / am, ti)
        t_dn = min((vm + speed) / am, ti)
        up_sq, dn_sq = t_up * t_up, t_dn * t_dn
        along = t_m * (ti - 0.5 * t_m)
        across = 0.25 * (ti * (t_up + t_dn) - 0.5 * (up_sq + dn_sq))
        if (t_dn < ti) or (t_up >= ti):
          core = am * along
        else:
          core = am * math.sqrt(across * across + along * along)
        shift = speed * ti + 0.5 * am * (ti * (t_up - t_dn)
                                         - 0.5 * (up_sq - dn_sq))
        if speed > vm:
          core = speed * ti
          shift = 0.0
        for r in range(3):
          centre[i, n, r] = positions[n, r] + shift * direction[r]
      else:
        core = 0.5 * am * (ti * ti)
        for r in range(3):
          centre[i, n, r] = positions[n, r] + ti * velocities[n, r]
      radius[i, n] = core + error_pos + error_vel[n] * ti
  count_k = count_t - 1
  count_b = half_thickness.shape[0]
  c1 = np.empty((count_k, count_b, 3))
  c2 = np.empty((count_k, count_b, 3))
  body_r = np.empty((count_k, count_b))
  ball_c = np.empty(3)
  for k in range(count_k):
    for b in range(count_b):
      largest = 0.0
      for side in range(2):
        n = ends[side * count_b + b]
        # geometry.enclosing_ball of the balls at t_k and t_{k+1}.
        r1, r2 = radius[k, n], radius[k + 1, n]
        d0 = centre[k, n, 0] - centre[k + 1, n, 0]
        d1 = centre[k, n, 1] - centre[k + 1, n, 1]
        d2 = centre[k, n, 2] - centre[k + 1, n, 2]
        d = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        lam = min(max((r1 - r2) / max(d, _TINY_DISTANCE), -1.0), 1.0)
        weight = 0.5 + 0.5 * lam
        ball_c[0] = centre[k + 1, n, 0] + weight * d0
        ball_c[1] = centre[k + 1, n, 1] + weight * d1
        ball_c[2] = centre[k + 1, n, 2] + weight * d2
        ball_r = max(max(r1, r2), 0.5 * (r1 + r2 + d))
        if side == 0:
          c1[k, b] = ball_c
          largest = ball_r
        else:
          c2[k, b] = ball_c
          largest = max(largest, ball_r)
      body_r[k, b] = largest + half_thickness[b]
  return c1, c2, body_r


@_inline
def _ball_gap(m0, m1, m2, grow, centre, radius, b):
  """Gap between the ball (m0, m1, m2) of radius grow and ball b of
  centre (B, 3) and radius (B,): centre distance minus both radii."""
  g0 = m0 - centre[b, 0]
  g1 = m1 - centre[b, 1]
  g2 = m2 - centre[b, 2]
  return math.sqrt(g0 * g0 + g1 * g1 + g2 * g2) - grow - radius[b]


@_jit
def balls_capsules_distance(centre, radius, c1, c2, r):
  """Lower bound (before the slack) of the distance between balls (B,) and
  capsules (K, L): each capsule bounded by the ball around its midpoint."""
  count_k, count_l = r.shape
  count_b = radius.shape[0]
  best = np.inf
  for k in range(count_k):
    for l in range(count_l):
      m0 = 0.5 * (c1[k, l, 0] + c2[k, l, 0])
      m1 = 0.5 * (c1[k, l, 1] + c2[k, l, 1])
      m2 = 0.5 * (c1[k, l, 2] + c2[k, l, 2])
      h0 = c2[k, l, 0] - c1[k, l, 0]
      h1 = c2[k, l, 1] - c1[k, l, 1]
      h2 = c2[k, l, 2] - c1[k, l, 2]
      reach = 0.5 * math.sqrt(h0 * h0 + h1 * h1 + h2 * h2) + r[k, l]
      for b in range(count_b):
        d = _ball_gap(m0, m1, m2, reach, centre, radius, b)
        if d < best:
          best = d
  return best


@_jit
def swept_balls_gap(q_edges, s_edges, frames, points, frame_index, alpha,
                    static_radius, levers, half_lengths, centre, radius,
                    stop):
  """A lower bound of balls_capsules_distance(centre, radius,
  *robot_reach(q_edges, s_edges, ...)) from one forward kinematics, the
  link frames (dof, 3, 4) at q_edges[0] (`_chain`; docs/shield_maths.md,
  5.3): every reach capsule of link l and the ball around its midpoint
  that balls_capsules_distance uses lie in the ball around the link's
  midpoint at q_edges[0] of radius
  sum_j levers[j, l] (D_j + C_j / 2) + alpha_l max(ds)^2 / 8 +
  static_radius[l] + half_lengths[l] (D_j, C_j: the largest |q_ij - q_0j|
  and |q_i+1,j - q_ij| over the edges; levers: RobotReach.joint_levers).
  Minus _BOUND_SLACK (round-off). Returns at the first pair at or below
  `stop` (then only that it is not above)."""
  count_k = q_edges.shape[0] - 1
  dof = q_edges.shape[1]
  motion = np.empty(dof)
  for j in range(dof):
    away = 0.0
    step = 0.0
    for k in range(count_k):
      away = max(away, abs(q_edges[k + 1, j] - q_edges[0, j]))
      step = max(step, abs(q_edges[k + 1, j] - q_edges[k, j]))
    motion[j] = away + 0.5 * step
  curvature = 0.0
  for k in range(count_k):
    ds = s_edges[k + 1] - s_edges[k]
    curvature = max(curvature, ds * ds * 0.125)
  best = np.inf
  # From the hand to the base: near a person, the first pairs tried are
  # those most likely to stop the loop.
  for l in range(levers.shape[1] - 1, -1, -1):
    grow = curvature * alpha[l] + static_radius[l] + half_lengths[l]
    for j in range(dof):
      grow += levers[j, l] * motion[j]
    f = frame_index[l]
    m0 = 0.5 * (_world(frames[f], points[l, 0], 0)
                + _world(frames[f], points[l, 1], 0))
    m1 = 0.5 * (_world(frames[f], points[l, 0], 1)
                + _world(frames[f], points[l, 1], 1))
    m2 = 0.5 * (_world(frames[f], points[l, 0], 2)
                + _world(frames[f], points[l, 1], 2))
    for b in range(radius.shape[0]):
      d = _ball_gap(m0, m1, m2, grow, centre, radius, b)
      if d < best:
        best = d
        if best - _BOUND_SLACK <= stop:
          return best - _BOUND_SLACK
  return best - _BOUND_SLACK


@_jit
def horizon_balls(positions, velocities, v_max, body_ends, half_thickness,
                  age, error_pos, base):
  """The shield's VEL balls over the whole horizon, one per body: centres
  (B, 3) at the body capsule's midpoint, radii (B,) = max(v_max, measured
  speed) of the faster end x age + thickness / 2 + position error + half
  the body length; and the smallest gap between any ball and the point
  `base` (3,) (centre distance minus radius)."""
  count_b = half_thickness.shape[0]
  centre = np.empty((count_b, 3))
  grow = np.empty(count_b)
  gap = np.inf
  for b in range(count_b):
    fastest = 0.0
    for side in range(2):
      n = body_ends[side, b]
      vx, vy, vz = velocities[n, 0], velocities[n, 1], velocities[n, 2]
      speed = max(math.sqrt(vx * vx + vy * vy + vz * vz), v_max[n])
      if side == 0:
        fastest = speed
      else:
        fastest = max(fastest, speed)
    i, j = body_ends[0, b], body_ends[1, b]
    h0 = positions[j, 0] - positions[i, 0]
    h1 = positions[j, 1] - positions[i, 1]
    h2 = positions[j, 2] - positions[i, 2]
    radius = fastest * age + half_thickness[b] + error_pos
    radius += 0.5 * math.sqrt(h0 * h0 + h1 * h1 + h2 * h2)
    grow[b] = radius
    distance = 0.0
    for r in range(3):
      centre[b, r] = 0.5 * (positions[i, r] + positions[j, r])
      d = centre[b, r] - base[r]
      distance += d * d
    gap = min(gap, math.sqrt(distance) - radius)
  return centre, grow, gap


@_jit
def plan_positions(coefficients, start_time, inverse_cycle, cycle_time, s,
                   out, first):
  """Joint positions on a plan at plan times s (K,) into out[first:]
  (LongTermPlan.positions: Taylor expansion from the sample at or before
  s, clamped to the plan; coefficients (N, 4, dof) = q, dq, ddq, dddq)."""
  last = coefficients.shape[0] - 1
  dof = coefficients.shape[2]
  for i in range(s.shape[0]):
    x = s[i]
    k = int(math.floor((x - start_time) * inverse_cycle))
    k = 0 if k < 0 else (last if k > last else k)
    t = x - start_time - k * cycle_time
    t2 = 0.5 * t * t
    t3 = t2 * t / 3.0
    for d in range(dof):
      out[first + i, d] = (coefficients[k, 0, d] + t * coefficients[k, 1, d]
                           + t2 * coefficients[k, 2, d]
                           + t3 * coefficients[k, 3, d])
  return out


@_jit
def speed_tables(speeds, width):
  """PFL tables of a plan from its capsules' surface speeds (N, L): the
  largest speed over samples i..i+width (clamped to the plan), and from
  sample i to the end (both (N,))."""
  count = speeds.shape[0]
  top = np.empty(count)
  for i in range(count):
    top[i] = speeds[i].max()
  return _tables(top, width)


@_jit
def _tables(top, width):
  """speed_tables from each sample's largest speed top (N,)."""
  count = top.shape[0]
  window = np.empty(count)
  suffix = np.empty(count)
  best = -np.inf
  for i in range(count - 1, -1, -1):
    best = max(best, top[i])
    suffix[i] = best
    largest = top[i]
    for j in range(i + 1, min(i + width + 1, count)):
      largest = max(largest, top[j])
    window[i] = largest
  return window, suffix


@_jit
def capsules_min_distance(q, fixed, points, frame_index, radii, keypoints,
                          ends, half_thickness):
  """The smallest signed distance between the robot's real capsules at q
  (dof,) and the person's body capsules (keypoints (N_kp, 3), end indices
  (2 B,), radii (B,)): Shield.min_distance, pair by pair
  (geometry.capsule_distance's minimum over all pairs)."""
  robot = _endpoints(_frames(q.reshape(1, -1), fixed), points, frame_index)
  bodies = half_thickness.shape[0]
  best = np.inf
  for l in range(radii.shape[0]):
    a0, a1 = robot[0, l, 0], robot[0, l, 1]
    for b in range(bodies):
      h0, h1 = keypoints[ends[b]], keypoints[ends[bodies + b]]
      distance = segment_distance(
          a0[0], a0[1], a0[2], h0[0], h0[1], h0[2],
          a1[0] - a0[0], a1[1] - a0[1], a1[2] - a0[2],
          h1[0] - h0[0], h1[1] - h0[1], h1[2] - h0[2]) - radii[l] - (
              half_thickness[b])
      best = min(best, distance)
  return best



@_jit
def tracking_error(q, reference, fixed, points, frame_index):
  """TrackingBounds.error (safety/shield/tracking.py): the largest
  displacement (m) of a capsule axis end between joint positions q and
  reference (dof,)."""
  pair = np.empty((2, q.shape[0]))
  pair[0] = q
  pair[1] = reference
  ends = _endpoints(_frames(pair, fixed), points, frame_index)
  largest = 0.0
  for l in range(ends.shape[1]):
    for j in range(2):
      d0 = ends[0, l, j, 0] - ends[1, l, j, 0]
      d1 = ends[0, l, j, 1] - ends[1, l, j, 1]
      d2 = ends[0, l, j, 2] - ends[1, l, j, 2]
      largest = max(largest, d0 * d0 + d1 * d1 + d2 * d2)
  return math.sqrt(largest)


_warm = False


def warm_up():
  """Compiles (or loads from the cache) every kernel for the argument types
  the shield passes, once per process, so no cycle pays for it."""
  global _warm
  if _warm:
    return
  dof, count_l, count_b, count_n = 2, 2, 1, 2
  q = np.zeros((2, dof))
  fixed = np.zeros((dof, 3, 4))
  points = np.zeros((count_l, 2, 4))
  frame_index = np.zeros(count_l, dtype=np.int64)
  ones = np.ones(count_l)
  c1, c2, r = robot_reach(q, np.arange(2.0), fixed, points, frame_index,
                          ones, ones)
  speed_tables(surface_speeds(q, q, fixed, points, frame_index, ones), 6)
  positions = np.zeros((count_n, 3))
  ends = np.zeros(2 * count_b, dtype=np.int64)
  rates = np.ones(count_n)
  h1, h2, hr = human_velocity_capsules(
      positions, positions, rates, rates, np.arange(2.0), 0.0,
      np.zeros(count_n), ends, np.ones(count_b), True)
  human = (h1[None], h2[None], hr[None])
  ssm_first_unsafe(c1, c2, r, *human)
  ssm_clearances(c1, c2, r, *human)
  centre, radius, _ = horizon_balls(positions, positions, rates,
                                    ends.reshape(2, count_b),
                                    np.ones(count_b), 0.0, 0.0, np.zeros(3))
  balls_capsules_distance(centre, radius, c1, c2, r)
  swept_balls_gap(q, np.arange(2.0), _frames(q[:1], fixed)[0], points,
                  frame_index, ones, ones, np.zeros((dof, count_l)), ones,
                  centre, radius, 0.0)
  capsules_min_distance(q[0], fixed, points, frame_index, ones, positions,
                        ends, np.ones(count_b))
  tracking_error(q[0], q[1], fixed, points, frame_index)
  coefficients = np.zeros((1, 4, dof))
  plan_positions(coefficients, 0.0, 1.0, 1.0, np.zeros(1), q, 1)
  coefficients.flags.writeable = False   # Plans made from given samples.
  plan_positions(coefficients, 0.0, 1.0, 1.0, np.zeros(1), q, 1)
  _warm = True
