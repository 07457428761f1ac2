"""Compiled (numba) PFL speed tables of a long-term plan.

`plan_speed_tables` computes `kernels.speed_tables(kernels.surface_speeds(
q, dq), width)` of a plan's samples (the shield's `_plan_speeds`; its
NumPy reference `shield.pfl_speed_tables(robot.surface_speeds(...))`)
without the (N, L) speeds: only each sample's largest capsule surface
speed is kept, and a capsule whose speed bound is below the largest
speed found is skipped.

Each sample is computed with the operations of `kernels._chain`,
`kernels._spins` and `kernels._capsule_speed`, in the same order, so the
tables are the same bits (tests/safety/test_kernels.py). They run over a
block of samples at a time, stored joint by joint and coordinate by
coordinate, so that the compiler vectorises the frames, spins and bounds
across samples (the sines and cosines stay calls to libm): 0.6 of the
cost of one sample after another (docs/benchmarks.md, "PFL speed
tables"). Same compilation settings as the shield's kernels.
"""

import math

import numpy as np

from hrc_suite.safety import kernels

_jit = kernels._jit
_inline = kernels._inline

# Samples per block: a block's frames, spins and bounds (about 70 KiB for
# seven joints) stay in the core's L2 cache (512 KiB on the development
# machine); 32 and 128 measured the same.
BLOCK = 64
# A capsule is skipped where its speed bound, grown by these (relative,
# absolute in m/s), is below the largest speed found: far above the
# round-off of the computed speeds and bounds (about 1e-15 relative).
_PRUNE_RELATIVE = 1e-6
_PRUNE_ABSOLUTE = 1e-9
# A frame's 12 numbers (the top rows of its 4x4 transform), row by row.
_ROW = 4


@_inline
def _block_frames(samples, first, count, fixed, cos, sin, frames):
  """Link frames (dof, 12, >= count) of samples first..first + count - 1
  (`kernels._chain` of each: A_i Rz(q_i) chained by affine products)."""
  dof = samples.shape[2]
  for i in range(dof):
    for n in range(count):
      angle = samples[first + n, 0, i]
      cos[n] = math.cos(angle)
      sin[n] = math.sin(angle)
    f = fixed[i]
    f00, f01, f02, f03 = f[0, 0], f[0, 1], f[0, 2], f[0, 3]
    f10, f11, f12, f13 = f[1, 0], f[1, 1], f[1, 2], f[1, 3]
    f20, f21, f22, f23 = f[2, 0], f[2, 1], f[2, 2], f[2, 3]
    out = frames[i]
    if i == 0:
      for n in range(count):
        c, s = cos[n], sin[n]
        out[0, n] = c * f00 + s * f01
        out[1, n] = c * f01 - s * f00
        out[2, n] = f02
        out[3, n] = f03
        out[4, n] = c * f10 + s * f11
        out[5, n] = c * f11 - s * f10
        out[6, n] = f12
        out[7, n] = f13
        out[8, n] = c * f20 + s * f21
        out[9, n] = c * f21 - s * f20
        out[10, n] = f22
        out[11, n] = f23
      continue
    parent = frames[i - 1]
    for n in range(count):
      c, s = cos[n], sin[n]
      l00 = c * f00 + s * f01
      l01 = c * f01 - s * f00
      l10 = c * f10 + s * f11
      l11 = c * f11 - s * f10
      l20 = c * f20 + s * f21
      l21 = c * f21 - s * f20
      for r in range(3):
        p0 = parent[_ROW * r, n]
        p1 = parent[_ROW * r + 1, n]
        p2 = parent[_ROW * r + 2, n]
        p3 = parent[_ROW * r + 3, n]
        out[_ROW * r, n] = p0 * l00 + p1 * l10 + p2 * l20
        out[_ROW * r + 1, n] = p0 * l01 + p1 * l11 + p2 * l21
        out[_ROW * r + 2, n] = p0 * f02 + p1 * f12 + p2 * f22
        out[_ROW * r + 3, n] = p0 * f03 + p1 * f13 + p2 * f23 + p3


@_inline
def _block_spins(samples, first, count, frames, omega, offset):
  """`kernels._spins` of each sample: w_i = sum_{k<=i} dq_k z_k and U_i =
  sum_{k<=i} dq_k z_k x o_k into omega, offset (dof, 3, >= count)."""
  dof = samples.shape[2]
  for i in range(dof):
    frame = frames[i]
    for n in range(count):
      dq = samples[first + n, 1, i]
      z0 = frame[2, n] * dq
      z1 = frame[6, n] * dq
      z2 = frame[10, n] * dq
      o0, o1, o2 = frame[3, n], frame[7, n], frame[11, n]
      if i == 0:
        w0 = w1 = w2 = u0 = u1 = u2 = 0.0
      else:
        w0, w1, w2 = omega[i - 1, 0, n], omega[i - 1, 1, n], omega[i - 1, 2, n]
        u0, u1, u2 = (offset[i - 1, 0, n], offset[i - 1, 1, n],
                      offset[i - 1, 2, n])
      omega[i, 0, n] = w0 + z0
      omega[i, 1, n] = w1 + z1
      omega[i, 2, n] = w2 + z2
      offset[i, 0, n] = u0 + (z1 * o2 - z2 * o1)
      offset[i, 1, n] = u1 + (z2 * o0 - z0 * o2)
      offset[i, 2, n] = u2 + (z0 * o1 - z1 * o0)


@_inline
def _capsule_speed(frames, omega, offset, points, radii, l, f, n):
  """`kernels._capsule_speed` of capsule l (on frame f) of block sample n."""
  a0, a1, a2 = omega[f, 0, n], omega[f, 1, n], omega[f, 2, n]
  frame = frames[f]
  best = 0.0
  for j in range(2):
    x, y, z = points[l, j, 0], points[l, j, 1], points[l, j, 2]
    p0 = frame[0, n] * x + frame[1, n] * y + frame[2, n] * z + frame[3, n]
    p1 = frame[4, n] * x + frame[5, n] * y + frame[6, n] * z + frame[7, n]
    p2 = frame[8, n] * x + frame[9, n] * y + frame[10, n] * z + frame[11, n]
    v0 = a1 * p2 - a2 * p1 - offset[f, 0, n]
    v1 = a2 * p0 - a0 * p2 - offset[f, 1, n]
    v2 = a0 * p1 - a1 * p0 - offset[f, 2, n]
    best = max(best, v0 * v0 + v1 * v1 + v2 * v2)
  return (math.sqrt(best)
          + math.sqrt(a0 * a0 + a1 * a1 + a2 * a2) * radii[l])


@_jit
def plan_speed_tables(samples, fixed, points, frame_index, radii, width):
  """speed_tables(surface_speeds(q, dq), width) of a plan's samples (N, 4,
  dof) (q = samples[:, 0], dq = samples[:, 1]): the same values. The
  capsule with the largest speed bound is computed first, then those whose
  bound is not below the largest speed found. The bound: at a point p of
  a capsule on a frame with origin o, |v(p)| <= |v(o)| + |w| |p - o|, and
  |p - o| is at most the farther end's distance from o in the frame (the
  frames are rigid) plus the radius."""
  count, _, dof = samples.shape
  count_l = points.shape[0]
  reach = np.empty(count_l)
  for l in range(count_l):
    far = 0.0
    for j in range(2):
      x, y, z = points[l, j, 0], points[l, j, 1], points[l, j, 2]
      far = max(far, math.sqrt(x * x + y * y + z * z))
    reach[l] = far + radii[l]
  cos, sin = np.empty(BLOCK), np.empty(BLOCK)
  frames = np.empty((dof, 3 * _ROW, BLOCK))
  omega = np.empty((dof, 3, BLOCK))
  offset = np.empty((dof, 3, BLOCK))
  bound = np.empty((count_l, BLOCK))
  grow = 1.0 + _PRUNE_RELATIVE
  top = np.empty(count)
  for first in range(0, count, BLOCK):
    size = min(BLOCK, count - first)
    _block_frames(samples, first, size, fixed, cos, sin, frames)
    _block_spins(samples, first, size, frames, omega, offset)
    for l in range(count_l):
      f = frame_index[l]
      frame = frames[f]
      for n in range(size):
        a0, a1, a2 = omega[f, 0, n], omega[f, 1, n], omega[f, 2, n]
        o0, o1, o2 = frame[3, n], frame[7, n], frame[11, n]
        v0 = a1 * o2 - a2 * o1 - offset[f, 0, n]
        v1 = a2 * o0 - a0 * o2 - offset[f, 1, n]
        v2 = a0 * o1 - a1 * o0 - offset[f, 2, n]
        bound[l, n] = ((math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
                        + math.sqrt(a0 * a0 + a1 * a1 + a2 * a2) * reach[l])
                       * grow + _PRUNE_ABSOLUTE)
    for n in range(size):
      fastest = 0
      for l in range(count_l):
        if bound[l, n] > bound[fastest, n]:
          fastest = l
      best = _capsule_speed(frames, omega, offset, points, radii, fastest,
                            frame_index[fastest], n)
      for l in range(count_l):
        if l != fastest and bound[l, n] >= best:
          best = max(best, _capsule_speed(frames, omega, offset, points,
                                          radii, l, frame_index[l], n))
      top[first + n] = best
  return kernels._tables(top, width)


_warm = False


def warm_up():
  """Compiles (or loads from the cache) the kernel for the plans the
  shield passes (made by Ruckig: writeable; from samples: read-only), once
  per process."""
  global _warm
  if _warm:
    return
  dof, count_l = 2, 2
  fixed = np.zeros((dof, 3, 4))
  points = np.zeros((count_l, 2, 4))
  frame_index = np.zeros(count_l, dtype=np.int64)
  samples = np.zeros((2, 4, dof))
  for writeable in (True, False):
    samples.flags.writeable = writeable
    plan_speed_tables(samples, fixed, points, frame_index, np.ones(count_l),
                      6)
  _warm = True
