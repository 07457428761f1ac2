"""Jerk-limited trajectories: limits, rest at waypoints, time-optimality."""

import numpy as np
import pytest

from hrc_suite import robot_description
from hrc_suite.control import trajectory

DT = 0.004


@pytest.fixture(scope='module')
def panda():
  return robot_description.load('panda')


def _waypoints(description, seed=0, count=4):
  rs = np.random.RandomState(seed)
  lim = description.limits
  return rs.uniform(lim.q_min + 0.1, lim.q_max - 0.1, (count, description.dof))


@pytest.mark.parametrize('limits', ['full', 'ltt'])
@pytest.mark.parametrize('name', robot_description.ROBOT_NAMES)
def test_respects_limits_and_integrates(name, limits):
  description = robot_description.load(name)
  waypoints = _waypoints(description)
  q, dq, ddq = trajectory.jerk_limited_trajectory(description, waypoints,
                                                  dt=DT, limits=limits)
  lim = description.limits
  a_max = lim.a_max if limits == 'full' else lim.a_max_ltt
  j_max = lim.j_max if limits == 'full' else lim.j_max_ltt
  assert q.shape == dq.shape == ddq.shape == (len(q), description.dof)
  assert np.all(np.abs(dq) <= lim.v_max * (1 + 1e-6))
  assert np.all(np.abs(ddq) <= a_max * (1 + 1e-6))
  # Jerk from finite differences (a sample may straddle a profile switch).
  assert np.all(np.abs(np.diff(ddq, axis=0)) / DT <= j_max * (1 + 1e-3))
  assert np.all(q >= lim.q_min - 1e-9) and np.all(q <= lim.q_max + 1e-9)
  # Velocities and accelerations are the derivatives of the samples.
  np.testing.assert_allclose(np.diff(q, axis=0),
                             (dq[1:] + dq[:-1]) / 2 * DT,
                             atol=a_max.max() * DT ** 2)
  # The full limits are actually used (the move is time-optimal).
  assert np.max(np.abs(dq)) > 0.99 * np.min(lim.v_max)


def test_starts_ends_and_rests_at_every_waypoint(panda):
  waypoints = _waypoints(panda, seed=1, count=3)
  legs = trajectory.plan_legs(panda, waypoints)
  q, dq, ddq = trajectory.jerk_limited_trajectory(panda, waypoints, dt=DT)
  np.testing.assert_allclose(q[0], waypoints[0], atol=1e-12)
  np.testing.assert_allclose(q[-1], waypoints[-1], atol=1e-9)
  assert np.abs(dq[[0, -1]]).max() < 1e-9 and np.abs(ddq[-1]).max() < 1e-9
  # At the middle waypoint the robot is at rest at the waypoint.
  k = int(round(legs[0].duration / DT))
  np.testing.assert_allclose(q[k], waypoints[1], atol=1e-3)
  assert np.abs(dq[k]).max() < 0.05
  assert len(q) == int(np.ceil(sum(l.duration for l in legs) / DT)) + 1


def test_single_joint_duration_is_time_optimal(panda):
  # A long single-joint move reaches v and a: T = d/v + v/a + a/j.
  start = np.clip(np.zeros(7), panda.limits.q_min, panda.limits.q_max)
  goal = start.copy()
  goal[0] = 2.5
  legs = trajectory.plan_legs(panda, [start, goal])
  v, a, j = (panda.limits.v_max[0], panda.limits.a_max[0],
             panda.limits.j_max[0])
  assert legs[0].duration == pytest.approx(2.5 / v + v / a + a / j, rel=1e-6)


def test_joints_are_synchronised(panda):
  waypoints = _waypoints(panda, seed=2, count=2)
  q, dq, _ = trajectory.jerk_limited_trajectory(panda, waypoints, dt=DT)
  moving = np.abs(dq) > 1e-6
  # Every joint that moves keeps moving until the common end.
  last = [np.nonzero(moving[:, i])[0].max() for i in range(7)]
  assert max(last) - min(last) <= 2


def test_ltt_is_slower_and_velocity_scale_slows(panda):
  waypoints = _waypoints(panda, seed=3, count=2)
  full = trajectory.jerk_limited_trajectory(panda, waypoints)[0]
  ltt = trajectory.jerk_limited_trajectory(panda, waypoints, limits='ltt')[0]
  half = trajectory.jerk_limited_trajectory(panda, waypoints,
                                            velocity_scale=0.5)
  assert len(ltt) > len(full) and len(half[0]) > len(full)
  assert np.abs(half[1]).max() <= 0.5 * panda.limits.v_max.max() + 1e-9


def test_single_waypoint_is_a_rest_sample(panda):
  q, dq, ddq = trajectory.jerk_limited_trajectory(panda, [panda.q_home])
  assert q.shape == (1, 7) and np.all(dq == 0) and np.all(ddq == 0)


@pytest.mark.parametrize('kwargs, message', [
    (dict(waypoints=np.zeros((2, 6))), 'shape'),
    (dict(waypoints=np.full((2, 7), 10.0)), 'outside'),
    (dict(waypoints=np.full((2, 7), np.nan)), 'finite'),
    (dict(limits='fast'), 'limit set'),
    (dict(velocity_scale=0.0), 'velocity_scale'),
    (dict(dt=0.0), 'dt'),
])
def test_bad_input_is_named(panda, kwargs, message):
  args = dict(waypoints=np.stack([panda.q_home, panda.q_home]))
  args.update(kwargs)
  with pytest.raises(ValueError, match=message):
    trajectory.jerk_limited_trajectory(panda, **args)
