"""Readable NumPy references of shield kernels that the package runs
compiled only (docs/architecture.md, "Kernels and their references"):
the tests compare the kernels with these."""

import numpy as np

from hrc_suite.safety import geometry
from hrc_suite.safety.shield import shield as shield_lib


def tracking_error(shield, q, reference=None):
  """Shield.tracking_error by NumPy (robot capsules by RobotReach.capsules):
  the largest displacement of a capsule axis end between q and reference
  (None: the command)."""
  reference = shield.q if reference is None else reference
  q = np.asarray(q, dtype=float)
  reference = np.asarray(reference, dtype=float)
  p1, p2, _ = shield.robot.capsules(np.stack([q, reference]))
  moved = np.concatenate([p1[0] - p1[1], p2[0] - p2[1]])
  return float(np.sqrt(np.einsum('ni,ni->n', moved, moved).max()))


def min_distance(shield):
  """Shield.min_distance by NumPy (geometry.capsule_distance over all
  pairs of the robot's capsules at the command and the human's body
  capsules at the last measurement)."""
  if shield.human.positions is None:
    return np.inf
  r1, r2, rr = shield.robot.capsules(shield.q)
  h1, h2, hr = shield.human.body_capsules(shield.human.positions)
  return float(geometry.capsule_distance(
      r1[:, None], r2[:, None], rr[:, None], h1[None], h2[None],
      hr[None]).min())


def horizon_balls(shield, now, horizon):
  """The first broad phase's balls by NumPy (path_check.PathCheck runs
  kernels.horizon_balls): one ball per human body containing its
  maximal-velocity (VEL) reachable set over the whole horizon (s after
  the cycle's time `now`): the measured body capsule grown by max(v_max,
  measured speed) of its faster end times the measurement's age plus
  horizon and delay, plus the position error. Returns centres (B, 3) and
  radii (B,)."""
  human, config = shield.human, shield.human.config
  p1, p2, radius = human.body_capsules(human.positions)
  speeds = np.sqrt(np.einsum('ni,ni->n', human.velocities,
                             human.velocities))
  np.maximum(speeds, config.v_max, out=speeds)
  ends = speeds[shield.terms.body_ends]
  age = now - human.last_measurement_time + config.delay + horizon
  half = p2 - p1
  grow = (np.maximum(ends[0], ends[1]) * age + radius
          + config.measurement_error_pos)
  grow += 0.5 * np.sqrt(np.einsum('bi,bi->b', half, half))
  return 0.5 * (p1 + p2), grow


def balls_capsules_distance(centre, radius, capsules):
  """kernels.balls_capsules_distance by NumPy: a lower bound of the
  distance between balls (B,) and capsules (K, L), each capsule bounded by
  the ball around its midpoint; centre distances from one matrix product
  (|a|^2 + |b|^2 - 2 a.b), the broad phase's slack subtracted."""
  c1, c2, r = capsules
  middle = (0.5 * (c1 + c2)).reshape(-1, 3)
  half = (c2 - c1).reshape(-1, 3)
  reach = 0.5 * np.sqrt(np.einsum('ni,ni->n', half, half)) + r.reshape(-1)
  squared = (np.einsum('ni,ni->n', middle, middle)[:, None]
             + np.einsum('bi,bi->b', centre, centre)
             - 2.0 * (middle @ centre.T))
  np.maximum(squared, 0.0, out=squared)
  return float((np.sqrt(squared) - reach[:, None] - radius).min()
               - shield_lib._BROAD_PHASE_SLACK)


def _sample_index(plan, s, samples):
  k = int((s - plan.start_time) * (1.0 / plan.cycle_time) // 1.0)
  last = samples.shape[0] - 1
  return 0 if k < 0 else (last if k > last else k)


def plan_positions(plan, s):
  """LongTermPlan.positions by NumPy (index arithmetic in Python floats):
  q at path positions s (K,) -> (K, dof)."""
  samples = plan.samples()
  indices, weights = [], []
  for x in np.asarray(s, dtype=float).tolist():
    k = _sample_index(plan, x, samples)
    t = x - plan.start_time - k * plan.cycle_time
    t2 = 0.5 * t * t
    indices.append(k)
    weights.append((1.0, t, t2, t2 * t / 3.0))
  return np.einsum('kc,kcd->kd', np.array(weights), samples[indices])


def plan_state(plan, s, s_dot=1.0, s_ddot=0.0, jerk=0.0):
  """LongTermPlan.state by NumPy: (5, dof) q, dq, ddq, dddq, v_nominal.

  The chain rule of docs/shield_maths.md, 2 with the Taylor expansion
  folded into one 5x4 matrix: dq = v s_dot, ddq = v s_ddot + a s_dot^2,
  dddq = j s_dot^3 + 3 a s_ddot s_dot + v jerk; v_nominal = v.
  """
  samples = plan.samples()
  k = _sample_index(plan, s, samples)
  t = s - plan.start_time - k * plan.cycle_time
  t2 = 0.5 * t * t
  t3 = t2 * t / 3.0
  v2 = s_dot * s_dot
  sa = 3.0 * s_ddot * s_dot
  # Rows: [q, v, a, j] of the Taylor expansion, combined by the chain rule.
  matrix = np.array((
      (1.0, t, t2, t3),
      (0.0, s_dot, s_dot * t, s_dot * t2),
      (0.0, s_ddot, s_ddot * t + v2, s_ddot * t2 + v2 * t),
      (0.0, jerk, jerk * t + sa, jerk * t2 + sa * t + v2 * s_dot),
      (0.0, 1.0, t, t2)))
  return matrix @ samples[k]


def sample_pieces(table, starts, joint_shift, goal, cycle_time, duration,
                  first, stop):
  """plan_kernels.sample_pieces by NumPy (same arguments): samples
  first..stop - 1 (n, 4, dof) of a plan's piecewise constant-jerk
  motion, the goal at rest from the motion's end on."""
  times = np.arange(first, stop) * cycle_time
  index = np.searchsorted(starts, times[:, None] + joint_shift,
                          side='right') - 1
  rows = table[index]                                      # (n, dof, 5)
  d = times[:, None] - rows[..., 0]
  p, v, a, j = rows[..., 1], rows[..., 2], rows[..., 3], rows[..., 4]
  samples = np.empty((len(times), 4, len(joint_shift)))
  samples[:, 0] = p + d * (v + d * (0.5 * a + d * j / 6.0))
  samples[:, 1] = v + d * (a + 0.5 * d * j)
  samples[:, 2] = a + d * j
  samples[:, 3] = j
  end = times >= duration
  samples[end, 0] = goal
  samples[end, 1:] = 0.0
  return samples
