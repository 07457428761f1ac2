"""Compiled (numba) capsule frames of the human's segments.

`segment_frames` computes what human.segment_frames (the NumPy reference)
computes, the same operations in the same order (its dot products in
human._row_dots' written-out order, the quaternion as
rotations.axes_to_quat sums it), so the two agree bit for bit
(tests/entities/test_human_kernels.py, tests/test_rotations.py);
`faster_than` is the task's check that no keypoint outran the shield's
human model (ShieldedStepper._faster_than_model), likewise. The task's playback
uses them on the fast path (entities/human_playback.py). Same
compilation settings as the shield's kernels (safety/kernels.py: cache,
IEEE arithmetic).
"""

import math

import numpy as np

from hrc_suite.safety import kernels

_jit = kernels._jit

# human.segment_frames: frames whose x axis is this short fall back to the
# horizontal perpendicular of z; fallbacks this short to (1, 0, 0).
_WEAK = 0.2
_DEGENERATE = 1e-6
_MIN_LENGTH = 1e-9


@_jit
def _dot3(x0, x1, x2, y0, y1, y2):
  """human._row_dots of one pair of 3-vectors (its order)."""
  return (x0 * y0 + x2 * y2) + x1 * y1


@_jit
def _quaternion(x, y, z, out):
  """rotations.axes_to_quat for one frame (columns x, y, z) into out."""
  d0, d1, d2 = x[0], y[1], z[2]
  # 1 + diagonal @ _DIAGONAL_SIGNS.T, row by row (signs +-1: exact).
  m0 = 0.5 * math.sqrt(max(0.0, 1.0 + (d0 + d1 + d2)))
  m1 = 0.5 * math.sqrt(max(0.0, 1.0 + (d0 - d1 - d2)))
  m2 = 0.5 * math.sqrt(max(0.0, 1.0 + (-d0 + d1 - d2)))
  m3 = 0.5 * math.sqrt(max(0.0, 1.0 + (-d0 - d1 + d2)))
  m1 = math.copysign(m1, y[2] - z[1])
  m2 = math.copysign(m2, z[0] - x[2])
  m3 = math.copysign(m3, x[1] - y[0])
  # rotations.axes_to_quat's order: (0 + 2) + (1 + 3).
  norm = math.sqrt((m0 * m0 + m2 * m2) + (m1 * m1 + m3 * m3))
  out[0] = m0 / norm
  out[1] = m1 / norm
  out[2] = m2 / norm
  out[3] = m3 / norm


@_jit
def segment_frames(positions, proximal, distal, reference, middles,
                   quaternions):
  """Midpoints (S, 3) and quaternions (S, 4) of segments from keypoints
  `positions` (K, 3), written into middles and quaternions; the segments'
  ends are positions[proximal], positions[distal], their x reference
  `reference` (S, 3) (human.segment_frames)."""
  x = np.empty(3)
  y = np.empty(3)
  z = np.empty(3)
  for s in range(proximal.shape[0]):
    a = positions[proximal[s]]
    b = positions[distal[s]]
    axis0, axis1, axis2 = b[0] - a[0], b[1] - a[1], b[2] - a[2]
    length = math.sqrt(_dot3(axis0, axis1, axis2, axis0, axis1, axis2))
    scale = max(length, _MIN_LENGTH)
    z[0], z[1], z[2] = axis0 / scale, axis1 / scale, axis2 / scale
    r = reference[s]
    along = _dot3(r[0], r[1], r[2], z[0], z[1], z[2])
    for i in range(3):
      x[i] = r[i] - along * z[i]
    norm = math.sqrt(_dot3(x[0], x[1], x[2], x[0], x[1], x[2]))
    if norm < _WEAK:
      x[0], x[1], x[2] = -z[1], z[0], 0.0
      if abs(x[0]) + abs(x[1]) + abs(x[2]) < _DEGENERATE:
        x[0], x[1], x[2] = 1.0, 0.0, 0.0
      norm = math.sqrt(_dot3(x[0], x[1], x[2], x[0], x[1], x[2]))
    for i in range(3):
      x[i] = x[i] / norm
    # z cross x, as human.segment_frames' index form.
    y[0] = z[1] * x[2] - z[2] * x[1]
    y[1] = z[2] * x[0] - z[0] * x[2]
    y[2] = z[0] * x[1] - z[1] * x[0]
    for i in range(3):
      middles[s, i] = 0.5 * (a[i] + b[i])
    _quaternion(x, y, z, quaternions[s])


@_jit
def playback_frames(positions, proximal, distal, left, right, reference,
                    middles, quaternions, mocap_rows):
  """human_playback's frames of an RL step: the reference lines
  reference[r] = positions[left[r]] - positions[right[r]] (rows with
  left[r] < 0 keep theirs), then `segment_frames` of all rows; if
  mocap_rows (L, S + K, 3) is not empty, each substep's middles (S) and
  keypoints (K) copied into its row."""
  for r in range(left.shape[0]):
    if left[r] >= 0:
      for c in range(3):
        reference[r, c] = positions[left[r], c] - positions[right[r], c]
  segment_frames(positions, proximal, distal, reference, middles,
                 quaternions)
  if mocap_rows.shape[0]:
    steps = mocap_rows.shape[0]
    count = middles.shape[0] // steps
    keypoints = positions.shape[0] // steps
    for k in range(steps):
      for s in range(count):
        for c in range(3):
          mocap_rows[k, s, c] = middles[k * count + s, c]
      for j in range(keypoints):
        for c in range(3):
          mocap_rows[k, count + j, c] = positions[k * keypoints + j, c]


@_jit
def faster_than(frames, dt, v_max):
  """Whether a keypoint moves faster than v_max (K,) m/s between
  consecutive frames (L, K, 3) dt seconds apart: the reference's
  np.linalg.norm(np.diff(frames, axis=0), axis=-1) / dt > v_max, its sums
  in its order (x, y, z)."""
  for k in range(1, frames.shape[0]):
    for j in range(frames.shape[1]):
      d0 = frames[k, j, 0] - frames[k - 1, j, 0]
      d1 = frames[k, j, 1] - frames[k - 1, j, 1]
      d2 = frames[k, j, 2] - frames[k - 1, j, 2]
      if math.sqrt((d0 * d0 + d1 * d1) + d2 * d2) / dt > v_max[j]:
        return True
  return False


def warm_up():
  """Compiles (or loads from the cache) the kernels for the argument types
  the task's playback uses, so that no episode step pays for it."""
  positions = np.zeros((2, 1, 3))
  ends = np.zeros(1, dtype=np.int64)
  segment_frames(positions.reshape(-1, 3), ends, ends, np.ones((1, 3)),
                 np.empty((1, 3)), np.empty((1, 4)))
  playback_frames(positions.reshape(-1, 3), ends, ends, ends, ends,
                  np.ones((1, 3)), np.empty((1, 3)), np.empty((1, 4)),
                  np.empty((0, 2, 3)))
  faster_than(positions, 1.0, np.ones(1))
