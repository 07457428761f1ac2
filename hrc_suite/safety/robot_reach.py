"""The robot's capsules, its reachable capsules over time slices, its speeds.

Link capsules come from the robot description (one per joint, in the frame
after the joint's rotation); an optional tool capsule (the gripper) is
appended in the last link's frame. Forward kinematics is batched over any
number of configurations: per joint one stacked 4x4 product, then one product
for all capsule end points.

Reachable capsule over an interval (docs/shield_maths.md, 5.2): a point
moving along a curve p(s) with ||d^2p/ds^2|| <= alpha stays within
alpha ds^2 / 8 of its chord, so the link stays inside the capsule between the
chord midpoints of its two end points with radius
  max(half chord) + alpha ds^2 / 8 + r + secure_radius.
"""

import numpy as np

from hrc_suite import layout
from hrc_suite import rotations
from hrc_suite.safety import kernels


def pose_matrix(pose):
  """4x4 pose from None (the default mount's robot base), a 4x4 matrix, or
  (x, y, z, roll, pitch, yaw) with R = Rz(yaw) Ry(pitch) Rx(roll)."""
  if pose is None:
    out = np.eye(4)
    out[:3, 3] = layout.ROBOT_BASE_POS
    return out
  pose = np.asarray(pose, dtype=float)
  if pose.shape == (4, 4):
    rotation = pose[:3, :3]
    if (not np.allclose(rotation @ rotation.T, np.eye(3), atol=1e-6)
        or np.linalg.det(rotation) <= 0 or
        not np.allclose(pose[3], [0, 0, 0, 1])):
      raise ValueError(f'base_pose: expected a rigid 4x4 transform, got '
                       f'{pose.tolist()}')
    return pose.copy()
  if pose.shape == (6,):
    x, y, z, roll, pitch, yaw = pose
    out = np.eye(4)
    out[:3, :3] = (rotations.about_axis(rotations.Z, yaw)
                   @ rotations.about_axis(rotations.Y, pitch)
                   @ rotations.about_axis(rotations.X, roll))
    out[:3, 3] = (x, y, z)
    return out
  raise ValueError(f'base_pose: expected None, a 4x4 matrix or (x, y, z, '
                   f'roll, pitch, yaw), got shape {pose.shape}')


def _check_tool_capsule(tool_capsule):
  try:
    p1, p2, radius = tool_capsule
    p1 = np.asarray(p1, dtype=float)
    p2 = np.asarray(p2, dtype=float)
    radius = float(radius)
  except (TypeError, ValueError):
    raise ValueError(f'tool_capsule: expected (p1 (3,), p2 (3,), radius), '
                     f'got {tool_capsule!r}') from None
  if p1.shape != (3,) or p2.shape != (3,) or not radius > 0:
    raise ValueError(f'tool_capsule: expected (p1 (3,), p2 (3,), radius > 0),'
                     f' got {tool_capsule!r}')
  return p1, p2, radius


class RobotReach:
  """Capsules of a robot (plus tool), batched FK, reachable capsules.

  Attributes:
    kernel_model: (rotations and translations of the fixed transforms, the
      base pose folded into the first (dof, 3, 4); homogeneous capsule end
      points (L, 2, 4)), the robot model as the compiled kernels
      (hrc_suite/safety/kernels.py) take it.
    kernel_frames: (L,) int64, the joint frame each capsule moves with.
    kernel_alpha: (L,) float64, alpha_i: the bound on ||d^2p/ds^2|| of
      each capsule's points (the module docstring).
    kernel_static: (L,) float64, capsule radius plus the secure radius.
    kernel_radii: (L,) float64, capsule radii.
    kernel_levers: (dof, L), joint_levers(): the end points' distances
      from each joint's axis origin.
    kernel_half_lengths: (L,) half the capsules' segment lengths.

  The kernel arrays are contiguous, built once, and read-only by
  convention: the compiled kernels and the shield's cycle constants share
  them.
  """

  def __init__(self, description, base_pose=None, tool_capsule=None,
               secure_radius=None, alpha=None):
    self.description = description
    self.dof = description.dof
    self.base_pose = (layout.robot_mount(description.name).base_pose()
                      if base_pose is None else pose_matrix(base_pose))
    self._fixed = description.fixed_transforms()          # (dof, 4, 4)
    p1, p2, radius = description.capsule_arrays()
    frame_index = list(range(self.dof))
    if tool_capsule is not None:
      t1, t2, tr = _check_tool_capsule(tool_capsule)
      p1 = np.vstack([p1, t1])
      p2 = np.vstack([p2, t2])
      radius = np.append(radius, tr)
      frame_index.append(self.dof - 1)
    self.has_tool = tool_capsule is not None
    self.num_capsules = len(radius)
    self.frame_index = np.array(frame_index)
    self.radii = radius
    # Homogeneous end points stacked as rows: (L, 2, 4).
    self._points = np.ones((self.num_capsules, 2, 4))
    self._points[:, 0, :3] = p1
    self._points[:, 1, :3] = p2
    rest, cos, sin = np.zeros((3, 4, 4))
    rest[2, 2] = rest[3, 3] = 1.0
    cos[0, 0] = cos[1, 1] = 1.0
    sin[1, 0], sin[0, 1] = 1.0, -1.0
    # The base pose is folded into the first fixed transform.
    fixed = self._fixed.copy()
    fixed[0] = self.base_pose @ fixed[0]
    self._fixed_rest = fixed @ rest
    self._fixed_cos = fixed @ cos
    self._fixed_sin = fixed @ sin
    self.secure_radius = float(description.shield.secure_radius
                               if secure_radius is None else secure_radius)
    if not self.secure_radius >= 0:
      raise ValueError(f'secure_radius: expected >= 0, got {secure_radius}')
    alpha = description.shield.alpha_i_max if alpha is None else alpha
    alpha = np.asarray(alpha, dtype=float)
    if alpha.ndim == 0:
      alpha = np.full(self.num_capsules, float(alpha))
    elif alpha.shape == (self.dof,) and self.has_tool:
      alpha = np.append(alpha, alpha[-1])  # The tool moves with the last link.
    if alpha.shape != (self.num_capsules,) or np.any(alpha < 0):
      raise ValueError(f'alpha: expected a non-negative scalar or '
                       f'{self.num_capsules} values, got {alpha.tolist()}')
    self.alpha = alpha
    self._static_radius = self.radii + self.secure_radius   # (L,)
    # The compiled kernels' arguments (the class docstring).
    self.kernel_model = (np.ascontiguousarray(fixed[:, :3]),
                         np.ascontiguousarray(self._points))
    self.kernel_frames = np.ascontiguousarray(self.frame_index,
                                              dtype=np.int64)
    self.kernel_alpha = np.ascontiguousarray(self.alpha, dtype=float)
    self.kernel_static = np.ascontiguousarray(self._static_radius,
                                              dtype=float)
    self.kernel_radii = np.ascontiguousarray(self.radii, dtype=float)
    # The swept broad phase's motion bounds (kernels.swept_balls_gap).
    self.kernel_levers = np.ascontiguousarray(self.joint_levers())
    self.kernel_half_lengths = 0.5 * np.linalg.norm(p2 - p1, axis=-1)

  def joint_levers(self, with_radius=False):
    """(dof, L): lever[k, l] >= the distance of capsule l's end points
    (with_radius: of any point of the capsule) from joint k's origin in
    every configuration, 0 where joint k does not move capsule l. Turning
    joint k by dq_k moves such a point by at most lever[k, l] |dq_k|, so a
    joint step dq moves it by at most sum_k lever[k, l] |dq_k|: the origin
    of joint j + 1 is |t_j+1| from that of joint j (t: the translations of
    the fixed transforms, rotations keep lengths), and the capsule's points
    are their local norm from their frame's origin."""
    points = self._points[:, :, :3]                                # (L, 2, 3)
    extent = np.linalg.norm(points, axis=-1).max(axis=-1)
    if with_radius:
      extent = extent + self.radii
    hop = np.linalg.norm(self._fixed[:, :3, 3], axis=-1)
    levers = np.zeros((self.dof, self.num_capsules))
    for c, frame in enumerate(self.frame_index):
      for k in range(frame + 1):
        levers[k, c] = hop[k + 1:frame + 1].sum() + extent[c]
    return levers

  def _check_q(self, q, name='q'):
    q = np.asarray(q, dtype=float)
    if q.ndim == 0 or q.shape[-1] != self.dof:
      raise ValueError(f'{name}: expected shape (..., {self.dof}) for '
                       f'{self.description.name}, got {q.shape}')
    return q

  def frames(self, q):
    """World frames of the links after their joints, (..., dof, 4, 4)."""
    q = self._check_q(q)
    return self._chain(q.reshape(-1, self.dof))[:, :self.dof].reshape(
        q.shape[:-1] + (self.dof, 4, 4))

  def _chain(self, q):
    """Frames (N, L, 4, 4) of the capsules for q (N, dof); the tool's frame
    repeats the last link's."""
    c = np.cos(q)[..., None, None]
    s = np.sin(q)[..., None, None]
    # A_i Rz(q_i) = A_i diag(0, 0, 1, 1) + c A_i diag(1, 1, 0, 0) + s A_i S.
    local = self._fixed_rest + c * self._fixed_cos + s * self._fixed_sin
    out = np.empty((q.shape[0], self.num_capsules, 4, 4))
    out[:, 0] = local[:, 0]
    for i in range(1, self.dof):
      np.matmul(out[:, i - 1], local[:, i], out=out[:, i])
    if self.has_tool:
      out[:, self.dof] = out[:, self.dof - 1]
    return out

  def _endpoints(self, frames):
    """End points (N, L, 2, 3) from capsule frames (N, L, 4, 4)."""
    return np.matmul(self._points, frames[..., :3, :].swapaxes(-1, -2))

  def capsules(self, q):
    """Real-size world capsules: p1 (..., L, 3), p2 (..., L, 3), r (L,)."""
    q = self._check_q(q)
    ends = self._endpoints(self._chain(q.reshape(-1, self.dof)))
    ends = ends.reshape(q.shape[:-1] + ends.shape[1:])
    return ends[..., 0, :], ends[..., 1, :], self.radii

  def reach_capsules(self, q_edges, s_edges, compiled=True):
    """Capsules enclosing every link over each of K intervals.

    q_edges (K+1, dof): configurations at the interval edges; s_edges (K+1,):
    path positions (plan time, s) at the edges. Returns c1, c2 (K, L, 3) and
    r (K, L), including the curvature term and the secure radius.
    compiled=False runs the NumPy reference instead of the kernel.
    """
    q_edges = np.ascontiguousarray(q_edges, dtype=float)
    s_edges = np.ascontiguousarray(s_edges, dtype=float)
    if (q_edges.ndim != 2 or q_edges.shape[1] != self.dof or
        s_edges.shape != (q_edges.shape[0],) or q_edges.shape[0] < 2):
      raise ValueError(f'reach_capsules: expected q_edges (K+1, {self.dof}) '
                       f'and s_edges (K+1,) with K >= 1, got {q_edges.shape} '
                       f'and {s_edges.shape}')
    if compiled:
      return kernels.robot_reach(q_edges, s_edges, *self.kernel_model,
                                 self.kernel_frames, self.kernel_alpha,
                                 self.kernel_static)
    ends = self._endpoints(self._chain(q_edges))           # (K+1, L, 2, 3)
    start, end = ends[:-1], ends[1:]
    centres = 0.5 * (start + end)
    chord = end - start
    chord_sq = np.vecdot(chord, chord)
    ds = s_edges[1:] - s_edges[:-1]
    radius = (0.5 * np.sqrt(chord_sq.max(axis=-1))
              + (ds * ds * 0.125)[:, None] * self.alpha + self._static_radius)
    return centres[:, :, 0], centres[:, :, 1], radius

  def surface_speeds(self, q, dq, compiled=True):
    """Upper bound of the surface speed of each capsule (..., L), m/s.

    Point velocity on link i: v(p) = w_i x p - U_i with w_i = sum_{k<=i}
    dq_k z_k and U_i = sum_{k<=i} dq_k z_k x o_k, o_k the origin of joint k's
    frame (on its axis; fixes L7; docs/shield_maths.md, 7). Velocity is
    affine along the segment, so the maximum is at an end point; ||w|| r
    covers the surface.
    compiled=False runs the NumPy reference instead of the kernel.
    """
    q = self._check_q(q)
    dq = self._check_q(dq, 'dq')
    q, dq = np.broadcast_arrays(q, dq)
    batch = q.shape[:-1]
    dq = dq.reshape(-1, self.dof)
    if compiled:
      out = kernels.surface_speeds(
          np.ascontiguousarray(q.reshape(-1, self.dof)),
          np.ascontiguousarray(dq), *self.kernel_model,
          self.kernel_frames, self.kernel_radii)
      return out.reshape(batch + (self.num_capsules,))
    chain = self._chain(q.reshape(-1, self.dof))
    frames = chain[:, :self.dof]
    spin = frames[..., :3, 2] * dq[..., None]               # dq_k z_k
    omega = np.cumsum(spin, axis=1)
    offset = np.cumsum(_cross(spin, frames[..., :3, 3]), axis=1)
    omega = omega[:, self.frame_index]                       # (N, L, 3)
    offset = offset[:, self.frame_index]
    ends = self._endpoints(chain)                # (N, L, 2, 3)
    v = _cross(omega[:, :, None], ends) - offset[:, :, None]
    speed_sq = np.vecdot(v, v).max(axis=-1)
    spin_rate = np.sqrt(np.vecdot(omega, omega))
    out = np.sqrt(speed_sq) + spin_rate * self.radii
    return out.reshape(batch + (self.num_capsules,))


_NEXT = np.array([1, 2, 0])
_PREV = np.array([2, 0, 1])


def _cross(a, b):
  """Cross product over the last axis (faster than np.cross on small
  arrays)."""
  return a[..., _NEXT] * b[..., _PREV] - a[..., _PREV] * b[..., _NEXT]
