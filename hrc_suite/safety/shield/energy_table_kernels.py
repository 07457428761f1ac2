"""Compiled (numba) energy PFL tables of a long-term plan.

`plan_energy_tables` computes `arm_energy.ArmEnergyModel.plan_tables` of a
plan's samples (the shield's `plan_energies`; its reference:
`energy_kernels.energy_bounds`, a sample at a time, then
`energy_kernels.energy_tables`): per sample the contact energy bound of
every link on the plan's piece from it (docs/shield_maths.md, 9.4,
"Between samples"), then the window and suffix maxima ("Tables").

Each sample is computed with the operations of
`energy_kernels._sample_energies` and `energy_kernels._inflation`, in the
same order, so the tables are the same bits
(tests/safety/test_energy_tables.py). They run over a block of samples
at a time, stored link by link and coordinate by coordinate, so that the
compiler vectorises them across samples (the frames and spins:
`speed_kernels`, as PFL's tables; the sines and cosines stay calls to
libm). Same compilation settings as the shield's kernels.
"""

import math
from typing import NamedTuple

import numpy as np

from hrc_suite.safety import energy_kernels
from hrc_suite.safety import kernels
from hrc_suite.safety.shield import speed_kernels

_jit = kernels._jit
_inline = kernels._inline

# Samples per block (speed_kernels.BLOCK): a block's frames, spins, link
# quantities and the bound's reach terms (about 120 KiB for seven joints)
# stay in the core's L2 cache.
BLOCK = speed_kernels.BLOCK
# A frame's 12 numbers (the top rows of its 4x4 transform), row by row
# (speed_kernels._block_frames).
_ROW = 4


@_inline
def _block_own(samples, first, count, arm, scratch):
  """Per link i of block samples first..first + count - 1 its world
  centre of mass into scratch.com (dof, 3, BLOCK) and its own kinetic
  energy T_i into scratch.own (dof, BLOCK) (energy_kernels.
  _sample_energies' first loop; frames and spins already in scratch)."""
  dof = samples.shape[2]
  for i in range(dof):
    f = scratch.frames[i]
    w, u = scratch.omega[i], scratch.offset[i]
    com, own = scratch.com[i], scratch.own[i]
    x, y, z = arm.centres[i, 0], arm.centres[i, 1], arm.centres[i, 2]
    inertia = arm.inertias[i]
    i00, i01, i02 = inertia[0, 0], inertia[0, 1], inertia[0, 2]
    i10, i11, i12 = inertia[1, 0], inertia[1, 1], inertia[1, 2]
    i20, i21, i22 = inertia[2, 0], inertia[2, 1], inertia[2, 2]
    mass = arm.masses[i]
    for n in range(count):
      w0, w1, w2 = w[0, n], w[1, n], w[2, n]
      c0 = f[0, n] * x + f[1, n] * y + f[2, n] * z + f[3, n]
      c1 = f[4, n] * x + f[5, n] * y + f[6, n] * z + f[7, n]
      c2 = f[8, n] * x + f[9, n] * y + f[10, n] * z + f[11, n]
      com[0, n], com[1, n], com[2, n] = c0, c1, c2
      v0 = w1 * c2 - w2 * c1 - u[0, n]
      v1 = w2 * c0 - w0 * c2 - u[1, n]
      v2 = w0 * c1 - w1 * c0 - u[2, n]
      # Angular velocity in the link's axes: R_i^T w_i.
      b0 = f[0, n] * w0 + f[4, n] * w1 + f[8, n] * w2
      b1 = f[1, n] * w0 + f[5, n] * w1 + f[9, n] * w2
      b2 = f[2, n] * w0 + f[6, n] * w1 + f[10, n] * w2
      rotational = (b0 * (i00 * b0 + i01 * b1 + i02 * b2)
                    + b1 * (i10 * b0 + i11 * b1 + i12 * b2)
                    + b2 * (i20 * b0 + i21 * b1 + i22 * b2))
      own[n] = 0.5 * (mass * (v0 * v0 + v1 * v1 + v2 * v2) + rotational)


@_inline
def _block_energies(samples, first, count, arm, scratch):
  """E_j (dof, BLOCK) of the block's samples into scratch.energies
  (energy_kernels._sample_energies: the composite of links j..n about the
  world origin, accumulated backwards, then the links before j and the
  rotors)."""
  dof = samples.shape[2]
  composite = scratch.composite
  for r in range(9):
    for n in range(count):
      composite[r, n] = 0.0
  mass = 0.0
  for j in range(dof - 1, -1, -1):
    f = scratch.frames[j]
    w, u = scratch.omega[j], scratch.offset[j]
    com, out = scratch.com[j], scratch.energies[j]
    inertia = arm.inertias[j]
    m = arm.masses[j]
    i00, i01, i02 = inertia[0, 0], inertia[0, 1], inertia[0, 2]
    i11, i12, i22 = inertia[1, 1], inertia[1, 2], inertia[2, 2]
    mass += m
    # Link j's inertia about the world origin: R I R^T + m (|c|^2 1 - c c^T)
    # in composite rows 3..8's order, into rows 10..15, ...
    for n in range(count):
      f00, f01, f02 = f[0, n], f[1, n], f[2, n]
      f10, f11, f12 = f[4, n], f[5, n], f[6, n]
      f20, f21, f22 = f[8, n], f[9, n], f[10, n]
      c0, c1, c2 = com[0, n], com[1, n], com[2, n]
      # R I R^T (I symmetric), upper triangle: rows r of R times I.
      r00 = f00 * i00 + f01 * i01 + f02 * i02
      r01 = f00 * i01 + f01 * i11 + f02 * i12
      r02 = f00 * i02 + f01 * i12 + f02 * i22
      r10 = f10 * i00 + f11 * i01 + f12 * i02
      r11 = f10 * i01 + f11 * i11 + f12 * i12
      r12 = f10 * i02 + f11 * i12 + f12 * i22
      r20 = f20 * i00 + f21 * i01 + f22 * i02
      r21 = f20 * i01 + f21 * i11 + f22 * i12
      r22 = f20 * i02 + f21 * i12 + f22 * i22
      world00 = r00 * f00 + r01 * f01 + r02 * f02
      world01 = r00 * f10 + r01 * f11 + r02 * f12
      world02 = r00 * f20 + r01 * f21 + r02 * f22
      world11 = r10 * f10 + r11 * f11 + r12 * f12
      world12 = r10 * f20 + r11 * f21 + r12 * f22
      world22 = r20 * f20 + r21 * f21 + r22 * f22
      squared = c0 * c0 + c1 * c1 + c2 * c2
      composite[10, n] = world00 + m * (squared - c0 * c0)
      composite[11, n] = world11 + m * (squared - c1 * c1)
      composite[12, n] = world22 + m * (squared - c2 * c2)
      composite[13, n] = world01 - m * c0 * c1
      composite[14, n] = world02 - m * c0 * c2
      composite[15, n] = world12 - m * c1 * c2
    # ... added to the composite of links j + 1..n, and E_j's composite
    # term into row 9.
    for n in range(count):
      c0, c1, c2 = com[0, n], com[1, n], com[2, n]
      h0 = composite[0, n] + m * c0
      h1 = composite[1, n] + m * c1
      h2 = composite[2, n] + m * c2
      s00 = composite[3, n] + composite[10, n]
      s11 = composite[4, n] + composite[11, n]
      s22 = composite[5, n] + composite[12, n]
      s01 = composite[6, n] + composite[13, n]
      s02 = composite[7, n] + composite[14, n]
      s12 = composite[8, n] + composite[15, n]
      composite[0, n], composite[1, n], composite[2, n] = h0, h1, h2
      composite[3, n], composite[4, n], composite[5, n] = s00, s11, s22
      composite[6, n], composite[7, n], composite[8, n] = s01, s02, s12
      w0, w1, w2 = w[0, n], w[1, n], w[2, n]
      u0, u1, u2 = u[0, n], u[1, n], u[2, n]
      quadratic = (s00 * w0 * w0 + s11 * w1 * w1 + s22 * w2 * w2
                   + 2.0 * (s01 * w0 * w1 + s02 * w0 * w2 + s12 * w1 * w2))
      cross = (u0 * (w1 * h2 - w2 * h1) + u1 * (w2 * h0 - w0 * h2)
               + u2 * (w0 * h1 - w1 * h0))
      composite[9, n] = 0.5 * (quadratic - 2.0 * cross
                               + mass * (u0 * u0 + u1 * u1 + u2 * u2))
    for n in range(count):
      out[n] = composite[9, n]
  # The links before j and the rotors: composite rows 0 and 1 hold
  # sum_{i<j} T_i and sum_{i<=j} a_i dq_i^2 / 2.
  for n in range(count):
    composite[0, n] = 0.0
    composite[1, n] = 0.0
  for j in range(dof):
    armature = arm.armature[j]
    out, own, dq = scratch.energies[j], scratch.own[j], scratch.dq[j]
    for n in range(count):
      rotor = composite[1, n] + 0.5 * armature * dq[n] * dq[n]
      composite[1, n] = rotor
      out[n] += composite[0, n] + rotor
      composite[0, n] += own[n]


@_inline
def _block_inflation(samples, first, count, arm, step, scratch):
  """delta_j (dof, BLOCK) of the block's samples into scratch.delta
  (energy_kernels._inflation: sqrt(E_j) grows by at most delta_j on the
  plan's piece from each sample)."""
  dof = samples.shape[2]
  step_q, step_v, dq = scratch.step_q, scratch.step_v, scratch.dq
  reach_lin, reach_ang = scratch.reach_lin, scratch.reach_ang
  moved, sums = scratch.moved, scratch.sums
  for i in range(dof):
    for n in range(count):
      # The acceleration is linear on the piece: largest at one of its
      # ends.
      acceleration = samples[first + n, 2, i]
      a = max(abs(acceleration),
              abs(acceleration + step * samples[first + n, 3, i]))
      step_v[i, n] = a * step
      step_q[i, n] = step * (abs(dq[i, n]) + 0.5 * a * step)
  # moved[k]: sum_{i<k} D_i.
  for n in range(count):
    moved[0, n] = 0.0
  for k in range(1, dof):
    for n in range(count):
      moved[k, n] = moved[k - 1, n] + step_q[k - 1, n]
  # reach_lin[l, k]: first sum_{i=k}^{l} lever_il D_i, reach_ang[l, k]
  # sum_{i=k+1}^{l} D_i (accumulated from k = l down); then
  # sum_{k' <= k} |v_k'| Y_k'l and likewise with Z.
  for l in range(dof):
    lever, lin, ang, d = arm.levers[l, l], reach_lin[l, l], reach_ang[l, l], (
        step_q[l])
    for n in range(count):
      lin[n] = 0.0 + lever * d[n]
      ang[n] = 0.0
    for k in range(l - 1, -1, -1):
      lever, d = arm.levers[k, l], step_q[k]
      lin, ang = reach_lin[l, k], reach_ang[l, k]
      lin_after, ang_after, d_after = (reach_lin[l, k + 1],
                                       reach_ang[l, k + 1], step_q[k + 1])
      for n in range(count):
        lin[n] = lin_after[n] + lever * d[n]
        ang[n] = ang_after[n] + d_after[n]
    for k in range(l + 1):
      lever, before, speed = arm.levers[k, l], moved[k], dq[k]
      lin, ang = reach_lin[l, k], reach_ang[l, k]
      if k == 0:
        for n in range(count):
          lin[n] = 0.0 + abs(speed[n]) * (lever * before[n] + lin[n])
          ang[n] = 0.0 + abs(speed[n]) * ang[n]
        continue
      lin_before, ang_before = reach_lin[l, k - 1], reach_ang[l, k - 1]
      for n in range(count):
        lin[n] = lin_before[n] + abs(speed[n]) * (lever * before[n] + lin[n])
        ang[n] = ang_before[n] + abs(speed[n]) * ang[n]
  velocity, spread = sums[0], sums[1]
  for n in range(count):
    velocity[n] = 0.0
  root_half = math.sqrt(0.5)
  for j in range(dof):
    v = step_v[j]
    for n in range(count):
      velocity[n] += v[n] * v[n]
      spread[n] = 0.0
    for l in range(dof):
      k = min(l, j)
      mass, spin = arm.masses[l], arm.inertia_bound[l]
      lin, ang = reach_lin[l, k], reach_ang[l, k]
      for n in range(count):
        spread[n] += (mass * lin[n] * lin[n] + spin * ang[n] * ang[n])
    bound, out = arm.trace_bound[j], scratch.delta[j]
    for n in range(count):
      out[n] = (bound * math.sqrt(velocity[n]) + math.sqrt(spread[n])) * (
          root_half)


class Scratch(NamedTuple):
  """A block's arrays (BLOCK samples; dof links)."""
  cos: np.ndarray         # (BLOCK,) speed_kernels._block_frames' ...
  sin: np.ndarray         # (BLOCK,)
  frames: np.ndarray      # (dof, 12, BLOCK) link frames.
  omega: np.ndarray       # (dof, 3, BLOCK) spins w_i ...
  offset: np.ndarray      # (dof, 3, BLOCK) ... and U_i.
  dq: np.ndarray          # (dof, BLOCK) joint velocities.
  com: np.ndarray         # (dof, 3, BLOCK) world centres of mass.
  own: np.ndarray         # (dof, BLOCK) T_i.
  energies: np.ndarray    # (dof, BLOCK) E_j.
  composite: np.ndarray   # (16, BLOCK) h, S (00, 11, 22, 01, 02, 12),
                          # E_j's term, link j's part of S.
  delta: np.ndarray       # (dof, BLOCK) delta_j.
  step_q: np.ndarray      # (dof, BLOCK) D_i ...
  step_v: np.ndarray      # (dof, BLOCK) ... and A_i dt.
  moved: np.ndarray       # (dof, BLOCK) sum_{i<k} D_i.
  reach_lin: np.ndarray   # (dof, dof, BLOCK) the bound's reach terms.
  reach_ang: np.ndarray   # (dof, dof, BLOCK)
  sums: np.ndarray        # (2, BLOCK) |(A_i dt)_{i<=j}|^2 and
                          # sum_l (m_l X_l^2 + mu_l W_l^2).


@_inline
def _scratch(dof):
  """A `Scratch` for dof links."""
  return Scratch(
      np.empty(BLOCK), np.empty(BLOCK), np.empty((dof, 3 * _ROW, BLOCK)),
      np.empty((dof, 3, BLOCK)), np.empty((dof, 3, BLOCK)),
      np.empty((dof, BLOCK)), np.empty((dof, 3, BLOCK)),
      np.empty((dof, BLOCK)), np.empty((dof, BLOCK)), np.empty((16, BLOCK)),
      np.empty((dof, BLOCK)), np.empty((dof, BLOCK)),
      np.empty((dof, BLOCK)), np.empty((dof, BLOCK)),
      np.empty((dof, dof, BLOCK)), np.empty((dof, dof, BLOCK)),
      np.empty((2, BLOCK)))


@_jit
def plan_energy_bounds(samples, arm, step):
  """energy_kernels.energy_bounds of a plan's samples (N, 4, dof) (q, dq,
  ddq, dddq at nominal path speed, every `step` seconds) and the arm's
  `energy_kernels.ArmArrays`: the same (N, dof) bounds, J."""
  count, _, dof = samples.shape
  scratch = _scratch(dof)
  out = np.empty((count, dof))
  last = dof - 1
  for first in range(0, count, BLOCK):
    size = min(BLOCK, count - first)
    speed_kernels._block_frames(samples, first, size, arm.fixed,
                                scratch.cos, scratch.sin, scratch.frames)
    speed_kernels._block_spins(samples, first, size, scratch.frames,
                               scratch.omega, scratch.offset)
    dq = scratch.dq
    for i in range(dof):
      for n in range(size):
        dq[i, n] = samples[first + n, 1, i]
    _block_own(samples, first, size, arm, scratch)
    _block_energies(samples, first, size, arm, scratch)
    _block_inflation(samples, first, size, arm, step, scratch)
    energies, delta = scratch.energies, scratch.delta
    for n in range(size):
      whole = math.sqrt(max(energies[last, n], 0.0)) + delta[last, n]
      for j in range(dof):
        bound = min(math.sqrt(max(energies[j, n], 0.0)) + delta[j, n],
                    whole)
        out[first + n, j] = bound * bound
  return out


@_jit
def plan_energy_tables(samples, arm, step, width):
  """ArmEnergyModel.plan_tables of a plan's samples (N, 4, dof), the arm's
  `energy_kernels.ArmArrays`, the sample period `step` (s) and the window
  `width`: (window (N, dof), suffix (N,)), J, the same bits."""
  return energy_kernels.energy_tables(plan_energy_bounds(samples, arm, step),
                                      width)


_warm = False


def warm_up():
  """Compiles (or loads from the cache) the kernels for the plans the
  shield passes (writeable and read-only samples), once per process."""
  global _warm
  if _warm:
    return
  dof = 2
  arm = energy_kernels.ArmArrays(
      np.zeros((dof, 3, 4)), np.ones(dof), np.zeros((dof, 3)),
      np.zeros((dof, 3, 3)), np.zeros(dof), np.zeros((dof, dof)),
      np.zeros(dof), np.zeros(dof))
  samples = np.zeros((2, 4, dof))
  for writeable in (True, False):
    samples.flags.writeable = writeable
    plan_energy_tables(samples, arm, 0.004, 6)
  _warm = True
