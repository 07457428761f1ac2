"""Compiled (numba) shield cycles: many SSM cycles in one call.

`ssm_cycles` runs what shield.Shield.step does (SSM mode) for a sequence
of cycles whose human keypoints are known in advance (a playback), on the
shield's state held in arrays (`shield.Shield.step_many` packs and unpacks
them): the human measurement (no Kalman filter, combined model), the
monitored path (one intended step, then the failsafe: `path_kernels`), its
verification (joint limits, the broad phases, robot and human reach
capsules and the SSM verdict: the `kernels` the Python cycle calls) and the
command from the plan's samples (long_term_plan.LongTermPlan.state).

A pending goal's candidate plan (Ruckig, made by the caller) is verified
and adopted as Shield.step does while the verified path stays where it
was planned from. A cycle the kernel does not cover stops the call before
anything of it is changed, and the caller runs that cycle in Python: a
candidate needed from a new state (Ruckig), a plan sample not computed
yet, a measurement the Python `measure` would refuse. Cycles are thus
either wholly compiled or wholly the reference, and the shield's state
after each is the same (tests/safety/test_step_many.py).
"""

import math

import numpy as np

from hrc_suite.safety import kernels
from hrc_suite.safety import path_kernels as pk

_jit = kernels._jit

# Indices of `params` (float64 array of shield constants).
CYCLE, INTERVAL, WORKSPACE, ERROR_POS, ERROR_VEL, DELAY, MIN_PERIOD, SAME, \
    SLACK, PFL, ALLOWED, S_DOT_TOLERANCE, REST = range(13)
NUM_PARAMS = 13
# Indices of `human` (float64): last measurement time, its period, count.
LAST_T, LAST_PERIOD, COUNT = range(3)
# Indices of `flags` (int64): an intended path is kept, a goal is pending,
# a candidate plan is pending, the cycle that adopted it (-1: none).
HAS_INTENDED, GOAL_PENDING, HAS_CANDIDATE, ADOPTED_AT = range(4)


@_jit
def plan_state(plan, start, inverse, cycle, s, s_dot, s_ddot, jerk, out):
  """LongTermPlan.state into out (5, dof) (plan (N, 4, dof) samples, all
  needed ones computed): the Taylor step's 5 x 4 matrix of
  LongTermPlan.state_reference applied in a fixed order (shared by the
  Python and the compiled cycle, so both give the same bits)."""
  last = plan.shape[0] - 1
  k = int(math.floor((s - start) * inverse))
  k = 0 if k < 0 else (last if k > last else k)
  t = s - start - k * cycle
  t2 = 0.5 * t * t
  t3 = t2 * t / 3.0
  v2 = s_dot * s_dot
  sa = 3.0 * s_ddot * s_dot
  m = ((1.0, t, t2, t3),
       (0.0, s_dot, s_dot * t, s_dot * t2),
       (0.0, s_ddot, s_ddot * t + v2, s_ddot * t2 + v2 * t),
       (0.0, jerk, jerk * t + sa, jerk * t2 + sa * t + v2 * s_dot),
       (0.0, 1.0, t, t2))
  for row in range(5):
    r = m[row]
    for d in range(plan.shape[2]):
      out[row, d] = (r[0] * plan[k, 0, d] + r[1] * plan[k, 1, d]
                     + r[2] * plan[k, 2, d] + r[3] * plan[k, 3, d])
  return out


@_jit
def _plan_state(plan, start, inverse, cycle, filled, s, s_dot, s_ddot, jerk,
                out):
  """plan_state; False if the sample at s is not computed yet."""
  last = plan.shape[0] - 1
  k = int(math.floor((s - start) * inverse))
  k = 0 if k < 0 else (last if k > last else k)
  if k >= filled:
    return False
  plan_state(plan, start, inverse, cycle, s, s_dot, s_ddot, jerk, out)
  return True


@_jit
def _path_limits(v_nominal, den_offset, acc_numerator, jerk_numerator,
                 jerk_acc):
  """Shield._path_limits."""
  dof = v_nominal.shape[0]
  acc = np.inf
  for i in range(dof):
    acc = min(acc, acc_numerator[i] / (abs(v_nominal[i]) + den_offset[i]))
  acc = acc if acc > 0.0 else 0.0
  jerk = np.inf
  for i in range(dof):
    jerk = min(jerk, (jerk_numerator[i] - jerk_acc[i] * acc)
               / (abs(v_nominal[i]) + den_offset[i]))
  return acc, (jerk if jerk > 0.0 else 0.0)


@_jit
def _sample_index(s, start, inverse, last):
  """LongTermPlan.sample_index."""
  k = int(math.floor((s - start) * inverse))
  return 0 if k < 0 else (last if k > last else k)


@_jit
def _slow_enough(params, start, inverse, last, window, suffix, current_s_dot,
                 failsafe, pieces, num, s_edges, first, count):
  """Shield._slow_enough (PFL): the robot's surface speed stays below
  v_safe from slice `first` on, and after the failsafe."""
  interval = params[INTERVAL]
  end = failsafe[6]
  allowed = params[ALLOWED] * (1.0 + params[S_DOT_TOLERANCE])
  for i in range(first, count + 1):
    if i == 0:
      s_dot = max(current_s_dot, failsafe[1])
    else:
      before = i * interval if i < count else end
      s_dot = pk.max_s_dot(pieces, num, (i - 1) * interval, before)
    if window[_sample_index(s_edges[i], start, inverse, last)] * s_dot > (
        allowed):
      return False
  return (suffix[_sample_index(s_edges[count + 1], start, inverse, last)]
          * pk.final_s_dot(failsafe) <= allowed)


@_jit
def _verify(params, plan, start, inverse, filled, current_s, current_s_dot,
            previous_q, failsafe, now, positions, velocities, last_t,
            last_period, q_min, q_max, fixed, points, frame_index, alpha,
            static_radius, levers, half_lengths, v_max, a_max, body_ends,
            ends, half_thickness, base, window, suffix):
  """Shield._verify (SSM or PFL, a measured human with a velocity; PFL's
  speed tables window and suffix (N,) of the plan). Returns
  (status, first unsafe slice, reach distance (nan: not computed), s_edges,
  t_edges, q_edges); status 1 verified, 0 not, -1 a plan sample is missing
  (the cycle goes to Python)."""
  dt = params[CYCLE]
  interval = params[INTERVAL]
  dof = previous_q.shape[0]
  end = failsafe[6]
  count = max(int(math.ceil(end / interval - 1e-9)), 1)
  pieces = np.empty((pk.MAX_PIECES, 5))
  num = pk.segments(failsafe, pieces)
  s_edges = np.empty(count + 2)
  t_edges = np.empty(count + 2)
  q_edges = np.empty((count + 2, dof))
  s_edges[0] = current_s
  t_edges[0] = 0.0
  last = plan.shape[0] - 1
  for i in range(count + 1):
    time = i * interval if i < count else end
    s = pk.sample_s(pieces, num, time)
    s_edges[i + 1] = s
    t_edges[i + 1] = time + dt
    k = int(math.floor((s - start) * inverse))
    k = 0 if k < 0 else (last if k > last else k)
    if k >= filled:
      return -1, 0, np.nan, s_edges, t_edges, q_edges
  q_edges[0] = previous_q
  kernels.plan_positions(plan, start, inverse, dt, s_edges[1:], q_edges, 1)
  for d in range(dof):
    q = q_edges[count + 1, d]
    if not (q_min[d] <= q <= q_max[d]):
      return 0, count, -np.inf, s_edges, t_edges, q_edges
  age = now - last_t + params[DELAY] + t_edges[count + 1]
  centre, radius, gap = kernels.horizon_balls(
      positions, velocities, v_max, body_ends, half_thickness, age,
      params[ERROR_POS], base)
  bound = gap - params[WORKSPACE]
  if bound > 0.0:
    return 1, -1, bound, s_edges, t_edges, q_edges
  # The edges' link frames, the first one for the bound from one forward
  # kinematics, the others only if the reach capsules are needed.
  frames = np.empty((count + 2, dof, 3, 4))
  kernels._chain(q_edges[0], fixed, frames[0])
  bound = kernels.swept_balls_gap(
      q_edges, s_edges, frames[0], points, frame_index, alpha,
      static_radius, levers, half_lengths, centre, radius,
      params[SLACK]) - params[SLACK]
  if bound > 0.0:
    return 1, -1, bound, s_edges, t_edges, q_edges
  for n in range(1, count + 2):
    kernels._chain(q_edges[n], fixed, frames[n])
  rc1, rc2, rr = kernels.reach_from_frames(frames, s_edges, points,
                                           frame_index, alpha, static_radius)
  bound = (kernels.balls_capsules_distance(centre, radius, rc1, rc2, rr)
           - params[SLACK])
  if bound > 0.0:
    return 1, -1, bound, s_edges, t_edges, q_edges
  t = (now - last_t) + t_edges + params[DELAY]
  error_vel = params[ERROR_VEL] + a_max * (0.5 * last_period)
  hc1, hc2, hr = kernels.human_velocity_capsules(
      positions, velocities, v_max, a_max, t, params[ERROR_POS], error_vel,
      ends, half_thickness, True)
  first = kernels.ssm_first_unsafe(rc1, rc2, rr, hc1.reshape((1,) + hc1.shape),
                                   hc2.reshape((1,) + hc2.shape),
                                   hr.reshape((1,) + hr.shape))
  safe = first < 0
  if not safe and params[PFL] == 1.0:
    # PFL: contact is possible from slice `first` on; from then on the
    # robot must be slower than v_safe.
    safe = _slow_enough(params, start, inverse, last, window, suffix,
                        current_s_dot, failsafe, pieces, num, s_edges,
                        first, count)
  return (1 if safe else 0), first, np.nan, s_edges, t_edges, q_edges


@_jit
def _stop(c, check, missing):
  """ssm_cycles' result when it stops before cycle c."""
  status, first, distance, s_edges, t_edges, q_edges = check
  return c, status, first, distance, s_edges, t_edges, q_edges, missing


@_jit
def ssm_cycles(params, frames, times, command, previous_q, verified,
               intended, flags, human, positions, velocities, plan,
               plan_meta, candidate, candidate_meta, limits, clip, fixed,
               points, frame_index, alpha, static_radius, levers,
               half_lengths, v_max, a_max, body_ends, ends, half_thickness,
               base, plan_window, plan_suffix, candidate_window,
               candidate_suffix, setpoints, intervened):
  """Runs SSM cycles for keypoints frames (n, N_kp, 3) at times (n,),
  updating the state arrays in place: command (5, dof), previous_q,
  verified and intended (10,), flags (int64: has_intended, goal_pending,
  has_candidate, the cycle at which the candidate was adopted or -1),
  human (3,), positions and velocities (N_kp, 3). plan and candidate
  (N, 4, dof) are the adopted plan's and the pending goal's candidate
  plan's samples (writeable), plan_meta (start time, samples computed)
  and candidate_meta (start time, samples computed, and the s, s_dot of
  the verified path it was planned from: Shield._candidate_plan's key).
  limits (7, dof): den_offset, acc_numerator, jerk_numerator, jerk_acc,
  q_min, q_max (Shield's per-joint terms) and a_max_ltt; fixed to
  half_lengths: the robot's model (RobotReach's _kernel_ arrays). PFL
  (params[PFL] == 1): the plans' speed tables (Shield._plan_speeds).

  Writes each cycle's set-point (q, dq, ddq) to setpoints (>= n, 3, dof)
  and whether it intervened to intervened (>= n,), from row 0.

  Returns (cycles done, the last cycle's check: status (1 verified, 0
  not, 2 no monitored path), first unsafe slice, reach distance (nan: not
  computed), s_edges, t_edges, q_edges; and whether it stopped for a plan
  sample not computed yet). Stops before a cycle it cannot run (see the
  module).
  """
  count = frames.shape[0]
  dof = command.shape[1]
  dt = params[CYCLE]
  inverse = 1.0 / dt
  check = (2, 0, -np.inf, np.zeros(0), np.zeros(0), np.zeros((0, dof)))
  current = np.empty(pk.PATH_SIZE)
  new_intended = np.empty(pk.PATH_SIZE)
  nominal = np.empty(pk.PATH_SIZE)
  failsafe = np.empty(pk.PATH_SIZE)
  moved = np.empty(pk.PATH_SIZE)
  state = np.empty((5, dof))
  wanted = np.empty((5, dof))
  new_positions = np.empty_like(positions)
  new_velocities = np.empty_like(velocities)
  plan_start, plan_filled = plan_meta[0], int(plan_meta[1])
  for c in range(count):
    # The measurement (HumanReach.measure without the Kalman filter).
    t = times[c]
    keypoints = frames[c]
    if not np.all(np.isfinite(keypoints)):
      return _stop(c, check, False)
    period = t - human[LAST_T]
    if period < 0.0:
      return _stop(c, check, False)
    # Replanning (Shield._candidate_plan): the candidate made from this
    # verified state, or none while braking harder than the plans allow.
    use_candidate = False
    drop_candidate = False
    if flags[GOAL_PENDING] == 1:
      braking = False
      for d in range(dof):
        if abs(command[2, d]) > limits[6, d]:
          braking = True
      same_key = (flags[HAS_CANDIDATE] == 1
                  and candidate_meta[2] == verified[0]
                  and candidate_meta[3] == verified[1])
      if same_key:
        use_candidate = True
      elif braking:
        drop_candidate = True
      else:
        return _stop(c, check, False)
    if use_candidate:
      now_plan, now_start = candidate, candidate_meta[0]
      now_filled = int(candidate_meta[1])
      now_window, now_suffix = candidate_window, candidate_suffix
      pk.make(current, verified[0], 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
              0.0)
    else:
      now_plan, now_start, now_filled = plan, plan_start, plan_filled
      now_window, now_suffix = plan_window, plan_suffix
      current[:] = verified
    measured = period >= params[MIN_PERIOD]
    if measured:
      for n in range(keypoints.shape[0]):
        for r in range(3):
          new_velocities[n, r] = (keypoints[n, r] - positions[n, r]) / period
      last_t, last_period = t, period
    else:
      new_velocities[:] = velocities
      last_t, last_period = human[LAST_T], human[LAST_PERIOD]
    new_positions[:] = keypoints
    # The monitored path: one intended step, then the failsafe; a
    # candidate from rest that does not verify at path velocity 1 tries 0
    # (Shield.step).
    max_acc, max_jerk = _path_limits(command[4], limits[0], limits[1],
                                     limits[2], limits[3])
    attempts = 1
    if use_candidate:
      attempts = 2
      for d in range(dof):
        if (abs(command[1, d]) > params[REST]
            or abs(command[2, d]) > params[REST]):
          attempts = 1
    have_nominal = False
    safe = False
    c_check = (2, 0, -np.inf, check[3], check[4], check[5])
    for attempt in range(attempts):
      if attempt == 1:
        pk.make(current, verified[0], 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
                0.0, 0.0)
      have = (not use_candidate and flags[HAS_INTENDED] == 1
              and not (intended[6] <= pk._TIME_EPS and intended[1] != 1.0))
      if have:
        new_intended[:] = intended
      else:
        have = pk.plan_profile(new_intended, current[0], current[1],
                               current[2], 1.0, max_acc, max_jerk, dt)
      has_failsafe = False
      if have:
        pk.advance(new_intended, dt)
        target = 0.0   # SSM: brake to rest.
        if params[PFL] == 1.0:   # Shield._s_dot_limit.
          remaining = now_suffix[_sample_index(
              new_intended[0], now_start, inverse, now_plan.shape[0] - 1)]
          target = (1.0 if remaining <= params[ALLOWED]
                    else params[ALLOWED] / remaining)
        has_failsafe = pk.plan_profile(failsafe, new_intended[0],
                                       new_intended[1], new_intended[2],
                                       target, max_acc, max_jerk, dt)
      if attempt == 0:   # What was wanted (Shield.step's `nominal`).
        nominal[:] = new_intended
        have_nominal = have
      c_check = (2, 0, -np.inf, check[3], check[4], check[5])
      if not has_failsafe or new_intended[0] < current[0]:
        safe = False
      else:
        c_check = _verify(
            params, now_plan, now_start, inverse, now_filled, current[0],
            current[1], command[0], failsafe, t, new_positions,
            new_velocities, last_t, last_period, limits[4], limits[5],
            fixed, points, frame_index, alpha, static_radius, levers,
            half_lengths, v_max, a_max, body_ends, ends, half_thickness, base,
            now_window, now_suffix)
        if c_check[0] < 0:
          return _stop(c, check, True)
        safe = c_check[0] == 1
      if safe:
        break
    if safe:
      ok = _plan_state(now_plan, now_start, inverse, dt, now_filled,
                       new_intended[0], new_intended[1], new_intended[2],
                       new_intended[3], state)
      c_intervened = False
    else:
      moved[:] = verified
      pk.advance(moved, dt)
      ok = _plan_state(plan, plan_start, inverse, dt, plan_filled, moved[0],
                       moved[1], moved[2], moved[3], state)
      c_intervened = True
      if ok and have_nominal:
        ok = _plan_state(now_plan, now_start, inverse, dt, now_filled,
                         nominal[0], nominal[1], nominal[2], nominal[3],
                         wanted)
        same = True
        for d in range(dof):
          if not (abs(wanted[0, d] - state[0, d]) <= params[SAME]):
            same = False
        if same:
          for d in range(dof):
            if not (abs(wanted[1, d] - state[1, d]) <= params[SAME]):
              same = False
        c_intervened = not same
    if not ok:
      return _stop(c, check, True)
    # Commit the cycle.
    positions[:] = new_positions
    velocities[:] = new_velocities
    if measured:
      human[LAST_T] = last_t
      human[LAST_PERIOD] = last_period
      human[COUNT] += 1.0
    previous_q[:] = command[0]
    if drop_candidate:
      flags[HAS_CANDIDATE] = 0
    if safe:
      if use_candidate:   # Shield._adopt.
        plan, plan_start, plan_filled = now_plan, now_start, now_filled
        plan_window, plan_suffix = now_window, now_suffix
        flags[GOAL_PENDING] = 0
        flags[HAS_CANDIDATE] = 0
        flags[ADOPTED_AT] = c
      verified[:] = failsafe
      intended[:] = new_intended
      flags[HAS_INTENDED] = 1
    else:
      verified[:] = moved
      flags[HAS_INTENDED] = 0
    for row in range(1, 4):
      for d in range(dof):
        state[row, d] = min(max(state[row, d], -clip[row - 1, d]),
                            clip[row - 1, d])
    command[:] = state
    for row in range(3):
      setpoints[c, row] = state[row]
    intervened[c] = c_intervened
    check = c_check
  return _stop(count, check, False)


_warm = False


def warm_up():
  """Compiles (or loads from the cache) the kernels for the argument types
  the shield passes (plan_state: plans with writeable and read-only
  samples), once per process, so no cycle pays for it."""
  global _warm
  if _warm:
    return
  dof, count_l, count_b, count_n = 2, 2, 1, 2
  floats = lambda *shape: np.zeros(shape)
  ints = lambda *shape: np.zeros(shape, dtype=np.int64)
  params = floats(NUM_PARAMS)
  params[CYCLE] = 1.0
  for writeable in (True, False):
    plan = floats(1, 4, dof)
    plan.flags.writeable = writeable
    plan_state(plan, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0, floats(5, dof))
  plan = floats(1, 4, dof)
  ssm_cycles(params, floats(0, count_n, 3), floats(0),
             floats(5, dof), floats(dof), floats(pk.PATH_SIZE),
             floats(pk.PATH_SIZE), ints(4), floats(3), floats(count_n, 3),
             floats(count_n, 3), plan, floats(2), plan, floats(4),
             floats(7, dof), floats(3, dof), floats(dof, 3, 4),
             floats(count_l, 2, 4), ints(count_l), floats(count_l),
             floats(count_l), floats(dof, count_l), floats(count_l),
             floats(count_n), floats(count_n),
             ints(2, count_b), ints(2 * count_b), floats(count_b), floats(3),
             floats(1), floats(1), floats(1), floats(1), floats(0, 3, dof),
             np.zeros(0, dtype=np.bool_))
  _warm = True
