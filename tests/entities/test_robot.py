"""Robot entity: compiles, MuJoCo frames equal the description's FK."""

import dataclasses

import mujoco
import numpy as np
import pytest
from dm_control import mjcf

from hrc_suite import robot_description
from hrc_suite.entities import gripper as gripper_lib
from hrc_suite.entities import robot as robot_lib


def _physics(robot):
  return mjcf.Physics.from_mjcf_model(robot.mjcf_model)


def test_registry_is_the_description_list():
  assert robot_lib.ROBOTS == robot_description.ROBOT_NAMES


@pytest.mark.parametrize('make', [robot_lib.make_robot, robot_lib.Robot])
def test_unknown_robot_names_the_valid_ones(make):
  with pytest.raises(ValueError, match='Unknown robot .*panda.*schunk'):
    make('optimus')


@pytest.mark.parametrize('name', robot_lib.ROBOTS)
def test_link_frames_and_capsules_match_description_fk(name):
  robot = robot_lib.make_robot(name)
  physics = _physics(robot)
  description = robot.description
  assert len(robot.joints) == len(robot.actuators) == description.dof
  assert len(robot.link_bodies) == len(robot.link_geoms) == description.dof
  p1, p2, radius = description.capsule_arrays()
  rs = np.random.RandomState(0)
  for _ in range(5):
    q = rs.uniform(description.limits.q_min, description.limits.q_max)
    robot.set_joint_positions(physics, q)
    physics.forward()
    np.testing.assert_allclose(robot.joint_positions(physics), q)
    frames = description.forward_kinematics(q)
    bodies = physics.bind(robot.link_bodies)
    np.testing.assert_allclose(bodies.xpos, frames[:, :3, 3], atol=1e-12)
    np.testing.assert_allclose(bodies.xmat.reshape(-1, 3, 3),
                               frames[:, :3, :3], atol=1e-12)
    flange = frames[-1] @ description.flange_transform()
    site = physics.bind(robot.flange_site)
    np.testing.assert_allclose(site.xpos, flange[:3, 3], atol=1e-12)
    np.testing.assert_allclose(site.xmat.reshape(3, 3), flange[:3, :3],
                               atol=1e-12)
    # Geom centre = capsule midpoint; sizes = radius (and half length).
    geoms = physics.bind(robot.link_geoms)
    middle = np.einsum('nij,nj->ni', frames[:, :3, :3], (p1 + p2) / 2)
    np.testing.assert_allclose(geoms.xpos, middle + frames[:, :3, 3],
                               atol=1e-12)
  np.testing.assert_allclose(geoms.size[:, 0], radius)
  half_length = np.linalg.norm(p2 - p1, axis=1) / 2
  is_capsule = half_length > 1e-9
  np.testing.assert_allclose(geoms.size[is_capsule, 1],
                             half_length[is_capsule], atol=1e-12)


@pytest.mark.parametrize('name', robot_lib.ROBOTS)
def test_limits_dynamics_and_actuators_come_from_description(name):
  robot = robot_lib.make_robot(name)
  physics = _physics(robot)
  description = robot.description
  joints = physics.bind(robot.joints)
  np.testing.assert_allclose(joints.range[:, 0], description.limits.q_min)
  np.testing.assert_allclose(joints.range[:, 1], description.limits.q_max)
  assert np.all(joints.armature > 0) and np.all(joints.damping > 0)
  actuators = physics.bind(robot.actuators)
  np.testing.assert_allclose(actuators.ctrlrange[:, 1],
                             description.limits.torque)
  np.testing.assert_allclose(actuators.ctrlrange[:, 0],
                             -description.limits.torque)
  bodies = physics.bind(robot.link_bodies)
  np.testing.assert_allclose(bodies.mass, [l.mass for l in description.links])
  np.testing.assert_allclose(bodies.ipos,
                             [l.center_of_mass for l in description.links])
  for link, body, inertia, quat in zip(description.links, robot.link_bodies,
                                       bodies.inertia, bodies.iquat):
    rot = np.empty(9)
    mujoco.mju_quat2Mat(rot, quat)
    rot = rot.reshape(3, 3)
    np.testing.assert_allclose(rot @ np.diag(inertia) @ rot.T, link.inertia,
                               atol=1e-9, err_msg=body.name)
  assert not robot.inertia_corrections


def test_a_torque_moves_the_joint_it_drives():
  robot = robot_lib.make_robot('ur5e')
  physics = _physics(robot)
  physics.model.opt.gravity[:] = 0
  physics.bind(robot.actuators[0]).ctrl = 10.0
  physics.step(250)
  q = robot.joint_positions(physics)
  assert q[0] > 0.1 and np.abs(q[1:]).max() < 0.5 * q[0]


def test_gripper_tcp_and_observables():
  robot = robot_lib.make_robot('panda')
  assert robot.tcp_site is robot.flange_site and robot.gripper is None
  gripper = robot.attach_gripper(gripper_lib.ParallelGripper())
  assert robot.gripper is gripper and robot.tcp_site is gripper.tcp_site
  with pytest.raises(ValueError, match='already has a gripper'):
    robot.attach_gripper(gripper_lib.ParallelGripper())
  physics = _physics(robot)
  q = np.array([0.1, 0.4, -0.3, -1.8, 0.2, 1.9, 0.6])
  robot.set_joint_positions(physics, q)
  physics.forward()
  flange = robot.description.forward_kinematics(q)[-1] @ (
      robot.description.flange_transform())
  tcp = flange[:3, 3] + flange[:3, 2] * gripper_lib.TCP_OFFSET
  observables = robot.observables
  np.testing.assert_allclose(
      observables.end_effector_position(physics), tcp, atol=1e-12)
  quat = observables.end_effector_quaternion(physics)
  rot = np.empty(9)
  mujoco.mju_quat2Mat(rot, quat)
  np.testing.assert_allclose(rot.reshape(3, 3), flange[:3, :3], atol=1e-9)
  np.testing.assert_allclose(observables.joint_positions(physics), q)
  np.testing.assert_allclose(observables.joint_velocities(physics),
                             np.zeros(7))


def test_bad_joint_vector_is_named():
  robot = robot_lib.make_robot('ur5e')
  physics = _physics(robot)
  with pytest.raises(ValueError, match=r'ur5e must have shape \(6,\)'):
    robot.set_joint_positions(physics, np.zeros(7))


def test_an_inertia_mujoco_would_reject_is_balanced_visibly():
  description = robot_description.load('ur5e')
  bad = np.diag([0.001, 0.001, 0.01])   # 0.001 + 0.001 < 0.01.
  links = list(description.links)
  links[2] = dataclasses.replace(links[2], inertia=bad)
  robot = robot_lib.Robot(dataclasses.replace(description, links=tuple(links)))
  assert set(robot.inertia_corrections) == {2}
  before, after = robot.inertia_corrections[2]
  np.testing.assert_allclose(before, [0.001, 0.001, 0.01])
  assert after[0] + after[1] >= after[2] and after[2] == 0.01
  physics = _physics(robot)   # Compiles.
  assert sorted(physics.bind(robot.link_bodies[2]).inertia)[-1] == (
      pytest.approx(0.01))
