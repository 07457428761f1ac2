"""Visual-only goal markers and the "object at target" check.

A `TargetMarker` is a sphere (or flat disc) drawn as a site on a body
without joints or geoms, so it has no collision and no mass effect. Every
task's goal marker is one. Attach it with `arena.attach(marker)` (fixed;
move it with `marker.set_pose(physics, position)`, which edits the model)
or with `marker.attach_mocap(arena)` (a mocap frame: its position is
physics state, so snapshots carry it; move it with
`marker.set_mocap_position`). Attached to a moving body's frame it follows
that body.
"""

import numbers
from typing import Any, Sequence

from dm_control import composer
from dm_control import mjcf
from dm_control.composer.observation import observable
import numpy as np

MARKER_RADIUS = 0.02                     # m
MARKER_RGBA = (0.1, 0.85, 0.2, 0.45)     # translucent green.
DISC_HALF_THICKNESS = 0.001              # m
SHAPES = ('sphere', 'disc')
MARKER_GROUP = 0                         # visible by default.


class TargetMarker(composer.Entity):
  """A translucent sphere or disc marking a goal; it touches nothing."""

  def _build(self, radius: float = MARKER_RADIUS,
             rgba: Sequence[float] = MARKER_RGBA, shape: str = 'sphere',
             name: str = 'target',
             half_thickness: float = DISC_HALF_THICKNESS,
             offset: Sequence[float] = (0.0, 0.0, 0.0)):
    """Builds the marker's body and site.

    Args:
      radius: of the sphere or disc, m, > 0.
      rgba: 4 values in [0, 1].
      shape: 'sphere' or 'disc'.
      name: the MJCF model's and the body's name.
      half_thickness: the disc's, m, > 0.
      offset: (3,) the site's position in the marker's frame, m.

    Raises:
      ValueError: a radius or half_thickness that is not a positive finite
        number, an unknown shape, bad rgba, or an offset that is not a
        finite 3-vector.
    """
    self._radius = _positive(radius, 'radius')
    half_thickness = _positive(half_thickness, 'half_thickness')
    if shape not in SHAPES:
      raise ValueError(f'Unknown marker shape {shape!r}: expected one of '
                       f'{", ".join(SHAPES)}')
    rgba = np.asarray(rgba, dtype=float)
    if rgba.shape != (4,) or np.any((rgba < 0) | (rgba > 1)):
      raise ValueError(f'rgba must be 4 values in [0, 1], got {rgba.tolist()}')
    site_position = _finite_point(offset)
    if site_position is None:
      raise ValueError(f'Marker offset must be a finite 3-vector, got '
                       f'{offset!r}')
    self._mjcf_root = mjcf.RootElement(model=name)
    self._body = self._mjcf_root.worldbody.add('body', name=name)
    if shape == 'sphere':
      kind, size = 'sphere', (self._radius,)
    else:
      kind, size = 'cylinder', (self._radius, half_thickness)
    # A site: drawn, but never collides and has no mass.
    self._site = self._body.add('site', name='site', type=kind, size=size,
                                rgba=rgba, group=MARKER_GROUP,
                                pos=site_position)
    self._mocap_frame = None

  def _build_observables(self):
    return TargetMarkerObservables(self)

  @property
  def mjcf_model(self) -> mjcf.RootElement:
    """The marker's MJCF model."""
    return self._mjcf_root

  @property
  def radius(self) -> float:
    """The sphere's or disc's radius, m."""
    return self._radius

  @property
  def body(self) -> mjcf.Element:
    """The marker's body (no joints, no geoms)."""
    return self._body

  @property
  def site(self) -> mjcf.Element:
    """The marker's visual site; its origin is the goal."""
    return self._site

  def position(self, physics: mjcf.Physics) -> np.ndarray:
    """The site's world position, the goal.

    Args:
      physics: the physics.

    Returns:
      (3,) a copy.
    """
    return physics.bind(self._site).xpos.copy()

  def attach_mocap(self, arena: composer.Entity) -> mjcf.Element:
    """Attaches the marker to `arena` on a mocap frame.

    Args:
      arena: the arena (e.g. the workcell).

    Returns:
      The mocap attachment frame.
    """
    frame = arena.attach(self)
    frame.mocap = 'true'
    self._mocap_frame = frame
    return frame

  def _mocap(self, physics):
    if self._mocap_frame is None:
      raise ValueError(f'Marker {self._mjcf_root.model!r} has no mocap '
                       'frame: attach it with attach_mocap(arena)')
    return physics.bind(self._mocap_frame)

  def set_mocap_position(self, physics: mjcf.Physics,
                         position: Sequence[float]) -> None:
    """Moves the mocap frame (the site follows at `offset`).

    Args:
      physics: the physics.
      position: (3,) world position.

    Raises:
      ValueError: a marker not attached with `attach_mocap`.
    """
    self._mocap(physics).mocap_pos = position

  def mocap_position(self, physics: mjcf.Physics) -> np.ndarray:
    """World position of the mocap frame, the marker's goal.

    Args:
      physics: the physics.

    Returns:
      (3,) a copy.

    Raises:
      ValueError: a marker not attached with `attach_mocap`.
    """
    return self._mocap(physics).mocap_pos.copy()


def _positive(value, what):
  if not isinstance(value, numbers.Real) or not np.isfinite(value) or value <= 0:
    raise ValueError(f'Marker {what} must be a positive finite number, got '
                     f'{value!r}')
  return float(value)


def _finite_point(value):
  """`value` as a float (3,) array, or None if not a finite 3-vector."""
  point = np.asarray(value, dtype=float)
  return point if point.shape == (3,) and np.all(np.isfinite(point)) else None


class TargetMarkerObservables(composer.Observables):
  """World position of the marker's centre."""

  @composer.observable
  def position(self) -> observable.MJCFFeature:
    """The site's world position (3,)."""
    return observable.MJCFFeature('xpos', self._entity.site)


def position_of(physics: mjcf.Physics, thing: Any) -> np.ndarray:
  """World position of a prop or marker, an MJCF element, or a 3-vector.

  Args:
    physics: the physics.
    thing: a TargetMarker (its site), an entity with a `body` (a prop), an
      MJCF body, site or geom, or a finite 3-vector (itself).

  Returns:
    (3,) the position (the binding's array for entities and elements).

  Raises:
    ValueError: an element of another kind, or anything else.
  """
  if isinstance(thing, TargetMarker):
    return physics.bind(thing.site).xpos
  body = getattr(thing, 'body', None)
  if isinstance(thing, composer.Entity) and body is not None:
    return physics.bind(body).xpos
  if isinstance(thing, mjcf.Element):
    if thing.tag not in ('body', 'site', 'geom'):
      raise ValueError(f'Cannot take the position of a <{thing.tag}> element '
                       f'{thing.full_identifier!r}: expected a body, site or '
                       'geom')
    return physics.bind(thing).xpos
  position = _finite_point(thing)
  if position is None:
    raise ValueError(f'Expected a prop, marker, MJCF body/site/geom or a '
                     f'finite 3-vector, got {thing!r}')
  return position


def distance_to_target(physics: mjcf.Physics, obj: Any, target: Any
                       ) -> float:
  """Euclidean distance between `obj` and `target`.

  Args:
    physics: the physics.
    obj: anything `position_of` takes.
    target: anything `position_of` takes.

  Returns:
    The distance, m.
  """
  delta = position_of(physics, obj) - position_of(physics, target)
  return float(np.sqrt(delta @ delta))


def is_within(physics: mjcf.Physics, obj: Any, target: Any,
              distance: float) -> bool:
  """Whether `obj` is within `distance` of `target`.

  Args:
    physics: the physics.
    obj: anything `position_of` takes.
    target: anything `position_of` takes.
    distance: m, >= 0.

  Returns:
    Whether their distance is at most `distance`.

  Raises:
    ValueError: a negative (or NaN) distance.
  """
  if not distance >= 0:
    raise ValueError(f'distance must be non-negative, got {distance!r}')
  return distance_to_target(physics, obj, target) <= distance
