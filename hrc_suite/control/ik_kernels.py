"""Compiled (numba) gripper-down IK: ik.InverseKinematics' iteration.

`solve` runs one Levenberg-Marquardt run of ik.InverseKinematics
(`_solve_reference`: pinocchio kinematics, NumPy linear algebra) in one
call: the same error, damping, active set, step limit, clipping and stall
rule, with forward kinematics and the TCP Jacobian of the revolute-z chain
computed here (`forward`) from the pinocchio model's own joint and TCP
placements, the rotation error by the rotation's logarithm (`log3`) and
the damped normal equations by Cholesky. The results agree with the
reference to round-off (tests/control/test_ik_kernels.py), not bit for
bit. `solve_gripper_down` is InverseKinematics.solve's compiled path in
one call (the start clipped, the half-turn choice of the yaw, both
runs). Both take the robot's chain (`IkChain`) and the iteration's
settings (`IkSettings`) as named groups. Same compilation settings as
the shield's kernels (cache, IEEE arithmetic).
"""

import math
import typing

import numba
import numpy as np

_jit = numba.njit(cache=True, fastmath=False, nogil=True)

# Rotation angles (rad) within this of pi take the logarithm's axis from
# the rotation's symmetric part (the antisymmetric part vanishes there).
_NEAR_PI = 1e-3
# Below this angle (rad) the logarithm is half the antisymmetric part
# (theta / (2 sin theta) = 1/2 to double precision below ~1e-8).
_SMALL_ANGLE = 1e-8


class IkChain(typing.NamedTuple):
  """The robot's revolute-z chain and joint limits (float64 arrays)."""
  placements: np.ndarray   # (dof, 3, 4) joint placements (`forward`)
  tcp: np.ndarray          # (3, 4) the TCP in the last joint's frame
  q_min: np.ndarray        # (dof,) rad
  q_max: np.ndarray        # (dof,) rad


class IkSettings(typing.NamedTuple):
  """The Levenberg-Marquardt iteration's settings (ik.InverseKinematics'
  arguments and constants)."""
  weights: np.ndarray            # (6,) position and orientation weights
  base_damping: float
  max_step: float                # rad, largest joint step
  max_iterations: int
  position_tolerance: float      # m
  orientation_tolerance: float   # rad
  stall_iterations: int          # iterations without progress to stop
  stall_progress: float          # relative cost decrease that counts


@_jit
def forward(q, placements, tcp, frames, pose):
  """Joint frames (dof, 3, 4) and TCP pose (3, 4) (top rows of the 4x4
  transforms, world) for q (dof,), written into `frames` and `pose`.
  placements (dof, 3, 4): joint i's placement in joint i-1's frame (the
  first one in the world); tcp (3, 4): the TCP in the last joint's frame.
  Joint i turns about its frame's z axis (rotations.about_axis(Z, q[i]))."""
  dof = q.shape[0]
  local = np.empty((3, 4))
  for i in range(dof):
    c = math.cos(q[i])
    s = math.sin(q[i])
    a = placements[i]
    for r in range(3):   # placement times the rotation about z.
      local[r, 0] = c * a[r, 0] + s * a[r, 1]
      local[r, 1] = c * a[r, 1] - s * a[r, 0]
      local[r, 2] = a[r, 2]
      local[r, 3] = a[r, 3]
    if i == 0:
      frames[0, :, :] = local
    else:
      _compose(frames[i - 1], local, frames[i])
  _compose(frames[dof - 1], tcp, pose)


@_jit
def _compose(a, b, out):
  """out = a b for affine 3x4 transforms (top rows)."""
  for r in range(3):
    for c in range(4):
      value = a[r, 0] * b[0, c] + a[r, 1] * b[1, c] + a[r, 2] * b[2, c]
      out[r, c] = value + a[r, 3] if c == 3 else value


@_jit
def log3(m, out):
  """Rotation vector (3,) of rotation matrix m (3, 3): axis times angle
  in [0, pi], into `out` (pinocchio's log3; rotations.quat_to_rotvec of
  rotations.mat_to_quat(m))."""
  v0 = m[2, 1] - m[1, 2]
  v1 = m[0, 2] - m[2, 0]
  v2 = m[1, 0] - m[0, 1]
  cos = 0.5 * (m[0, 0] + m[1, 1] + m[2, 2] - 1.0)
  sin = 0.5 * math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
  theta = math.atan2(sin, cos)
  if theta < _SMALL_ANGLE:
    out[0], out[1], out[2] = 0.5 * v0, 0.5 * v1, 0.5 * v2
  elif theta < math.pi - _NEAR_PI:
    scale = theta / (2.0 * sin)
    out[0], out[1], out[2] = scale * v0, scale * v1, scale * v2
  else:
    # m = cos I + sin [n]x + (1 - cos) n n^T: n from the symmetric part,
    # its largest component first, the sign from the antisymmetric part.
    k = 0
    for i in range(1, 3):
      if m[i, i] > m[k, k]:
        k = i
    big = math.sqrt(max((m[k, k] - cos) / (1.0 - cos), 0.0))
    n = np.empty(3)
    for i in range(3):
      n[i] = big if i == k else (0.5 * (m[i, k] + m[k, i])
                                 / ((1.0 - cos) * big))
    if n[0] * v0 + n[1] * v1 + n[2] * v2 < 0.0:
      for i in range(3):
        n[i] = -n[i]
    for i in range(3):
      out[i] = theta * n[i]


@_jit
def _error(q, target, rotation, placements, tcp, weights, frames, pose,
           error, jacobian):
  """Weighted error (6,) and Jacobian (6, dof) into `error`, `jacobian`;
  returns (position error, angle error) (unweighted norms)."""
  dof = q.shape[0]
  forward(q, placements, tcp, frames, pose)
  relative = np.empty((3, 3))
  for r in range(3):
    for c in range(3):   # target rotation times the TCP rotation's inverse
      relative[r, c] = (rotation[r, 0] * pose[c, 0]
                        + rotation[r, 1] * pose[c, 1]
                        + rotation[r, 2] * pose[c, 2])
  angle = np.empty(3)
  log3(relative, angle)
  for r in range(3):
    error[r] = target[r] - pose[r, 3]
    error[3 + r] = angle[r]
  position_error = math.sqrt(error[0] * error[0] + error[1] * error[1]
                             + error[2] * error[2])
  angle_error = math.sqrt(angle[0] * angle[0] + angle[1] * angle[1]
                          + angle[2] * angle[2])
  for i in range(dof):
    z0, z1, z2 = frames[i, 0, 2], frames[i, 1, 2], frames[i, 2, 2]
    d0 = pose[0, 3] - frames[i, 0, 3]
    d1 = pose[1, 3] - frames[i, 1, 3]
    d2 = pose[2, 3] - frames[i, 2, 3]
    jacobian[0, i] = z1 * d2 - z2 * d1
    jacobian[1, i] = z2 * d0 - z0 * d2
    jacobian[2, i] = z0 * d1 - z1 * d0
    jacobian[3, i] = z0
    jacobian[4, i] = z1
    jacobian[5, i] = z2
  for r in range(6):
    error[r] *= weights[r]
    for i in range(dof):
      jacobian[r, i] *= weights[r]
  return position_error, angle_error


@_jit
def _solve_spd(matrix, rhs, active, out):
  """out[active] = solution of the symmetric positive definite system
  restricted to the active entries (Cholesky); 0 elsewhere."""
  index = np.flatnonzero(active)
  count = index.shape[0]
  low = np.zeros((count, count))
  for i in range(count):
    for j in range(i + 1):
      total = matrix[index[i], index[j]]
      for k in range(j):
        total -= low[i, k] * low[j, k]
      if i == j:
        low[i, i] = math.sqrt(total)
      else:
        low[i, j] = total / low[j, j]
  y = np.empty(count)
  for i in range(count):
    total = rhs[index[i]]
    for k in range(i):
      total -= low[i, k] * y[k]
    y[i] = total / low[i, i]
  out[:] = 0.0
  for i in range(count - 1, -1, -1):
    total = y[i]
    for k in range(i + 1, count):
      total -= low[k, i] * out[index[k]]
    out[index[i]] = total / low[i, i]


@_jit
def _step(q, error, jacobian, cost, q_min, q_max, base_damping, max_step,
          step):
  """The damped least-squares step into `step` (InverseKinematics._step)."""
  dof = q.shape[0]
  gradient = np.zeros(dof)
  hessian = np.zeros((dof, dof))
  for i in range(dof):
    for r in range(6):
      gradient[i] += jacobian[r, i] * error[r]
    for j in range(dof):
      for r in range(6):
        hessian[i, j] += jacobian[r, i] * jacobian[r, j]
  damping = 0.5 * cost + base_damping
  for i in range(dof):
    hessian[i, i] += damping
  active = np.ones(dof, dtype=np.bool_)
  _solve_spd(hessian, gradient, active, step)
  frozen = False
  for i in range(dof):
    if ((q[i] <= q_min[i] and step[i] < 0.0) or
        (q[i] >= q_max[i] and step[i] > 0.0)):
      active[i] = False
      frozen = True
  if frozen:
    _solve_spd(hessian, gradient, active, step)
  largest = 0.0
  for i in range(dof):
    largest = max(largest, abs(step[i]))
  if largest > max_step:
    scale = max_step / largest
    for i in range(dof):
      step[i] *= scale


@_jit
def solve(q_init, target, rotation, chain, settings):
  """One LM run (ik.InverseKinematics._solve_reference) from q_init (within
  the limits) to the TCP at target (3,) with rotation (3, 3), for the
  IkChain `chain` with the IkSettings `settings`. Returns (q, success,
  position error, angle error, iterations): the first iterate within
  tolerance, else the lowest-cost one."""
  placements, tcp, q_min, q_max = (chain.placements, chain.tcp, chain.q_min,
                                   chain.q_max)
  weights, base_damping, max_step = (settings.weights,
                                     settings.base_damping,
                                     settings.max_step)
  max_iterations = settings.max_iterations
  position_tolerance = settings.position_tolerance
  orientation_tolerance = settings.orientation_tolerance
  stall_iterations = settings.stall_iterations
  stall_progress = settings.stall_progress
  dof = q_init.shape[0]
  q = q_init.copy()
  frames = np.empty((dof, 3, 4))
  pose = np.empty((3, 4))
  error = np.empty(6)
  jacobian = np.empty((6, dof))
  step = np.empty(dof)
  best_q = q.copy()
  best_cost, best_position, best_angle = np.inf, 0.0, 0.0
  last_progress = 0
  iteration = 0
  for iteration in range(max_iterations + 1):
    position_error, angle_error = _error(
        q, target, rotation, placements, tcp, weights, frames, pose, error,
        jacobian)
    cost = 0.0
    for r in range(6):
      cost += error[r] * error[r]
    if (position_error <= position_tolerance and
        angle_error <= orientation_tolerance):
      return q, True, position_error, angle_error, iteration
    if cost < best_cost:
      if cost < (1.0 - stall_progress) * best_cost:
        last_progress = iteration
      best_cost, best_position, best_angle = cost, position_error, angle_error
      best_q[:] = q
    if (iteration == max_iterations or
        iteration - last_progress >= stall_iterations):
      break
    _step(q, error, jacobian, cost, q_min, q_max, base_damping, max_step,
          step)
    for i in range(dof):
      q[i] = min(max(q[i] + step[i], q_min[i]), q_max[i])
  return best_q, False, best_position, best_angle, iteration


@_jit
def tcp_pose(q, placements, tcp):
  """TCP pose (3, 4) (top rows of the 4x4 transform, world) at q."""
  frames = np.empty((q.shape[0], 3, 4))
  pose = np.empty((3, 4))
  forward(q, placements, tcp, frames, pose)
  return pose


@_jit
def _wrap(angle):
  """rotations.wrap_angle of one angle (Python's float remainder)."""
  return (angle + math.pi) % (2 * math.pi) - math.pi


@_jit
def _gripper_down(yaw):
  """ik.gripper_down_rotation(yaw)."""
  c, s = math.cos(yaw), math.sin(yaw)
  rotation = np.empty((3, 3))
  rotation[0, 0], rotation[0, 1], rotation[0, 2] = c, s, 0.0
  rotation[1, 0], rotation[1, 1], rotation[1, 2] = s, -c, 0.0
  rotation[2, 0], rotation[2, 1], rotation[2, 2] = 0.0, 0.0, -1.0
  return rotation


@_jit
def solve_gripper_down(q_init, target, yaw, half_turn, chain, settings):
  """ik.InverseKinematics.solve's compiled path in one call: q_init (dof,)
  clipped to the limits; with `half_turn` the target yaw or yaw + pi,
  whichever is nearer the start's TCP heading, and the other if that run
  fails (the run that succeeds, else the one nearer the target; the
  iterations of both counted). chain: IkChain, settings: IkSettings, as
  the plain tuples of their fields (safety.kernels.as_fields: called
  every RL step). Returns (q, success, position error, angle error,
  iterations, yaw used)."""
  chain, settings = IkChain(*chain), IkSettings(*settings)
  q_min, q_max = chain.q_min, chain.q_max
  dof = q_init.shape[0]
  q = np.empty(dof)
  for i in range(dof):
    q[i] = min(max(q_init[i], q_min[i]), q_max[i])
  if not half_turn:
    q_out, success, position, angle, count = solve(
        q, target, _gripper_down(yaw), chain, settings)
    return q_out, success, position, angle, count, yaw
  pose = tcp_pose(q, chain.placements, chain.tcp)
  seed_yaw = math.atan2(pose[1, 0], pose[0, 0])
  nearer = yaw
  if abs(_wrap(seed_yaw - yaw)) > math.pi / 2:
    nearer = _wrap(yaw + math.pi)
  q_out, success, position, angle, count = solve(
      q, target, _gripper_down(nearer), chain, settings)
  if success:
    return q_out, success, position, angle, count, nearer
  other = _wrap(nearer + math.pi)
  q_other, success_other, position_other, angle_other, count_other = solve(
      q, target, _gripper_down(other), chain, settings)
  if success_other or position_other < position:
    return (q_other, success_other, position_other, angle_other,
            count_other + count, other)
  return q_out, success, position, angle, count + count_other, nearer
