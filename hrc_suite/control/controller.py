"""Computed-torque joint tracking for the MuJoCo robot.

tau = M(q) (ddq_d + Kp e + Kd de) + c(q, dq) - f_passive(dq) + h D a

with e = q_d - q, de = dq_d - h/2 ddq_d - dq (MuJoCo's qvel is a half-step
velocity, see __call__), M the joint-space inertia (with armature),
c the Coriolis, centrifugal and gravity forces (MuJoCo's qfrc_bias, which
includes the gripper and anything it holds), f_passive the joint damping, and
h D a the correction for MuJoCo's Euler integrator, which treats joint damping
implicitly (it solves (M + h D) ddq = f). With this exact model the closed
loop is e'' + Kd e' + Kp e = 0 up to torque saturation and contacts; the
measured tracking error on the test trajectories is ~3e-5 rad.

The mass-matrix product runs over the whole model (mujoco.mj_mulM) with the
acceleration vector zero outside the arm's dofs, then the arm's rows are
taken: the arm's torques then include the coupling to the gripper fingers
only through bias forces, which is negligible.

Physics state must be forwarded (qM, qfrc_bias, qfrc_passive current), as it
is after dm_control's `physics.step()` or `physics.forward()`.
"""

import mujoco
import numpy as np

# Closed-loop natural frequency and damping ratio of the joint error
# dynamics. 60 rad/s (~10 Hz) is well below the 4 ms step's stability limit
# (omega h = 0.24) and well above the trajectories' bandwidth (jerk-limited,
# 10 rad/s^2 with 400 rad/s^3 ramps, i.e. ~25 ms).
DEFAULT_NATURAL_FREQUENCY = 60.0   # rad/s
DEFAULT_DAMPING_RATIO = 1.0        # critically damped


def _index(ids):
  """A slice if the ids are contiguous (views, no copies), else the array."""
  ids = np.asarray(ids, dtype=np.intp)
  if ids.size and np.array_equal(ids, np.arange(ids[0], ids[0] + ids.size)):
    return slice(int(ids[0]), int(ids[0]) + ids.size)
  return ids


class JointTrackingController:
  """Computed-torque PD tracking of desired joint states, torque-clipped."""

  def __init__(self, physics, robot,
               natural_frequency: float = DEFAULT_NATURAL_FREQUENCY,
               damping_ratio: float = DEFAULT_DAMPING_RATIO):
    if not natural_frequency > 0:
      raise ValueError('natural_frequency must be positive, got '
                       f'{natural_frequency}')
    if not damping_ratio > 0:
      raise ValueError(f'damping_ratio must be positive, got {damping_ratio}')
    self._robot = robot
    self._dof = robot.description.dof
    self.kp = natural_frequency ** 2
    self.kd = 2.0 * damping_ratio * natural_frequency
    joints = physics.bind(robot.joints)
    actuators = physics.bind(robot.actuators)
    if np.any(physics.model.jnt_type[joints.element_id] !=
              mujoco.mjtJoint.mjJNT_HINGE):
      raise ValueError('JointTrackingController needs hinge joints')
    self._qpos = _index(joints.qposadr)
    self._dofs = _index(joints.dofadr)
    self._ctrl = _index(actuators.element_id)
    self._model = physics.model.ptr
    self._data = physics.data.ptr
    self._torque_limit = np.asarray(robot.description.limits.torque,
                                    dtype=float)
    self._negative_limit = -self._torque_limit
    self._damping_step = (physics.model.dof_damping[self._dofs] *
                          physics.model.opt.timestep)
    self._half_step = physics.model.opt.timestep / 2
    self._acceleration = np.zeros(physics.model.nv)
    self._product = np.zeros(physics.model.nv)
    self._error = np.zeros(self._dof)
    self._torque = np.zeros(self._dof)
    self._scratch = np.zeros(self._dof)

  @property
  def torque_limit(self) -> np.ndarray:
    return self._torque_limit

  def __call__(self, physics, q_d, dq_d, ddq_d) -> np.ndarray:
    """Writes and returns the arm's torques for the desired joint state.

    The returned array is reused by the next call; copy it to keep it.
    """
    data = self._data
    error, scratch, acc = self._error, self._scratch, self._acceleration
    # a = ddq_d + Kp (q_d - q) + Kd (dq_d - dq)
    np.subtract(q_d, data.qpos[self._qpos], out=error)
    np.multiply(error, self.kp, out=error)
    # MuJoCo's semi-implicit Euler moves q with the end-of-step velocity, so
    # qvel acts as the velocity half a step earlier than its time stamp:
    # compare it with dq_d(t - h/2) = dq_d - h/2 ddq_d, or the damping term
    # holds a steady lag of Kd h a / (2 Kp) (6.5e-4 rad at 10 rad/s^2).
    np.multiply(ddq_d, -self._half_step, out=scratch)
    scratch += dq_d
    scratch -= data.qvel[self._dofs]
    np.multiply(scratch, self.kd, out=scratch)
    np.add(error, scratch, out=error)
    np.add(error, ddq_d, out=error)
    acc[self._dofs] = error
    mujoco.mj_mulM(self._model, data, self._product, acc)
    torque = self._torque
    np.multiply(self._damping_step, error, out=torque)
    torque += self._product[self._dofs]
    torque += data.qfrc_bias[self._dofs]
    torque -= data.qfrc_passive[self._dofs]
    np.clip(torque, self._negative_limit, self._torque_limit, out=torque)
    data.ctrl[self._ctrl] = torque
    return torque
