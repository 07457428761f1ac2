"""A parallel two-finger gripper with one position-controlled opening.

Mount frame = the robot's flange: +z points out of the flange towards the
fingertips, the fingers slide along +-y. Proportions and limits follow the
Robotiq 2F-85 (datasheet: 85 mm stroke, 0.9 kg, grip force 20-235 N), a
common gripper on all seven arms.

The two finger joints are coupled by an equality constraint (they open
symmetrically, like the real linkage) and driven through one fixed tendon
(their sum, i.e. the aperture) by one position actuator, so a single command
in [-1, 1] (-1 fully open, +1 closed) sets the opening target.
"""

from typing import Sequence, Tuple

from dm_control import composer
from dm_control import mjcf
from dm_control.composer.observation import observable
import numpy as np

from hrc_suite.entities import collision_groups
from hrc_suite.entities import element_ids
from hrc_suite.entities import gripper_kernels

TCP_OFFSET = 0.12        # m along the mount's +z, between the fingertips.
MAX_APERTURE = 0.085     # m between the pads (Robotiq 2F-85 stroke).
GRIP_FORCE = 40.0        # N, force limit on the opening (2F-85 range 20-235).
# Commanding +1 targets this (negative) aperture, so a grasped object is
# squeezed with the full GRIP_FORCE rather than a spring force near zero.
CLOSED_TARGET = -0.02    # m
OPENING_STIFFNESS = 2000.0   # N/m of the position servo on the aperture.
# Reflected inertia of the finger drive (motor + lead screw) per finger and
# viscous damping: the servo is nearly critically damped (ratio ~0.8) and a
# full stroke takes ~0.07 s (faster than the 2F-85's 150 mm/s, so a grasp
# completes within one 0.1 s agent step).
FINGER_ARMATURE = 0.3    # kg
FINGER_DAMPING = 60.0    # N s/m

PALM_MASS = 0.75         # kg; + 2 fingers = 0.9 kg, the 2F-85's mass.
FINGER_MASS = 0.06       # kg
PAD_MASS = 0.015         # kg
# Rubber pads: sliding friction 1.5 (rubber on wood/plastic is 1-2),
# torsional friction so a held object does not spin about the grip axis.
PAD_FRICTION = (1.5, 0.02, 0.0001)
# Stiffer than MuJoCo's default contact (0.02 s, solimp 0.9-0.95): the pads
# sink ~1 mm instead of ~2 mm into a held object at GRIP_FORCE; 0.008 s is
# the smallest time constant MuJoCo allows at a 4 ms step (2 timesteps).
PAD_SOLREF = (0.008, 1.0)
PAD_SOLIMP = (0.95, 0.99, 0.001)

# Geometry (m): boxes as (half sizes, centre) in the mount frame at zero
# opening; finger boxes are in the left finger's frame (mirrored for the
# right one) and move by half the aperture along y.
_COUPLING_RADIUS = 0.037
_COUPLING_HALF_HEIGHT = 0.01
_PALM = ((0.022, 0.06, 0.0225), (0.0, 0.0, 0.0425))
_FINGER = ((0.011, 0.006, 0.0325), (0.0, 0.01, 0.0975))
_PAD = ((0.01, 0.002, 0.02), (0.0, 0.002, 0.11))


def _box_corners(half, centre):
  signs = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1).T
  return np.asarray(centre) + signs * np.asarray(half)


def _all_corners():
  """Corners of boxes bounding every gripper geom at both opening extremes."""
  corners = [_box_corners((_COUPLING_RADIUS, _COUPLING_RADIUS,
                           _COUPLING_HALF_HEIGHT),
                          (0.0, 0.0, _COUPLING_HALF_HEIGHT)),
             _box_corners(*_PALM)]
  for opening in (0.0, MAX_APERTURE / 2):
    for half, centre in (_FINGER, _PAD):
      left = _box_corners(half, centre) + np.array([0.0, opening, 0.0])
      corners += [left, left * np.array([-1.0, -1.0, 1.0])]
  return np.concatenate(corners)


class ParallelGripper(composer.Entity):
  """Two fingers on a palm; one command opens and closes them."""

  TCP_OFFSET = TCP_OFFSET
  MAX_APERTURE = MAX_APERTURE

  def _build(self, name: str = 'gripper', grip_force: float = GRIP_FORCE):
    """Builds the palm, the fingers, their coupling and the actuator.

    Args:
      name: the MJCF model's name.
      grip_force: N, the opening's force limit (2F-85: 20-235 N). The
        servo squeezes with all of it objects at least grip_force /
        OPENING_STIFFNESS + CLOSED_TARGET thick (0 m at 40 N, 3 cm at
        100 N).

    Raises:
      ValueError: a grip_force outside [20, 235] N.
    """
    if not (np.isfinite(grip_force) and 20.0 <= grip_force <= 235.0):
      raise ValueError(f'grip_force={grip_force!r}: expected a force in '
                       '[20, 235] N (the Robotiq 2F-85 range)')
    self._grip_force = float(grip_force)
    root = mjcf.RootElement(model=name)
    self._mjcf_root = root
    aluminium = root.asset.add('material', name='aluminium',
                               rgba=(0.72, 0.73, 0.76, 1), specular=0.7,
                               shininess=0.7)
    dark = root.asset.add('material', name='dark', rgba=(0.14, 0.14, 0.15, 1),
                          specular=0.3, shininess=0.3)
    rubber = root.asset.add('material', name='rubber',
                            rgba=(0.85, 0.45, 0.1, 1), specular=0.1,
                            shininess=0.1)

    geoms = [
        root.worldbody.add('geom', name='coupling', type='cylinder',
                           size=(_COUPLING_RADIUS, _COUPLING_HALF_HEIGHT),
                           pos=(0, 0, _COUPLING_HALF_HEIGHT), material=dark,
                           mass=0.2 * PALM_MASS),
        root.worldbody.add('geom', name='palm', type='box', size=_PALM[0],
                           pos=_PALM[1], material=aluminium,
                           mass=0.8 * PALM_MASS)]
    fingers, pads, joints = [], [], []
    for side, yaw in (('left', 0.0), ('right', np.pi)):
      finger = root.worldbody.add('body', name=f'{side}_finger',
                                  euler=(0, 0, yaw))
      joints.append(finger.add(
          'joint', name=f'{side}_slide', type='slide', axis=(0, 1, 0),
          limited=True, range=(0.0, MAX_APERTURE / 2),
          armature=FINGER_ARMATURE, damping=FINGER_DAMPING))
      geoms.append(finger.add('geom', name=f'{side}_finger', type='box',
                              size=_FINGER[0], pos=_FINGER[1],
                              material=aluminium, mass=FINGER_MASS))
      pad = finger.add('geom', name=f'{side}_pad', type='box', size=_PAD[0],
                       pos=_PAD[1], material=rubber, mass=PAD_MASS,
                       friction=PAD_FRICTION, condim=4, solref=PAD_SOLREF,
                       solimp=PAD_SOLIMP)
      geoms.append(pad)
      fingers.append(finger)
      pads.append(pad)
    for geom in geoms:
      collision_groups.set_robot(geom)

    root.equality.add('joint', name='symmetric', joint1=joints[0],
                      joint2=joints[1], polycoef=(0, 1, 0, 0, 0))
    opening = root.tendon.add('fixed', name='opening')
    for joint in joints:
      opening.add('joint', joint=joint, coef=1.0)
    # force = k * (target(u) - aperture); target(-1) = MAX_APERTURE,
    # target(+1) = CLOSED_TARGET, linear in between.
    mid = (MAX_APERTURE + CLOSED_TARGET) / 2
    half_span = (CLOSED_TARGET - MAX_APERTURE) / 2
    self._actuator = root.actuator.add(
        'general', name='fingers', tendon=opening, ctrllimited=True,
        ctrlrange=(-1, 1), forcelimited=True,
        forcerange=(-self._grip_force, self._grip_force),
        biastype='affine',
        gainprm=(OPENING_STIFFNESS * half_span,),
        biasprm=(OPENING_STIFFNESS * mid, -OPENING_STIFFNESS, 0.0))

    self._tcp_site = root.worldbody.add(
        'site', name='tcp', pos=(0, 0, TCP_OFFSET), size=(0.006,),
        rgba=(0.1, 0.8, 0.2, 0.0), group=4)
    self._fingers = tuple(fingers)
    self._finger_geoms = tuple(pads)
    self._finger_joints = tuple(joints)
    self._geoms = tuple(geoms)
    # Per-step reads by id (element_ids): the fingers, their joints, the
    # actuator; the bodies `grasping` is asked about, by their tuple.
    self._finger_ids = element_ids.ElementIds(fingers)
    self._finger_joint_ids = element_ids.ElementIds(joints)
    self._actuator_id = element_ids.ElementIds([self._actuator])
    self._body_ids = {}
    gripper_kernels.warm_up()   # Once per process, not mid-run.

  def _build_observables(self):
    return GripperObservables(self)

  @property
  def mjcf_model(self) -> mjcf.RootElement:
    """The gripper's MJCF model."""
    return self._mjcf_root

  @property
  def tcp_site(self) -> mjcf.Element:
    """The tool centre point, between the fingertips (TCP_OFFSET along z)."""
    return self._tcp_site

  @property
  def grip_force(self) -> float:
    """N, the force limit of the opening (how hard a grasp squeezes)."""
    return self._grip_force

  @property
  def finger_geoms(self) -> Tuple[mjcf.Element, ...]:
    """The (left, right) finger pads."""
    return self._finger_geoms

  @property
  def finger_bodies(self) -> Tuple[mjcf.Element, ...]:
    """The (left, right) finger bodies."""
    return self._fingers

  @property
  def finger_joints(self) -> Tuple[mjcf.Element, ...]:
    """The (left, right) slide joints, m (each half the aperture)."""
    return self._finger_joints

  @property
  def geoms(self) -> Tuple[mjcf.Element, ...]:
    """Every collision geom of the gripper."""
    return self._geoms

  @property
  def actuator(self) -> mjcf.Element:
    """The position actuator on the opening."""
    return self._actuator

  @property
  def actuators(self) -> Tuple[mjcf.Element, ...]:
    """The gripper's actuators: (actuator,)."""
    return (self._actuator,)

  def set_command(self, physics: mjcf.Physics, u: float) -> None:
    """Sets the opening's target.

    Args:
      physics: the physics.
      u: in [-1, 1]: -1 fully open, +1 closed (clipped).

    Raises:
      ValueError: a non-finite u.
    """
    u = float(u)
    if not np.isfinite(u):
      raise ValueError(f'gripper command must be finite, got {u}')
    # MjData's row, not the binding: a ctrl write through a binding marks
    # dm_control's physics dirty, and the next binding read then runs a
    # whole mj_forward (a control changes no position or velocity).
    physics.data.ctrl[self._actuator_id(physics)[0]] = min(max(u, -1.0), 1.0)

  def aperture(self, physics: mjcf.Physics) -> float:
    """Opening between the pads, normalised: 0 closed, 1 fully open.

    Args:
      physics: the physics.

    Returns:
      The aperture in [0, 1].
    """
    # The joints' qpos rows (what their binding reads; a qpos read never
    # runs mj_forward), summed in the binding's order.
    rows = physics.model.jnt_qposadr[self._finger_joint_ids(physics)]
    opening = np.sum(physics.data.qpos[rows])
    return float(min(max(opening / MAX_APERTURE, 0.0), 1.0))

  def is_grasping(self, physics: mjcf.Physics, body: mjcf.Element) -> bool:
    """Whether both fingers touch geoms of `body` (and its subtree).

    Args:
      physics: the physics.
      body: an MJCF body (e.g. a prop's `body`).

    Returns:
      Whether it is grasped.
    """
    return bool(self.grasping(physics, (body,))[0])

  def grasping(self, physics: mjcf.Physics,
               bodies: Sequence[mjcf.Element]) -> np.ndarray:
    """is_grasping for each of `bodies`, from one pass over the contacts
    (compiled: gripper_kernels.grasped; its NumPy reference is in
    tests/entities/entity_references.py).

    Args:
      physics: the physics.
      bodies: n MJCF bodies.

    Returns:
      (n,) bools.
    """
    data = physics.data
    grasped = np.zeros(len(bodies), dtype=bool)
    ncon = data.ncon
    if ncon == 0:
      return grasped
    contact, model = data.contact, physics.model
    gripper_kernels.grasped(
        contact.geom1[:ncon], contact.geom2[:ncon], model.geom_bodyid,
        model.body_rootid, self._finger_ids(physics),
        self._target_ids(physics, bodies), grasped)
    return grasped

  def _target_ids(self, physics, bodies):
    """Body ids of `bodies`, looked up once per Physics and tuple."""
    key = tuple(bodies)
    ids = self._body_ids.get(key)
    if ids is None:
      ids = self._body_ids[key] = element_ids.ElementIds(bodies)
    return ids(physics)

  def enclosing_capsule(self) -> Tuple[np.ndarray, np.ndarray, float]:
    """A capsule in the mount frame covering the gripper fully open or
    closed: a segment along z through the bounding boxes of all geoms.

    Returns:
      (p1 (3,), p2 (3,), radius), m.
    """
    corners = _all_corners()
    radius = float(np.max(np.linalg.norm(corners[:, :2], axis=1)))
    p1 = np.array([0.0, 0.0, corners[:, 2].min()])
    p2 = np.array([0.0, 0.0, corners[:, 2].max()])
    return p1, p2, radius


class GripperObservables(composer.Observables):
  """Normalised aperture of the gripper."""

  @composer.observable
  def aperture(self) -> observable.Generic:
    """The normalised aperture (1,)."""
    return observable.Generic(
        lambda physics: np.array([self._entity.aperture(physics)]))
