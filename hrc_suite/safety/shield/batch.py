"""Many shield cycles at once: `step_many`, checkpoints for a replay.

`step_many(shield, frames, times)` is `Shield.step` for each cycle of a
sequence whose human keypoints are known in advance (a task's RL step:
the playback's frames for its L physics steps). With compiled=True the
cycles the compiled kernel covers (`cycle_kernels.ssm_cycles`: every
mode that gates the motion, `modes`, with its compiled verification,
`mode_kernels`; the combined human model without Kalman filter, a
measured human with a velocity; a pending goal's candidate plan made
here beforehand, as Shield.step makes it) run in one call; a call that
stops for a candidate plan from a moved state is followed by one that
makes it (Ruckig, in Python) and goes on; every other cycle (no
candidate can be made, a mode that does not gate such as 'off', the
first measurements) runs `Shield.step`, the readable reference.
compiled=False runs the reference for all.

Both read the shield's state (`Shield.state`, a frozen
`shield_state.ShieldState`) and make the next one: here it is unpacked
into the kernel's arrays (`cycle_kernels.CycleState`) and the kernel's
result packed into the next record. `checkpoint(shield)` is that record
and `restore(shield, saved)` sets it back: a task that precomputed an RL
step's set-points and finds the robot pushed after physics step k
restores the checkpoint and replays cycles 0..k (deterministic: the same
set-points) before `Shield.resync`.
"""

import math
from typing import Tuple

import numpy as np

from hrc_suite.safety.shield import cycle_kernels as ck
from hrc_suite.safety.shield import human_reach as human_reach_lib
from hrc_suite.safety.shield import shield as shield_lib
from hrc_suite.safety.shield import shield_state

# Plan samples computed ahead of a compiled call, beyond the cycles' own
# reach and the longest failsafe (robot_description: max_s_stop); if one
# is still missing the whole plan is sampled and the call repeated (so
# which cycles run compiled never depends on how much of a plan was
# sampled before: snapshots and replays give the same bits).
_FILL_MARGIN_CYCLES = 8


def checkpoint(shield: shield_lib.Shield) -> shield_state.ShieldState:
  """The shield's state now, for `restore`.

  Args:
    shield: the shield.

  Returns:
    Its `ShieldState` (frozen: the checkpoint itself).
  """
  return shield.state


def restore(shield: shield_lib.Shield,
            saved: shield_state.ShieldState) -> None:
  """Returns the shield to a `checkpoint`.

  Args:
    shield: the shield the checkpoint is of.
    saved: the checkpoint.
  """
  shield.state = saved


def _compiled_eligible(shield):
  """Whether the next cycle may run compiled (see the module)."""
  human = shield.human
  return (shield.gates and human.use_combined_model
          and not human.use_kalman_filter and human.positions is not None
          and human.has_velocity)


def _kernel_plan(shield, plan, tables, s, count):
  """`plan` for the kernel: the fields of its `cycle_kernels.Plan` (a
  plain tuple, the mode's tables as `tables`, their fields): its samples
  (writeable) computed up to the reach of `count` cycles and a failsafe
  from plan time s."""
  horizon = (count + _FILL_MARGIN_CYCLES) * shield.cycle_time
  samples = plan.samples_through(
      plan.sample_index(s + horizon + shield.max_s_stop))
  if not samples.flags.writeable:
    samples = np.array(samples)
  return samples, plan.start_time, plan.filled, tables


def _cycle_state(state):
  """The kernel's arrays of a `ShieldState` (copies: the kernel changes
  them in place), as the fields of a `cycle_kernels.CycleState`."""
  human = state.human
  key = state.candidate_key or (0.0, 0.0)
  scalars = np.empty(1, dtype=ck.SCALARS)
  scalars[0] = (   # In SCALARS' order.
      state.intended is not None, state.goal_pending,
      state.candidate is not None, -1, key[0], key[1],
      human.last_measurement_time, human.last_period,
      human.num_measurements)
  intended = state.intended
  return (   # command, previous_q, verified, intended, ...
      state.command.copy(), np.array(state.previous_q, dtype=float),
      shield_state.path_array(state.verified),
      (np.zeros(shield_state.PATH_SIZE) if intended is None
       else shield_state.path_array(intended)),
      np.array(human.positions, dtype=float),
      np.array(human.velocities, dtype=float), scalars)


def _run_compiled(shield, frames, times, setpoints, intervened):
  """Runs what the kernel covers of frames/times; returns cycles done."""
  constants = shield.kernel_constants
  mode = shield.kernel_parameters()
  state = shield.state
  if state.goal_pending:   # What Shield.step does first.
    candidate, key = shield.candidate(state)
    if candidate is not state.candidate or key != state.candidate_key:
      state = state.replace(candidate=candidate, candidate_key=key)
  plan, candidate, key = state.plan, state.candidate, state.candidate_key
  s = state.verified.s
  arrays = _cycle_state(state)
  flags = arrays[-1][0]   # The SCALARS record, changed by the kernel.
  # The mode's tables of each plan, made once per call (Shield.kernel_tables).
  tables = {}
  def plan_fields(made):
    kept = tables.get(id(made))
    if kept is None:
      group = shield.kernel_tables(made)
      kept = tables[id(made)] = (made, type(group), tuple(group))
    return kept[1], _kernel_plan(shield, made, kept[2], s, len(times))
  total, check = 0, None
  while total < len(times):
    tables_class, plan_group = plan_fields(plan)
    candidate_group = plan_group
    if candidate is not None:
      candidate_group = plan_fields(candidate)[1]
    (done, status, first, distance, s_edges, t_edges, q_edges,
     missing) = ck.run_cycle_fields(
         constants, mode, tables_class, arrays, plan_group, candidate_group,
         frames[total:], times[total:], setpoints[total:],
         intervened[total:])
    if done:
      total += done
      check = (status, first, distance, s_edges, t_edges, q_edges)
    if flags['adopted_at'] >= 0:   # The candidate was adopted.
      plan, candidate = candidate, None
      flags['adopted_at'] = -1
    if not missing:
      if not (done and total < len(times) and flags['goal_pending']):
        break
      # The kernel stopped for a candidate from the moved command
      # (Shield.candidate; it stops only where a plan may start there):
      # made here (nobody planned from this command before: not looked
      # up among recent plans), the cycles go on.
      verified = arrays[2]
      made = shield.candidate_from(arrays[0], verified[0], verified[1],
                                   recent=False)
      if made is None:
        break   # step_many's next call runs the cycle as Shield.step.
      candidate, key = made
      flags['has_candidate'] = 1
      flags['key_s'], flags['key_s_dot'] = key
      continue
    if plan.fully_sampled and (candidate is None
                               or candidate.fully_sampled):
      break
    plan.samples()
    if candidate is not None:
      candidate.samples()
  if not total:
    if state is not shield.state:   # The candidate made, kept for step.
      shield.state = state
    return 0
  shield.state = _next_state(state, arrays, plan, candidate, key, check,
                             frames, times, total, intervened)
  return total


def _next_state(state, arrays, plan, candidate, key, check, frames, times,
                total, intervened):
  """The `ShieldState` after `total` compiled cycles from `state`
  (arrays: the kernel's `CycleState` fields)."""
  status, first, distance, s_edges, t_edges, q_edges = check
  command, previous_q, verified, intended, positions, velocities, scalars = (
      arrays)
  (has_intended, goal_pending, has_candidate, _, _, _, last_t, last_period,
   count) = scalars.item(0)   # SCALARS' fields.
  human = state.human
  length_positions = human.length_positions
  if count != human.num_measurements:
    # HumanReach.measure keeps the positions of the last velocity update
    # for the POS model's lengths.
    last = total - 1   # The last cycle that measured (usually the last).
    while last > 0 and times[last] != last_t:
      last -= 1
    length_positions = (positions if last == total - 1
                        else np.array(frames[last], dtype=float))
  record = shield_state.record
  return record(
      shield_state.ShieldState,
      command=command, previous_q=previous_q,
      verified=shield_state.path_from_array(verified),
      intended=(shield_state.path_from_array(intended)
                if has_intended else None),
      plan=plan, goal=state.goal, goal_pending=bool(goal_pending),
      candidate=candidate if has_candidate else None,
      candidate_key=key if has_candidate else None,
      time=float(times[total - 1]),
      intervened=bool(intervened[total - 1]),
      verification=record(
          shield_state.Verification, is_safe=status == 1,
          first_unsafe_interval=int(first),
          reach_distance=None if math.isnan(distance) else float(distance),
          edges=None if status == 2 else shield_state.ReachEdges(
              plan, s_edges.tolist(), t_edges.tolist(), q_edges),
          pending=None),
      human=record(
          human_reach_lib.HumanState, positions=positions,
          velocities=velocities, last_measurement_time=last_t,
          last_period=last_period, num_measurements=count,
          covariance=human.covariance,
          extremity_lengths=human.extremity_lengths,
          length_positions=length_positions))


def step_many(shield: shield_lib.Shield, frames: np.ndarray,
              times: np.ndarray, compiled: bool = True
              ) -> Tuple[np.ndarray, np.ndarray]:
  """Shield.step for each of n cycles (see the module).

  Args:
    shield: the shield.
    frames: (n, N_kp, 3) the human keypoints measured at each cycle.
    times: (n,) the cycles' times, s.
    compiled: False runs Shield.step for every cycle.

  Returns:
    (set-points (n, 3, dof): q, dq, ddq of each cycle, the cycles'
    `intervened` flags (n,)).

  Raises:
    ValueError: frames and times do not match.
  """
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
    if compiled and _compiled_eligible(shield):
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
