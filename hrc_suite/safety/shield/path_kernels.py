"""Compiled (numba) path parameterisation: `path` on 10-float arrays.

A path is the array of shield._path_array: s, s_dot, s_ddot, jerk, the
three cumulative phase end times and the three phase jerks. Each function
does what its `path` counterpart does, in the same operations and order
(Python float arithmetic and IEEE doubles agree; powers go through
math.pow, as Python's `**` on floats does), so the compiled shield cycle
(`cycle_kernels`) follows the same path as the readable reference
(`path.Path`, `path.plan_profile`); tests/safety/test_path_kernels.py
compares them.
"""

import math

import numpy as np

from hrc_suite.safety import kernels
from hrc_suite.safety.shield import path as path_lib

_jit = kernels._jit
_inline = kernels._inline

PATH_SIZE = 10
# Pieces of constant jerk of a path (segments): three phases and the coast.
MAX_PIECES = 4
_EPS = path_lib.PROFILE_EPSILON
_TIME_EPS = path_lib._TIME_EPSILON
_REST = path_lib._REST_S_DOT
_SEARCH = path_lib._SEARCH_CYCLES


@_jit
def make(out, s, s_dot, s_ddot, jerk, e0, e1, e2, j0, j1, j2):
  """path.Path(s, s_dot, s_ddot, jerk, (e0, e1, e2), (j0, j1, j2))."""
  out[0], out[1], out[2], out[3] = s, s_dot, s_ddot, jerk
  out[4], out[5], out[6] = e0, e1, e2
  out[7], out[8], out[9] = j0, j1, j2
  update_jerk(out)


@_jit
def update_jerk(p):
  """Path._update_jerk."""
  if p[4] > _TIME_EPS:
    p[3] = p[7]
  elif p[5] > _TIME_EPS:
    p[3] = p[8]
  elif p[6] > _TIME_EPS:
    p[3] = p[9]
  else:
    p[3] = 0.0
    p[2] = 0.0
    if p[1] < _REST:
      p[1] = 0.0


@_jit
def _first_zero(v, a, jerk, duration):
  """path._first_zero."""
  if v <= 0.0:
    return 0.0
  if abs(jerk) < 1e-12:
    return min(max(-v / a, 0.0), duration) if a < 0.0 else duration
  disc = a * a - 2.0 * jerk * v
  if disc < 0.0:
    return duration
  sqrt_disc = math.sqrt(disc)
  r0 = (-a - sqrt_disc) / jerk
  r1 = (-a + sqrt_disc) / jerk
  if r1 < r0:
    r0, r1 = r1, r0
  if 0.0 <= r0 <= duration:
    return r0
  if 0.0 <= r1 <= duration:
    return r1
  return duration


@_jit
def integrate(p, duration, jerk):
  """Path._integrate: the stop time, or -1.0 (None) if the path did not
  stop."""
  v, a = p[1], p[2]
  v_end = v + a * duration + 0.5 * jerk * duration * duration
  v_low = v_end
  if jerk > 0.0 and a < 0.0 and -a / jerk < duration:
    t_low = -a / jerk
    v_low = v + a * t_low + 0.5 * jerk * t_low * t_low
  if min(v_low, v_end) < 0.0:
    root = _first_zero(v, a, jerk, duration)
    p[0] += v * root + 0.5 * a * root * root + jerk * math.pow(root,
                                                               3.0) / 6.0
    p[1] = 0.0
    p[2] = 0.0
    return root
  p[0] += (v * duration + 0.5 * a * duration * duration
           + jerk * math.pow(duration, 3.0) / 6.0)
  p[1] = v_end
  p[2] = a + jerk * duration
  return -1.0


@_jit
def advance(p, duration):
  """Path.advance."""
  elapsed = 0.0
  for i in range(3):
    if p[4 + i] - elapsed <= _TIME_EPS:
      continue
    step = min(p[4 + i], duration) - elapsed
    if step <= 0.0:
      break
    if integrate(p, step, p[7 + i]) >= 0.0:
      p[4] = p[5] = p[6] = 0.0
      p[3] = 0.0
      return
    elapsed += step
  rest = duration - elapsed
  if rest > 0.0:
    p[0] += p[1] * rest
  for i in range(3):
    p[4 + i] = max(p[4 + i] - duration, 0.0)
  update_jerk(p)


@_jit
def segments(p, out):
  """Path.segments into out (MAX_PIECES, 5) rows (start time, s, s_dot,
  s_ddot, jerk); returns the number of pieces."""
  q = p.copy()
  count = 0
  start = 0.0
  for i in range(3):
    duration = q[4 + i] - start
    if duration <= _TIME_EPS:
      continue
    jerk = q[7 + i]
    out[count, 0], out[count, 1], out[count, 2] = start, q[0], q[1]
    out[count, 3], out[count, 4] = q[2], jerk
    count += 1
    stop = integrate(q, duration, jerk)
    if stop >= 0.0:
      out[count, 0], out[count, 1], out[count, 2] = start + stop, q[0], 0.0
      out[count, 3], out[count, 4] = 0.0, 0.0
      return count + 1
    start = q[4 + i]
  out[count, 0], out[count, 1] = start, q[0]
  out[count, 2] = 0.0 if q[1] < _REST else q[1]
  out[count, 3], out[count, 4] = 0.0, 0.0
  return count + 1


@_inline
def _piece_at(pieces, count, t):
  """Path.sample's piece at one time t from now (pieces from `segments`):
  its index i, and d, the time since its start (0 before it)."""
  i = count - 1
  while i > 0 and pieces[i, 0] > t:
    i -= 1
  d = t - pieces[i, 0]
  if d < 0.0:
    d = 0.0
  return i, d


@_jit
def sample_s(pieces, count, t):
  """Path.sample's s at one time t from now (pieces from `segments`)."""
  i, d = _piece_at(pieces, count, t)
  v, a, jerk = pieces[i, 2], pieces[i, 3], pieces[i, 4]
  return pieces[i, 1] + d * (v + d * (0.5 * a + d * jerk / 6.0))


@_jit
def sample_s_dot(pieces, count, t):
  """Path.sample's s_dot at one time t from now."""
  i, d = _piece_at(pieces, count, t)
  return pieces[i, 2] + d * (pieces[i, 3] + 0.5 * d * pieces[i, 4])


@_jit
def max_s_dot(pieces, count, after, before):
  """Path.max_s_dot(after, before, pieces)."""
  best = sample_s_dot(pieces, count, after)
  best = max(best, sample_s_dot(pieces, count, before))
  for i in range(count):
    start, v, a, jerk = pieces[i, 0], pieces[i, 2], pieces[i, 3], pieces[i, 4]
    end = pieces[i + 1, 0] if i + 1 < count else np.inf
    if end <= after or start >= before:
      continue
    if start >= after:
      best = max(best, v)
    if a > 0.0 and jerk < 0.0:
      t_peak = start - a / jerk
      if after <= t_peak <= end and t_peak <= before:
        best = max(best, v + a * (t_peak - start) + 0.5 * jerk
                   * math.pow(t_peak - start, 2.0))
  return best


@_jit
def final_s_dot(p):
  """Path.final()'s s_dot."""
  q = p.copy()
  advance(q, p[6])
  return q[1]


@_jit
def ceil_to_cycle(duration, cycle_time):
  """path.ceil_to_cycle."""
  cycles = math.ceil(duration / cycle_time - 1e-9)
  return max(cycles, 0) * cycle_time


@_jit
def _peak(v, a, v_e, t01, t12, t23):
  return (v_e - v - a * t01 / 2.0) / (t01 / 2.0 + t12 + t23 / 2.0)


@_jit
def _feasible(peak, a, max_s_ddot, max_s_dddot, t01, t23):
  tolerance = 1.0 + 1e-9
  return (abs(peak - a) <= max_s_dddot * t01 * tolerance and
          abs(peak) <= max_s_dddot * t23 * tolerance and
          abs(peak) <= max_s_ddot * tolerance + _EPS)


@_jit
def plan_profile(out, s, s_dot, s_ddot, target_s_dot, max_s_ddot,
                 max_s_dddot, cycle_time):
  """path.plan_profile into out (10,); False where it returns None."""
  eps = _EPS
  v, a, v_e, dt = s_dot, s_ddot, target_s_dot, cycle_time
  big_a, big_j = max_s_ddot, max_s_dddot
  if not (big_a >= 0.0 and big_j > 0.0) or abs(a) > big_a + eps:
    return False
  if abs(v - v_e) < eps and abs(a) < eps:
    make(out, s, v, a, 0.0, dt, dt, dt, 0.0, 0.0, 0.0)
    return True
  t0 = ceil_to_cycle(abs(a) / big_j, dt)
  if t0 > 0.0:
    v0 = v + a * t0 / 2.0
    if abs(v0 - v_e) < eps:
      make(out, s, v, a, 0.0, t0, t0, t0, -a / t0, 0.0, 0.0)
      return True
  else:
    v0 = v
  braking = v0 > v_e + eps
  delta_v = (v - v_e) if braking else (v_e - v)
  sign = -1.0 if braking else 1.0
  if delta_v * big_j > big_a * big_a - a * a / 2.0:
    peak = sign * big_a
    t01 = max(ceil_to_cycle(abs(peak - a) / big_j, dt), dt)
    t23 = max(ceil_to_cycle(abs(peak) / big_j, dt), dt)
    v01 = (a + peak) * t01 / 2.0
    v23 = peak * t23 / 2.0
    t12 = ceil_to_cycle((v_e - v - v01 - v23) / peak, dt)
  else:
    peak = sign * math.sqrt(max(delta_v * big_j + a * a / 2.0, 0.0))
    t01 = max(ceil_to_cycle(abs(peak - a) / big_j, dt), dt)
    t23 = max(ceil_to_cycle(abs(peak) / big_j, dt), dt)
    t12 = 0.0
  if t12 < 0.0:
    return False
  peak = _peak(v, a, v_e, t01, t12, t23)
  if not _feasible(peak, a, big_a, big_j, t01, t23):
    found = False
    best_total = 0
    k0 = int(np.rint(t01 / dt))
    m0 = int(np.rint(t23 / dt))
    n0 = int(np.rint(t12 / dt))
    for n in range(max(n0 - 1, 0), n0 + 2):
      for k in range(max(k0 - _SEARCH, 1), k0 + _SEARCH + 1):
        for m in range(max(m0 - _SEARCH, 1), m0 + _SEARCH + 1):
          if found and k + m + n >= best_total:
            continue
          p = _peak(v, a, v_e, k * dt, n * dt, m * dt)
          if _feasible(p, a, big_a, big_j, k * dt, m * dt):
            found = True
            best_total = k + m + n
            t01, t12, t23, peak = k * dt, n * dt, m * dt, p
    if not found:
      return False
  make(out, s, v, a, 0.0, t01, t01 + t12, t01 + t12 + t23,
       (peak - a) / t01, 0.0, -peak / t23)
  return True
