"""A robot arm generated from its description: one class for all seven robots.

The MJCF is built from the `RobotDescription` (the one source of truth): a
body per link carrying the fixed transform A_i, a hinge about the body's z
axis, the link's capsule as collision and visual geometry, and its inertial.
Body `link{i}`'s frame is therefore exactly link frame i of the description
(after joint i's rotation), so MuJoCo's `xpos`/`xmat` of `link_bodies[i]`
equal `description.forward_kinematics(q)[i]` composed with the base pose.
"""

from typing import Optional, Tuple, Union

from absl import logging
from dm_control import composer
from dm_control import mjcf
from dm_control.composer.observation import observable
import numpy as np

from hrc_suite import robot_description
from hrc_suite import rotations
from hrc_suite.entities import collision_groups
from hrc_suite.entities import element_ids

# The shipped robots (more register: robot_description.names()).
ROBOTS = robot_description.ROBOT_NAMES

# Joint drive model. The descriptions give no rotor data, so reflected rotor
# inertia (armature) and viscous joint friction (damping) are scaled with the
# joint's torque limit (motor and gearbox size grow with torque), anchored at
# MuJoCo Menagerie's Franka Panda (franka_emika_panda/panda.xml: armature 0.1
# kg m^2 and damping 1 N m s/rad on its 87 N m joints).
ARMATURE_PER_NEWTON_METRE = 0.1 / 87.0   # kg m^2 per N m of torque limit.
DAMPING_PER_NEWTON_METRE = 1.0 / 87.0    # N m s/rad per N m of torque limit.

# Looks: (link colour, joint-housing colour) per robot, from the
# manufacturers' liveries; alternate links use the second colour.
_LIVERY = {
    'panda': ((0.93, 0.93, 0.93), (0.25, 0.25, 0.27)),
    'sawyer': ((0.72, 0.09, 0.09), (0.22, 0.22, 0.24)),
    'iiwa': ((0.96, 0.47, 0.06), (0.86, 0.86, 0.86)),
    'jaco': ((0.16, 0.16, 0.18), (0.42, 0.42, 0.45)),
    'kinova3': ((0.62, 0.63, 0.66), (0.2, 0.2, 0.22)),
    'ur5e': ((0.62, 0.76, 0.86), (0.78, 0.79, 0.8)),
    'schunk': ((0.2, 0.34, 0.66), (0.72, 0.73, 0.75)),
}
_DEFAULT_LIVERY = ((0.8, 0.8, 0.8), (0.3, 0.3, 0.3))
_BASE_RADIUS = 0.08   # m, visual-only mounting flange under link 1.
_BASE_HEIGHT = 0.02   # m


def make_robot(name: str) -> 'Robot':
  """A `Robot` by name or description path (`robot_description.resolve`).

  Args:
    name: a robot name (`robot_description.names()`) or the path of a
      .json description file.

  Returns:
    The robot, without a gripper.

  Raises:
    ValueError: an unknown name (the message lists the valid ones).
  """
  return Robot(robot_description.load(robot_description.resolve(name)))


def _inertia_for_mujoco(inertia: np.ndarray):
  """MJCF `fullinertia` (Ixx, Iyy, Izz, Ixy, Ixz, Iyz) of a 3x3 tensor.

  MuJoCo rejects principal moments that break the triangle inequality
  (A + B >= C). None of the shipped descriptions do; should one, the two
  smaller moments are raised just enough (keeping the principal axes), the
  fix is returned as the second value so the robot can report it.
  """
  eigvals, eigvecs = np.linalg.eigh(inertia)
  fixed = None
  if eigvals[0] + eigvals[1] < eigvals[2]:
    deficit = eigvals[2] - eigvals[0] - eigvals[1]
    balanced = eigvals + np.array([deficit / 2, deficit / 2, 0.0]) * 1.0001
    inertia = eigvecs @ np.diag(balanced) @ eigvecs.T
    fixed = (eigvals, balanced)
  full = [inertia[0, 0], inertia[1, 1], inertia[2, 2],
          inertia[0, 1], inertia[0, 2], inertia[1, 2]]
  return full, fixed


class Robot(composer.Entity):
  """A serial arm with torque-controlled hinge joints, built from data."""

  def _build(self,
             description: Union[robot_description.RobotDescription, str],
             name: Union[str, None] = None):
    """Builds the arm's MJCF from its description.

    Args:
      description: the robot's description, or a robot name or
        description path (`robot_description.resolve`).
      name: the MJCF model's name (default: the description's name).

    Raises:
      TypeError: a description that is neither a RobotDescription nor a
        string.
      ValueError: an unknown robot name.
    """
    if isinstance(description, str):
      description = robot_description.load(
          robot_description.resolve(description))
    if not isinstance(description, robot_description.RobotDescription):
      raise TypeError('description must be a RobotDescription or a robot '
                      f'name, got {type(description).__name__}')
    self._description = description
    self._gripper = None
    self._tcp_id = (None, None)   # (TCP site, its ElementIds): tcp_frame
    self.inertia_corrections = {}

    root = mjcf.RootElement(model=name or description.name)
    root.compiler.angle = 'radian'
    self._mjcf_root = root
    link_rgb, joint_rgb = _LIVERY.get(description.name, _DEFAULT_LIVERY)
    materials = (
        root.asset.add('material', name='link', rgba=(*link_rgb, 1.0),
                       specular=0.5, shininess=0.6, reflectance=0.0),
        root.asset.add('material', name='housing', rgba=(*joint_rgb, 1.0),
                       specular=0.4, shininess=0.4, reflectance=0.0))

    base = root.worldbody.add('body', name='base')
    base.add('geom', name='base_visual', type='cylinder',
             size=(_BASE_RADIUS, _BASE_HEIGHT / 2),
             pos=(0.0, 0.0, _BASE_HEIGHT / 2), material=materials[1],
             contype=0, conaffinity=0)

    limits = description.limits
    joints, actuators, bodies, geoms = [], [], [], []
    parent = base
    for i, link in enumerate(description.links):
      body = parent.add('body', name=f'link{i + 1}',
                        pos=link.fixed_translation,
                        quat=rotations.mat_to_quat(link.fixed_rotation))
      full_inertia, fixed = _inertia_for_mujoco(link.inertia)
      if fixed is not None:
        self.inertia_corrections[i] = fixed
        logging.warning('%s link %d: principal inertia %s breaks A + B >= C; '
                        'balanced to %s for MuJoCo', description.name, i + 1,
                        fixed[0], fixed[1])
      body.add('inertial', pos=link.center_of_mass, mass=link.mass,
               fullinertia=full_inertia)
      torque = float(limits.torque[i])
      joint = body.add(
          'joint', name=f'joint{i + 1}', type='hinge', axis=(0, 0, 1),
          limited=True, range=(limits.q_min[i], limits.q_max[i]),
          armature=ARMATURE_PER_NEWTON_METRE * torque,
          damping=DAMPING_PER_NEWTON_METRE * torque)
      capsule = link.capsule
      material = materials[i % 2]
      if np.allclose(capsule.p1, capsule.p2):
        geom = body.add('geom', name=f'link{i + 1}_capsule', type='sphere',
                        size=(capsule.radius,), pos=capsule.p1,
                        material=material)
      else:
        geom = body.add('geom', name=f'link{i + 1}_capsule', type='capsule',
                        size=(capsule.radius,),
                        fromto=np.concatenate([capsule.p1, capsule.p2]),
                        material=material)
      collision_groups.set_robot(geom)
      actuators.append(root.actuator.add(
          'motor', name=f'torque{i + 1}', joint=joint, gear=(1.0,),
          ctrllimited=True, ctrlrange=(-torque, torque)))
      joints.append(joint)
      bodies.append(body)
      geoms.append(geom)
      parent = body

    self._flange_site = parent.add(
        'site', name='flange', pos=description.flange_translation,
        quat=rotations.mat_to_quat(description.flange_rotation), size=(0.01,),
        rgba=(0.9, 0.2, 0.2, 0.0), group=4)
    self._joints = tuple(joints)
    self._actuators = tuple(actuators)
    self._link_bodies = tuple(bodies)
    self._link_geoms = tuple(geoms)

  def _build_observables(self):
    return RobotObservables(self)

  @property
  def mjcf_model(self) -> mjcf.RootElement:
    """The arm's MJCF model."""
    return self._mjcf_root

  @property
  def description(self) -> robot_description.RobotDescription:
    """The description the arm is built from."""
    return self._description

  @property
  def dof(self) -> int:
    """The number of joints."""
    return self._description.dof

  @property
  def joints(self) -> Tuple[mjcf.Element, ...]:
    """The hinge joints, base to flange."""
    return self._joints

  @property
  def actuators(self) -> Tuple[mjcf.Element, ...]:
    """The joints' torque motors (N m, limited to the joints' torques)."""
    return self._actuators

  @property
  def link_bodies(self) -> Tuple[mjcf.Element, ...]:
    """The link bodies; body i's frame is the description's link frame i."""
    return self._link_bodies

  @property
  def link_geoms(self) -> Tuple[mjcf.Element, ...]:
    """The links' collision capsules (spheres where a capsule is a point)."""
    return self._link_geoms

  @property
  def flange_site(self) -> mjcf.Element:
    """The site where a gripper is mounted."""
    return self._flange_site

  @property
  def gripper(self) -> Optional[composer.Entity]:
    """The attached gripper, or None."""
    return self._gripper

  @property
  def tcp_site(self) -> mjcf.Element:
    """The tool centre point: the gripper's TCP site, or the flange's."""
    if self._gripper is not None:
      return self._gripper.tcp_site
    return self._flange_site

  def attach_gripper(self, gripper: composer.Entity) -> composer.Entity:
    """Mounts a gripper at the flange site (one gripper per robot).

    Args:
      gripper: the gripper entity (e.g. `gripper.ParallelGripper`).

    Returns:
      The gripper.

    Raises:
      ValueError: if the robot already has a gripper.
    """
    if self._gripper is not None:
      raise ValueError(f'Robot {self.mjcf_model.model!r} already has a '
                       f'gripper ({self._gripper.mjcf_model.model!r})')
    self.attach(gripper, self._flange_site)
    self._gripper = gripper
    return gripper

  def _check_vector(self, values, what):
    values = np.asarray(values, dtype=float)
    if values.shape != (self.dof,):
      raise ValueError(f'{what} for {self._description.name} must have shape '
                       f'({self.dof},), got {values.shape}')
    return values

  def set_joint_positions(self, physics: mjcf.Physics, q: np.ndarray
                          ) -> None:
    """Writes joint positions (call physics.forward() before reading poses).

    Args:
      physics: the physics.
      q: (dof,) joint positions, rad.

    Raises:
      ValueError: q of another shape.
    """
    physics.bind(self._joints).qpos = self._check_vector(q, 'joint positions')

  def set_joint_velocities(self, physics: mjcf.Physics, dq: np.ndarray
                           ) -> None:
    """Writes joint velocities.

    Args:
      physics: the physics.
      dq: (dof,) joint velocities, rad/s.

    Raises:
      ValueError: dq of another shape.
    """
    physics.bind(self._joints).qvel = self._check_vector(dq,
                                                         'joint velocities')

  def joint_positions(self, physics: mjcf.Physics) -> np.ndarray:
    """A copy of the joint positions.

    Args:
      physics: the physics.

    Returns:
      (dof,) joint positions, rad.
    """
    return physics.bind(self._joints).qpos.copy()

  def joint_velocities(self, physics: mjcf.Physics) -> np.ndarray:
    """A copy of the joint velocities.

    Args:
      physics: the physics.

    Returns:
      (dof,) joint velocities, rad/s.
    """
    return physics.bind(self._joints).qvel.copy()

  def tcp_frame(self, physics: mjcf.Physics
                ) -> Tuple[np.ndarray, np.ndarray]:
    """The TCP site's frame in the world: copies of MjData's rows, the
    values its binding reads (element_ids), for code that runs every RL
    step.

    Args:
      physics: the physics.

    Returns:
      (position (3,), rotation matrix (9,) row-major).
    """
    site = self.tcp_site   # Changes when a gripper is attached.
    if self._tcp_id[0] is not site:
      self._tcp_id = (site, element_ids.ElementIds([site]))
    row = self._tcp_id[1](physics)[0]
    data = element_ids.synced_data(physics)
    return data.site_xpos[row].copy(), data.site_xmat[row].copy()

  def tcp_pose(self, physics: mjcf.Physics
               ) -> Tuple[np.ndarray, np.ndarray]:
    """The TCP's pose in the world.

    Args:
      physics: the physics.

    Returns:
      (position (3,), quaternion (4,) w first).
    """
    position, rotation = self.tcp_frame(physics)
    return position, rotations.mat_to_quat(rotation.reshape(3, 3))


class RobotObservables(composer.Observables):
  """Joint state and end-effector (TCP) pose of a robot."""

  @composer.observable
  def joint_positions(self) -> observable.MJCFFeature:
    """The joint positions, rad."""
    return observable.MJCFFeature('qpos', self._entity.joints)

  @composer.observable
  def joint_velocities(self) -> observable.MJCFFeature:
    """The joint velocities, rad/s."""
    return observable.MJCFFeature('qvel', self._entity.joints)

  @composer.observable
  def end_effector_position(self) -> observable.Generic:
    """The TCP's world position (3,)."""
    # Generic, so the TCP follows a gripper attached after construction.
    return observable.Generic(
        lambda physics: self._entity.tcp_frame(physics)[0])

  @composer.observable
  def end_effector_quaternion(self) -> observable.Generic:
    """The TCP's world quaternion (4,), w first."""
    return observable.Generic(lambda physics: self._entity.tcp_pose(physics)[1])
