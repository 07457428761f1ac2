"""Path parameterisation of a long-term plan: how fast the robot follows it.

The shield never changes the geometric path of the plan; it only changes how
fast the robot moves along it. The plan is a function of plan time `s`
(seconds); the path velocity `s_dot` in [0, 1] scales it (1 = nominal speed,
0 = standstill). A `Path` holds the current (s, s_dot, s_ddot, jerk) and a
schedule of three constant-jerk phases given as cumulative end times relative
to now (docs/shield_maths.md, 2). `plan_profile` builds the three-phase
jerk-limited change of path velocity used for the intended motion (to
s_dot = 1) and the failsafe (to rest) (section 4 there), and `path_limits`
turns joint limits into path acceleration and jerk bounds (section 3).

Scalars only, in plain Python floats: this runs several times per 4 ms cycle
and Python float arithmetic is faster than NumPy on 1-element arrays.
"""

import math

# Tolerance of the profile planner on velocities and accelerations
# (docs/shield_maths.md, 4).
PROFILE_EPSILON = 1e-6
# Phase end times at or below this are treated as elapsed (float residue of
# subtracting whole cycles from multiples of the cycle time).
_TIME_EPSILON = 1e-12
# Path velocities below this at the end of a schedule are round-off of a
# profile to rest (the peak correction leaves ~1e-15) and become exactly 0.
_REST_S_DOT = 1e-9
# Half-width (cycles) of the duration search used when rounding up the phase
# durations makes the corrected profile violate a bound.
_SEARCH_CYCLES = 4


def ceil_to_cycle(duration, cycle_time):
  """Rounds a duration up to whole cycles (docs/shield_maths.md, 4)."""
  cycles = math.ceil(duration / cycle_time - 1e-9)
  return max(cycles, 0) * cycle_time


class Path:
  """Position, velocity, acceleration and jerk along the plan, and a schedule.

  `phase_ends` are cumulative end times (t1 <= t2 <= t3, seconds from now) of
  three phases of constant jerk `phase_jerks`. After t3 the path coasts at
  constant s_dot (acceleration and jerk zero).
  """

  __slots__ = ('s', 's_dot', 's_ddot', 'jerk', 'phase_ends', 'phase_jerks')

  def __init__(self, s=0.0, s_dot=0.0, s_ddot=0.0, jerk=0.0,
               phase_ends=(0.0, 0.0, 0.0), phase_jerks=(0.0, 0.0, 0.0)):
    self.s = float(s)
    self.s_dot = float(s_dot)
    self.s_ddot = float(s_ddot)
    self.jerk = float(jerk)
    self.phase_ends = [float(t) for t in phase_ends]
    self.phase_jerks = [float(j) for j in phase_jerks]
    if len(self.phase_ends) != 3 or len(self.phase_jerks) != 3:
      raise ValueError('A path has exactly three phases, got phase_ends='
                       f'{phase_ends!r}, phase_jerks={phase_jerks!r}')
    if not (0.0 <= self.phase_ends[0] <= self.phase_ends[1]
            <= self.phase_ends[2]):
      raise ValueError('phase_ends must be non-negative and non-decreasing, '
                       f'got {self.phase_ends}')
    self._update_jerk()

  def copy(self):
    out = Path.__new__(Path)
    out.s = self.s
    out.s_dot = self.s_dot
    out.s_ddot = self.s_ddot
    out.jerk = self.jerk
    out.phase_ends = list(self.phase_ends)
    out.phase_jerks = list(self.phase_jerks)
    return out

  def __repr__(self):
    return (f'Path(s={self.s!r}, s_dot={self.s_dot!r}, s_ddot={self.s_ddot!r},'
            f' jerk={self.jerk!r}, phase_ends={self.phase_ends!r}, '
            f'phase_jerks={self.phase_jerks!r})')

  @property
  def state(self):
    return self.s, self.s_dot, self.s_ddot, self.jerk

  def end_time(self):
    """Time from now until the schedule ends (t3)."""
    return self.phase_ends[2]

  def is_finished(self):
    return self.phase_ends[2] <= _TIME_EPSILON

  def _update_jerk(self):
    ends = self.phase_ends
    if ends[0] > _TIME_EPSILON:
      self.jerk = self.phase_jerks[0]
    elif ends[1] > _TIME_EPSILON:
      self.jerk = self.phase_jerks[1]
    elif ends[2] > _TIME_EPSILON:
      self.jerk = self.phase_jerks[2]
    else:
      self.jerk = 0.0
      self.s_ddot = 0.0
      if self.s_dot < _REST_S_DOT:
        self.s_dot = 0.0   # Round-off residue of a profile to rest.

  def _integrate(self, duration, jerk):
    """Constant-jerk motion for `duration`.

    If s_dot would become negative, the path stops at the first zero of
    s_dot (docs/shield_maths.md, 2) and stays at rest: returns the time of
    the stop, else None.
    """
    v, a = self.s_dot, self.s_ddot
    v_end = v + a * duration + 0.5 * jerk * duration * duration
    v_low = v_end
    if jerk > 0.0 and a < 0.0 and -a / jerk < duration:
      t_low = -a / jerk
      v_low = v + a * t_low + 0.5 * jerk * t_low * t_low
    if min(v_low, v_end) < 0.0:
      root = _first_zero(v, a, jerk, duration)
      self.s += v * root + 0.5 * a * root * root + jerk * root ** 3 / 6.0
      self.s_dot = 0.0
      self.s_ddot = 0.0
      return root
    self.s += (v * duration + 0.5 * a * duration * duration
               + jerk * duration ** 3 / 6.0)
    self.s_dot = v_end
    self.s_ddot = a + jerk * duration
    return None

  def advance(self, duration):
    """Moves the path `duration` seconds forward through its schedule."""
    ends = self.phase_ends
    elapsed = 0.0
    for i in range(3):
      if ends[i] - elapsed <= _TIME_EPSILON:
        continue
      step = min(ends[i], duration) - elapsed
      if step <= 0.0:
        break
      if self._integrate(step, self.phase_jerks[i]) is not None:
        # Came to rest: the schedule is over, the path stays at rest.
        ends[0] = ends[1] = ends[2] = 0.0
        self.jerk = 0.0
        return
      elapsed += step
    rest = duration - elapsed
    if rest > 0.0:
      self.s += self.s_dot * rest
    for i in range(3):
      ends[i] = max(ends[i] - duration, 0.0)
    self._update_jerk()

  def final(self):
    """(s, s_dot, s_ddot) after the whole schedule."""
    end = self.copy()
    end.advance(self.phase_ends[2])
    return end.s, end.s_dot, end.s_ddot

  def segments(self):
    """Pieces of constant jerk: list of (start time, s, s_dot, s_ddot, jerk).

    The last piece (coasting, or at rest after a stop) lasts forever.
    """
    path = self.copy()
    out = []
    start = 0.0
    for i in range(3):
      duration = path.phase_ends[i] - start
      if duration <= _TIME_EPSILON:
        continue
      jerk = path.phase_jerks[i]
      out.append((start, path.s, path.s_dot, path.s_ddot, jerk))
      stop = path._integrate(duration, jerk)
      if stop is not None:
        out.append((start + stop, path.s, 0.0, 0.0, 0.0))
        return out
      start = path.phase_ends[i]
    v_end = 0.0 if path.s_dot < _REST_S_DOT else path.s_dot
    out.append((start, path.s, v_end, 0.0, 0.0))
    return out

  def max_s_dot(self, after=0.0, before=None, pieces=None):
    """Largest s_dot between `after` and `before` seconds from now (None:
    for ever; s_dot is constant after the schedule).

    Checks piece boundaries and interior maxima (s_ddot crossing zero from
    above inside a piece of negative jerk). `pieces`: this path's
    segments(), if already computed.
    """
    if pieces is None:
      pieces = self.segments()
    _, (best,), _, _ = self.sample((after,), pieces)
    if before is not None:
      best = max(best, self.sample((before,), pieces)[1][0])
    for i, (start, _, v, a, jerk) in enumerate(pieces):
      end = pieces[i + 1][0] if i + 1 < len(pieces) else math.inf
      if end <= after or (before is not None and start >= before):
        continue
      if start >= after:
        best = max(best, v)
      if a > 0.0 and jerk < 0.0:
        t_peak = start - a / jerk
        if (after <= t_peak <= end and
            (before is None or t_peak <= before)):
          best = max(best, v + a * (t_peak - start) + 0.5 * jerk *
                     (t_peak - start) ** 2)
    return best

  def sample(self, times, pieces=None):
    """States at times from now: lists (s, s_dot, s_ddot, jerk). `pieces`:
    this path's segments(), if already computed."""
    if pieces is None:
      pieces = self.segments()
    last = len(pieces) - 1
    s_out, v_out, a_out, j_out = [], [], [], []
    for t in times:
      i = last
      while i > 0 and pieces[i][0] > t:
        i -= 1
      start, s, v, a, jerk = pieces[i]
      d = t - start
      if d < 0.0:
        d = 0.0
      s_out.append(s + d * (v + d * (0.5 * a + d * jerk / 6.0)))
      v_out.append(v + d * (a + 0.5 * d * jerk))
      a_out.append(a + d * jerk)
      j_out.append(jerk)
    return s_out, v_out, a_out, j_out


def _first_zero(v, a, jerk, duration):
  """Smallest t in [0, duration] with v + a t + jerk t^2 / 2 = 0 (v >= 0)."""
  if v <= 0.0:
    return 0.0
  if abs(jerk) < 1e-12:
    return min(max(-v / a, 0.0), duration) if a < 0.0 else duration
  # 0.5 jerk t^2 + a t + v = 0.
  disc = a * a - 2.0 * jerk * v
  if disc < 0.0:
    return duration
  sqrt_disc = math.sqrt(disc)
  roots = sorted(((-a - sqrt_disc) / jerk, (-a + sqrt_disc) / jerk))
  for root in roots:
    if 0.0 <= root <= duration:
      return root
  return duration


def plan_profile(s, s_dot, s_ddot, target_s_dot, max_s_ddot, max_s_dddot,
                 cycle_time):
  """Three-phase jerk-limited change of path velocity (docs/shield_maths.md,
  4).

  From (s, s_dot, s_ddot) to s_dot = target_s_dot with s_ddot = 0 at the end,
  |s_ddot| <= max_s_ddot and |jerk| <= max_s_dddot (up to the rounding of the
  phase durations up to whole cycles, which the peak correction compensates).
  Uses the physically consistent trapezoid threshold A^2 - a^2/2 in all four
  sign cases (fixes defect B6 of the original, docs/shield_maths.md, 10).

  Returns a `Path` starting at the given state, or None if no such profile
  exists (negative bounds or |s_ddot| above the bound).
  """
  eps = PROFILE_EPSILON
  v, a, v_e, dt = s_dot, s_ddot, target_s_dot, cycle_time
  A, J = max_s_ddot, max_s_dddot
  if not (A >= 0.0 and J > 0.0) or abs(a) > A + eps:
    return None
  # 1. Already there.
  if abs(v - v_e) < eps and abs(a) < eps:
    return Path(s, v, a, 0.0, (dt, dt, dt), (0.0, 0.0, 0.0))
  # 2. Ramping the acceleration to zero is enough.
  t0 = ceil_to_cycle(abs(a) / J, dt)
  if t0 > 0.0:
    v0 = v + a * t0 / 2.0
    if abs(v0 - v_e) < eps:
      return Path(s, v, a, 0.0, (t0, t0, t0), (-a / t0, 0.0, 0.0))
  else:
    v0 = v
  # 3. Peak acceleration: trapezoid if the triangle would exceed A.
  braking = v0 > v_e + eps
  delta_v = (v - v_e) if braking else (v_e - v)
  sign = -1.0 if braking else 1.0
  if delta_v * J > A * A - a * a / 2.0:
    peak = sign * A
    t01 = max(ceil_to_cycle(abs(peak - a) / J, dt), dt)
    t23 = max(ceil_to_cycle(abs(peak) / J, dt), dt)
    v01 = (a + peak) * t01 / 2.0
    v23 = peak * t23 / 2.0
    t12 = ceil_to_cycle((v_e - v - v01 - v23) / peak, dt)
  else:
    peak = sign * math.sqrt(max(delta_v * J + a * a / 2.0, 0.0))
    t01 = max(ceil_to_cycle(abs(peak - a) / J, dt), dt)
    t23 = max(ceil_to_cycle(abs(peak) / J, dt), dt)
    t12 = 0.0
  if t12 < 0.0:
    return None
  # 4. Exact peak for the rounded durations: the velocity change
  # a t01/2 + p (t01/2 + t12 + t23/2) must equal v_e - v.
  peak = _peak(v, a, v_e, t01, t12, t23)
  if not _feasible(peak, a, A, J, t01, t23):
    # Rounding up can lower the peak so much that a ramp becomes too steep
    # (e.g. when the peak falls below a large initial a): search whole-cycle
    # durations near the rounded ones for the shortest feasible profile.
    best = None
    k0, m0, n0 = (round(x / dt) for x in (t01, t23, t12))
    for n in range(max(n0 - 1, 0), n0 + 2):
      for k in range(max(k0 - _SEARCH_CYCLES, 1), k0 + _SEARCH_CYCLES + 1):
        for m in range(max(m0 - _SEARCH_CYCLES, 1), m0 + _SEARCH_CYCLES + 1):
          if best is not None and k + m + n >= best[0]:
            continue
          p = _peak(v, a, v_e, k * dt, n * dt, m * dt)
          if _feasible(p, a, A, J, k * dt, m * dt):
            best = (k + m + n, k * dt, n * dt, m * dt, p)
    if best is None:
      return None
    _, t01, t12, t23, peak = best
  return Path(s, v, a, 0.0, (t01, t01 + t12, t01 + t12 + t23),
              ((peak - a) / t01, 0.0, -peak / t23))


def _peak(v, a, v_e, t01, t12, t23):
  return (v_e - v - a * t01 / 2.0) / (t01 / 2.0 + t12 + t23 / 2.0)


def _feasible(peak, a, max_s_ddot, max_s_dddot, t01, t23):
  tolerance = 1.0 + 1e-9
  return (abs(peak - a) <= max_s_dddot * t01 * tolerance and
          abs(peak) <= max_s_dddot * t23 * tolerance and
          abs(peak) <= max_s_ddot * tolerance + PROFILE_EPSILON)


def path_limits(prev_dq, a_max, j_max, a_max_ltt, j_max_ltt, max_s_stop):
  """(max_s_ddot, max_s_dddot) keeping joint acceleration and jerk in limits.

  docs/shield_maths.md, 3 (eq. 2.6a/b of the TUM thesis the original cites):
  the plan itself uses up to a_max_ltt / j_max_ltt, so the path may add
  s_ddot * |dq| and s_dddot * |dq| on top, with |dq| bounded over the braking
  horizon by |prev_dq| + a_max_ltt * max_s_stop. Arguments are per-joint
  sequences; pass the plan's nominal joint velocity as `prev_dq` to bound it
  for any s_dot <= 1.
  """
  max_s_ddot = math.inf
  dens = []
  for i in range(len(prev_dq)):
    den = abs(prev_dq[i]) + abs(a_max_ltt[i]) * max_s_stop
    if i == 0:
      den += 1e-9
    dens.append(den)
    max_s_ddot = min(max_s_ddot, (a_max[i] - abs(a_max_ltt[i])) / den)
  max_s_ddot = max(0.0, max_s_ddot)
  max_s_dddot = math.inf
  for i in range(len(prev_dq)):
    max_s_dddot = min(max_s_dddot, (j_max[i] - 3.0 * abs(a_max_ltt[i])
                                    * max_s_ddot - abs(j_max_ltt[i])) / dens[i])
  return max_s_ddot, max(0.0, max_s_dddot)
