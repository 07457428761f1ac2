"""Tests for the pinocchio kinematic model and the robots' home poses."""

from dm_control import mjcf
import numpy as np
import pinocchio as pin
import pytest

from hrc_suite import layout
from hrc_suite import robot_description
from hrc_suite.control import kinematics
from hrc_suite.entities import gripper as gripper_lib
from hrc_suite.entities import robot as robot_lib

ROBOTS = robot_description.ROBOT_NAMES
NUM_CONFIGURATIONS = 100
POSITION_TOLERANCE = 1e-6  # m (issue 2, item 6).


def _random_configurations(description, seed=0, n=NUM_CONFIGURATIONS):
  random_state = np.random.RandomState(seed)
  return random_state.uniform(description.limits.q_min,
                              description.limits.q_max,
                              size=(n, description.dof))


ROTATION_TOLERANCE = 1e-6


def _base_pose():
  pose = np.eye(4)
  angle = 0.3
  pose[:3, :3] = [[np.cos(angle), -np.sin(angle), 0],
                  [np.sin(angle), np.cos(angle), 0], [0, 0, 1]]
  pose[:3, 3] = (0.1, -0.2, 0.82)
  return pose


@pytest.mark.parametrize('name', ROBOTS)
def test_link_frames_match_description_fk(name):
  description = robot_description.load(name)
  base = _base_pose()
  model = kinematics.KinematicModel(description, base_pose=base)
  tolerance = ROTATION_TOLERANCE
  for q in _random_configurations(description):
    ours = model.link_frames(q)
    expected = description.forward_kinematics(q, base=base)
    np.testing.assert_allclose(ours[:, :3, 3], expected[:, :3, 3],
                               atol=POSITION_TOLERANCE)
    np.testing.assert_allclose(ours[:, :3, :3], expected[:, :3, :3],
                               atol=tolerance)


def _mujoco_physics(description):
  robot = robot_lib.Robot(description)
  physics = mjcf.Physics.from_mjcf_model(robot.mjcf_model)
  return robot, physics


@pytest.mark.parametrize('name', ROBOTS)
def test_link_frames_match_mujoco(name):
  description = robot_description.load(name)
  robot, physics = _mujoco_physics(description)
  model = kinematics.KinematicModel(description)
  bodies = physics.bind(robot.link_bodies)
  joints = physics.bind(robot.joints)
  flange = physics.bind(robot.flange_site)
  for q in _random_configurations(description, seed=1):
    joints.qpos = q
    physics.forward()
    frames = model.link_frames(q)
    np.testing.assert_allclose(frames[:, :3, 3], bodies.xpos,
                               atol=POSITION_TOLERANCE)
    np.testing.assert_allclose(frames[:, :3, :3].reshape(-1, 9), bodies.xmat,
                               atol=ROTATION_TOLERANCE)
    np.testing.assert_allclose(model.flange_pose(q)[:3, 3], flange.xpos,
                               atol=POSITION_TOLERANCE)


@pytest.mark.parametrize('name', ROBOTS)
def test_tcp_matches_mujoco_gripper_tcp_site(name):
  description = robot_description.load(name)
  robot = robot_lib.Robot(description)
  gripper = gripper_lib.ParallelGripper()
  robot.attach_gripper(gripper)
  physics = mjcf.Physics.from_mjcf_model(robot.mjcf_model)
  model = kinematics.KinematicModel(
      description, tcp_offset=gripper_lib.ParallelGripper.TCP_OFFSET)
  joints = physics.bind(robot.joints)
  tcp = physics.bind(robot.tcp_site)
  for q in _random_configurations(description, seed=3, n=10):
    joints.qpos = q
    physics.forward()
    pose = model.tcp_pose(q)
    np.testing.assert_allclose(pose[:3, 3], tcp.xpos,
                               atol=POSITION_TOLERANCE)
    np.testing.assert_allclose(pose[:3, :3].reshape(9), tcp.xmat,
                               atol=ROTATION_TOLERANCE)


@pytest.mark.parametrize('name', ROBOTS)
def test_tcp_is_offset_along_flange_z(name):
  description = robot_description.load(name)
  model = kinematics.KinematicModel(description, tcp_offset=0.12)
  for q in _random_configurations(description, n=5):
    flange, tcp = model.flange_pose(q), model.tcp_pose(q)
    np.testing.assert_allclose(tcp[:3, :3], flange[:3, :3], atol=1e-12)
    np.testing.assert_allclose(tcp[:3, 3], flange[:3, 3] + 0.12 * flange[:3, 2],
                               atol=1e-12)
    # The flange is the description's flange transform after the last link.
    last = description.forward_kinematics(q)[-1]
    np.testing.assert_allclose(
        flange[:3, 3],
        last[:3, 3] + last[:3, :3] @ description.flange_translation,
        atol=1e-5)


@pytest.mark.parametrize('name', ROBOTS)
def test_tcp_jacobian_matches_finite_differences(name):
  description = robot_description.load(name)
  model = kinematics.KinematicModel(description, base_pose=_base_pose())
  step = 1e-6
  for q in _random_configurations(description, seed=2, n=5):
    jacobian = model.tcp_jacobian(q)
    pose = model.tcp_pose(q)
    numeric = np.empty((6, description.dof))
    for i in range(description.dof):
      shifted = q.copy()
      shifted[i] += step
      moved = model.tcp_pose(shifted)
      numeric[:3, i] = (moved[:3, 3] - pose[:3, 3]) / step
      numeric[3:, i] = pin.log3(moved[:3, :3] @ pose[:3, :3].T) / step
    np.testing.assert_allclose(jacobian, numeric, atol=1e-5)
    pose_again, jacobian_again = model.tcp_pose_and_jacobian(q)
    np.testing.assert_allclose(pose_again, pose, atol=1e-12)
    np.testing.assert_allclose(jacobian_again, jacobian, atol=1e-12)


@pytest.mark.parametrize('name', ROBOTS)
def test_pinocchio_model_carries_limits_and_inertias(name):
  description = robot_description.load(name)
  model = kinematics.KinematicModel(description)
  pin_model = model.pin_model
  assert pin_model.nq == description.dof
  np.testing.assert_array_equal(pin_model.lowerPositionLimit,
                                description.limits.q_min)
  np.testing.assert_array_equal(pin_model.upperPositionLimit,
                                description.limits.q_max)
  for i, link in enumerate(description.links):
    inertia = pin_model.inertias[i + 1]
    assert inertia.mass == pytest.approx(link.mass)
    np.testing.assert_allclose(inertia.lever, link.center_of_mass)
    np.testing.assert_allclose(inertia.inertia, link.inertia, atol=1e-12)
  # Gravity torque at the home pose equals -d(potential)/dq, by differences.
  q = description.q_home
  gravity = pin.computeGeneralizedGravity(pin_model, model.pin_data, q)
  def potential(q):
    pin.computePotentialEnergy(pin_model, model.pin_data, q)
    return model.pin_data.potential_energy
  step = 1e-6
  numeric = np.array([(potential(q + step * e) - potential(q - step * e)) /
                      (2 * step) for e in np.eye(description.dof)])
  np.testing.assert_allclose(gravity, numeric, atol=1e-5)


def test_link_capsules_are_in_world_frame():
  description = robot_description.load('panda')
  base = _base_pose()
  model = kinematics.KinematicModel(description, base_pose=base)
  q = description.q_home
  p1, p2, radius = model.link_capsules(q)
  frames = description.forward_kinematics(q, base=base)
  local_p1, local_p2, local_radius = description.capsule_arrays()
  for i in range(description.dof):
    np.testing.assert_allclose(
        p1[i], frames[i, :3, :3] @ local_p1[i] + frames[i, :3, 3], atol=1e-9)
    np.testing.assert_allclose(
        p2[i], frames[i, :3, :3] @ local_p2[i] + frames[i, :3, 3], atol=1e-9)
  np.testing.assert_array_equal(radius, local_radius)


def test_bad_input_raises_clear_errors():
  description = robot_description.load('ur5e')
  with pytest.raises(ValueError, match=r'shape \(6,\)'):
    kinematics.KinematicModel(description).tcp_pose(np.zeros(7))
  with pytest.raises(ValueError, match='finite'):
    kinematics.KinematicModel(description).link_frames(np.full(6, np.nan))
  with pytest.raises(ValueError, match='base_pose'):
    kinematics.KinematicModel(description, base_pose=np.eye(3))
  with pytest.raises(ValueError, match='base_pose rotation'):
    kinematics.KinematicModel(description, base_pose=np.diag([1, 1, -1, 1.0]))
  with pytest.raises(ValueError, match='tcp_offset'):
    kinematics.KinematicModel(description, tcp_offset=-0.1)
  with pytest.raises(TypeError, match='RobotDescription'):
    kinematics.KinematicModel('ur5e')


# --- Home poses (q_home in the description files). ---

# Where the home TCP should be, relative to the default mount's base, m
# (issue 2; the same world point for every robot, whatever its mount, see
# scripts/compute_home_poses.py).
HOME_TCP = {name: (0.45, 0.0, 0.25) for name in ROBOTS}
# Link indices of shoulder, elbow and wrist (as in compute_home_poses.py).
ARM_POINTS = {
    'panda': (1, 3, 5), 'sawyer': (1, 3, 5), 'iiwa': (1, 3, 5),
    'jaco': (1, 3, 5), 'kinova3': (1, 3, 5), 'ur5e': (1, 2, 3),
    'schunk': (1, 2, 4),
}
HOME_LIMIT_MARGIN = 0.2    # rad from every joint limit.
HOME_CLEARANCE = 0.02      # m, capsules above the table top / off the pedestal.


def _world_model(description):
  return kinematics.KinematicModel(
      description, base_pose=layout.robot_mount(description.name).base_pose())


def _capsule_points(model, q, samples=51):
  p1, p2, radius = model.link_capsules(q)
  t = np.linspace(0, 1, samples)[None, :, None]
  points = p1[:, None] + t * (p2 - p1)[:, None]
  return points, np.broadcast_to(radius[:, None], points.shape[:2])


@pytest.mark.parametrize('name', ROBOTS)
def test_home_pose_is_a_gripper_down_ready_pose(name):
  description = robot_description.load(name)
  model = _world_model(description)
  q = description.q_home
  assert np.all(q >= description.limits.q_min + HOME_LIMIT_MARGIN)
  assert np.all(q <= description.limits.q_max - HOME_LIMIT_MARGIN)
  tcp = model.tcp_pose(q)
  np.testing.assert_allclose(tcp[:3, 3] - layout.ROBOT_BASE_POS,
                             HOME_TCP[name], atol=1e-4)
  np.testing.assert_allclose(tcp[:3, 2], (0, 0, -1), atol=1e-4)
  assert abs(tcp[1, 0]) < 1e-3   # TCP x axis along world +-x.
  # Elbow up: above the straight line from shoulder to wrist.
  frames = model.link_frames(q)
  shoulder, elbow, wrist = (frames[i, :3, 3] for i in ARM_POINTS[name])
  t = np.dot(elbow - shoulder, wrist - shoulder) / np.sum(
      (wrist - shoulder) ** 2)
  assert elbow[2] > shoulder[2] + t * (wrist[2] - shoulder[2]) + 0.05
  # Away from singularities: the TCP Jacobian has full rank with margin.
  jacobian = model.tcp_jacobian(q).copy()
  jacobian[3:] *= 0.2  # m per rad
  assert np.linalg.svd(jacobian, compute_uv=False)[-1] > 0.02


@pytest.mark.parametrize('name', ROBOTS)
def test_home_pose_links_clear_table_and_pedestal(name):
  description = robot_description.load(name)
  model = _world_model(description)
  points, radius = _capsule_points(model, description.q_home)
  x, y, z = points[..., 0], points[..., 1], points[..., 2]
  over_table = x + radius > layout.TABLE_X[0]
  assert np.all((z - radius)[over_table] > layout.TABLE_TOP_Z + HOME_CLEARANCE)
  mount = layout.robot_mount(name)
  cx, cy = mount.pedestal_center_xy
  hx, hy = mount.pedestal_half_size
  beside = np.hypot(np.maximum(np.abs(x - cx) - hx, 0),
                    np.maximum(np.abs(y - cy) - hy, 0)) - radius
  above = z - radius - mount.base_position[2]
  assert np.all(np.maximum(beside, above) > HOME_CLEARANCE)
  # The TCP itself (gripper fingertips) is above the table, too.
  assert model.tcp_pose(description.q_home)[2, 3] > layout.TABLE_TOP_Z + 0.1
