"""Compiled (numba) kernels of the joint tracking controller.

`acceleration` and `torque` compute, around MuJoCo's mj_mulM, what
controller.JointTrackingController's NumPy path (its `compiled=False`
reference) computes: the same IEEE operations in the same order
(fastmath=False), so the torques are the same bit for bit
(tests/control/test_controller.py). The compiled physics loop
(tasks/runtime/physics_loop.py) calls them inside its loop with the controller's
`ControllerMemory` and `TrackingGains`.
"""

import typing

import numba
import numpy as np

_jit = numba.njit(cache=True, fastmath=False, nogil=True)


class TrackingGains(typing.NamedTuple):
  """The controller's gains and limits (fixed for a physics)."""
  kp: float                    # 1/s^2, omega^2
  kd: float                    # 1/s, 2 zeta omega
  half_step: float             # s, h / 2
  damping_step: np.ndarray     # (dof,) joint damping times h (h D)
  torque_limit: np.ndarray     # (dof,) N m


class ControllerMemory(typing.NamedTuple):
  """Where the controller reads and writes: views into MjData (its
  buffers never move) and its own buffers (float64)."""
  q: np.ndarray                  # (dof,) the arm's qpos
  dq: np.ndarray                 # (dof,) the arm's qvel
  bias: np.ndarray               # (dof,) the arm's qfrc_bias
  passive: np.ndarray            # (dof,) the arm's qfrc_passive
  ctrl: np.ndarray               # (dof,) the arm's ctrl
  acceleration: np.ndarray       # (nv,) zero outside the arm's dofs
  arm_acceleration: np.ndarray   # (dof,) the arm's block of it
  product: np.ndarray            # (nv,) M acceleration (mj_mulM)
  arm_product: np.ndarray        # (dof,) the arm's block of it
  torque: np.ndarray             # (dof,) the last torques


@_jit
def acceleration(q_d, dq_d, ddq_d, q, dq, kp, kd, half_step, out):
  """out = ddq_d + Kp (q_d - q) + Kd (dq_d - h/2 ddq_d - dq), in the
  order of the NumPy calls of JointTrackingController.__call__."""
  for i in range(out.shape[0]):
    damping = ((ddq_d[i] * -half_step + dq_d[i]) - dq[i]) * kd
    out[i] = ((q_d[i] - q[i]) * kp + damping) + ddq_d[i]


@_jit
def torque(damping_step, acceleration_, product, bias, passive, limit,
           out, ctrl):
  """out = clip(h D a + M a + c - f_passive, -limit, limit) -> ctrl."""
  for i in range(out.shape[0]):
    value = (((damping_step[i] * acceleration_[i]) + product[i]) + bias[i]
             - passive[i])
    if value < -limit[i]:
      value = -limit[i]
    elif value > limit[i]:
      value = limit[i]
    out[i] = value
    ctrl[i] = value
