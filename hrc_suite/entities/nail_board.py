"""A wooden block with a nail the human hammers in while the robot holds it.

The nail sits on a slide joint into the block. Driving it in is resisted by
dry friction (MuJoCo `frictionloss`, a force that holds up to its limit and
dissipates energy while the nail moves), so each hammer blow pushes it some
millimetres, roughly in proportion to the blow's energy, and a nail left
alone stays where it is. The joint's range ends with the head on the block.

Body frame: centre of the block, x along its length (handle at -x, nail at
+x), z up through its top face. Sites: `grip_site` (TCP frame of a top grasp
on the handle, fingers closing along x, see props.py), `nail_head_site` (top
centre of the nail head; it moves as the nail goes in).
"""

from typing import Sequence

from dm_control import composer
from dm_control import mjcf
from dm_control.composer.observation import observable
import numpy as np

from hrc_suite.entities import props

# Block: 15 x 8 x 4 cm of pine (WOOD_DENSITY), 0.35 kg with its handle. The
# nail sits 9.5 cm from the handle: as close as a hammer head (25 mm face)
# can strike without touching the open gripper's palm (+-6 cm along the
# fingers' closing axis), which keeps the blows' moment on the grip small.
BLOCK_HALF_SIZE = (0.075, 0.04, 0.02)     # m
HANDLE_HALF_SIZE = (0.015, 0.03, 0.03)    # m: 3 cm thick across the grip.
HANDLE_INSET = 0.0                        # m from the block's -x end.
NAIL_X = 0.035                            # m from the block's centre.
# Nail: a 40 mm clout nail (BS 1202-1 sizes: 3 mm shank, head about three
# shank diameters), started 8 mm into the wood; 30 mm remain to drive.
NAIL_LENGTH = 0.04           # m, head included.
NAIL_SHANK_RADIUS = 0.0015   # m
NAIL_HEAD_RADIUS = 0.005     # m
NAIL_HEAD_HALF_THICKNESS = 0.001   # m
NAIL_START_DEPTH = 0.008     # m in the wood before the first blow.
NAIL_TRAVEL = NAIL_LENGTH - NAIL_START_DEPTH - 2 * NAIL_HEAD_HALF_THICKNESS
STEEL_DENSITY = 7850.0       # kg/m^3
# Insertion resistance as dry friction. A real 3 mm nail in softwood needs
# ~0.5-1 kN, delivered by a blow's ~1 ms force peak through a rigidly held
# workpiece. Here the workpiece is held by a 40 N parallel gripper (pads
# slip above 2 x 1.5 x 40 = 120 N) and a 4 ms step cannot resolve the peak,
# so the friction is set to what the grip can react: with 60 N the block
# slips ~1-2 mm in the fingers per blow, and a 0.6 kg hammer drives the nail
# of a robot-held block ~3.5 mm per blow at 1.5 m/s and ~6 mm at 2 m/s
# (five blows), ~14 mm at 2 m/s into a rigidly fixed block (measured in
# tests/entities/test_nail_board.py: depth per blow about the blow's
# energy over the friction).
NAIL_FRICTION = 60.0         # N
# Friction loss is a soft constraint: under a load below the limit the
# joint creeps at a rate proportional to (1 - impedance). Impedance at
# MuJoCo's maximum (0.9999) and gravity compensation on the nail (2.5 g)
# keep a resting nail in place (a hammer resting on it: ~10 um/s).
NAIL_SOLIMP_FRICTION = (0.9999, 0.9999, 0.001)
# Effective mass of the driven nail (MuJoCo armature on the slide): the wood
# the nail pushes aside moves with it. Against a 2.5 g nail the hammer's
# contact sinks through the thin head; with this mass the blow's energy
# goes into the friction (depth per blow about proportional to energy) and
# the face stays on the head (penetration < 1.5 cm at 3 m/s). It adds no
# mass to the block's own motion.
NAIL_ARMATURE = 0.5          # kg


class NailBoard(props.Prop):
  """A block with a handle and a nail on a slide joint."""

  def _build(self, name: str = 'nail_board',
             block_half_size: Sequence[float] = BLOCK_HALF_SIZE,
             nail_x: float = NAIL_X):
    """Builds the block, its handle and the nail.

    Args:
      name: the MJCF model's and the body's name.
      block_half_size: half extents (m) of the block (at least the nail's
        length thick).
      nail_x: the nail's distance (m) from the block's centre along +x
        (hammering/robot_hammers uses a longer plank).

    Raises:
      ValueError: half sizes that are not 3 positive lengths, a block
        thinner than the nail, or a nail off the block.
    """
    block_half_size = np.asarray(block_half_size, float)
    if (block_half_size.shape != (3,) or not np.all(block_half_size > 0)
        or 2 * block_half_size[2] < NAIL_LENGTH
        or not abs(nail_x) + NAIL_HEAD_RADIUS <= block_half_size[0]):
      raise ValueError(
          f'NailBoard needs 3 positive half sizes, at least {NAIL_LENGTH / 2} '
          f'm half thick, with the nail (x = {nail_x!r} m) on the block; got '
          f'{block_half_size.tolist()}')
    body = self._build_root(name)
    root = self._mjcf_root
    wood = root.asset.add('material', name='pine', rgba=(0.86, 0.72, 0.5, 1),
                          specular=0.1)
    steel = root.asset.add('material', name='steel',
                           rgba=(0.6, 0.61, 0.64, 1), specular=0.8,
                           shininess=0.8)
    half_x, _, half_z = block_half_size
    self._block = self._add_collision_geom(
        name='block', type='box', size=block_half_size, material=wood,
        mass=props.WOOD_DENSITY * 8 * np.prod(block_half_size))
    handle_x = -half_x + HANDLE_INSET + HANDLE_HALF_SIZE[0]
    handle_top = half_z + 2 * HANDLE_HALF_SIZE[2]
    self._handle = self._add_collision_geom(
        name='handle', type='box', size=HANDLE_HALF_SIZE,
        pos=(handle_x, 0, half_z + HANDLE_HALF_SIZE[2]), material=wood,
        mass=props.WOOD_DENSITY * 8 * np.prod(HANDLE_HALF_SIZE))
    self._grip_site = body.add(
        'site', name='grip_site', size=(0.005,),
        pos=(handle_x, 0, handle_top - props.HANDLE_GRIP_DEPTH),
        xyaxes=props.TOP_GRASP_CLOSING_X, group=4)

    # The nail body's origin is the top of its head; the joint's axis points
    # into the wood, so its position is the depth driven since the start.
    head_top = half_z + NAIL_TRAVEL + 2 * NAIL_HEAD_HALF_THICKNESS
    self._nail = body.add('body', name='nail', pos=(nail_x, 0, head_top),
                          gravcomp=1)
    self._joint = self._nail.add(
        'joint', name='insertion', type='slide', axis=(0, 0, -1),
        limited=True, range=(0.0, NAIL_TRAVEL), frictionloss=NAIL_FRICTION,
        solimpfriction=NAIL_SOLIMP_FRICTION, armature=NAIL_ARMATURE)
    shank_half = (NAIL_LENGTH - 2 * NAIL_HEAD_HALF_THICKNESS) / 2
    self._nail.add(
        'geom', name='shank', type='cylinder',
        size=(NAIL_SHANK_RADIUS, shank_half),
        pos=(0, 0, -2 * NAIL_HEAD_HALF_THICKNESS - shank_half),
        material=steel, contype=0, conaffinity=0,
        mass=STEEL_DENSITY * np.pi * NAIL_SHANK_RADIUS ** 2 * 2 * shank_half)
    # Only the head collides. It is thin, but a hammer face (much wider
    # than the head) pressing into it is pushed back along the nail's axis
    # for penetrations up to about the face's radius; its own stiff contact
    # parameters take precedence (priority) in every contact.
    self._head = self._add_collision_geom(
        parent=self._nail, name='head', type='cylinder',
        size=(NAIL_HEAD_RADIUS, NAIL_HEAD_HALF_THICKNESS),
        pos=(0, 0, -NAIL_HEAD_HALF_THICKNESS), material=steel,
        mass=STEEL_DENSITY * np.pi * NAIL_HEAD_RADIUS ** 2
        * 2 * NAIL_HEAD_HALF_THICKNESS,
        priority=1, solref=props.STRIKE_SOLREF, solimp=props.STRIKE_SOLIMP)
    self._nail_head_site = self._nail.add('site', name='nail_head_site',
                                          size=(0.004,), group=4)
    self._qpos_cache = None

  def _build_observables(self):
    return NailBoardObservables(self)

  @property
  def block(self) -> mjcf.Element:
    """The block's box geom."""
    return self._block

  @property
  def handle(self) -> mjcf.Element:
    """The handle's box geom."""
    return self._handle

  @property
  def nail(self) -> mjcf.Element:
    """The nail's body."""
    return self._nail

  @property
  def nail_head(self) -> mjcf.Element:
    """The nail head's geom (the nail's only collision geom)."""
    return self._head

  @property
  def nail_joint(self) -> mjcf.Element:
    """The nail's slide joint: its position is the depth driven."""
    return self._joint

  @property
  def grip_site(self) -> mjcf.Element:
    """TCP frame of a top grasp on the handle, fingers closing along x."""
    return self._grip_site

  @property
  def nail_head_site(self) -> mjcf.Element:
    """The top centre of the nail head."""
    return self._nail_head_site

  def _qpos_address(self, physics):
    if self._qpos_cache is None or self._qpos_cache[0] is not physics:
      self._qpos_cache = (physics,
                          int(physics.bind(self._joint).qposadr))
    return self._qpos_cache[1]

  def depth(self, physics: mjcf.Physics) -> float:
    """Depth the nail has been driven since the start.

    Args:
      physics: the physics.

    Returns:
      The depth, m.
    """
    return float(physics.data.qpos[self._qpos_address(physics)])

  def progress(self, physics: mjcf.Physics) -> float:
    """How far the nail is in.

    Args:
      physics: the physics.

    Returns:
      In [0, 1]: 0 as started, 1 with the head on the wood.
    """
    return min(max(self.depth(physics) / NAIL_TRAVEL, 0.0), 1.0)

  def set_progress(self, physics: mjcf.Physics, progress: float) -> None:
    """Puts the nail at `progress`, at rest.

    Args:
      physics: the physics.
      progress: in [0, 1] (`progress`).

    Raises:
      ValueError: a progress outside [0, 1].
    """
    progress = float(progress)
    if not 0.0 <= progress <= 1.0:
      raise ValueError(f'Nail progress must be in [0, 1], got {progress}')
    binding = physics.bind(self._joint)
    binding.qpos = progress * NAIL_TRAVEL
    binding.qvel = 0.0


class NailBoardObservables(props.PropObservables):
  """Adds the nail's progress and its head's world position."""

  @composer.observable
  def nail_progress(self) -> observable.Generic:
    """The nail's progress (1,)."""
    return observable.Generic(
        lambda physics: np.array([self._entity.progress(physics)]))

  @composer.observable
  def nail_head_position(self) -> observable.MJCFFeature:
    """The nail head site's world position (3,)."""
    return observable.MJCFFeature('xpos', self._entity.nail_head_site)
