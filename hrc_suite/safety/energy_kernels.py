"""Compiled (numba) link energies of a robot arm and energy tables of a plan.

`link_energies` computes robot_energy.ArmInertia.link_energies (pinocchio's
composite-rigid-body algorithm, the reference) from the links' frames,
masses, centres of mass and inertias, without forming B(q)
(docs/shield_maths.md, 9.4). With w_i = sum_{k<=i} dq_k z_k and
U_i = sum_{k<=i} dq_k z_k x o_k (docs/shield_maths.md, 7), a point p moving
with link i has the velocity w_i x p - U_i. The energy of the motion of
joints 1..j (joints beyond j locked, links j..n carried rigidly by link j):

  E_j = sum_{i<j} T_i  +  C_j  +  1/2 sum_{i<=j} a_i dq_i^2,
  T_i = 1/2 m_i |w_i x c_i - U_i|^2 + 1/2 w_i^T R_i I_i R_i^T w_i,
  C_j = 1/2 (w_j^T S_j w_j - 2 U_j . (w_j x h_j) + M_j |U_j|^2),

with c_i the world centre of mass of link i, I_i its inertia about it in
the link's axes, a_i the armature, and over links i >= j the composite
mass M_j, first moment h_j = sum m_i c_i and inertia about the world
origin S_j = sum (R_i I_i R_i^T + m_i (|c_i|^2 1 - c_i c_i^T)). The
payload (gripper, held object) is part of the last link. The frames are
the robot's own (`kernels._chain`); the energies do not depend on the
base pose, so callers pass frames relative to the base (coordinates of
about a metre, so the origin's moments lose no significant digits).

`energy_bounds` inflates each sample's energies to bound the plan's
nominal energy between samples, and `energy_tables` takes their window and
suffix maxima (docs/shield_maths.md, 9.4). Compiled like the shield's
kernels (cache=True, fastmath=False).
"""

import math
from typing import NamedTuple

import numpy as np

from hrc_suite.safety import kernels

_jit = kernels._jit
_inline = kernels._inline


class ArmArrays(NamedTuple):
  """An arm's energy model for the kernels (arm_energy.ArmEnergyModel):
  `energy_bounds`' arguments after the samples, but the step."""
  fixed: np.ndarray          # (dof, 3, 4) fixed transforms A_i.
  masses: np.ndarray         # (dof,) kg, the payload merged into the last.
  centres: np.ndarray        # (dof, 3) m, centres of mass (link axes).
  inertias: np.ndarray       # (dof, 3, 3) kg m^2, about them.
  armature: np.ndarray       # (dof,) kg m^2.
  levers: np.ndarray         # (dof, dof) m (energy_bounds).
  trace_bound: np.ndarray    # (dof,) (energy_bounds).
  inertia_bound: np.ndarray  # (dof,) kg m^2 (energy_bounds).


@_inline
def _sample_energies(q, dq, fixed, masses, centres, inertias, armature,
                     frames, spin, offset, com, own, out):
  """E_j (dof,) of one configuration q and joint velocity dq into out
  (the module's formulas); the other arrays are scratch space: frames
  (dof, 3, 4), spin, offset, com (dof, 3), own (dof,)."""
  dof = q.shape[0]
  kernels._chain(q, fixed, frames)
  w0 = w1 = w2 = u0 = u1 = u2 = 0.0
  for i in range(dof):
    f = frames[i]
    z0, z1, z2 = f[0, 2] * dq[i], f[1, 2] * dq[i], f[2, 2] * dq[i]
    o0, o1, o2 = f[0, 3], f[1, 3], f[2, 3]
    w0 += z0
    w1 += z1
    w2 += z2
    u0 += z1 * o2 - z2 * o1
    u1 += z2 * o0 - z0 * o2
    u2 += z0 * o1 - z1 * o0
    spin[i, 0], spin[i, 1], spin[i, 2] = w0, w1, w2
    offset[i, 0], offset[i, 1], offset[i, 2] = u0, u1, u2
    x, y, z = centres[i, 0], centres[i, 1], centres[i, 2]
    c0 = f[0, 0] * x + f[0, 1] * y + f[0, 2] * z + o0
    c1 = f[1, 0] * x + f[1, 1] * y + f[1, 2] * z + o1
    c2 = f[2, 0] * x + f[2, 1] * y + f[2, 2] * z + o2
    com[i, 0], com[i, 1], com[i, 2] = c0, c1, c2
    v0 = w1 * c2 - w2 * c1 - u0
    v1 = w2 * c0 - w0 * c2 - u1
    v2 = w0 * c1 - w1 * c0 - u2
    # Angular velocity in the link's axes: R_i^T w_i.
    b0 = f[0, 0] * w0 + f[1, 0] * w1 + f[2, 0] * w2
    b1 = f[0, 1] * w0 + f[1, 1] * w1 + f[2, 1] * w2
    b2 = f[0, 2] * w0 + f[1, 2] * w1 + f[2, 2] * w2
    inertia = inertias[i]
    rotational = (b0 * (inertia[0, 0] * b0 + inertia[0, 1] * b1
                        + inertia[0, 2] * b2)
                  + b1 * (inertia[1, 0] * b0 + inertia[1, 1] * b1
                          + inertia[1, 2] * b2)
                  + b2 * (inertia[2, 0] * b0 + inertia[2, 1] * b1
                          + inertia[2, 2] * b2))
    own[i] = 0.5 * (masses[i] * (v0 * v0 + v1 * v1 + v2 * v2) + rotational)
  # Composite of links j..n about the world origin, accumulated backwards.
  mass = h0 = h1 = h2 = 0.0
  s00 = s01 = s02 = s11 = s12 = s22 = 0.0
  for j in range(dof - 1, -1, -1):
    f = frames[j]
    inertia = inertias[j]
    m = masses[j]
    c0, c1, c2 = com[j, 0], com[j, 1], com[j, 2]
    i00, i01, i02 = inertia[0, 0], inertia[0, 1], inertia[0, 2]
    i11, i12, i22 = inertia[1, 1], inertia[1, 2], inertia[2, 2]
    # R I R^T (I symmetric), upper triangle: rows r of R times I.
    r00 = f[0, 0] * i00 + f[0, 1] * i01 + f[0, 2] * i02
    r01 = f[0, 0] * i01 + f[0, 1] * i11 + f[0, 2] * i12
    r02 = f[0, 0] * i02 + f[0, 1] * i12 + f[0, 2] * i22
    r10 = f[1, 0] * i00 + f[1, 1] * i01 + f[1, 2] * i02
    r11 = f[1, 0] * i01 + f[1, 1] * i11 + f[1, 2] * i12
    r12 = f[1, 0] * i02 + f[1, 1] * i12 + f[1, 2] * i22
    r20 = f[2, 0] * i00 + f[2, 1] * i01 + f[2, 2] * i02
    r21 = f[2, 0] * i01 + f[2, 1] * i11 + f[2, 2] * i12
    r22 = f[2, 0] * i02 + f[2, 1] * i12 + f[2, 2] * i22
    world00 = r00 * f[0, 0] + r01 * f[0, 1] + r02 * f[0, 2]
    world01 = r00 * f[1, 0] + r01 * f[1, 1] + r02 * f[1, 2]
    world02 = r00 * f[2, 0] + r01 * f[2, 1] + r02 * f[2, 2]
    world11 = r10 * f[1, 0] + r11 * f[1, 1] + r12 * f[1, 2]
    world12 = r10 * f[2, 0] + r11 * f[2, 1] + r12 * f[2, 2]
    world22 = r20 * f[2, 0] + r21 * f[2, 1] + r22 * f[2, 2]
    squared = c0 * c0 + c1 * c1 + c2 * c2
    mass += m
    h0 += m * c0
    h1 += m * c1
    h2 += m * c2
    s00 += world00 + m * (squared - c0 * c0)
    s11 += world11 + m * (squared - c1 * c1)
    s22 += world22 + m * (squared - c2 * c2)
    s01 += world01 - m * c0 * c1
    s02 += world02 - m * c0 * c2
    s12 += world12 - m * c1 * c2
    w0, w1, w2 = spin[j, 0], spin[j, 1], spin[j, 2]
    u0, u1, u2 = offset[j, 0], offset[j, 1], offset[j, 2]
    quadratic = (s00 * w0 * w0 + s11 * w1 * w1 + s22 * w2 * w2
                 + 2.0 * (s01 * w0 * w1 + s02 * w0 * w2 + s12 * w1 * w2))
    cross = (u0 * (w1 * h2 - w2 * h1) + u1 * (w2 * h0 - w0 * h2)
             + u2 * (w0 * h1 - w1 * h0))
    out[j] = 0.5 * (quadratic - 2.0 * cross
                    + mass * (u0 * u0 + u1 * u1 + u2 * u2))
  before = 0.0
  rotor = 0.0
  for j in range(dof):
    rotor += 0.5 * armature[j] * dq[j] * dq[j]
    out[j] += before + rotor
    before += own[j]


@_jit
def link_energies(q, dq, fixed, masses, centres, inertias, armature):
  """E_j (N, dof), J, of configurations q and joint velocities dq (N, dof).

  fixed (dof, 3, 4): the fixed transforms A_i (`kernels._chain`); masses
  (dof,), centres (dof, 3) and inertias (dof, 3, 3) (about the centre of
  mass, link axes) of the links, the payload merged into the last;
  armature (dof,), kg m^2."""
  count, dof = q.shape
  out = np.empty((count, dof))
  frames = np.empty((dof, 3, 4))
  spin = np.empty((dof, 3))
  offset = np.empty((dof, 3))
  com = np.empty((dof, 3))
  own = np.empty(dof)
  for n in range(count):
    _sample_energies(q[n], dq[n], fixed, masses, centres, inertias, armature,
                     frames, spin, offset, com, own, out[n])
  return out


@_inline
def _inflation(samples, n, levers, trace_bound, inertia_bound, masses, step,
               step_q, step_v, reach_lin, reach_ang, out):
  """delta_j (dof,) of sample n into out: on the plan's piece from sample
  n (its Taylor polynomial over 0 <= tau < step, docs/shield_maths.md, 2),
  sqrt(E_j) exceeds sqrt(E_j) at the sample by at most delta_j
  (docs/shield_maths.md, 9.4, "Between samples")."""
  dof = samples.shape[2]
  for i in range(dof):
    # The acceleration is linear on the piece: largest at one of its ends.
    a = max(abs(samples[n, 2, i]),
            abs(samples[n, 2, i] + step * samples[n, 3, i]))
    step_v[i] = a * step
    step_q[i] = step * (abs(samples[n, 1, i]) + 0.5 * a * step)
  # reach_lin[l, k]: sum_{k' <= k} |v_k'| Y_k'l, reach_ang likewise with Z.
  for l in range(dof):
    inner_lin = 0.0   # sum_{i=k}^{l} lever_il |dq_i|
    inner_ang = 0.0   # sum_{i=k+1}^{l} |dq_i|
    for k in range(l, -1, -1):
      inner_lin += levers[k, l] * step_q[k]
      reach_lin[l, k] = inner_lin
      reach_ang[l, k] = inner_ang
      inner_ang += step_q[k]
    before = 0.0      # sum_{i<k} |dq_i|
    total_lin = total_ang = 0.0
    for k in range(l + 1):
      speed = abs(samples[n, 1, k])
      total_lin += speed * (levers[k, l] * before + reach_lin[l, k])
      total_ang += speed * reach_ang[l, k]
      reach_lin[l, k] = total_lin
      reach_ang[l, k] = total_ang
      before += step_q[k]
  velocity = 0.0
  for j in range(dof):
    velocity += step_v[j] * step_v[j]
    moved = 0.0
    for l in range(dof):
      k = min(l, j)
      moved += (masses[l] * reach_lin[l, k] * reach_lin[l, k]
                + inertia_bound[l] * reach_ang[l, k] * reach_ang[l, k])
    out[j] = (trace_bound[j] * math.sqrt(velocity)
              + math.sqrt(moved)) * math.sqrt(0.5)


@_jit
def energy_bounds(samples, fixed, masses, centres, inertias, armature,
                  levers, trace_bound, inertia_bound, step):
  """Per-sample contact energy bounds (N, dof), J, of a plan's samples
  (N, 4, dof) (q, dq, ddq, dddq at nominal path speed, every `step`
  seconds): min(e_j, e_n)^2 with e_j = sqrt(E_j) + delta_j, which bounds
  the nominal energy of a contact at link j on the plan's piece from the
  sample to the next (docs/shield_maths.md, 9.4). levers (dof, dof): lever[i, l] >= the
  distance of link l's centre of mass from joint i's origin (i <= l);
  trace_bound (dof,): sqrt of a bound of trace(B_1..j); inertia_bound
  (dof,): the largest principal moment of each link's inertia."""
  count, _, dof = samples.shape
  out = np.empty((count, dof))
  frames = np.empty((dof, 3, 4))
  spin = np.empty((dof, 3))
  offset = np.empty((dof, 3))
  com = np.empty((dof, 3))
  own = np.empty(dof)
  energies = np.empty(dof)
  delta = np.empty(dof)
  step_q = np.empty(dof)
  step_v = np.empty(dof)
  reach_lin = np.empty((dof, dof))
  reach_ang = np.empty((dof, dof))
  for n in range(count):
    _sample_energies(samples[n, 0], samples[n, 1], fixed, masses, centres,
                     inertias, armature, frames, spin, offset, com, own,
                     energies)
    _inflation(samples, n, levers, trace_bound, inertia_bound, masses,
               step, step_q, step_v, reach_lin, reach_ang, delta)
    whole = math.sqrt(max(energies[dof - 1], 0.0)) + delta[dof - 1]
    for j in range(dof):
      bound = min(math.sqrt(max(energies[j], 0.0)) + delta[j], whole)
      out[n, j] = bound * bound
  return out


@_jit
def energy_tables(bounds, width):
  """Energy tables of a plan from its per-sample bounds (N, dof): per link
  the largest over samples i..i+width (clamped to the plan), (N, dof), and
  the largest of any link from sample i to the end, (N,)."""
  count, dof = bounds.shape
  window = np.empty((count, dof))
  suffix = np.empty(count)
  best = -np.inf
  for i in range(count - 1, -1, -1):
    for j in range(dof):
      best = max(best, bounds[i, j])
      largest = bounds[i, j]
      for k in range(i + 1, min(i + width + 1, count)):
        largest = max(largest, bounds[k, j])
      window[i, j] = largest
    suffix[i] = best
  return window, suffix


_warm = False


def warm_up():
  """Compiles (or loads from the cache) the kernels once per process."""
  global _warm
  if _warm:
    return
  dof = 2
  fixed = np.zeros((dof, 3, 4))
  vectors = np.zeros((dof, 3))
  matrices = np.zeros((dof, 3, 3))
  values = np.zeros(dof)
  link_energies(np.zeros((1, dof)), np.zeros((1, dof)), fixed, values,
                vectors, matrices, values)
  samples = np.zeros((2, 4, dof))
  for writeable in (True, False):   # Plans' samples: both occur.
    samples.flags.writeable = writeable
    bounds = energy_bounds(samples, fixed, values, vectors, matrices,
                           values, np.zeros((dof, dof)), values, values,
                           0.004)
  energy_tables(bounds, 6)
  _warm = True
