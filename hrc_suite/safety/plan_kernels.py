"""Compiled (numba) sampling of a Ruckig plan's constant-jerk pieces.

`sample_pieces` computes what its NumPy reference
(tests/safety/safety_references.py, `sample_pieces`) computes, the same operations
in the same order (bit for bit, tests/safety/test_long_term_plan.py): the
plan's samples one cycle apart from the table of each joint's pieces,
which `piece_table` builds from Ruckig's profiles. `start_state_ok` and
`plan_inputs_ok` are the fast paths of long_term_plan's input checks;
`plan_state` is a plan's state at a path state (LongTermPlan.state, and
the shield's compiled cycles).
Same compilation settings as the shield's kernels (cache, IEEE
arithmetic).
"""

import math

import numpy as np

from hrc_suite.safety import kernels

_jit = kernels._jit


@_jit
def _last_at_or_before(sorted_values, x):
  """The last index with sorted_values[index] <= x (-1 if none):
  np.searchsorted(sorted_values, x, side='right') - 1."""
  low, high = 0, sorted_values.shape[0]
  while low < high:
    middle = (low + high) // 2
    if sorted_values[middle] <= x:
      low = middle + 1
    else:
      high = middle
  return low - 1


@_jit
def sample_pieces(table, starts, joint_shift, goal, cycle_time, duration,
                  first, stop, out):
  """Samples (q and its three derivatives) at plan times first..stop - 1
  cycles into out[first:stop] (out: (N >= stop, 4, dof), a plan's
  samples, filled in place). table (dof * P, 5): rows (start time, p,
  v, a, j) of constant-jerk pieces, joint i's P rows from i * P; starts:
  the rows' start times shifted by joint_shift (dof,) per joint (sorted);
  from `duration` on the goal (dof,) at rest.

  The sample times, and so each joint's query time + joint_shift[i],
  never decrease (floating-point products and sums are monotone): each
  joint's row is searched once and then walked forward, to the same row
  the search would give."""
  dof = joint_shift.shape[0]
  rows = np.full(dof, -2, dtype=np.int64)   # -2: not searched yet.
  last = starts.shape[0] - 1
  for n in range(first, stop):
    time = n * cycle_time
    if time >= duration:
      for i in range(dof):
        out[n, 0, i] = goal[i]
        out[n, 1, i] = 0.0
        out[n, 2, i] = 0.0
        out[n, 3, i] = 0.0
      continue
    for i in range(dof):
      x = time + joint_shift[i]
      row = rows[i]
      if row == -2:
        row = _last_at_or_before(starts, x)
      else:
        while row < last and starts[row + 1] <= x:
          row += 1
      rows[i] = row
      d = time - table[row, 0]
      p, v, a, j = table[row, 1], table[row, 2], table[row, 3], table[row, 4]
      out[n, 0, i] = p + d * (v + d * (0.5 * a + d * j / 6.0))
      out[n, 1, i] = v + d * (a + 0.5 * d * j)
      out[n, 2, i] = a + d * j
      out[n, 3, i] = j


@_jit
def start_state_ok(q0, dq0, ddq0, q_min, q_max, v_max, a_max, j_max,
                   slack):
  """Whether a plan may start at (q0, dq0, ddq0) (dof,): the conditions of
  long_term_plan.check_start_state, element by element (its fast path;
  it names the failing condition itself)."""
  for i in range(q0.shape[0]):
    ramped = abs(dq0[i] + ddq0[i] * abs(ddq0[i]) / (2.0 * j_max[i]))
    if not (q0[i] >= q_min[i] - slack and q0[i] <= q_max[i] + slack and
            abs(dq0[i]) <= v_max[i] + slack and
            abs(ddq0[i]) <= a_max[i] + slack and
            ramped <= v_max[i] + slack):
      return False
  return True


@_jit
def plan_inputs_ok(q0, dq0, ddq0, q_goal, q_min, q_max, v_max, a_max,
                   j_max, slack, margin, goal):
  """Whether long_term_plan.plan_to_goal's inputs (dof,) pass its checks
  (all finite, `start_state_ok`), its fast path; if so the goal clamped
  `margin` inside the joint limits (np.clip(q_goal, q_min + margin,
  q_max - margin)) is written to goal."""
  for i in range(q0.shape[0]):
    if not (math.isfinite(q0[i]) and math.isfinite(dq0[i]) and
            math.isfinite(ddq0[i]) and math.isfinite(q_goal[i])):
      return False
  if not start_state_ok(q0, dq0, ddq0, q_min, q_max, v_max, a_max, j_max,
                        slack):
    return False
  return clamped_goal(q_goal, q_min, q_max, margin, goal)


@_jit
def clamped_goal(q_goal, q_min, q_max, margin, goal):
  """Whether q_goal (dof,) is finite; if so q_goal clamped `margin` inside
  the joint limits (np.minimum(np.maximum(q_goal, q_min + margin),
  q_max - margin)) is written to goal (long_term_plan.clamp_goal's fast
  path)."""
  for i in range(q_goal.shape[0]):
    if not math.isfinite(q_goal[i]):
      return False
  for i in range(q_goal.shape[0]):
    goal[i] = min(max(q_goal[i], q_min[i] + margin), q_max[i] - margin)
  return True


# Ruckig's arrays of one joint's profile, concatenated (ruckig's Profile):
# durations t (7), then p, v, a at the pieces' starts (8 each: the last is
# the end), then jerks j (7).
PROFILE_SIZE = 38
_P, _V, _A, _J = 7, 15, 23, 31


@_jit
def piece_table(profiles, brakes, duration):
  """(table, starts, joint_shift) of long_term_plan's sampler from Ruckig's
  profiles (dof, PROFILE_SIZE) and brake pre-profiles (dof, 5, 2): rows
  t, p, v, a, j; (0, 5, 2) for none). table (dof * P, 5): rows (start
  time, p, v, a, j) of each joint's constant-jerk pieces, first the brake
  pieces of positive duration, then the 7 of the profile, each starting
  where the previous ends (times summed in that order), padded to P rows
  with rows of duration + 0.5; joint_shift (dof,): i * (duration + 1);
  starts: the rows' start times plus their joint's shift (sorted)."""
  dof = profiles.shape[0]
  count = 7
  for i in range(brakes.shape[0]):
    extra = 0
    for k in range(2):
      if brakes[i, 0, k] > 0.0:
        extra += 1
    count = max(count, 7 + extra)
  table = np.full((dof * count, 5), duration + 0.5)
  for i in range(dof):
    row = i * count
    time = 0.0
    if brakes.shape[0] > 0:
      for k in range(2):
        if brakes[i, 0, k] > 0.0:
          table[row, 0] = time
          for c in range(1, 5):
            table[row, c] = brakes[i, c, k]
          time += brakes[i, 0, k]
          row += 1
    for k in range(7):
      table[row, 0] = time
      table[row, 1] = profiles[i, _P + k]
      table[row, 2] = profiles[i, _V + k]
      table[row, 3] = profiles[i, _A + k]
      table[row, 4] = profiles[i, _J + k]
      time += profiles[i, k]
      row += 1
  joint_shift = np.empty(dof)
  span = duration + 1.0
  for i in range(dof):
    joint_shift[i] = float(i) * span
  starts = np.empty(dof * count)
  for r in range(dof * count):
    starts[r] = table[r, 0] + joint_shift[r // count]
  return table, starts, joint_shift


@_jit
def plan_state(plan, start, inverse, cycle, s, s_dot, s_ddot, jerk, out):
  """LongTermPlan.state into out (5, dof) (plan (N, 4, dof) samples, all
  needed ones computed): the Taylor step's 5 x 4 matrix of
  the chain rule (docs/shield_maths.md, 2; its NumPy reference:
  tests/safety/safety_references.py, `plan_state`) applied in a fixed
  order (shared by the Python and the compiled cycle, so both give the
  same bits)."""
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


_warm = False


def warm_up():
  """Compiles (or loads from the cache) the kernels for the argument types
  long_term_plan passes (its inputs writeable, the JointLimits' arrays
  read-only), once per process: the first new goal of a run then does not
  pay for it inside an RL step."""
  global _warm
  if _warm:
    return
  dof = 2
  state = np.zeros(dof)
  limit = np.ones(dof)
  limit.flags.writeable = False
  start_state_ok(state, state, state, limit, limit, limit, limit, limit, 0.0)
  plan_inputs_ok(state, state, state, state, limit, limit, limit, limit,
                 limit, 0.0, 0.0, np.empty(dof))
  clamped_goal(state, limit, limit, 0.0, np.empty(dof))
  table, starts, joint_shift = piece_table(
      np.zeros((dof, PROFILE_SIZE)), np.zeros((0, 5, 2)), 1.0)
  sample_pieces(table, starts, joint_shift, state, 1.0, 1.0, 0, 1,
                np.empty((1, 4, dof)))
  _warm = True

