"""Rotation maths, written once for the whole package.

Conventions: quaternions are MuJoCo's (w, x, y, z); rotation matrices are
row-major 3x3 arrays whose columns are the rotated frame's axes in the
outer frame (MuJoCo's xmat reshaped to (3, 3)); angles are in radians.
Functions take one rotation or a batch (leading axes) where they say so.

Compiled kernels that need scalar code of their own name the function here
that they compute (entities/human_kernels.py,
tasks/runtime/tool_hold_kernels.py, control/ik_kernels.py);
tests/test_rotations.py checks that they agree.
"""

import math

import mujoco
import numpy as np

X, Y, Z = 0, 1, 2   # coordinate axes, for `about_axis`
IDENTITY_QUAT = np.array([1.0, 0.0, 0.0, 0.0])
# Quaternion magnitudes from a rotation's diagonal: 4 |q_i|^2 = 1 + C diag.
_DIAGONAL_SIGNS = np.array([[1.0, 1.0, 1.0], [1.0, -1.0, -1.0],
                            [-1.0, 1.0, -1.0], [-1.0, -1.0, 1.0]])
# mju_quat2Vel's time step: a rotation vector is the velocity over 1 s.
_UNIT_TIME = 1.0
# Near-parallel quaternions interpolate linearly (`slerp`).
_SLERP_LINEAR = 0.9995


def _array(value, name, shape):
  """`value` as a float array whose trailing shape is `shape`, else a
  ValueError naming `name`."""
  try:
    array = np.asarray(value, dtype=float)
  except (TypeError, ValueError) as e:
    raise ValueError(f'{name}: expected numbers of shape (..., '
                     f'{", ".join(map(str, shape))}), got {value!r:.80}') from e
  if array.shape[array.ndim - len(shape):] != shape or array.ndim < len(
      shape) or not np.isfinite(array).all():
    raise ValueError(f'{name}: expected finite numbers of shape (..., '
                     f'{", ".join(map(str, shape))}), got shape '
                     f'{array.shape}: {value!r:.80}')
  return array


def _quat(value, name):
  """One quaternion (4,) as floats, else a ValueError naming `name`."""
  quat = _array(value, name, (4,))
  if quat.shape != (4,):
    raise ValueError(f'{name}: expected one quaternion (4,), got shape '
                     f'{quat.shape}')
  return quat


def _nonzero(quat, name):
  """|quat| over the last axis, each as np.linalg.norm of one row (a
  dot product: stacked np.matmul, as human.row_norms); zeros raise."""
  norm = np.sqrt(np.matmul(quat[..., None, :], quat[..., :, None])[..., 0, 0])
  if (norm == 0.0).any():
    raise ValueError(f'{name}: expected non-zero quaternions, got {quat!r}')
  return norm


def quat_to_mat(quat):
  """Rotation matrices (..., 3, 3) of quaternions (..., 4), normalised
  first."""
  q = _array(quat, 'quat', (4,))
  w, x, y, z = np.moveaxis(q / _nonzero(q, 'quat')[..., None], -1, 0)
  return np.stack([
      np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z),
                2 * (x * z + w * y)], -1),
      np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z),
                2 * (y * z - w * x)], -1),
      np.stack([2 * (x * z - w * y), 2 * (y * z + w * x),
                1 - 2 * (x * x + y * y)], -1)], -2)


def mat_to_quat(matrix):
  """Unit quaternions (..., 4) of rotation matrices (..., 3, 3): MuJoCo's
  mju_mat2Quat (exact near half turns; the sign follows its branch)."""
  m = _array(matrix, 'matrix', (3, 3))
  flat = m.reshape(-1, 9)
  out = np.empty((len(flat), 4))
  for k, row in enumerate(flat):
    mujoco.mju_mat2Quat(out[k], np.ascontiguousarray(row))
  return out.reshape(m.shape[:-2] + (4,))


def axes_to_quat(x, y, z):
  """Unit quaternions (..., 4) of the frames with columns x, y, z (each
  (..., 3)), branch-free: magnitudes from the diagonal, signs from the
  antisymmetric part, so w >= 0 and the result moves continuously with
  the frame; exact to ~1e-8 for unit frames (mat_to_quat is exact). For
  many frames at once (the person's capsules)."""
  x, y, z = (_array(v, name, (3,)) for v, name in ((x, 'x'), (y, 'y'),
                                                   (z, 'z')))
  batch = np.broadcast_shapes(x.shape, y.shape, z.shape)[:-1]
  x, y, z = (np.broadcast_to(v, batch + (3,)).reshape(-1, 3)
             for v in (x, y, z))
  diagonal = np.column_stack([x[:, 0], y[:, 1], z[:, 2]])
  # diagonal @ _DIAGONAL_SIGNS.T, summed in order (no BLAS order).
  signed = diagonal[:, None, :] * _DIAGONAL_SIGNS[None]
  q = 0.5 * np.sqrt(np.maximum(
      0.0, 1.0 + ((signed[..., 0] + signed[..., 1]) + signed[..., 2])))
  antisymmetric = np.column_stack([y[:, 2] - z[:, 1],    # m21 - m12
                                   z[:, 0] - x[:, 2],    # m02 - m20
                                   x[:, 1] - y[:, 0]])   # m10 - m01
  np.copysign(q[:, 1:], antisymmetric, out=q[:, 1:])
  # |q|^2 summed (0 + 2) + (1 + 3), the order human_kernels repeats.
  squares = q * q
  norm = np.sqrt((squares[:, 0] + squares[:, 2])
                 + (squares[:, 1] + squares[:, 3]))
  return (q / norm[:, None]).reshape(batch + (4,))


def xyaxes_to_mat(xyaxes):
  """Rotation matrix of an MJCF `xyaxes` frame (x, then y made
  orthogonal to it, z = x cross y)."""
  values = _array(xyaxes, 'xyaxes', (6,))
  x, y = values[:3].copy(), values[3:].copy()
  x /= np.linalg.norm(x)
  y -= x * (x @ y)
  y /= np.linalg.norm(y)
  return np.stack([x, y, np.cross(x, y)], axis=1)


def quat_mul(a, b):
  """The quaternion product a b (rotate by b, then by a): mju_mulQuat."""
  out = np.empty(4)
  mujoco.mju_mulQuat(out, _quat(a, 'a'), _quat(b, 'b'))
  return out


def quat_conj(quat):
  """The conjugate (inverse of a unit quaternion): mju_negQuat."""
  out = np.empty(4)
  mujoco.mju_negQuat(out, _quat(quat, 'quat'))
  return out


def quat_to_rotvec(quat):
  """Rotation vector (3,) (axis times angle in [0, pi]) of a unit
  quaternion: mju_quat2Vel over unit time."""
  out = np.empty(3)
  mujoco.mju_quat2Vel(out, _quat(quat, 'quat'), _UNIT_TIME)
  return out


def slerp(q0, q1, t):
  """Spherical interpolation from unit quaternion q0 (t = 0) to q1 (t = 1)
  along the shorter arc."""
  q0, q1 = _quat(q0, 'q0'), _quat(q1, 'q1')
  dot = float(q0 @ q1)
  if dot < 0.0:
    q1, dot = -q1, -dot
  if dot > _SLERP_LINEAR:
    q = q0 + t * (q1 - q0)
  else:
    angle = math.acos(dot)
    q = (math.sin((1 - t) * angle) * q0
         + math.sin(t * angle) * q1) / math.sin(angle)
  return q / np.linalg.norm(q)


def about_axis(axis, angle):
  """Rotation matrices (..., 3, 3) by angles (...) about coordinate axis
  `axis` (X, Y or Z); entries are exactly cos, sin, 0 and 1."""
  if axis not in (X, Y, Z):
    raise ValueError(f'axis: expected X, Y or Z (0, 1, 2), got {axis!r}')
  angle = _array(angle, 'angle', ())
  c, s = np.cos(angle), np.sin(angle)
  out = np.zeros(angle.shape + (3, 3))
  i, j = [(Y, Z), (Z, X), (X, Y)][axis]
  out[..., axis, axis] = 1.0
  out[..., i, i] = c
  out[..., j, j] = c
  out[..., i, j] = -s
  out[..., j, i] = s
  return out


def yaw_to_mat(yaw):
  """Rotation matrices (..., 3, 3) about the vertical (z) by yaws (...)."""
  return about_axis(Z, yaw)


def yaw_to_quat(yaw):
  """Unit quaternion (4,) of the rotation about z by `yaw`."""
  half = 0.5 * float(yaw)
  return np.array([np.cos(half), 0.0, 0.0, np.sin(half)])


def axis_angle_to_mat(axis, angle):
  """Rotation matrix by `angle` about the unit vector `axis` (Rodrigues'
  formula); a zero axis (no direction) gives the identity."""
  a = _array(axis, 'axis', (3,))
  norm = np.linalg.norm(a)
  if a.shape != (3,) or not (np.isclose(norm, 1.0) or norm == 0.0):
    raise ValueError(f'axis: expected a unit (or zero) 3-vector, got '
                     f'{axis!r}')
  k = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
  return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def wrap_angle(angle):
  """Angles wrapped into [-pi, pi)."""
  return (angle + np.pi) % (2 * np.pi) - np.pi


def mat_yaw(matrix):
  """Yaw (rad) of the x axes of rotations (..., 3, 3): the heading of
  their horizontal part."""
  m = _array(matrix, 'matrix', (3, 3))
  return np.arctan2(m[..., 1, 0], m[..., 0, 0])


def quat_yaw(quat):
  """Yaw (rad) of the x axis of the rotation of a quaternion (4,)."""
  return float(mat_yaw(quat_to_mat(quat)))


def nearest_rotation(matrix):
  """The rotation matrix closest (Frobenius) to a nearly orthonormal 3x3
  matrix (SVD; a reflection is turned into the nearest rotation)."""
  m = _array(matrix, 'matrix', (3, 3))
  if m.shape != (3, 3):
    raise ValueError(f'matrix: expected shape (3, 3), got {m.shape}')
  u, _, vt = np.linalg.svd(m)
  rotation = u @ vt
  if np.linalg.det(rotation) < 0:
    u[:, -1] *= -1
    rotation = u @ vt
  return rotation
