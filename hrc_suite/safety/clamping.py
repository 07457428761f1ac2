"""Which possible robot-human contacts are clamped (energy-based PFL).

ISO/TS 15066 lets a transient contact (the body part can move away)
transfer four times the energy of a clamped one (body_regions.py). The
shield decides per time slice, human model, robot capsule l and human body
capsule b whose reach capsules intersect (a possible contact;
docs/shield_maths.md, 9.1) whether the contact may be clamped
(docs/shield_maths.md, 9.4, "Clamping"):

  clamped  iff  the body's reach capsule grown by the body's thickness
                (its diameter) meets a static box, or the reach capsule of
                a robot capsule that can close on the body with l.

* Static boxes: the workcell's (table, pedestal, floor, a task's extra
  boxes: collision_prevention.workcell_boxes and the boxes collision
  prevention checks).
* Self-clamping: a capsule of another link, unless the robot description
  lists the two links as unclampable (`shield.unclampable_links`).
  Capsules on the same link (a link and the gripper on the last link)
  move rigidly together and cannot close on anything.
* The growth: the reach capsule contains the body part wherever the
  person can move it in the slice, but a link pressing on the part pushes
  it on; a surface within one body thickness of where the part can be
  counts, as the table under a hand that a link presses down onto it.

Conservative where it cannot tell: any box or link within that distance
counts, whatever the direction the link moves in, and a box is tested
against the axis-aligned bounding box of the grown capsule's segment (a
lower bound of the distance, exact for boxes the segment lies beside
along one axis, as the table below a body).

This module is the NumPy reference; `energy_check_kernels` makes the same
decisions with the same floating-point operations in the same order
(tests/safety/test_energy_verification.py). Its segment distance is
`kernels.segment_distance`'s, written coordinate by coordinate.
"""

import dataclasses
from typing import Mapping, Sequence, Tuple

import numpy as np

from hrc_suite.safety.geometry import _DEGENERATE_SQUARED_LENGTH
from hrc_suite.safety.geometry import _PARALLEL_SIN_SQUARED


@dataclasses.dataclass(frozen=True)
class ClampGeometry:
  """What a body part can be clamped against.

  Attributes:
    box_min: (X, 3) m, the static boxes' lower corners (world frame).
    box_max: (X, 3) m, their upper corners.
    clampable: (L, L) bool, robot capsules l, l' that can close on a body
      part together (symmetric, False on the diagonal).
  """
  box_min: np.ndarray
  box_max: np.ndarray
  clampable: np.ndarray


def clamp_geometry(description, frame_index: Sequence[int],
                   boxes=()) -> ClampGeometry:
  """The ClampGeometry of a robot's capsules and static boxes.

  Args:
    description: the robot's description (its `shield.unclampable_links`).
    frame_index: (L,) the link of each robot capsule
      (robot_reach.RobotReach.frame_index; the gripper's is the last link).
    boxes: the static boxes: a mapping name -> (min (3,), max (3,)) as
      collision_prevention.workcell_boxes, or a sequence of such pairs.

  Returns:
    The ClampGeometry.
  """
  frame_index = np.asarray(frame_index, dtype=int)
  if frame_index.ndim != 1 or ((frame_index < 0)
                               | (frame_index >= description.dof)).any():
    raise ValueError(f'frame_index={frame_index.tolist()}: expected link '
                     f'indices in [0, {description.dof})')
  pairs = list(boxes.values()) if isinstance(boxes, Mapping) else list(boxes)
  box_min = np.zeros((len(pairs), 3))
  box_max = np.zeros((len(pairs), 3))
  for i, pair in enumerate(pairs):
    try:
      low, high = (np.asarray(x, dtype=float) for x in pair)
    except (TypeError, ValueError):
      raise ValueError(f'boxes[{i}]={pair!r}: expected (min (3,), max '
                       f'(3,))') from None
    if low.shape != (3,) or high.shape != (3,) or not (low <= high).all():
      raise ValueError(f'boxes[{i}]={pair!r}: expected (min (3,), max (3,))'
                       f' with min <= max')
    box_min[i], box_max[i] = low, high
  unclampable = {frozenset(pair) for pair in
                 description.shield.unclampable_links}
  links = frame_index.tolist()
  clampable = np.array([[a != b and frozenset((a, b)) not in unclampable
                         for b in links] for a in links], dtype=bool)
  return ClampGeometry(box_min=box_min, box_max=box_max,
                       clampable=clampable)


def segment_distance(p, d, q, e):
  """Distance of segments p + s d and q + t e, s, t in [0, 1] (each
  argument a tuple of three coordinate arrays): kernels.segment_distance,
  operation for operation, broadcast over arrays."""
  p0, p1, p2 = p
  d0, d1, d2 = d
  q0, q1, q2 = q
  e0, e1, e2 = e
  a = d0 * d0 + d1 * d1 + d2 * d2
  ee = e0 * e0 + e1 * e1 + e2 * e2
  r0, r1, r2 = p0 - q0, p1 - q1, p2 - q2
  b = d0 * e0 + d1 * e1 + d2 * e2
  c = d0 * r0 + d1 * r1 + d2 * r2
  f = e0 * r0 + e1 * r1 + e2 * r2
  a_ok = a > _DEGENERATE_SQUARED_LENGTH
  e_ok = ee > _DEGENERATE_SQUARED_LENGTH
  denom = a * ee - b * b
  general = denom > _PARALLEL_SIN_SQUARED * a * ee
  with np.errstate(divide='ignore', invalid='ignore'):
    s = np.where(general, _clamp01((b * f - c * ee) / denom), 0.0)
    t = np.where(e_ok, (b * s + f) / ee, -1.0)
    t_clamped = _clamp01(t)
    s = np.where(a_ok, np.where(t != t_clamped,
                                _clamp01((b * t_clamped - c) / a), s), 0.0)
  r0 = (r0 + s * d0) - t_clamped * e0
  r1 = (r1 + s * d1) - t_clamped * e1
  r2 = (r2 + s * d2) - t_clamped * e2
  return np.sqrt(r0 * r0 + r1 * r1 + r2 * r2)


def _clamp01(x):
  return np.minimum(np.maximum(x, 0.0), 1.0)


def _coordinates(x):
  return x[..., 0], x[..., 1], x[..., 2]


def box_gap(start, end, box_min, box_max):
  """Lower bound (...) of the distance of segments [start, end] (..., 3)
  from the box [box_min, box_max] (3,): the distance of the segments'
  axis-aligned bounding boxes."""
  total = 0.0
  for i in range(3):
    low = np.minimum(start[..., i], end[..., i])
    high = np.maximum(start[..., i], end[..., i])
    gap = np.maximum(np.maximum(box_min[i] - high, low - box_max[i]), 0.0)
    total = total + gap * gap
  return np.sqrt(total)


def contacts_and_clamps(robot, human, thickness, geometry: ClampGeometry
                        ) -> Tuple[np.ndarray, np.ndarray]:
  """Possible contacts and which of them are clamped (see the module).

  Args:
    robot: reach capsules (c1 (K, L, 3), c2 (K, L, 3), r (K, L)).
    human: body reach capsules (c1 (M, K, B, 3), c2, r (M, K, B)).
    thickness: (B,) m, each body's thickness (diameter).
    geometry: the ClampGeometry of the robot's L capsules.

  Returns:
    contact (M, K, L, B) bool: the reach capsules intersect (signed
    distance < 0); clamped (M, K, L, B) bool: contact and clamped.
  """
  rc1, rc2, rr = (np.asarray(x, dtype=float) for x in robot)
  hc1, hc2, hr = (np.asarray(x, dtype=float) for x in human)
  thickness = np.asarray(thickness, dtype=float)
  if thickness.shape != hr.shape[2:]:
    raise ValueError(f'thickness: expected shape {hr.shape[2:]} (one per '
                     f'body), got {thickness.shape}')
  count_l = rr.shape[1]
  if geometry.clampable.shape != (count_l, count_l):
    raise ValueError(f'geometry.clampable: expected ({count_l}, {count_l})'
                     f' for {count_l} robot capsules, got '
                     f'{geometry.clampable.shape}')
  # Axes (M, K, L, B): robot capsules [None, :, :, None], bodies
  # [:, :, None, :].
  r_start = rc1[None, :, :, None]
  r_dir = (rc2 - rc1)[None, :, :, None]
  h_start = hc1[:, :, None]
  h_dir = (hc2 - hc1)[:, :, None]
  distance = segment_distance(_coordinates(r_start), _coordinates(r_dir),
                              _coordinates(h_start), _coordinates(h_dir))
  contact = (distance - rr[None, :, :, None]) - hr[:, :, None] < 0.0
  grown = hr + thickness                                         # (M, K, B)
  static = np.zeros(hr.shape, dtype=bool)
  for low, high in zip(geometry.box_min, geometry.box_max):
    static |= box_gap(hc1, hc2, low, high) - grown < 0.0
  # meets[m, k, l', b]: robot capsule l' meets body b grown.
  meets = (distance - rr[None, :, :, None]) - grown[:, :, None] < 0.0
  pinched = np.einsum('mklb,nl->mknb', meets.astype(np.int64),
                      geometry.clampable.astype(np.int64)) > 0
  clamped = contact & (static[:, :, None, :] | pinched)
  return contact, clamped
