"""Many shield cycles at once: `step_many`, checkpoints for a replay.

`step_many(shield, frames, times)` is `Shield.step` for each cycle of a
sequence whose human keypoints are known in advance (a task's RL step:
the playback's frames for its L physics steps). With compiled=True the
cycles the compiled kernel covers (`cycle_kernels.ssm_cycles`: every
mode that gates the motion, `modes`, its speed limit if any as the
kernel's PFL parameter; the combined human model without Kalman filter, a
measured human with a velocity; a pending goal's candidate plan made here
beforehand, as Shield.step makes it) run in one call; a call that stops
for a candidate plan from a moved state is followed by one that makes it
(Ruckig, in Python) and goes on; every other cycle (no candidate can be
made, a mode that does not gate such as 'off', the first measurements)
runs `Shield.step`, the readable reference. compiled=False runs the
reference for all.

`checkpoint(shield)` / `restore(shield, saved)` save and restore the
shield's state between cycles cheaply (the reference replaces its arrays
and paths instead of changing them in place, so shallow copies suffice;
the one array changed in place, the human's extremity lengths, is
copied). A task that precomputed an RL step's set-points and finds the
robot pushed after physics step k restores the checkpoint and replays
cycles 0..k (deterministic: the same set-points) before `Shield.resync`.

This module is the shield's compiled twin: it reads and writes the
shield's (and its HumanReach's) private state, as Shield.step does.
"""

import numpy as np

from hrc_suite.safety import cycle_kernels as ck
from hrc_suite.safety import human_reach as human_reach_lib
from hrc_suite.safety import path as path_lib
from hrc_suite.safety import shield as shield_lib

# Plan samples computed ahead of a compiled call, beyond the cycles' own
# reach and the longest failsafe (robot_description: max_s_stop); if one
# is still missing the whole plan is sampled and the call repeated (so
# which cycles run compiled never depends on how much of a plan was
# sampled before: snapshots and replays give the same bits).
_FILL_MARGIN_CYCLES = 8


def checkpoint(shield):
  """The shield's state now (for `restore`)."""
  human = shield.human
  return (dict(shield.__dict__), dict(human.__dict__),
          human._extremity_lengths.copy())


def restore(shield, saved):
  """Returns the shield to a `checkpoint`."""
  own, human, lengths = saved
  shield.__dict__.clear()
  shield.__dict__.update(own)
  shield.human.__dict__.clear()
  shield.human.__dict__.update(human)
  shield.human._extremity_lengths = lengths.copy()


def _constants(shield):
  """The kernel's constant arguments for this shield (cached on it)."""
  cached = shield.__dict__.get('_batch_constants')
  if cached is not None:
    return cached
  params = np.zeros(ck.NUM_PARAMS)
  config = shield.human.config
  params[ck.CYCLE] = shield.cycle_time
  params[ck.INTERVAL] = shield.interval
  params[ck.WORKSPACE] = shield._workspace_radius
  params[ck.ERROR_POS] = config.measurement_error_pos
  params[ck.ERROR_VEL] = config.measurement_error_vel
  params[ck.DELAY] = config.delay
  params[ck.MIN_PERIOD] = human_reach_lib._MIN_SAMPLE_PERIOD
  params[ck.SAME] = shield_lib._SAME_COMMAND
  params[ck.REST] = shield_lib.REST_TOLERANCE
  params[ck.SLACK] = shield_lib._BROAD_PHASE_SLACK
  # The mode (safety/modes.py): a speed limit where contact is possible
  # (PFL) or none (SSM).
  params[ck.PFL] = float(shield.speed_limit is not None)
  params[ck.ALLOWED] = shield.speed_limit or 0.0
  params[ck.S_DOT_TOLERANCE] = shield_lib._S_DOT_TOLERANCE
  s = shield
  limits = np.ascontiguousarray([
      s._den_offset, s._acc_numerator, s._jerk_numerator, s._jerk_acc,
      s._q_min, s._q_max, s.limits.a_max_ltt], dtype=float)
  robot, human = shield.robot, shield.human
  cached = (params, limits, np.ascontiguousarray(s._clip, dtype=float),
            *robot._kernel_model, robot._kernel_frames,
            robot._kernel_alpha, robot._kernel_static,
            robot._kernel_levers, robot._kernel_half_lengths,
            human._kernel_v_max, human._kernel_a_max,
            s._body_ends, human._kernel_ends,
            np.ascontiguousarray(human._half_thickness, dtype=float),
            np.ascontiguousarray(s._base, dtype=float))
  shield.__dict__['_batch_constants'] = cached
  return cached


def compiled_eligible(shield):
  """Whether the next cycle may run compiled (see the module)."""
  human = shield.human
  return (shield._gates and human.use_combined_model
          and not human.use_kalman_filter and human.positions is not None
          and human.has_velocity)


def _samples(plan, shield, count):
  """The plan's samples for the kernel (writeable), computed up to the
  reach of `count` cycles and a failsafe."""
  if plan._sampler is not None:
    horizon = (count + _FILL_MARGIN_CYCLES) * shield.cycle_time
    needed = plan.sample_index(shield.s + horizon + shield.max_s_stop)
    if needed >= plan._filled:
      plan._fill(needed)
  samples = plan._coefficients
  return samples if samples.flags.writeable else np.array(samples)


def _speed_tables(shield, plan):
  """PFL's speed tables of a plan (Shield._plan_speeds; SSM: unused)."""
  if shield.speed_limit is None or plan is None:
    return _NO_TABLE, _NO_TABLE
  return shield._plan_speeds(plan)


_NO_TABLE = np.zeros(1)


def _run_compiled(shield, frames, times, setpoints, intervened):
  """Runs what the kernel covers of frames/times; returns cycles done."""
  constants = _constants(shield)
  if shield.goal_pending:
    shield._candidate_plan()   # What Shield.step does first (cached).
  plan = shield._plan
  candidate, key = shield._candidate or (None, (0.0, 0.0))
  human = shield.human
  command = np.array(shield._state)
  previous_q = np.array(shield._previous_q, dtype=float)
  verified = shield_lib._path_array(shield._verified)
  intended_path = shield._intended
  flags = np.empty(4, dtype=np.int64)   # cycle_kernels.HAS_INTENDED, ...
  flags[ck.HAS_INTENDED] = intended_path is not None
  flags[ck.GOAL_PENDING] = shield.goal_pending
  flags[ck.HAS_CANDIDATE] = candidate is not None
  flags[ck.ADOPTED_AT] = -1
  intended = shield_lib._path_array(intended_path or path_lib.Path())
  state = np.array([human.last_measurement_time, human._last_period,
                    human.num_measurements], dtype=float)
  positions = np.array(human.positions, dtype=float)
  velocities = np.array(human.velocities, dtype=float)
  total, check = 0, None
  while total < len(times):
    tables = _speed_tables(shield, plan) + _speed_tables(shield, candidate)
    samples = _samples(plan, shield, len(times))
    candidate_samples = samples
    candidate_meta = np.zeros(4)
    if candidate is not None:
      candidate_samples = _samples(candidate, shield, len(times))
      candidate_meta[:] = (candidate.start_time, candidate._filled) + key
    (done, status, first, distance, s_edges, t_edges, q_edges,
     missing) = ck.ssm_cycles(
         constants[0], frames[total:], times[total:], command, previous_q,
         verified, intended, flags, state, positions, velocities, samples,
         np.array([plan.start_time, plan._filled]), candidate_samples,
         candidate_meta, constants[1], *constants[2:], *tables,
         setpoints[total:], intervened[total:])
    if done:
      total += done
      check = (status, first, distance, s_edges, t_edges, q_edges)
    if flags[ck.ADOPTED_AT] >= 0:   # The candidate was adopted (Shield._adopt).
      plan, candidate = candidate, None
      flags[ck.ADOPTED_AT] = -1
    if not missing:
      if not (done and total < len(times) and flags[ck.GOAL_PENDING]):
        break
      # The kernel stopped for a candidate from the moved command
      # (Shield._candidate_plan; it stops only where a plan may start
      # there, Shield._can_plan_from): made here (nobody planned from this
      # command before: not looked up among recent plans), the cycles go
      # on.
      made = shield.candidate_from(command, verified[0], verified[1],
                                   recent=False)
      if made is None:
        break   # step_many's next call runs the cycle as Shield.step.
      candidate, key = made
      shield._candidate = made
      flags[ck.HAS_CANDIDATE] = 1
      continue
    if plan._filled > plan._last and (candidate is None
                                      or candidate._filled > candidate._last):
      break
    plan._all()
    if candidate is not None:
      candidate._all()
  if not total:
    return 0
  status, first, distance, s_edges, t_edges, q_edges = check
  shield._plan = plan
  shield._goal_pending = bool(flags[ck.GOAL_PENDING])
  if not flags[ck.HAS_CANDIDATE]:
    shield._candidate = None
  shield._state = command
  shield._previous_q = previous_q
  shield._verified = shield_lib._path_from_array(verified)
  shield._intended = (shield_lib._path_from_array(intended)
                      if flags[ck.HAS_INTENDED] else None)
  shield.time = float(times[total - 1])
  shield._lazy = {}
  shield._pending_check = None
  shield.intervened = bool(intervened[total - 1])
  shield._is_safe = status == 1
  shield._first_unsafe_interval = int(first)
  shield._reach_distance = None if np.isnan(distance) else float(distance)
  shield._reach_arguments = (None if status == 2 else (
      plan, s_edges.tolist(), t_edges.tolist(), q_edges))
  count = int(state[ck.COUNT])
  if count != human.num_measurements:
    # HumanReach.measure keeps the positions of the last velocity update
    # for the POS model's lengths.
    last = total - 1   # The last cycle that measured (usually the last).
    while last > 0 and times[last] != state[ck.LAST_T]:
      last -= 1
    human._length_positions = (positions if last == total - 1
                               else np.array(frames[last], dtype=float))
  human.positions = positions
  human.velocities = velocities
  human.last_measurement_time = float(state[ck.LAST_T])
  human._last_period = float(state[ck.LAST_PERIOD])
  human.num_measurements = count
  return total


def step_many(shield, frames, times, compiled=True):
  """Shield.step for each cycle: frames (n, N_kp, 3) measured at times
  (n,). Returns set-points (n, 3, dof) (q, dq, ddq of each cycle) and
  the cycles' `intervened` flags (n,)."""
  frames = np.ascontiguousarray(frames, dtype=float)
  times = np.ascontiguousarray(times, dtype=float)
  count = times.shape[0]
  if frames.shape[0] != count or frames.ndim != 3:
    raise ValueError(f'frames: expected shape ({count}, N_kp, 3) for '
                     f'{count} times, got {frames.shape}')
  setpoints = np.empty((count, 3, shield.dof))
  intervened = np.empty(count, dtype=bool)
  c = 0
  while c < count:
    if compiled and compiled_eligible(shield):
      done = _run_compiled(shield, frames[c:], times[c:], setpoints[c:],
                           intervened[c:])
      c += done
      if c >= count:
        break
      if done:
        # Most stops need a candidate plan from the moved state: the next
        # call makes it (as Shield.step would) and runs that cycle.
        continue
    setpoints[c] = shield.step(frames[c], times[c])
    intervened[c] = shield.intervened
    c += 1
  return setpoints, intervened
