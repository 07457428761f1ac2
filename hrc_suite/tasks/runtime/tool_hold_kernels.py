"""The compliant hold's force and torque on the held tool, compiled.

`tool_hold.CompliantHold.apply` (the maths and the reasons for its numbers
are there) calls `apply` on every physics step; the compiled physics loop
(tasks/runtime/physics_loop.py) calls the same function between its physics
steps, so both paths give the same forces bit for bit. Quaternions are (w, x, y,
z); arithmetic in scalars, in a fixed order: `_mul`, `_matrix` and
`_rotation_vector` compute rotations.quat_mul, quat_to_mat and
quat_to_rotvec (tests/test_rotations.py checks they agree).

A hold is a `Hold`: its fixed `HoldParameters` and `HoldAddresses`, its
`HoldState` (what changes while it holds) and the MuJoCo arrays it reads
and writes (`HoldData`), numba-typed named tuples (float64, int64 and
their arrays, so one compiled signature serves every hold).
"""

import math
import typing

import numba
import numpy as np

_jit = numba.njit(cache=True, fastmath=False)


class HoldParameters(typing.NamedTuple):
  """A hold's fixed numbers (tool_hold.CompliantHold: their values and
  sources). Vectors are float64 arrays, the rest floats."""
  mass: float                # kg, the held body's
  dt: float                  # s, the physics step
  k: float                   # N/m, the hand's stiffness
  b: float                   # N s/m, its damping
  k_rot: np.ndarray          # (3,) N m/rad per principal axis
  b_rot: np.ndarray          # (3,) N m s/rad per principal axis
  inertia: np.ndarray        # (3,) kg m^2, principal moments
  com_local: np.ndarray      # (3,) centre of mass in the free joint's frame
  inertia_quat: np.ndarray   # (4,) principal axes in the free joint's frame
  offset_pos: np.ndarray     # (3,) held body in the free joint's frame
  offset_quat: np.ndarray    # (4,)
  gravity: np.ndarray        # (3,) m/s^2
  max_aim: float             # rad
  max_reach: float           # m
  max_force: float           # N
  max_torque: float          # N m


class HoldAddresses(typing.NamedTuple):
  """Where a hold's body lives in MuJoCo's arrays (int64)."""
  body: int   # the held body's id (its xfrc_applied row)
  qpos: int   # its free joint's qpos address
  qvel: int   # its free joint's qvel address


class HoldState(typing.NamedTuple):
  """What changes while a hold holds (int64 and float64 arrays, written
  in place)."""
  mocap: np.ndarray     # (1,) the hand's mocap id
  eq: np.ndarray        # (1,) the weld's id (its relative pose)
  holding: np.ndarray   # (1,) 1 while the hold is on
  aiming: np.ndarray    # (1,) 1 while it aims at `aim`
  aim: np.ndarray       # (3,) world point the tool's origin heads for
  history: np.ndarray   # (2, 7) targets (centre of mass, orientation) of
                        # the last two physics steps
  omega: np.ndarray     # (3,) the last target angular velocity
  fresh: np.ndarray     # (1,) steps of history since the start, at most 2


class HoldData(typing.NamedTuple):
  """The MuJoCo arrays a hold reads and writes (model and data views)."""
  mocap_pos: np.ndarray
  mocap_quat: np.ndarray
  eq_data: np.ndarray
  qpos: np.ndarray
  qvel: np.ndarray
  xfrc_applied: np.ndarray


class Hold(typing.NamedTuple):
  """`apply`'s argument: one hold and the physics it acts in."""
  parameters: HoldParameters
  addresses: HoldAddresses
  state: HoldState
  aim_source: np.ndarray   # (3,) copied into state.aim first, or (0,)
  data: HoldData


@_jit
def _mul(a0, a1, a2, a3, b0, b1, b2, b3):
  """Quaternion product a b (rotations.quat_mul)."""
  return (a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
          a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
          a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1,
          a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0)


@_jit
def _matrix(q0, q1, q2, q3, out):
  """Rotation matrix (3, 3) of a unit quaternion, into out
  (rotations.quat_to_mat; MuJoCo's form, which needs a unit one)."""
  out[0, 0] = q0 * q0 + q1 * q1 - q2 * q2 - q3 * q3
  out[0, 1] = 2.0 * (q1 * q2 - q0 * q3)
  out[0, 2] = 2.0 * (q1 * q3 + q0 * q2)
  out[1, 0] = 2.0 * (q1 * q2 + q0 * q3)
  out[1, 1] = q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3
  out[1, 2] = 2.0 * (q2 * q3 - q0 * q1)
  out[2, 0] = 2.0 * (q1 * q3 - q0 * q2)
  out[2, 1] = 2.0 * (q2 * q3 + q0 * q1)
  out[2, 2] = q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3


@_jit
def _times(m, v0, v1, v2, out):
  """out = m @ v."""
  for i in range(3):
    out[i] = m[i, 0] * v0 + m[i, 1] * v1 + m[i, 2] * v2


@_jit
def _times_transposed(m, v0, v1, v2, out):
  """out = m.T @ v."""
  for i in range(3):
    out[i] = m[0, i] * v0 + m[1, i] * v1 + m[2, i] * v2


@_jit
def _rotation_vector(t0, t1, t2, t3, f0, f1, f2, f3, out):
  """World-frame rotation vector (rad) turning orientation f to t:
  rotations.quat_to_rotvec(rotations.quat_mul(t, rotations.quat_conj(f)))."""
  d0, d1, d2, d3 = _mul(t0, t1, t2, t3, f0, -f1, -f2, -f3)
  if d0 < 0.0:
    d0, d1, d2, d3 = -d0, -d1, -d2, -d3
  sine = math.sqrt(d1 * d1 + d2 * d2 + d3 * d3)
  scale = 2.0 if sine < 1e-12 else 2.0 * math.atan2(sine, d0) / sine
  out[0], out[1], out[2] = d1 * scale, d2 * scale, d3 * scale


@_jit
def named_hold(fields):
  """The `Hold` of its fields (kernels.as_fields(hold): plain tuples)."""
  return Hold(HoldParameters(*fields[0]), HoldAddresses(*fields[1]),
              HoldState(*fields[2]), fields[3], HoldData(*fields[4]))


@_jit
def target(params, state, data, com, quat):
  """The centre of mass (com, 3) and free-joint frame orientation (quat,
  4) the hand wants the body at (CompliantHold.target); params:
  HoldParameters, state: HoldState, data: HoldData."""
  mocap, eq = state.mocap[0], state.eq[0]
  mocap_pos, mocap_quat, eq_data = (data.mocap_pos, data.mocap_quat,
                                    data.eq_data)
  aim = state.aim
  h0, h1, h2, h3 = (mocap_quat[mocap, 0], mocap_quat[mocap, 1],
                    mocap_quat[mocap, 2], mocap_quat[mocap, 3])
  r0, r1, r2, r3 = eq_data[eq, 6], eq_data[eq, 7], eq_data[eq, 8], eq_data[
      eq, 9]
  q0, q1, q2, q3 = _mul(h0, h1, h2, h3, r0, r1, r2, r3)
  rotation = np.empty((3, 3))
  _matrix(h0, h1, h2, h3, rotation)
  origin = np.empty(3)
  _times(rotation, eq_data[eq, 3], eq_data[eq, 4], eq_data[eq, 5], origin)
  hand = mocap_pos[mocap]
  for i in range(3):
    origin[i] += hand[i]
  if state.aiming[0]:
    arm0, arm1 = origin[0] - hand[0], origin[1] - hand[1]
    want0, want1 = aim[0] - hand[0], aim[1] - hand[1]
    turn = math.atan2(arm0 * want1 - arm1 * want0, arm0 * want0 + arm1 * want1)
    turn = min(max(turn, -params.max_aim), params.max_aim)
    c, s = math.cos(turn), math.sin(turn)
    origin[0] = hand[0] + (c * arm0 - s * arm1)
    origin[1] = hand[1] + (s * arm0 + c * arm1)
    q0, q1, q2, q3 = _mul(math.cos(turn / 2.0), 0.0, 0.0,
                          math.sin(turn / 2.0), q0, q1, q2, q3)
    distance = math.sqrt(want0 * want0 + want1 * want1)
    error = distance - math.sqrt(arm0 * arm0 + arm1 * arm1)
    size = abs(error)
    reach = params.max_reach
    if size > reach:
      error = math.copysign(max(0.0, 2.0 * reach - size), error)
    if distance > 0.0:
      origin[0] += error * want0 / distance
      origin[1] += error * want1 / distance
  o = params.offset_quat
  f0, f1, f2, f3 = _mul(q0, q1, q2, q3, o[0], -o[1], -o[2], -o[3])
  _matrix(f0, f1, f2, f3, rotation)
  offset = np.empty(3)
  p = params.offset_pos
  _times(rotation, p[0], p[1], p[2], offset)
  lever = np.empty(3)
  c = params.com_local
  _times(rotation, c[0], c[1], c[2], lever)
  for i in range(3):
    com[i] = (origin[i] - offset[i]) + lever[i]
  quat[0], quat[1], quat[2], quat[3] = f0, f1, f2, f3


@_jit
def apply(hold):
  """Sets the body's applied force and torque for the next physics step
  (CompliantHold.apply); nothing while the hold is off. hold: a `Hold`,
  whose aim_source (3,) is copied into its aim first (CompliantHold.aim
  at every step, e.g. a site's xpos row), unless it is (0,)."""
  params, state, data = hold.parameters, hold.state, hold.data
  if not state.holding[0]:
    return
  aim_source = hold.aim_source
  if aim_source.shape[0] == 3:
    state.aim[:] = aim_source
  history, omega, fresh = state.history, state.omega, state.fresh
  qpos, qvel = data.qpos, data.qvel
  com_target, quat_target = np.empty(3), np.empty(4)
  target(params, state, data, com_target, quat_target)
  dt = params.dt
  if fresh[0] == 0:
    for i in range(3):
      history[0, i] = history[1, i] = com_target[i]
    for i in range(4):
      history[0, 3 + i] = history[1, 3 + i] = quat_target[i]
  previous = history[0].copy()
  before = history[1].copy()
  previous_velocity, acceleration = np.empty(3), np.empty(3)
  for i in range(3):
    previous_velocity[i] = (previous[i] - before[i]) / dt
    velocity = (com_target[i] - previous[i]) / dt
    acceleration[i] = (velocity - previous_velocity[i]) / dt
  previous_omega = omega.copy()
  turned = np.empty(3)
  _rotation_vector(quat_target[0], quat_target[1], quat_target[2],
                   quat_target[3], previous[3], previous[4], previous[5],
                   previous[6], turned)
  alpha = np.empty(3)
  for i in range(3):
    omega[i] = turned[i] / dt
    alpha[i] = (omega[i] - previous_omega[i]) / dt
  if fresh[0] < 2:   # no full history yet: no feed-forward
    acceleration[:] = 0.0
    alpha[:] = 0.0
  history[1] = previous
  history[0, :3] = com_target
  history[0, 3:] = quat_target
  fresh[0] = min(fresh[0] + 1, 2)

  a, v = hold.addresses.qpos, hold.addresses.qvel
  rotation = np.empty((3, 3))
  _matrix(qpos[a + 3], qpos[a + 4], qpos[a + 5], qpos[a + 6], rotation)
  lever, body_omega = np.empty(3), np.empty(3)
  c = params.com_local
  _times(rotation, c[0], c[1], c[2], lever)
  _times(rotation, qvel[v + 3], qvel[v + 4], qvel[v + 5], body_omega)
  force = np.empty(3)
  for i in range(3):
    n, p = (i + 1) % 3, (i + 2) % 3
    com = qpos[a + i] + lever[i]
    com_velocity = qvel[v + i] + (body_omega[n] * lever[p]
                                  - body_omega[p] * lever[n])
    force[i] = (params.mass * (acceleration[i] - params.gravity[i])
                + params.k * (previous[i] - com)
                + params.b * (previous_velocity[i] - com_velocity))
  axes = np.empty((3, 3))
  o = params.inertia_quat
  _matrix(o[0], o[1], o[2], o[3], axes)
  principal = np.empty((3, 3))
  for i in range(3):
    _times_transposed(axes, rotation[i, 0], rotation[i, 1], rotation[i, 2],
                      principal[i])   # row i of rotation @ axes
  error = np.empty(3)
  _rotation_vector(previous[3], previous[4], previous[5], previous[6],
                   qpos[a + 3], qpos[a + 4], qpos[a + 5], qpos[a + 6], turned)
  _times_transposed(principal, turned[0], turned[1], turned[2], error)
  omega_error = np.empty(3)
  _times_transposed(principal, previous_omega[0] - body_omega[0],
                    previous_omega[1] - body_omega[1],
                    previous_omega[2] - body_omega[2], omega_error)
  # torque = principal diag(I) principal.T alpha
  #          + principal (k_rot rotation_error + b_rot omega_error)
  local, spring = np.empty(3), np.empty(3)
  _times_transposed(principal, alpha[0], alpha[1], alpha[2], local)
  for i in range(3):
    spring[i] = (params.inertia[i] * local[i]
                 + (params.k_rot[i] * error[i]
                    + params.b_rot[i] * omega_error[i]))
  torque = np.empty(3)
  _times(principal, spring[0], spring[1], spring[2], torque)
  _limit(force, params.max_force)
  _limit(torque, params.max_torque)
  body = hold.addresses.body
  xfrc_applied = data.xfrc_applied
  for i in range(3):
    xfrc_applied[body, i] = force[i]
    xfrc_applied[body, 3 + i] = torque[i]


@_jit
def _limit(vector, largest):
  """Scales vector (3,) down to norm `largest` if longer."""
  norm = math.sqrt(vector[0] * vector[0] + vector[1] * vector[1]
                   + vector[2] * vector[2])
  if norm > largest:
    scale = largest / norm
    for i in range(3):
      vector[i] *= scale
