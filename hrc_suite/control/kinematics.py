"""Pinocchio model of a robot, built from its description.

The model follows the description's conventions exactly (see
`hrc_suite.robot_description`): joint i is a revolute joint about z placed at
the fixed transform A_i in the frame of joint i-1 (the first one at
base_pose · A_1 in the world). Every link has a frame named after it at its
joint (the frame after the joint's rotation, where the description's capsules,
centres of mass and inertias live), plus a 'flange' frame at the description's
flange transform and a 'tcp' frame `tcp_offset` further along the flange's z.
"""

from typing import Optional

import numpy as np
import pinocchio as pin

from hrc_suite import robot_description
from hrc_suite import rotations

# Tool centre point of hrc_suite's parallel gripper along the flange z axis,
# metres; must match `hrc_suite.entities.gripper.ParallelGripper.TCP_OFFSET`.
DEFAULT_TCP_OFFSET = 0.12

FLANGE_FRAME = 'flange'
TCP_FRAME = 'tcp'


def _se3(rotation, translation) -> pin.SE3:
  # Description rotations are printed with four digits for some robots
  # (Sawyer's last joint), off SO(3) by ~3e-5; pinocchio needs proper ones.
  return pin.SE3(rotations.nearest_rotation(rotation),
                 np.asarray(translation, float))


def _check_pose(value, name):
  pose = np.asarray(value, dtype=float)
  if pose.shape != (4, 4) or not np.allclose(pose[3], [0, 0, 0, 1]):
    raise ValueError(f'{name} must be a 4x4 homogeneous transform, got '
                     f'{np.asarray(value).tolist()!r}')
  rotation = pose[:3, :3]
  if not np.allclose(rotation @ rotation.T, np.eye(3), atol=1e-6) or (
      np.linalg.det(rotation) < 0):
    raise ValueError(f'{name} rotation must be orthonormal with det +1, got '
                     f'{rotation.tolist()}')
  return pose


class KinematicModel:
  """Pinocchio model + data of one robot, with link, flange and TCP frames."""

  def __init__(self, description: robot_description.RobotDescription,
               base_pose: Optional[np.ndarray] = None,
               tcp_offset: float = DEFAULT_TCP_OFFSET):
    if not isinstance(description, robot_description.RobotDescription):
      raise TypeError('description must be a RobotDescription (see '
                      f'robot_description.load), got {type(description)!r}')
    if not np.isfinite(tcp_offset) or tcp_offset < 0:
      raise ValueError(f'tcp_offset must be a finite distance >= 0 m, got '
                       f'{tcp_offset!r}')
    self._description = description
    self._base_pose = (np.eye(4) if base_pose is None
                       else _check_pose(base_pose, 'base_pose'))
    self._tcp_offset = float(tcp_offset)
    self._pin_model = self._build_model()
    self._pin_data = self._pin_model.createData()
    self._link_frame_ids = [self._pin_model.getFrameId(link.name)
                            for link in description.links]
    self._flange_id = self._pin_model.getFrameId(FLANGE_FRAME)
    self._tcp_id = self._pin_model.getFrameId(TCP_FRAME)
    self._link_poses = np.tile(np.eye(4), (description.dof, 1, 1))
    self._q_min = description.limits.q_min.copy()
    self._q_max = description.limits.q_max.copy()
    self._q_min.flags.writeable = False
    self._q_max.flags.writeable = False

  def _build_model(self) -> pin.Model:
    description = self._description
    limits = description.limits
    model = pin.Model()
    model.name = description.name
    parent, parent_frame = 0, 0
    base = pin.SE3(self._base_pose[:3, :3].copy(),
                   self._base_pose[:3, 3].copy())
    for i, link in enumerate(description.links):
      placement = _se3(link.fixed_rotation, link.fixed_translation)
      if i == 0:
        placement = base * placement
      parent = model.addJoint(
          parent, pin.JointModelRZ(), placement, f'joint{i + 1}',
          limits.torque[i:i + 1], limits.v_max[i:i + 1],
          limits.q_min[i:i + 1], limits.q_max[i:i + 1])
      model.appendBodyToJoint(
          parent, pin.Inertia(link.mass, link.center_of_mass, link.inertia),
          pin.SE3.Identity())
      joint_frame = model.addJointFrame(parent, parent_frame)
      parent_frame = model.addBodyFrame(link.name, parent, pin.SE3.Identity(),
                                        joint_frame)
    flange = _se3(description.flange_rotation, description.flange_translation)
    flange_id = model.addFrame(pin.Frame(FLANGE_FRAME, parent, parent_frame,
                                         flange, pin.FrameType.OP_FRAME))
    tcp = flange * pin.SE3(np.eye(3), np.array([0.0, 0.0, self._tcp_offset]))
    model.addFrame(pin.Frame(TCP_FRAME, parent, flange_id, tcp,
                             pin.FrameType.OP_FRAME))
    return model

  @property
  def description(self) -> robot_description.RobotDescription:
    return self._description

  @property
  def dof(self) -> int:
    return self._description.dof

  @property
  def base_pose(self) -> np.ndarray:
    return self._base_pose.copy()

  @property
  def tcp_offset(self) -> float:
    return self._tcp_offset

  @property
  def q_min(self) -> np.ndarray:
    return self._q_min

  @property
  def q_max(self) -> np.ndarray:
    return self._q_max

  @property
  def pin_model(self) -> pin.Model:
    return self._pin_model

  @property
  def pin_data(self) -> pin.Data:
    return self._pin_data

  @property
  def tcp_frame_id(self) -> int:
    return self._tcp_id

  @property
  def flange_frame_id(self) -> int:
    return self._flange_id

  def check_q(self, q) -> np.ndarray:
    """q as a float array of shape (dof,), or a clear error."""
    q = np.asarray(q, dtype=float)
    if q.shape != (self.dof,):
      raise ValueError(f'{self._description.name}: expected a joint vector of '
                       f'shape ({self.dof},), got shape {q.shape}')
    if not np.isfinite(q).all():
      raise ValueError(f'{self._description.name}: joint vector must be '
                       f'finite, got {q.tolist()}')
    return q

  def within_limits(self, q, tolerance: float = 0.0) -> bool:
    q = self.check_q(q)
    return bool(np.all(q >= self._q_min - tolerance) and
                np.all(q <= self._q_max + tolerance))

  def forward(self, q) -> None:
    """Joint and frame placements for q into `pin_data`."""
    q = self.check_q(q)
    pin.framesForwardKinematics(self._pin_model, self._pin_data, q)

  def link_frames(self, q) -> np.ndarray:
    """(dof, 4, 4) world poses of the link frames (after joint rotation)."""
    q = self.check_q(q)
    pin.forwardKinematics(self._pin_model, self._pin_data, q)
    out = self._link_poses.copy()
    for i, placement in enumerate(self._pin_data.oMi[1:]):
      out[i, :3, :3] = placement.rotation
      out[i, :3, 3] = placement.translation
    return out

  def link_capsules(self, q):
    """World capsule end points (dof, 3) x 2 and radii (dof,) at q."""
    frames = self.link_frames(q)
    p1, p2, radius = self._description.capsule_arrays()
    turns, origins = frames[:, :3, :3], frames[:, :3, 3]
    world_p1 = np.einsum('nij,nj->ni', turns, p1) + origins
    world_p2 = np.einsum('nij,nj->ni', turns, p2) + origins
    return world_p1, world_p2, radius

  def frame_pose(self, q, frame_id: int) -> np.ndarray:
    """(4, 4) world pose of a pinocchio frame at q."""
    q = self.check_q(q)
    pin.forwardKinematics(self._pin_model, self._pin_data, q)
    return pin.updateFramePlacement(self._pin_model, self._pin_data,
                                    frame_id).homogeneous

  def flange_pose(self, q) -> np.ndarray:
    return self.frame_pose(q, self._flange_id)

  def tcp_pose(self, q) -> np.ndarray:
    """(4, 4) world pose of the tool centre point."""
    return self.frame_pose(q, self._tcp_id)

  def tcp_jacobian(self, q) -> np.ndarray:
    """(6, dof) TCP Jacobian: linear then angular velocity, world axes."""
    q = self.check_q(q)
    return pin.computeFrameJacobian(
        self._pin_model, self._pin_data, q, self._tcp_id,
        pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)

  def tcp_pose_and_jacobian(self, q):
    """TCP pose (4, 4) and Jacobian (6, dof) with one kinematics pass."""
    q = self.check_q(q)
    model, data = self._pin_model, self._pin_data
    pin.computeJointJacobians(model, data, q)
    pose = pin.updateFramePlacement(model, data, self._tcp_id)
    jacobian = pin.getFrameJacobian(model, data, self._tcp_id,
                                    pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
    return pose.homogeneous, jacobian
