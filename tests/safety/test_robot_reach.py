"""Tests for hrc_suite.safety.robot_reach (docs/shield_maths.md, 5, 7)."""

import dataclasses

import numpy as np
import pytest

from hrc_suite import robot_description
from hrc_suite.safety import geometry
from hrc_suite.safety import robot_reach

TOOL = ((0.0, 0.0, 0.11), (0.0, 0.0, 0.2), 0.05)


def _single_joint(description):
  """The first link of a robot as a one-joint robot."""
  limits = robot_description.JointLimits(**{
      f.name: getattr(description.limits, f.name)[:1]
      for f in dataclasses.fields(description.limits)})
  return dataclasses.replace(description, links=description.links[:1],
                             limits=limits, q_home=description.q_home[:1])


@pytest.mark.parametrize('name', robot_description.ROBOT_NAMES)
def test_capsules_follow_the_description_kinematics(name):
  description = robot_description.load(name)
  base = (0.1, -0.2, 0.8, 0.1, -0.2, 0.3)
  reach = robot_reach.RobotReach(description, base_pose=base,
                                 tool_capsule=TOOL)
  assert reach.num_capsules == description.dof + 1
  q = np.random.RandomState(0).uniform(description.limits.q_min,
                                       description.limits.q_max,
                                       (2, 3, description.dof))
  p1, p2, radius = reach.capsules(q)
  assert p1.shape == (2, 3, description.dof + 1, 3)
  frames = description.forward_kinematics(q, robot_reach.pose_matrix(base))
  local_p1, local_p2, local_r = description.capsule_arrays()
  expected = np.einsum('...lij,lj->...li', frames[..., :3, :3], local_p1) + (
      frames[..., :3, 3])
  np.testing.assert_allclose(p1[..., :-1, :], expected, atol=1e-12)
  tool_p2 = frames[..., -1, :3, :3] @ np.array(TOOL[1]) + frames[..., -1, :3, 3]
  np.testing.assert_allclose(p2[..., -1, :], tool_p2, atol=1e-12)
  np.testing.assert_allclose(radius, np.append(local_r, TOOL[2]))


def test_base_pose_convention_and_default():
  description = robot_description.load('panda')
  pose = robot_reach.pose_matrix((1, 2, 3, 0, 0, np.pi / 2))
  np.testing.assert_allclose(pose[:3, :3] @ [1, 0, 0], [0, 1, 0], atol=1e-12)
  np.testing.assert_allclose(pose[:3, 3], [1, 2, 3])
  reach = robot_reach.RobotReach(description)
  np.testing.assert_allclose(reach.base_pose[:3, 3], (0.0, 0.0, 0.82))
  with pytest.raises(ValueError, match='base_pose'):
    robot_reach.RobotReach(description, base_pose=(1, 2, 3))
  with pytest.raises(ValueError, match='tool_capsule'):
    robot_reach.RobotReach(description, tool_capsule=((0, 0), (0, 0, 1), 0.1))
  with pytest.raises(ValueError, match='q_edges'):
    reach.reach_capsules(np.zeros((3, 6)), np.zeros(3))


def test_single_joint_reach_radius_formula():
  description = _single_joint(robot_description.load('panda'))
  reach = robot_reach.RobotReach(description, base_pose=np.eye(4))
  r = description.links[0].capsule.radius
  alpha = description.shield.alpha_i_max
  secure = description.shield.secure_radius
  # At rest: the radius is r + alpha ds^2 / 8 + secure_radius.
  for ds in (0.02, 0.2, 1.0):
    c1, c2, radius = reach.reach_capsules([[0.3], [0.3]], [0.5, 0.5 + ds])
    assert radius.shape == (1, 1)
    assert radius[0, 0] == pytest.approx(r + alpha * ds ** 2 / 8 + secure)
    p1, p2, _ = reach.capsules(np.array([0.3]))
    np.testing.assert_allclose(c1[0, 0], p1[0])
    np.testing.assert_allclose(c2[0, 0], p2[0])
  # Rotating by theta: a point at distance rho from the axis moves along a
  # chord of half length rho sin(theta / 2).
  theta, ds = 0.4, 0.1
  c1, c2, radius = reach.reach_capsules([[0.0], [theta]], [0.0, ds])
  p1, p2, _ = description.capsule_arrays()
  rho = max(np.linalg.norm(p1[0, :2]), np.linalg.norm(p2[0, :2]))
  assert radius[0, 0] == pytest.approx(
      rho * np.sin(theta / 2) + alpha * ds ** 2 / 8 + r + secure)
  start, _, _ = reach.capsules(np.array([0.0]))
  end, _, _ = reach.capsules(np.array([theta]))
  np.testing.assert_allclose(c1[0, 0], 0.5 * (start[0] + end[0]))


def _curvature_bound(reach, q_a, velocity, ds, n=200):
  """max ||d^2 p / ds^2|| over the capsule end points along q_a + v s."""
  s = np.linspace(0.0, ds, n)
  p1, p2, _ = reach.capsules(q_a + s[:, None] * velocity)
  h = s[1] - s[0]
  second = [np.linalg.norm(p[2:] - 2 * p[1:-1] + p[:-2], axis=-1) / h ** 2
            for p in (p1, p2)]
  return np.maximum(second[0].max(axis=0), second[1].max(axis=0))


@pytest.mark.parametrize('name', robot_description.ROBOT_NAMES)
def test_reach_capsules_contain_the_link_throughout_each_interval(name):
  """Property: at every intermediate configuration of every interval the
  real link capsule lies inside the interval's reach capsule."""
  description = robot_description.load(name)
  rs = np.random.RandomState(5)
  for trial in range(4):
    probe = robot_reach.RobotReach(description, tool_capsule=TOOL)
    q_a = rs.uniform(description.limits.q_min, description.limits.q_max)
    velocity = rs.uniform(-1, 1, description.dof) * description.limits.v_max
    # Long intervals make the curvature term matter; alpha is a measured
    # bound (x1.2) and there is no secure radius to hide errors.
    ds = 0.3
    alpha = 1.2 * _curvature_bound(probe, q_a, velocity, 4 * ds) + 1e-6
    reach = robot_reach.RobotReach(description, tool_capsule=TOOL,
                                   secure_radius=0.0, alpha=alpha)
    s_edges = np.linspace(0.0, 4 * ds, 5)
    q_edges = q_a + s_edges[:, None] * velocity
    c1, c2, radius = reach.reach_capsules(q_edges, s_edges)
    for k in range(4):
      s = np.linspace(s_edges[k], s_edges[k + 1], 41)
      p1, p2, r = reach.capsules(q_a + s[:, None] * velocity)
      inside = geometry.capsule_contains_capsule(
          c1[k], c2[k], radius[k], p1, p2, r, tolerance=1e-9)
      assert inside.all(), (trial, k, np.argwhere(~inside))


def test_default_reach_covers_a_shield_interval():
  """With the default alpha and secure radius, a 20 ms slice at full joint
  speed contains the moving links."""
  description = robot_description.load('iiwa')
  reach = robot_reach.RobotReach(description, tool_capsule=TOOL)
  rs = np.random.RandomState(6)
  for _ in range(10):
    q_a = rs.uniform(description.limits.q_min, description.limits.q_max)
    velocity = description.limits.v_max * rs.choice([-1, 1], description.dof)
    s_edges = np.array([0.0, 0.02])
    c1, c2, radius = reach.reach_capsules(q_a + s_edges[:, None] * velocity,
                                          s_edges)
    s = np.linspace(0.0, 0.02, 21)
    p1, p2, r = reach.capsules(q_a + s[:, None] * velocity)
    assert geometry.capsule_contains_capsule(c1[0], c2[0], radius[0],
                                             p1, p2, r).all()
    # The enlargement is the secure radius plus at most half the largest
    # end-point travel (plus 0.25 mm of curvature term).
    travel = np.maximum(np.linalg.norm(p1[-1] - p1[0], axis=-1),
                        np.linalg.norm(p2[-1] - p2[0], axis=-1))
    np.testing.assert_allclose(radius[0] - reach.radii,
                               travel / 2 + 5.0 * 0.02 ** 2 / 8 + 0.02)


@pytest.mark.parametrize('name', ['panda', 'ur5e', 'sawyer'])
def test_surface_speeds_bound_every_surface_point(name):
  description = robot_description.load(name)
  reach = robot_reach.RobotReach(description, tool_capsule=TOOL)
  rs = np.random.RandomState(7)
  q = rs.uniform(description.limits.q_min, description.limits.q_max,
                 (6, description.dof))
  dq = rs.uniform(-1, 1, (6, description.dof))
  bound = reach.surface_speeds(q, dq)
  assert bound.shape == (6, reach.num_capsules)
  # Surface points: p1 + u (p2 - p1) + r n, n a unit vector fixed in the
  # link frame, moved with the link (finite differences).
  h = 1e-7
  frames = np.concatenate([reach.frames(q), reach.frames(q)[..., -1:, :, :]],
                          axis=-3)
  frames_h = reach.frames(q + h * dq)
  frames_h = np.concatenate([frames_h, frames_h[..., -1:, :, :]], axis=-3)
  p1, p2, r = reach.capsules(q)
  for _ in range(30):
    u = rs.uniform()
    n_local = rs.randn(reach.num_capsules, 3)
    n_local /= np.linalg.norm(n_local, axis=-1, keepdims=True)
    local = ((1 - u) * reach._points[:, 0, :3] + u * reach._points[:, 1, :3]
             + r[:, None] * n_local)
    world = np.einsum('nlij,lj->nli', frames[..., :3, :3], local) + (
        frames[..., :3, 3])
    world_h = np.einsum('nlij,lj->nli', frames_h[..., :3, :3], local) + (
        frames_h[..., :3, 3])
    speed = np.linalg.norm(world_h - world, axis=-1) / h
    assert np.all(speed <= bound + 1e-5)
  # Tight at the end points (without the radius term).
  p1_h, p2_h, _ = reach.capsules(q + h * dq)
  end_speed = np.maximum(np.linalg.norm(p1_h - p1, axis=-1),
                         np.linalg.norm(p2_h - p2, axis=-1)) / h
  assert np.all(bound >= end_speed - 1e-5)
  assert np.all(bound - end_speed <= r * np.sum(np.abs(dq), -1)[:, None]
                + 1e-5)
