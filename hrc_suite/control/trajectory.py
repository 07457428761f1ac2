"""Time-optimal, jerk-limited joint trajectories through rest waypoints.

Each leg between consecutive waypoints is a rest-to-rest move computed by
Ruckig (Berscheid and Kroeger, "Jerk-limited Real-time Trajectory Generation
with Arbitrary Target States", RSS 2021): time-optimal under per-joint
velocity, acceleration and jerk limits, with all joints synchronised to
finish together. Rest-to-rest legs are monotone per joint, so a leg between
waypoints inside the joint limits stays inside them.
"""

import numpy as np
import ruckig

from hrc_suite import robot_description

LIMIT_SETS = ('full', 'ltt')


def _limits(description, limits, velocity_scale):
  if limits not in LIMIT_SETS:
    raise ValueError(f'Unknown limit set {limits!r}: expected one of '
                     f'{", ".join(map(repr, LIMIT_SETS))}')
  if not 0.0 < velocity_scale <= 1.0:
    raise ValueError(f'velocity_scale must be in (0, 1], got {velocity_scale}')
  joint_limits = description.limits
  velocity = joint_limits.v_max * velocity_scale
  if limits == 'full':
    return velocity, joint_limits.a_max, joint_limits.j_max
  return velocity, joint_limits.a_max_ltt, joint_limits.j_max_ltt


def _check_waypoints(description, waypoints):
  waypoints = np.asarray(waypoints, dtype=float)
  dof = description.dof
  if waypoints.ndim != 2 or waypoints.shape[1] != dof or len(waypoints) < 1:
    raise ValueError(f'waypoints for {description.name} must have shape '
                     f'(N >= 1, {dof}), got {waypoints.shape}')
  if not np.all(np.isfinite(waypoints)):
    raise ValueError('waypoints must be finite')
  q_min, q_max = description.limits.q_min, description.limits.q_max
  outside = np.nonzero((waypoints < q_min) | (waypoints > q_max))
  if outside[0].size:
    k, j = outside[0][0], outside[1][0]
    raise ValueError(f'waypoint {k} joint {j} = {waypoints[k, j]:.4f} rad is '
                     f'outside [{q_min[j]:.4f}, {q_max[j]:.4f}] of '
                     f'{description.name}')
  return waypoints


def plan_legs(description: robot_description.RobotDescription, waypoints,
              limits: str = 'full', velocity_scale: float = 1.0):
  """Ruckig trajectories for each leg between consecutive waypoints."""
  waypoints = _check_waypoints(description, waypoints)
  velocity, acceleration, jerk = _limits(description, limits, velocity_scale)
  dof = description.dof
  generator = ruckig.Ruckig(dof)
  legs = []
  for start, goal in zip(waypoints[:-1], waypoints[1:]):
    params = ruckig.InputParameter(dof)
    params.current_position = start
    params.current_velocity = np.zeros(dof)
    params.current_acceleration = np.zeros(dof)
    params.target_position = goal
    params.target_velocity = np.zeros(dof)
    params.target_acceleration = np.zeros(dof)
    params.max_velocity = velocity
    params.max_acceleration = acceleration
    params.max_jerk = jerk
    leg = ruckig.Trajectory(dof)
    result = generator.calculate(params, leg)
    if result not in (ruckig.Result.Working, ruckig.Result.Finished):
      raise RuntimeError(f'Ruckig failed ({result}) from {start} to {goal}')
    legs.append(leg)
  return legs


def jerk_limited_trajectory(description: robot_description.RobotDescription,
                            waypoints, dt: float = 0.004,
                            limits: str = 'full',
                            velocity_scale: float = 1.0):
  """Samples (q, dq, ddq), each (T, dof), every dt through the waypoints.

  The robot rests at every waypoint; the first sample is the first waypoint
  at t = 0 and the last the final waypoint (T = ceil(duration / dt) + 1).
  `limits` picks the description's full limits (v_max, a_max, j_max) or the
  long-term-planning ones ('ltt': v_max, a_max_ltt, j_max_ltt); velocities
  are scaled by `velocity_scale`.
  """
  if not dt > 0:
    raise ValueError(f'dt must be positive, got {dt}')
  waypoints = _check_waypoints(description, waypoints)
  dof = description.dof
  legs = plan_legs(description, waypoints, limits, velocity_scale)
  durations = np.array([leg.duration for leg in legs])
  ends = np.cumsum(durations)
  total = float(ends[-1]) if legs else 0.0
  count = int(np.ceil(total / dt - 1e-9)) + 1
  q = np.empty((count, dof))
  dq = np.zeros((count, dof))
  ddq = np.zeros((count, dof))
  times = np.minimum(np.arange(count) * dt, total)
  leg_of_sample = np.minimum(np.searchsorted(ends, times, side='right'),
                             len(legs) - 1) if legs else None
  for k, t in enumerate(times):
    if not legs:
      q[k] = waypoints[0]
      continue
    index = leg_of_sample[k]
    start = ends[index] - durations[index]
    position, velocity, acceleration = legs[index].at_time(t - start)
    q[k], dq[k], ddq[k] = position, velocity, acceleration
  return q, dq, ddq
