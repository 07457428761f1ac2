"""Task props: cubes, a claw hammer and the board for collaborative lifting.

Every prop is built around one body (`prop.body`), so grasp checks
(`ParallelGripper.is_grasping`), the human's welds (`Human.add_holdable`) and
observables refer to the same element before and after attachment. Free
props are attached with `arena.add_free_entity(prop)` and placed with
`prop.set_pose(physics, position, quaternion)`; attached with
`arena.attach(prop)` they are fixed.

Grip sites follow one convention: a grip site's frame is the gripper's TCP
frame for that grasp (`ParallelGripper`: z points from the palm towards the
fingertips, the fingers close along y). A top grasp therefore has z pointing
down into the object.

Sizes and masses are named constants with their source; every collision geom
is in the OBJECT collision group.
"""

import numbers
from typing import Sequence, Tuple

from dm_control import composer
from dm_control import mjcf
from dm_control.composer.observation import observable
import numpy as np

from hrc_suite.entities import collision_groups
from hrc_suite.entities import element_ids
from hrc_suite.entities import gripper as gripper_lib

# --- Cubes. The reference's pick and place cube: 4 cm, here 0.1 kg (dense
# plastic or hardwood, ~1.6 g/cm^3). Stacking uses four 5 cm cubes, the size
# the human's stacking clips assume (hrc_suite.human.task_motions.CUBE_SIZE).
CUBE_SIZE = 0.04           # m, edge length.
CUBE_MASS = 0.1            # kg
STACKING_CUBE_SIZE = 0.05  # m
STACKING_CUBE_MASS = 0.1   # kg
# Distinct, colour-blind-safe colours (Okabe-Ito palette) for the four cubes.
STACKING_COLOURS = ((0.0, 0.45, 0.70, 1.0), (0.90, 0.62, 0.0, 1.0),
                    (0.0, 0.62, 0.45, 1.0), (0.80, 0.40, 0.0, 1.0))
CUBE_RGBA = (0.8, 0.15, 0.15, 1.0)

# --- Hammer: a typical 16 oz wood-handled claw hammer (head 0.45 kg, 12-13
# in = 0.31-0.33 m long, about 0.6 kg overall). Body frame: the handle runs
# along +x from its butt to the head, whose axis is z; the face points along
# -z, the claw along +z; the origin is where the handle and head axes meet.
HAMMER_HEAD_MASS = 0.45        # kg (16 oz).
HAMMER_HANDLE_MASS = 0.13      # kg: hickory (~800 kg/m^3), 0.30 x 25 x 22 mm.
HAMMER_HANDLE_LENGTH = 0.30    # m from the butt to the head's axis.
HAMMER_HANDLE_HALF_SECTION = (0.0125, 0.011)   # m: half width (y), depth (z).
HAMMER_FACE_RADIUS = 0.0125    # m (25 mm striking face).
HAMMER_FACE_OFFSET = 0.04      # m from the handle axis to the face.
HAMMER_CLAW_HEIGHT = 0.085     # m from the handle axis to the claw's end.
HAMMER_CLAW_HALF_SECTION = (0.009, 0.011)   # m: half x, half y.
HAMMER_NECK_HEIGHT = 0.02      # m: where the round neck becomes the claw.
# Where a person holds a hammer: near the butt, the palm 0.26 m from the
# head's axis (hrc_suite.human.task_motions.HAMMER_REACH assumes the same).
HAMMER_HUMAN_GRIP = 0.26       # m from the head's axis along the handle.
# Steel on steel is stiffer than MuJoCo's default contact (0.02 s): strikes
# use the smallest time constant allowed at a 4 ms step (2 steps).
STRIKE_SOLREF = (0.008, 1.0)
STRIKE_SOLIMP = (0.95, 0.99, 0.001)

# --- Board for collaborative lifting: the reference's 1.0 x 0.4 x 0.03 m,
# 2.5 kg (a light, e.g. honeycomb or poplar-ply, panel; solid pine would be
# ~6 kg). A handle block on the top face near the robot's end lets a
# gripper pointing down hold the board.
BOARD_SIZE = (1.0, 0.4, 0.03)    # m: length (x), width (y), thickness (z).
BOARD_MASS = 2.5                 # kg, including the handle.
# Handle: thin along x so the fingers, closing along x, take the board's
# weight moment (about y) through the pads' normal forces.
HANDLE_HALF_SIZE = (0.015, 0.04, 0.03)   # m: 3 cm thick, 8 cm wide, 6 cm tall.
HANDLE_INSET = 0.08              # m from the board's robot end (-x), default.
HUMAN_GRIP_INSET = 0.1           # m from the board's human end (+x).
# Fingertips sit 1 cm beyond the TCP (gripper.py: pads end at 0.13 m, TCP at
# 0.12 m): the TCP goes this far below the handle's top, leaving the pads
# 2.5 cm clear of the board.
HANDLE_GRIP_DEPTH = 0.025        # m
WOOD_DENSITY = 600.0             # kg/m^3, pine/spruce (for small parts).

# Orientations of grip sites (MJCF xyaxes: the frame's x then y axis).
TOP_GRASP_CLOSING_Y = (1, 0, 0, 0, -1, 0)   # z down, fingers close along y.
TOP_GRASP_CLOSING_X = (0, 1, 0, 1, 0, 0)    # z down, fingers close along x.


def _check_positive(value, what):
  if (not isinstance(value, numbers.Real) or not np.isfinite(value)
      or value <= 0):
    raise ValueError(f'{what} must be a positive finite number, got {value!r}')
  return float(value)


def _check_rgba(rgba):
  rgba = np.asarray(rgba, dtype=float)
  if rgba.shape != (4,) or np.any((rgba < 0) | (rgba > 1)):
    raise ValueError(f'rgba must be 4 values in [0, 1], got {rgba.tolist()}')
  return rgba


class Prop(composer.Entity):
  """A rigid prop: one body holding its geoms and sites."""

  def _build_root(self, name):
    self._mjcf_root = mjcf.RootElement(model=name)
    self._body = self._mjcf_root.worldbody.add('body', name=name)
    self._body_ids = element_ids.ElementIds([self._body])
    self._geoms = []
    return self._body

  def _add_collision_geom(self, parent=None, **kwargs):
    geom = (parent or self._body).add('geom', **kwargs)
    collision_groups.set_object(geom)
    self._geoms.append(geom)
    return geom

  def _build_observables(self):
    return PropObservables(self)

  @property
  def mjcf_model(self) -> mjcf.RootElement:
    """The prop's MJCF model."""
    return self._mjcf_root

  @property
  def body(self) -> mjcf.Element:
    """The prop's body: grasp, hold and observe this one."""
    return self._body

  @property
  def geoms(self) -> Tuple[mjcf.Element, ...]:
    """Every collision geom of the prop."""
    return tuple(self._geoms)

  def position(self, physics: mjcf.Physics) -> np.ndarray:
    """World position of the body (a copy of its MjData row, as its
    binding reads it: element_ids).

    Args:
      physics: the physics.

    Returns:
      (3,) the position.
    """
    row = self._body_ids(physics)[0]
    return element_ids.synced_data(physics).xpos[row].copy()

  def quaternion(self, physics: mjcf.Physics) -> np.ndarray:
    """World orientation of the body.

    Args:
      physics: the physics.

    Returns:
      (4,) the quaternion (w, x, y, z), a copy.
    """
    row = self._body_ids(physics)[0]
    return element_ids.synced_data(physics).xquat[row].copy()


class PropObservables(composer.Observables):
  """World position and orientation quaternion (w, x, y, z) of a prop."""

  @composer.observable
  def position(self) -> observable.MJCFFeature:
    """The body's world position (3,)."""
    return observable.MJCFFeature('xpos', self._entity.body)

  @composer.observable
  def quaternion(self) -> observable.MJCFFeature:
    """The body's world quaternion (4,), w first."""
    return observable.MJCFFeature('xquat', self._entity.body)


class Cube(Prop):
  """A solid cube with a top-grasp site at its centre."""

  def _build(self, size: float = CUBE_SIZE, mass: float = CUBE_MASS,
             rgba: Sequence[float] = CUBE_RGBA, name: str = 'cube'):
    """Builds the cube.

    Args:
      size: edge length, m, > 0.
      mass: kg, > 0.
      rgba: 4 values in [0, 1].
      name: the MJCF model's and the body's name.

    Raises:
      ValueError: a size or mass that is not a positive finite number, or
        bad rgba.
    """
    self._size = _check_positive(size, 'Cube size')
    self._mass = _check_positive(mass, 'Cube mass')
    body = self._build_root(name)
    self._geom = self._add_collision_geom(
        name='geom', type='box', size=[self._size / 2] * 3, mass=self._mass,
        rgba=_check_rgba(rgba))
    self._grip_site = body.add('site', name='grip_site', size=(0.005,),
                               xyaxes=TOP_GRASP_CLOSING_Y, group=4)

  @property
  def size(self) -> float:
    """Edge length (m)."""
    return self._size

  @property
  def mass(self) -> float:
    """Mass (kg)."""
    return self._mass

  @property
  def geom(self) -> mjcf.Element:
    """The cube's box geom."""
    return self._geom

  @property
  def grip_site(self) -> mjcf.Element:
    """TCP frame for a top grasp at the centre, fingers closing along y."""
    return self._grip_site


def make_stacking_cubes(size: float = STACKING_CUBE_SIZE,
                        mass: float = STACKING_CUBE_MASS,
                        colours: Sequence[Sequence[float]] = STACKING_COLOURS,
                        name: str = 'stacking_cube') -> Tuple[Cube, ...]:
  """Four cubes of one size in distinct colours, named `{name}_1` .. `_4`.

  Args:
    size: edge length, m.
    mass: each cube's, kg.
    colours: 4 rgba colours.
    name: the names' stem.

  Returns:
    The four cubes.

  Raises:
    ValueError: not 4 colours, or what `Cube` rejects.
  """
  if len(colours) != 4:
    raise ValueError(f'Expected 4 colours for the stacking cubes, got '
                     f'{len(colours)}')
  return tuple(Cube(size=size, mass=mass, rgba=rgba, name=f'{name}_{i + 1}')
               for i, rgba in enumerate(colours))


class Hammer(Prop):
  """A claw hammer: wooden handle, steel head with a round face and a claw.

  Sites: `grip_site` (the robot's grasp at the centre of mass, approach
  from +y, the hammer lying on its side), `human_grip_site` (the palm on the
  handle, frame = body frame), `head_site` (centre of the striking face).
  """

  def _build(self, name: str = 'hammer'):
    """Builds the hammer.

    Args:
      name: the MJCF model's and the body's name.
    """
    body = self._build_root(name)
    wood = self._mjcf_root.asset.add('material', name='hickory',
                                     rgba=(0.72, 0.52, 0.3, 1), specular=0.2)
    steel = self._mjcf_root.asset.add('material', name='steel',
                                      rgba=(0.35, 0.36, 0.4, 1),
                                      specular=0.8, shininess=0.8)
    half_y, half_z = HAMMER_HANDLE_HALF_SECTION
    # The handle ends at the head's axis (inside the head's eye).
    self._handle = self._add_collision_geom(
        name='handle', type='box',
        size=(HAMMER_HANDLE_LENGTH / 2, half_y, half_z),
        pos=(-HAMMER_HANDLE_LENGTH / 2, 0, 0), material=wood,
        mass=HAMMER_HANDLE_MASS)
    # Head mass split by volume between the round part and the claw.
    neck_half = (HAMMER_FACE_OFFSET + HAMMER_NECK_HEIGHT) / 2
    claw_half = (HAMMER_CLAW_HEIGHT - HAMMER_NECK_HEIGHT) / 2
    neck_volume = np.pi * HAMMER_FACE_RADIUS ** 2 * 2 * neck_half
    claw_volume = 8 * np.prod(HAMMER_CLAW_HALF_SECTION) * claw_half
    neck_mass = HAMMER_HEAD_MASS * neck_volume / (neck_volume + claw_volume)
    self._head = self._add_collision_geom(
        name='head', type='cylinder', size=(HAMMER_FACE_RADIUS, neck_half),
        pos=(0, 0, HAMMER_NECK_HEIGHT - neck_half), material=steel,
        mass=neck_mass, solref=STRIKE_SOLREF, solimp=STRIKE_SOLIMP)
    self._claw = self._add_collision_geom(
        name='claw', type='box', size=(*HAMMER_CLAW_HALF_SECTION, claw_half),
        pos=(0, 0, HAMMER_NECK_HEIGHT + claw_half), material=steel,
        mass=HAMMER_HEAD_MASS - neck_mass)
    centre_of_mass_x = (-HAMMER_HANDLE_LENGTH / 2 * HAMMER_HANDLE_MASS
                        / (HAMMER_HANDLE_MASS + HAMMER_HEAD_MASS))
    # Gripped at the centre of mass, gravity puts no torque about the
    # fingers' closing axis (which only the pads' torsional friction resists).
    self._grip_site = body.add('site', name='grip_site', size=(0.005,),
                               pos=(centre_of_mass_x, 0, 0),
                               xyaxes=(1, 0, 0, 0, 0, 1), group=4)
    self._human_grip_site = body.add('site', name='human_grip_site',
                                     size=(0.005,),
                                     pos=(-HAMMER_HUMAN_GRIP, 0, 0), group=4)
    self._head_site = body.add('site', name='head_site', size=(0.005,),
                               pos=(0, 0, -HAMMER_FACE_OFFSET), group=4)

  def _build_observables(self):
    return HammerObservables(self)

  @property
  def mass(self) -> float:
    """Mass (kg): head and handle."""
    return HAMMER_HEAD_MASS + HAMMER_HANDLE_MASS

  @property
  def handle(self) -> mjcf.Element:
    """The handle's box geom."""
    return self._handle

  @property
  def head(self) -> mjcf.Element:
    """The round part of the head, ending in the striking face."""
    return self._head

  @property
  def grip_site(self) -> mjcf.Element:
    """The robot's grasp: TCP frame at the centre of mass."""
    return self._grip_site

  @property
  def human_grip_site(self) -> mjcf.Element:
    """The person's palm on the handle (frame = body frame)."""
    return self._human_grip_site

  @property
  def head_site(self) -> mjcf.Element:
    """The centre of the striking face."""
    return self._head_site


class HammerObservables(PropObservables):
  """Adds the world position of the striking face's centre."""

  @composer.observable
  def head_position(self) -> observable.MJCFFeature:
    """The striking face's world position (3,)."""
    return observable.MJCFFeature('xpos', self._entity.head_site)


def _check_board_size(size, handle_inset):
  values = np.asarray(size, dtype=float)
  if values.shape != (3,) or not np.all(np.isfinite(values) & (values > 0)):
    raise ValueError('Board size must be 3 positive lengths (length, width, '
                     f'thickness), got {size!r}')
  if not 0 <= handle_inset < np.inf:
    raise ValueError(f'Board handle_inset must be a distance >= 0 m, got '
                     f'{handle_inset!r}')
  if values[0] / 2 < handle_inset + 2 * HANDLE_HALF_SIZE[0] or (
      values[1] < 2 * HANDLE_HALF_SIZE[1]):
    raise ValueError(f'Board size {size!r} is too small for its handle '
                     f'({2 * np.array(HANDLE_HALF_SIZE)} m, {handle_inset} m '
                     'from the end, on the robot\'s half)')
  return values


class Board(Prop):
  """A flat board with a handle for the robot at its -x end.

  Body frame: centre of the board, x along its length (robot end at -x,
  human end at +x), z normal to its top face. Sites: `robot_grip_site` (TCP
  frame of a top grasp on the handle, fingers closing along x),
  `human_grip_site` (centre of the human's end, on the top face).
  `handle_inset`: distance (m) from the robot's end to the handle, so a task
  can put the handle where its robots reach.
  """

  def _build(self, size: Sequence[float] = BOARD_SIZE,
             mass: float = BOARD_MASS, handle_inset: float = HANDLE_INSET,
             name: str = 'board'):
    """Builds the board and its handle.

    Args:
      size: (length, width, thickness), m.
      mass: kg, including the handle.
      handle_inset: m from the board's robot end to the handle.
      name: the MJCF model's and the body's name.

    Raises:
      ValueError: a size that is not 3 positive lengths or too small for
        the handle, a negative handle_inset, or a mass that is not above
        the handle's.
    """
    self._size = _check_board_size(size, handle_inset)
    self._mass = _check_positive(mass, 'Board mass')
    handle_mass = WOOD_DENSITY * 8 * np.prod(HANDLE_HALF_SIZE)
    if handle_mass >= self._mass:
      raise ValueError(f'Board mass {mass} kg must exceed its handle\'s '
                       f'{handle_mass:.3f} kg')
    body = self._build_root(name)
    wood = self._mjcf_root.asset.add('material', name='plywood',
                                     rgba=(0.8, 0.66, 0.45, 1), specular=0.1)
    length, width, thickness = self._size
    self._plate = self._add_collision_geom(
        name='plate', type='box', size=self._size / 2, material=wood,
        mass=self._mass - handle_mass)
    handle_x = -length / 2 + handle_inset + HANDLE_HALF_SIZE[0]
    handle_top = thickness / 2 + 2 * HANDLE_HALF_SIZE[2]
    self._handle = self._add_collision_geom(
        name='handle', type='box', size=HANDLE_HALF_SIZE,
        pos=(handle_x, 0, thickness / 2 + HANDLE_HALF_SIZE[2]),
        material=wood, mass=handle_mass)
    self._robot_grip_site = body.add(
        'site', name='robot_grip_site', size=(0.005,),
        pos=(handle_x, 0, handle_top - HANDLE_GRIP_DEPTH),
        xyaxes=TOP_GRASP_CLOSING_X, group=4)
    self._human_grip_site = body.add(
        'site', name='human_grip_site', size=(0.005,),
        pos=(length / 2 - HUMAN_GRIP_INSET, 0, thickness / 2), group=4)

  def _build_observables(self):
    return BoardObservables(self)

  @property
  def size(self) -> Tuple[float, float, float]:
    """(length, width, thickness), m."""
    return tuple(self._size)

  @property
  def mass(self) -> float:
    """Mass (kg), including the handle."""
    return self._mass

  @property
  def plate(self) -> mjcf.Element:
    """The board's box geom."""
    return self._plate

  @property
  def handle(self) -> mjcf.Element:
    """The handle block's geom."""
    return self._handle

  @property
  def robot_grip_site(self) -> mjcf.Element:
    """TCP frame of a top grasp on the handle, fingers closing along x."""
    return self._robot_grip_site

  @property
  def human_grip_site(self) -> mjcf.Element:
    """The centre of the person's end, on the top face."""
    return self._human_grip_site

  def _body_id(self, physics):
    return self._body_ids(physics)[0]

  def normal(self, physics: mjcf.Physics) -> np.ndarray:
    """World direction of the board's top-face normal.

    Args:
      physics: the physics.

    Returns:
      (3,) unit vector.
    """
    return physics.data.xmat[self._body_id(physics), 2::3].copy()  # z column

  def tilt(self, physics: mjcf.Physics) -> float:
    """Angle between the board's normal and world z.

    Args:
      physics: the physics.

    Returns:
      The angle, rad, in [0, pi].
    """
    cosine = physics.data.xmat[self._body_id(physics), 8]
    return float(np.arccos(min(max(cosine, -1.0), 1.0)))


class BoardObservables(PropObservables):
  """Adds the board's normal (its z component is the reference's balance)."""

  @composer.observable
  def normal(self) -> observable.Generic:
    """The board's top-face normal (3,)."""
    return observable.Generic(self._entity.normal)


def is_gripped(physics: mjcf.Physics, gripper: gripper_lib.ParallelGripper,
               prop: Prop) -> bool:
  """Whether both fingers of `gripper` touch `prop`'s body.

  Args:
    physics: the physics.
    gripper: the gripper.
    prop: the prop.

  Returns:
    Whether it is gripped.
  """
  return gripper.is_grasping(physics, prop.body)
