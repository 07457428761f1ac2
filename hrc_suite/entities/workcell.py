"""The workcell arena: floor, table, the robot's pedestal, lights, cameras.

Coordinates come from `hrc_suite.layout`. The physics timestep is set here
(4 ms, the reference benchmark's control cycle), so every task built on the
workcell runs the shield and the controller at 250 Hz.
"""

from typing import Sequence, Tuple

import numpy as np
from dm_control import composer
from dm_control import mjcf

from hrc_suite import layout
from hrc_suite.entities import collision_groups
from hrc_suite.entities import robot as robot_lib

PHYSICS_TIMESTEP = 0.004   # s; the shield/controller cycle of the reference.
FLOOR_HALF_SIZE = 4.0      # m
TABLE_LEG_HALF_SIZE = 0.03  # m, square legs.
TABLE_LEG_INSET = 0.06     # m from the table's corners.
HUMAN_EYE_HEIGHT = 1.6     # m, adult standing eye height (about 1.5-1.7 m).

# Cameras: (position, point looked at); all frame the robot and the table.
_CAMERAS = {
    'front': ((2.25, -0.95, 1.75), (0.45, 0.0, 0.95)),
    'side': ((0.55, -2.5, 1.55), (0.55, 0.0, 1.0)),
    'top': ((0.55, 0.0, 3.4), (0.55, 0.0, layout.TABLE_TOP_Z)),
    'human_view': ((layout.HUMAN_STATION_ACROSS[0],
                    layout.HUMAN_STATION_ACROSS[1], HUMAN_EYE_HEIGHT),
                   (0.15, 0.0, 1.0)),
}


def look_at_xyaxes(position: Sequence[float], target: Sequence[float]
                   ) -> np.ndarray:
  """MJCF camera `xyaxes` looking from `position` at `target`, z up.

  Args:
    position: (3,) the camera's world position.
    target: (3,) the world point it looks at.

  Returns:
    (6,) the image's x (right) and y (up) axes in the world.
  """
  forward = np.asarray(target, float) - np.asarray(position, float)
  forward /= np.linalg.norm(forward)
  up = np.array([0.0, 0.0, 1.0])
  if abs(forward @ up) > 0.999:   # Looking straight down: +x is image up.
    up = np.array([1.0, 0.0, 0.0])
  right = np.cross(forward, up)
  right /= np.linalg.norm(right)
  return np.concatenate([right, np.cross(right, forward)])


class Workcell(composer.Arena):
  """A table with the robot's pedestal at its near edge."""

  def _build(self, name: str = 'workcell',
             table: layout.Table = layout.DEFAULT_TABLE):
    """Builds the floor, the table, the pedestal, lights and cameras.

    Args:
      name: the MJCF model's name.
      table: the task's table.

    Raises:
      TypeError: a table that is not a layout.Table.
    """
    if not isinstance(table, layout.Table):
      raise TypeError(f'table must be a layout.Table, got {table!r}')
    super()._build(name=name)
    self._table_extent = table
    root = self._mjcf_root
    root.option.timestep = PHYSICS_TIMESTEP
    root.visual.quality.shadowsize = 2048
    root.visual.headlight.ambient = (0.25, 0.25, 0.25)
    root.visual.headlight.diffuse = (0.35, 0.35, 0.35)
    getattr(root.visual, 'global').offwidth = 1280
    getattr(root.visual, 'global').offheight = 960

    root.asset.add('texture', name='skybox', type='skybox', builtin='gradient',
                   rgb1=(0.62, 0.72, 0.82), rgb2=(0.12, 0.14, 0.18),
                   width=512, height=512)
    floor_texture = root.asset.add(
        'texture', name='floor', type='2d', builtin='checker',
        rgb1=(0.33, 0.35, 0.38), rgb2=(0.28, 0.3, 0.33), width=512,
        height=512, mark='edge', markrgb=(0.45, 0.47, 0.5))
    floor_material = root.asset.add('material', name='floor',
                                    texture=floor_texture, texrepeat=(8, 8),
                                    reflectance=0.1)
    wood_texture = root.asset.add(
        'texture', name='wood', type='2d', builtin='flat',
        rgb1=(0.66, 0.52, 0.36), rgb2=(0.6, 0.46, 0.3), width=256, height=256,
        mark='random', random=0.08, markrgb=(0.56, 0.42, 0.28))
    wood = root.asset.add('material', name='wood', texture=wood_texture,
                          texrepeat=(4, 4), specular=0.2, shininess=0.2)
    steel = root.asset.add('material', name='steel',
                           rgba=(0.42, 0.44, 0.47, 1), specular=0.6,
                           shininess=0.5)

    worldbody = root.worldbody
    worldbody.add('light', name='key', pos=(0.6, -1.2, 3.2),
                  dir=(-0.05, 0.35, -1.0), diffuse=(0.65, 0.65, 0.62),
                  specular=(0.2, 0.2, 0.2), castshadow=True, directional=False,
                  cutoff=60, exponent=2)
    worldbody.add('light', name='fill', pos=(2.0, 1.5, 2.8),
                  dir=(-0.5, -0.4, -1.0), diffuse=(0.3, 0.3, 0.32),
                  specular=(0.05, 0.05, 0.05), castshadow=False,
                  directional=True)

    self._floor = worldbody.add(
        'geom', name='floor', type='plane',
        size=(FLOOR_HALF_SIZE, FLOOR_HALF_SIZE, 0.1), material=floor_material)

    top_z = layout.TABLE_TOP_Z
    half_thickness = layout.TABLE_THICKNESS / 2
    x0, x1 = table.x
    y0, y1 = table.y
    self._table_top = worldbody.add(
        'geom', name='table_top', type='box',
        size=((x1 - x0) / 2, (y1 - y0) / 2, half_thickness),
        pos=((x0 + x1) / 2, (y0 + y1) / 2, top_z - half_thickness),
        material=wood)
    leg_half_height = (top_z - layout.TABLE_THICKNESS) / 2
    legs = []
    for x in (x0 + TABLE_LEG_INSET, x1 - TABLE_LEG_INSET):
      for y in (y0 + TABLE_LEG_INSET, y1 - TABLE_LEG_INSET):
        legs.append(worldbody.add(
            'geom', name=f'table_leg_{len(legs)}', type='box',
            size=(TABLE_LEG_HALF_SIZE, TABLE_LEG_HALF_SIZE, leg_half_height),
            pos=(x, y, leg_half_height), material=steel))
    self._table_legs = tuple(legs)

    self._pedestal = worldbody.add('geom', name='pedestal', type='box',
                                   material=steel)
    self._set_pedestal(layout.DEFAULT_MOUNT)   # attach_robot resizes it.

    self._static_geoms = (self._floor, self._table_top, *self._table_legs,
                          self._pedestal)
    for geom in self._static_geoms:
      collision_groups.set_static(geom)

    self._cameras = {}
    for camera_name, (position, target) in _CAMERAS.items():
      self._cameras[camera_name] = worldbody.add(
          'camera', name=camera_name, mode='fixed', pos=position,
          xyaxes=look_at_xyaxes(position, target), fovy=50)

  @property
  def floor(self) -> mjcf.Element:
    """The floor plane geom."""
    return self._floor

  @property
  def table(self) -> mjcf.Element:
    """The table top geom (its top face is at layout.TABLE_TOP_Z)."""
    return self._table_top

  @property
  def table_extent(self) -> layout.Table:
    """The table's extent (layout.Table)."""
    return self._table_extent

  @property
  def table_legs(self) -> Tuple[mjcf.Element, ...]:
    """The four table leg geoms."""
    return self._table_legs

  @property
  def pedestal(self) -> mjcf.Element:
    """The robot's pedestal geom, sized to the robot's mount."""
    return self._pedestal

  @property
  def static_geoms(self) -> Tuple[mjcf.Element, ...]:
    """Floor, table top and legs, pedestal: everything that never moves."""
    return self._static_geoms

  @property
  def cameras(self) -> Tuple[mjcf.Element, ...]:
    """The fixed cameras: 'front', 'side', 'top', 'human_view'."""
    return tuple(self._cameras.values())

  def attach_robot(self, robot: robot_lib.Robot) -> mjcf.Element:
    """Attaches the robot with its base frame at its mount
    (layout.robot_mount), facing +x, and sizes the pedestal to the mount.

    Args:
      robot: the robot arm.

    Returns:
      The attachment frame.
    """
    mount = layout.robot_mount(robot.description.name)
    self._set_pedestal(mount)
    frame = self.attach(robot)
    frame.pos = mount.base_position
    frame.quat = (1.0, 0.0, 0.0, 0.0)
    return frame

  def _set_pedestal(self, mount):
    height = mount.base_position[2]
    self._pedestal.size = (*mount.pedestal_half_size, height / 2)
    self._pedestal.pos = (*mount.pedestal_center_xy, height / 2)
