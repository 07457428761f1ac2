"""The human's body segments and their capsule frames from keypoints.

Each segment of `SEGMENTS` (keypoints.SEGMENTS plus the pelvis between
the hips) is a capsule between two keypoints. `segment_frames` computes the
capsules' frames from keypoint positions: the NumPy reference that
`Human.set_keypoints`, the task's playback (entities/human_playback.py) and
the compiled frames (entities/human_kernels.py) follow.
"""

from typing import Tuple

import numpy as np

from hrc_suite import rotations
from hrc_suite.human import keypoints

# (name, proximal keypoint, distal keypoint) of every capsule.
SEGMENTS = keypoints.SEGMENTS + (('pelvis', 'left_hip', 'right_hip'),)

_NEXT = np.array([1, 2, 0])
_PREV = np.array([2, 0, 1])


def _row_dots(x, y):
  """Row-wise dot products of (N, 3) arrays, summed in a fixed order
  (terms 0 + 2, then 1): the order np.einsum('ij,ij->i') took on this
  machine, written out so that the compiled frames (human_kernels) match
  on any machine."""
  products = x * y
  return (products[:, 0] + products[:, 2]) + products[:, 1]


def segment_frames(positions: np.ndarray, proximal: np.ndarray,
                   distal: np.ndarray, reference: np.ndarray
                   ) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
  """Midpoints, half lengths and quaternions of segments.

  The frame's z axis runs along the segment; x is `reference` made
  orthogonal to it (or, where the two are nearly parallel, the horizontal
  perpendicular of z), so frames change continuously with the keypoints.

  Args:
    positions: (K, 3) keypoint positions.
    proximal: (S,) row of each segment's first keypoint in `positions`.
    distal: (S,) row of each segment's second keypoint.
    reference: (S, 3) the line each segment's x axis follows.

  Returns:
    (midpoints (S, 3), half lengths (S,), quaternions (S, 4), w first).
  """
  a = positions[proximal]
  b = positions[distal]
  axis = b - a
  length = np.sqrt(_row_dots(axis, axis))
  z = axis / np.maximum(length, 1e-9)[:, None]
  x = reference - _row_dots(reference, z)[:, None] * z
  norm = np.sqrt(_row_dots(x, x))
  weak = norm < 0.2
  if weak.any():
    fallback = np.stack([-z[weak, 1], z[weak, 0], np.zeros(weak.sum())], -1)
    fallback[np.abs(fallback).sum(-1) < 1e-6] = (1.0, 0.0, 0.0)
    x[weak] = fallback
    norm[weak] = np.sqrt(_row_dots(fallback, fallback))
  x /= norm[:, None]
  y = z[:, _NEXT] * x[:, _PREV] - z[:, _PREV] * x[:, _NEXT]   # z cross x
  return 0.5 * (a + b), 0.5 * length, rotations.axes_to_quat(x, y, z)
