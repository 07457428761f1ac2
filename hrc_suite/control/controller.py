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

compiled=True (the default) computes the acceleration and the torque in
two numba kernels around mj_mulM (control/controller_kernels.py) instead
of a dozen NumPy calls; compiled=False runs the NumPy calls, the readable
reference: the same IEEE operations in the same order, so the torques are
the same bit for bit (tests/control/test_controller.py).
"""

import mujoco
import numpy as np

from hrc_suite.control import controller_kernels

# Closed-loop natural frequency and damping ratio of the joint error
# dynamics. 60 rad/s (~10 Hz) is well below the 4 ms step's stability limit
# (omega h = 0.24) and well above the trajectories' bandwidth (jerk-limited,
# 10 rad/s^2 with 400 rad/s^3 ramps, i.e. ~25 ms).
DEFAULT_NATURAL_FREQUENCY = 60.0   # rad/s
DEFAULT_DAMPING_RATIO = 1.0        # critically damped


def _contiguous(ids, what):
  """The slice covering `ids`, which must be consecutive indices."""
  ids = np.asarray(ids, dtype=np.intp)
  if not ids.size or not np.array_equal(ids, np.arange(ids[0],
                                                       ids[0] + ids.size)):
    raise ValueError(f'the robot\'s {what} are not consecutive in the model '
                     f'({ids.tolist()}); the controller reads them as one '
                     'block')
  return slice(int(ids[0]), int(ids[0]) + ids.size)


class JointTrackingController:
  """Computed-torque PD tracking of desired joint states, torque-clipped."""

  def __init__(self, physics, robot,
               natural_frequency: float = DEFAULT_NATURAL_FREQUENCY,
               damping_ratio: float = DEFAULT_DAMPING_RATIO,
               compiled: bool = True):
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
    qpos = _contiguous(joints.qposadr, 'joint positions')
    dofs = _contiguous(joints.dofadr, 'degrees of freedom')
    ctrl = _contiguous(actuators.element_id, 'actuators')
    model, data = physics.model.ptr, physics.data.ptr
    self._model, self._data = model, data
    # Views into MjData (its buffers never move): no per-call allocation.
    self._q = data.qpos[qpos]
    self._dq = data.qvel[dofs]
    self._bias = data.qfrc_bias[dofs]
    self._passive = data.qfrc_passive[dofs]
    self._ctrl = data.ctrl[ctrl]
    self._acceleration = np.zeros(model.nv)
    self._product = np.zeros(model.nv)
    self._arm_acceleration = self._acceleration[dofs]
    self._arm_product = self._product[dofs]
    self._torque_limit = np.asarray(robot.description.limits.torque,
                                    dtype=float)
    self._negative_limit = -self._torque_limit
    self._damping_step = model.dof_damping[dofs] * model.opt.timestep
    self._half_step = model.opt.timestep / 2
    self._torque = np.zeros(self._dof)
    self._scratch = np.zeros(self._dof)
    self._compiled = bool(compiled)
    # The controller's gains and memory as the compiled physics loop
    # (tasks/runtime/physics_loop.py) runs it.
    self.gains = controller_kernels.TrackingGains(
        float(self.kp), float(self.kd), float(self._half_step),
        self._damping_step, self._torque_limit)
    self.memory = controller_kernels.ControllerMemory(
        self._q, self._dq, self._bias, self._passive, self._ctrl,
        self._acceleration, self._arm_acceleration, self._product,
        self._arm_product, self._torque)

  @property
  def torque_limit(self) -> np.ndarray:
    return self._torque_limit

  def __call__(self, physics, q_d, dq_d, ddq_d) -> np.ndarray:
    """Writes and returns the arm's torques for the desired joint state.

    The returned array is reused by the next call; copy it to keep it.
    """
    if physics.data.ptr is not self._data:
      raise ValueError('this controller was built for another physics '
                       '(e.g. before a recompile); build a new one')
    if self._compiled:
      return self._call_compiled(q_d, dq_d, ddq_d)
    error, scratch = self._arm_acceleration, self._scratch
    # a = ddq_d + Kp (q_d - q) + Kd (dq_d - h/2 ddq_d - dq), written straight
    # into the arm's block of the full-size acceleration vector.
    np.subtract(q_d, self._q, out=error)
    error *= self.kp
    # MuJoCo's semi-implicit Euler moves q with the end-of-step velocity, so
    # qvel acts as the velocity half a step earlier than its time stamp:
    # compare it with dq_d(t - h/2) = dq_d - h/2 ddq_d, or the damping term
    # holds a steady lag of Kd h a / (2 Kp) (6.5e-4 rad at 10 rad/s^2).
    np.multiply(ddq_d, -self._half_step, out=scratch)
    scratch += dq_d
    scratch -= self._dq
    scratch *= self.kd
    error += scratch
    error += ddq_d
    mujoco.mj_mulM(self._model, self._data, self._product, self._acceleration)
    torque = self._torque
    np.multiply(self._damping_step, error, out=torque)
    torque += self._arm_product
    torque += self._bias
    torque -= self._passive
    np.clip(torque, self._negative_limit, self._torque_limit, out=torque)
    self._ctrl[:] = torque
    return torque

  def _call_compiled(self, q_d, dq_d, ddq_d):
    """__call__'s arithmetic in the two kernels (float64 inputs)."""
    controller_kernels.acceleration(
        q_d, dq_d, ddq_d, self._q, self._dq, self.kp, self.kd,
        self._half_step, self._arm_acceleration)
    mujoco.mj_mulM(self._model, self._data, self._product, self._acceleration)
    controller_kernels.torque(
        self._damping_step, self._arm_acceleration, self._arm_product,
        self._bias, self._passive, self._torque_limit, self._torque,
        self._ctrl)
    return self._torque
