"""Compiled (numba) shield cycles: many cycles in one call.

`ssm_cycles` runs what shield.Shield.step does (every mode that gates the
motion) for a sequence of cycles whose human keypoints are known in
advance (a playback), on the shield's state (`shield_state.ShieldState`)
held in arrays (`CycleState`; `batch.step_many` unpacks the record and
packs the result into the next one): the human measurement (no Kalman
filter, combined model), the monitored path (one intended step, then the
failsafe: `path_kernels`), its verification (joint limits, the broad
phases, robot and human reach capsules and the mode's exact verdict:
the `kernels` the Python cycle calls, and `mode_kernels`) and the
command from the plan's samples (long_term_plan.LongTermPlan.state).

Arguments travel in named groups (typing.NamedTuple; numba types each
field, float64 and int64 as in the arrays before): the shield's
`Constants`, the mode's parameter group (`ShieldMode.kernel_parameters`,
whose class selects the mode's compiled verification, `mode_kernels`),
the `CycleState` changed in place (its scalars one record of the
structured dtype `SCALARS`) and each `Plan`.

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
from typing import NamedTuple

import numpy as np

from hrc_suite.safety import kernels
from hrc_suite.safety import plan_kernels
from hrc_suite.safety.shield import mode_kernels
from hrc_suite.safety.shield import path_kernels as pk

_jit = kernels._jit
_inline = kernels._inline

Plan = mode_kernels.Plan


class CycleConstants(NamedTuple):
  """The shield's scalar constants (float64)."""
  cycle: float        # s, the shield cycle.
  interval: float     # s, a failsafe slice (Shield.interval).
  workspace: float    # m, the robot's workspace ball around its base.
  error_pos: float    # m, the human model's position error ...
  error_vel: float    # m/s, ... velocity error ...
  delay: float        # s, ... and measurement delay.
  min_period: float   # s, human_reach's shortest velocity sample period.
  same: float         # cycle_terms.SAME_COMMAND.
  slack: float        # m, cycle_terms.BROAD_PHASE_SLACK.
  rest: float         # cycle_terms.REST_TOLERANCE.


class JointTerms(NamedTuple):
  """The shield's per-joint terms (each (dof,) unless noted)."""
  den_offset: np.ndarray       # Shield._path_limits' terms ...
  acc_numerator: np.ndarray
  jerk_numerator: np.ndarray
  jerk_acc: np.ndarray
  q_min: np.ndarray            # rad, joint limits.
  q_max: np.ndarray
  a_max_ltt: np.ndarray        # rad/s^2, the plans' acceleration limit.
  clip: np.ndarray             # (3, dof) |dq|, |ddq|, |dddq| limits.


class RobotModel(NamedTuple):
  """The robot's capsule model (RobotReach's kernel arrays) and base."""
  fixed: np.ndarray
  points: np.ndarray
  frame_index: np.ndarray
  alpha: np.ndarray
  static_radius: np.ndarray
  levers: np.ndarray
  half_lengths: np.ndarray
  base: np.ndarray             # (3,) m, the workspace ball's centre.


class HumanModel(NamedTuple):
  """The human model's arrays (HumanReach's and Shield's)."""
  v_max: np.ndarray            # (N_kp,) m/s.
  a_max: np.ndarray            # (N_kp,) m/s^2.
  body_ends: np.ndarray        # (2, B) keypoints of the bodies' ends.
  ends: np.ndarray             # (2 B,) the same, proximal then distal.
  half_thickness: np.ndarray   # (B,) m.


class Constants(NamedTuple):
  """Everything of a shield that its cycles do not change."""
  cycle: CycleConstants
  joints: JointTerms
  robot: RobotModel
  human: HumanModel


# The scalars of a `CycleState` (one record, changed in place): an intended
# path is kept, a goal is pending, a candidate plan is pending, the cycle
# that adopted it (-1: none), the candidate's key (the verified path's s,
# s_dot it was planned from: Shield's candidate_key), and the human
# measurement's last time, period and count (HumanState).
SCALARS = np.dtype([
    ('has_intended', np.int64), ('goal_pending', np.int64),
    ('has_candidate', np.int64), ('adopted_at', np.int64),
    ('key_s', np.float64), ('key_s_dot', np.float64),
    ('last_t', np.float64), ('last_period', np.float64),
    ('count', np.int64)])


class CycleState(NamedTuple):
  """A shield state (shield_state.ShieldState) as the compiled cycles
  change it in place."""
  command: np.ndarray       # (5, dof) q, dq, ddq, dddq, v_nominal.
  previous_q: np.ndarray    # (dof,)
  verified: np.ndarray      # Path array (path_kernels).
  intended: np.ndarray      # Path array (valid if has_intended).
  positions: np.ndarray     # (N_kp, 3) the human's keypoints ...
  velocities: np.ndarray    # ... and their velocities.
  scalars: np.ndarray       # (1,) of SCALARS.


class Measurement(NamedTuple):
  """A cycle's human measurement."""
  positions: np.ndarray
  velocities: np.ndarray
  last_t: float
  last_period: float


@_inline
def _plan_state(plan, inverse, cycle, path, out):
  """plan_state of `Plan` plan at the path array's state; False if the
  sample at its s is not computed yet."""
  s = path[0]
  last = plan.samples.shape[0] - 1
  k = int(math.floor((s - plan.start) * inverse))
  k = 0 if k < 0 else (last if k > last else k)
  if k >= plan.filled:
    return False
  plan_kernels.plan_state(plan.samples, plan.start, inverse, cycle, s,
                          path[1], path[2], path[3], out)
  return True


@_inline
def _path_limits(v_nominal, joints):
  """Shield._path_limits."""
  dof = v_nominal.shape[0]
  acc = np.inf
  for i in range(dof):
    acc = min(acc, joints.acc_numerator[i]
              / (abs(v_nominal[i]) + joints.den_offset[i]))
  acc = acc if acc > 0.0 else 0.0
  jerk = np.inf
  for i in range(dof):
    jerk = min(jerk, (joints.jerk_numerator[i] - joints.jerk_acc[i] * acc)
               / (abs(v_nominal[i]) + joints.den_offset[i]))
  return acc, (jerk if jerk > 0.0 else 0.0)


@_inline
def _verify(constants, mode, plan, current, previous_q, failsafe, now,
            measured):
  """path_check.PathCheck.verify (a measured human with a velocity; the
  mode's exact verdict: mode_kernels) of the failsafe from path array
  `current` on `Plan` plan. Returns (status, first unsafe slice, reach
  distance (nan: not computed), s_edges, t_edges, q_edges); status 1
  verified, 0 not, -1 a plan sample is missing (the cycle goes to
  Python)."""
  cycle, robot, human = constants.cycle, constants.robot, constants.human
  joints = constants.joints
  dt = cycle.cycle
  interval = cycle.interval
  inverse = 1.0 / dt
  dof = previous_q.shape[0]
  end = failsafe[6]
  count = max(int(math.ceil(end / interval - 1e-9)), 1)
  pieces = np.empty((pk.MAX_PIECES, 5))
  num = pk.segments(failsafe, pieces)
  s_edges = np.empty(count + 2)
  t_edges = np.empty(count + 2)
  q_edges = np.empty((count + 2, dof))
  s_edges[0] = current[0]
  t_edges[0] = 0.0
  last = plan.samples.shape[0] - 1
  for i in range(count + 1):
    time = i * interval if i < count else end
    s = pk.sample_s(pieces, num, time)
    s_edges[i + 1] = s
    t_edges[i + 1] = time + dt
    k = int(math.floor((s - plan.start) * inverse))
    k = 0 if k < 0 else (last if k > last else k)
    if k >= plan.filled:
      return -1, 0, np.nan, s_edges, t_edges, q_edges
  q_edges[0] = previous_q
  kernels.plan_positions(plan.samples, plan.start, inverse, dt, s_edges[1:],
                         q_edges, 1)
  for d in range(dof):
    q = q_edges[count + 1, d]
    if not (joints.q_min[d] <= q <= joints.q_max[d]):
      return 0, count, -np.inf, s_edges, t_edges, q_edges
  age = now - measured.last_t + cycle.delay + t_edges[count + 1]
  centre, radius, gap = kernels.horizon_balls(
      measured.positions, measured.velocities, human.v_max, human.body_ends,
      human.half_thickness, age, cycle.error_pos, robot.base)
  bound = gap - cycle.workspace
  if bound > 0.0:
    return 1, -1, bound, s_edges, t_edges, q_edges
  # The edges' link frames, the first one for the bound from one forward
  # kinematics, the others only if the reach capsules are needed.
  frames = np.empty((count + 2, dof, 3, 4))
  kernels._chain(q_edges[0], robot.fixed, frames[0])
  bound = kernels.swept_balls_gap(
      q_edges, s_edges, frames[0], robot.points, robot.frame_index,
      robot.alpha, robot.static_radius, robot.levers, robot.half_lengths,
      centre, radius, cycle.slack) - cycle.slack
  if bound > 0.0:
    return 1, -1, bound, s_edges, t_edges, q_edges
  for n in range(1, count + 2):
    kernels._chain(q_edges[n], robot.fixed, frames[n])
  rc1, rc2, rr = kernels.reach_from_frames(
      frames, s_edges, robot.points, robot.frame_index, robot.alpha,
      robot.static_radius)
  bound = (kernels.balls_capsules_distance(centre, radius, rc1, rc2, rr)
           - cycle.slack)
  if bound > 0.0:
    return 1, -1, bound, s_edges, t_edges, q_edges
  t = (now - measured.last_t) + t_edges + cycle.delay
  error_vel = cycle.error_vel + human.a_max * (0.5 * measured.last_period)
  hc1, hc2, hr = kernels.human_velocity_capsules(
      measured.positions, measured.velocities, human.v_max, human.a_max, t,
      cycle.error_pos, error_vel, human.ends, human.half_thickness, True)
  slices = mode_kernels.Slices(
      rc1, rc2, rr, hc1.reshape((1,) + hc1.shape),
      hc2.reshape((1,) + hc2.shape), hr.reshape((1,) + hr.shape), s_edges,
      t_edges, q_edges, current, failsafe, pieces, num, interval, plan,
      inverse)
  safe, first = mode_kernels.verdict(mode, slices)
  return (1 if safe else 0), first, np.nan, s_edges, t_edges, q_edges


@_jit
def _stop(c, check, missing):
  """ssm_cycles' result when it stops before cycle c."""
  status, first, distance, s_edges, t_edges, q_edges = check
  return c, status, first, distance, s_edges, t_edges, q_edges, missing


def run_cycles(constants, mode, state, plan, candidate, frames, times,
               setpoints, intervened):
  """`ssm_cycles` on named groups: `Constants` constants, the mode's
  parameter group, `CycleState` state, `Plan` plan and candidate (the
  same tables' class). They cross into compiled code as plain tuples
  (numba types a plain tuple of arrays from a fingerprint, a NamedTuple
  in Python: microseconds a field) through the mode's entry
  (`_entry`), which names them again; `run_cycle_fields` takes them as
  such."""
  return run_cycle_fields(
      constants, mode, type(plan.tables), tuple(state),
      (plan[0], plan[1], plan[2], tuple(plan[3])),
      (candidate[0], candidate[1], candidate[2], tuple(candidate[3])),
      frames, times, setpoints, intervened)


def run_cycle_fields(constants, mode, tables_class, state, plan, candidate,
                     frames, times, setpoints, intervened):
  """`run_cycles` with state, plan and candidate as the plain tuples of
  their fields (the plans' tables, of class tables_class, too): what
  batch.step_many passes on every call.

  Args:
    constants: the shield's `Constants`.
    mode: the mode's parameter group (mode_kernels).
    tables_class: the class of the mode's plan tables (mode_kernels).
    state: `CycleState`'s fields, changed in place.
    plan, candidate: `Plan`'s fields, the tables as their fields.
    frames, times, setpoints, intervened: as `ssm_cycles`'.

  Returns:
    `ssm_cycles`' result.
  """
  if mode is not _LAST_MODE[0]:
    _LAST_MODE[:] = mode, tuple(mode)
  entry = _ENTRIES.get((type(mode), tables_class))
  if entry is None:
    entry = _ENTRIES[type(mode), tables_class] = _entry(type(mode),
                                                        tables_class)
  if constants is not _CONSTANT_FIELDS[0]:
    _CONSTANT_FIELDS[:] = constants, tuple(tuple(group)
                                           for group in constants)
  return entry(_CONSTANT_FIELDS[1], _LAST_MODE[1], state, plan, candidate,
               frames, times, setpoints, intervened)


# (parameter group class, tables class) -> the compiled entry (`_entry`).
_ENTRIES = {}
# The last `Constants` run and its fields as plain tuples: a shield makes
# its constants once (Shield.kernel_constants), so its calls share them.
_CONSTANT_FIELDS = [None, None]
# The last mode parameter group run and its fields, likewise (made once
# per mode: Shield.kernel_parameters).
_LAST_MODE = [None, None]


def _entry(parameters_class, tables_class):
  """The compiled entry of `ssm_cycles` for one mode: takes the groups'
  fields as plain tuples and names them (the classes are constants of
  the compiled code, so each mode compiles its own)."""

  @_jit
  def cycles(constant_fields, mode_fields, state_fields, plan_fields,
             candidate_fields, frames, times, setpoints, intervened):
    constants = Constants(CycleConstants(*constant_fields[0]),
                          JointTerms(*constant_fields[1]),
                          RobotModel(*constant_fields[2]),
                          HumanModel(*constant_fields[3]))
    plan = Plan(plan_fields[0], plan_fields[1], plan_fields[2],
                tables_class(*plan_fields[3]))
    candidate = Plan(candidate_fields[0], candidate_fields[1],
                     candidate_fields[2], tables_class(*candidate_fields[3]))
    return ssm_cycles(constants, parameters_class(*mode_fields),
                      CycleState(*state_fields), plan, candidate, frames,
                      times, setpoints, intervened)
  return cycles


@_jit
def ssm_cycles(constants, mode, state, plan, candidate, frames, times,
               setpoints, intervened):
  """Runs shield cycles for keypoints frames (n, N_kp, 3) at times (n,)
  on `CycleState` state, changed in place; `Constants` constants; the
  mode's parameter group `mode` (mode_kernels). plan and candidate
  (`Plan`) are the adopted plan and the pending goal's candidate plan
  (samples writeable; the candidate's key and whether there is one are
  in state.scalars).

  Writes each cycle's set-point (q, dq, ddq) to setpoints (>= n, 3, dof)
  and whether it intervened to intervened (>= n,), from row 0; the cycle
  that adopts the candidate to state.scalars' adopted_at.

  Called through `run_cycles` (the mode's entry).

  Returns (cycles done, the last cycle's check: status (1 verified, 0
  not, 2 no monitored path), first unsafe slice, reach distance (nan: not
  computed), s_edges, t_edges, q_edges; and whether it stopped for a plan
  sample not computed yet). Stops before a cycle it cannot run (see the
  module).
  """
  cycle, joints = constants.cycle, constants.joints
  command, previous_q = state.command, state.previous_q
  verified, intended = state.verified, state.intended
  positions, velocities = state.positions, state.velocities
  flags = state.scalars[0]
  count = frames.shape[0]
  dof = command.shape[1]
  dt = cycle.cycle
  inverse = 1.0 / dt
  check = (2, 0, -np.inf, np.zeros(0), np.zeros(0), np.zeros((0, dof)))
  current = np.empty(pk.PATH_SIZE)
  new_intended = np.empty(pk.PATH_SIZE)
  nominal = np.empty(pk.PATH_SIZE)
  failsafe = np.empty(pk.PATH_SIZE)
  moved = np.empty(pk.PATH_SIZE)
  setpoint = np.empty((5, dof))
  wanted = np.empty((5, dof))
  new_positions = np.empty_like(positions)
  new_velocities = np.empty_like(velocities)
  for c in range(count):
    # The measurement (HumanReach.measure without the Kalman filter).
    t = times[c]
    keypoints = frames[c]
    if not np.all(np.isfinite(keypoints)):
      return _stop(c, check, False)
    period = t - flags.last_t
    if period < 0.0:
      return _stop(c, check, False)
    # Replanning (Shield._candidate): the candidate made from this
    # verified state, or none while braking harder than the plans allow.
    use_candidate = False
    drop_candidate = False
    if flags.goal_pending == 1:
      braking = False
      for d in range(dof):
        if abs(command[2, d]) > joints.a_max_ltt[d]:
          braking = True
      same_key = (flags.has_candidate == 1
                  and flags.key_s == verified[0]
                  and flags.key_s_dot == verified[1])
      if same_key:
        use_candidate = True
      elif braking:
        drop_candidate = True
      else:
        return _stop(c, check, False)
    if use_candidate:
      now_plan = candidate
      pk.make(current, verified[0], 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
              0.0)
    else:
      now_plan = plan
      current[:] = verified
    measured = period >= cycle.min_period
    if measured:
      for n in range(keypoints.shape[0]):
        for r in range(3):
          new_velocities[n, r] = (keypoints[n, r] - positions[n, r]) / period
      last_t, last_period = t, period
    else:
      new_velocities[:] = velocities
      last_t, last_period = flags.last_t, flags.last_period
    new_positions[:] = keypoints
    measurement = Measurement(new_positions, new_velocities, last_t,
                              last_period)
    # The monitored path: one intended step, then the failsafe; a
    # candidate from rest that does not verify at path velocity 1 tries 0
    # (Shield.step).
    max_acc, max_jerk = _path_limits(command[4], joints)
    attempts = 1
    if use_candidate:
      attempts = 2
      for d in range(dof):
        if (abs(command[1, d]) > cycle.rest
            or abs(command[2, d]) > cycle.rest):
          attempts = 1
    have_nominal = False
    safe = False
    c_check = (2, 0, -np.inf, check[3], check[4], check[5])
    for attempt in range(attempts):
      if attempt == 1:
        pk.make(current, verified[0], 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
                0.0, 0.0)
      have = (not use_candidate and flags.has_intended == 1
              and not (intended[6] <= pk._TIME_EPS and intended[1] != 1.0))
      if have:
        new_intended[:] = intended
      else:
        have = pk.plan_profile(new_intended, current[0], current[1],
                               current[2], 1.0, max_acc, max_jerk, dt)
      has_failsafe = False
      if have:
        pk.advance(new_intended, dt)
        target = mode_kernels.failsafe_target(mode, now_plan, inverse,
                                              new_intended[0])
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
        c_check = _verify(constants, mode, now_plan, current, command[0],
                          failsafe, t, measurement)
        if c_check[0] < 0:
          return _stop(c, check, True)
        safe = c_check[0] == 1
      if safe:
        break
    if safe:
      ok = _plan_state(now_plan, inverse, dt, new_intended, setpoint)
      c_intervened = False
    else:
      moved[:] = verified
      pk.advance(moved, dt)
      ok = _plan_state(plan, inverse, dt, moved, setpoint)
      c_intervened = True
      if ok and have_nominal:
        ok = _plan_state(now_plan, inverse, dt, nominal, wanted)
        same = True
        for d in range(dof):
          if not (abs(wanted[0, d] - setpoint[0, d]) <= cycle.same):
            same = False
        if same:
          for d in range(dof):
            if not (abs(wanted[1, d] - setpoint[1, d]) <= cycle.same):
              same = False
        c_intervened = not same
    if not ok:
      return _stop(c, check, True)
    # Commit the cycle.
    positions[:] = new_positions
    velocities[:] = new_velocities
    if measured:
      flags.last_t = last_t
      flags.last_period = last_period
      flags.count += 1
    previous_q[:] = command[0]
    if drop_candidate:
      flags.has_candidate = 0
    if safe:
      if use_candidate:   # Shield's adoption of the candidate.
        plan = now_plan
        flags.goal_pending = 0
        flags.has_candidate = 0
        flags.adopted_at = c
      verified[:] = failsafe
      intended[:] = new_intended
      flags.has_intended = 1
    else:
      verified[:] = moved
      flags.has_intended = 0
    clip = joints.clip
    for row in range(1, 4):
      for d in range(dof):
        setpoint[row, d] = min(max(setpoint[row, d], -clip[row - 1, d]),
                               clip[row - 1, d])
    command[:] = setpoint
    for row in range(3):
      setpoints[c, row] = setpoint[row]
    intervened[c] = c_intervened
    check = c_check
  return _stop(count, check, False)


_warm = False


def warm_up():
  """Compiles (or loads from the cache) the kernels for the argument types
  the shield passes (plan_state: plans with writeable and read-only
  samples; ssm_cycles: the shipped modes' parameter groups,
  mode_kernels), once per process, so no cycle pays for it."""
  global _warm
  if _warm:
    return
  dof, count_l, count_b, count_n = 2, 2, 1, 2
  floats = lambda *shape: np.zeros(shape)
  ints = lambda *shape: np.zeros(shape, dtype=np.int64)
  for writeable in (True, False):
    samples = floats(1, 4, dof)
    samples.flags.writeable = writeable
    plan_kernels.plan_state(samples, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0,
                            floats(5, dof))
  constants = Constants(
      CycleConstants(1.0, *[0.0] * (len(CycleConstants._fields) - 1)),
      JointTerms(*[floats(dof)] * 7, floats(3, dof)),
      RobotModel(floats(dof, 3, 4), floats(count_l, 2, 4), ints(count_l),
                 floats(count_l), floats(count_l), floats(dof, count_l),
                 floats(count_l), floats(3)),
      HumanModel(floats(count_n), floats(count_n), ints(2, count_b),
                 ints(2 * count_b), floats(count_b)))
  state = CycleState(floats(5, dof), floats(dof), floats(pk.PATH_SIZE),
                     floats(pk.PATH_SIZE), floats(count_n, 3),
                     floats(count_n, 3), np.zeros(1, dtype=SCALARS))
  energy = mode_kernels.EnergyParameters(
      floats(count_b), floats(count_b), floats(count_b), 0.0, floats(1, 3),
      floats(1, 3), np.zeros((count_l, count_l), dtype=np.bool_),
      ints(count_l))
  for mode, tables in (
      (mode_kernels.SsmParameters(), mode_kernels.NoTables()),
      (mode_kernels.SpeedLimitParameters(0.0, 0.0),
       mode_kernels.SpeedTables(floats(1), floats(1))),
      (energy, mode_kernels.EnergyTables(floats(1, dof), floats(1)))):
    plan = Plan(floats(1, 4, dof), 0.0, 1, tables)
    run_cycles(constants, mode, state, plan, plan, floats(0, count_n, 3),
               floats(0), floats(0, 3, dof), np.zeros(0, dtype=np.bool_))
  _warm = True
