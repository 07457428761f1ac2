"""Inverse kinematics for workspace actions: TCP position, gripper down.

The target is a full TCP pose: the given position, the TCP z axis along world
-z (gripper pointing down) and the TCP x axis at angle `yaw` about world z. The
solver is a Levenberg-Marquardt (damped least squares) iteration on the 6-D
pose error with Sugihara's error-dependent damping (T. Sugihara, "Solvability-
unconcerned inverse kinematics by the Levenberg-Marquardt method", IEEE T-RO
2011), which converges quadratically near a solution and stays well behaved at
singularities and for unreachable targets. Joint limits are respected by an
active set: joints at a limit whose step points outward are frozen for that
iteration, and every iterate is clipped into the limits, so every returned q is
within limits. A solve that does not meet the tolerances reports
`success=False` (its q is the best iterate, for diagnostics only). Collisions
(table, self) are not considered here; the collision prevention checks goals.

hrc_suite's parallel gripper is symmetric under a half turn about its axis,
so by default the TCP x axis may point along yaw or yaw + pi: the solver aims
for the one nearer the seed's TCP x axis and tries the other if that fails.
This matters for robots whose wrist joints cannot turn a full circle (the
Schunk LWA 4P cannot point its gripper down at yaw 0 in front of it).

The iteration runs compiled (`ik_kernels.solve`, compiled=True, the
default); compiled=False runs the readable reference (`_solve_reference`:
pinocchio kinematics, NumPy linear algebra), which the kernel is tested
against (tests/control/test_ik_kernels.py: same outcome, q to round-off).
"""

import dataclasses

import numpy as np
import pinocchio as pin

from hrc_suite import layout
from hrc_suite import rotations
from hrc_suite.control import ik_kernels
from hrc_suite.control import kinematics

# Reference benchmark IK: residual 1e-3, at most 50 iterations
# (docs/reference_benchmark.md, Actions); the LM iteration here converges in
# far fewer.
DEFAULT_MAX_ITERATIONS = 100
DEFAULT_POSITION_TOLERANCE = 1e-3     # m
DEFAULT_ORIENTATION_TOLERANCE = 1e-2  # rad
# Metres of error one radian of orientation error counts as in the LM cost;
# about the distance from the wrist centre to the TCP.
DEFAULT_ORIENTATION_WEIGHT = 0.2
# Constant part of the LM damping (Sugihara's w_bar), in (weighted m)^2.
DEFAULT_BASE_DAMPING = 1e-6
# A run stops as failed when its cost has not dropped by STALL_PROGRESS
# (relative) for STALL_ITERATIONS iterations: it sits in a local minimum or at
# the closest point to an unreachable target.
STALL_ITERATIONS = 10
STALL_PROGRESS = 1e-3
# Largest joint change per iteration, rad; keeps steps inside the region where
# the linearisation holds.
DEFAULT_MAX_STEP = 0.4


@dataclasses.dataclass(frozen=True)
class IkResult:
  """Outcome of one IK solve; `q` is within the joint limits."""
  q: np.ndarray
  success: bool
  position_error: float     # m, |target - tcp position|
  orientation_error: float  # rad, angle between target and TCP rotation
  iterations: int
  yaw: float                # rad, the target yaw used (yaw or yaw + pi)


def gripper_down_rotation(yaw: float) -> np.ndarray:
  """TCP rotation with z along world -z and x at `yaw` about world z."""
  c, s = np.cos(yaw), np.sin(yaw)
  # Columns: x = (c, s, 0), y = z cross x = (s, -c, 0), z = (0, 0, -1).
  return np.array([[c, s, 0.0], [s, -c, 0.0], [0.0, 0.0, -1.0]])


class InverseKinematics:
  """Gripper-down position IK for one `KinematicModel`."""

  def __init__(self, model: kinematics.KinematicModel,
               max_iterations: int = DEFAULT_MAX_ITERATIONS,
               position_tolerance: float = DEFAULT_POSITION_TOLERANCE,
               orientation_tolerance: float = DEFAULT_ORIENTATION_TOLERANCE,
               orientation_weight: float = DEFAULT_ORIENTATION_WEIGHT,
               base_damping: float = DEFAULT_BASE_DAMPING,
               max_step: float = DEFAULT_MAX_STEP,
               half_turn_symmetric: bool = True, compiled: bool = True):
    if not isinstance(model, kinematics.KinematicModel):
      raise TypeError(f'model must be a KinematicModel, got {type(model)!r}')
    if int(max_iterations) != max_iterations or max_iterations < 1:
      raise ValueError(f'max_iterations must be a positive integer, got '
                       f'{max_iterations!r}')
    for name, value in (('position_tolerance', position_tolerance),
                        ('orientation_tolerance', orientation_tolerance),
                        ('orientation_weight', orientation_weight),
                        ('base_damping', base_damping),
                        ('max_step', max_step)):
      if not np.isfinite(value) or value <= 0:
        raise ValueError(f'{name} must be a positive number, got {value!r}')
    self._model = model
    self.max_iterations = int(max_iterations)
    self.position_tolerance = float(position_tolerance)
    self.orientation_tolerance = float(orientation_tolerance)
    self._weights = np.array([1.0, 1.0, 1.0] + [orientation_weight] * 3)
    self._base_damping = float(base_damping)
    self._max_step = float(max_step)
    self._identity = np.eye(model.dof)
    self.half_turn_symmetric = bool(half_turn_symmetric)
    self.compiled = bool(compiled)
    # The kernel's chain: joint placements (base folded into the first)
    # and the TCP in the last joint's frame, from the pinocchio model.
    pin_model = model.pin_model
    self._placements = np.ascontiguousarray(
        [p.homogeneous[:3] for p in pin_model.jointPlacements[1:]])
    self._tcp = np.ascontiguousarray(
        pin_model.frames[model.tcp_frame_id].placement.homogeneous[:3])
    self._chain = ik_kernels.IkChain(self._placements, self._tcp,
                                     model.q_min, model.q_max)
    self._settings = ik_kernels.IkSettings(
        self._weights, self._base_damping, self._max_step,
        self.max_iterations, self.position_tolerance,
        self.orientation_tolerance, STALL_ITERATIONS, STALL_PROGRESS)
    # As solve_gripper_down takes them (kernels.as_fields).
    self._kernel_groups = (tuple(self._chain), tuple(self._settings))

  @property
  def model(self) -> kinematics.KinematicModel:
    return self._model

  def tcp_position(self, q) -> np.ndarray:
    """TCP position (3,) at joint positions q: the kernel's forward
    kinematics when compiled (the same bits as pinocchio's:
    tests/control/test_ik_kernels.py), else the model's (pinocchio)."""
    q = self._model.check_q(q)
    if self.compiled:
      return ik_kernels.tcp_pose(np.ascontiguousarray(q), self._placements,
                                 self._tcp)[:, 3]
    return self._model.tcp_pose(q)[:3, 3]

  def _error(self, q, target_position, target_rotation):
    """Weighted 6-D error, weighted Jacobian, position and angle errors."""
    pose, jacobian = self._model.tcp_pose_and_jacobian(q)
    error = np.empty(6)
    error[:3] = target_position - pose[:3, 3]
    error[3:] = pin.log3(target_rotation @ pose[:3, :3].T)
    weighted_error = self._weights * error
    weighted_jacobian = self._weights[:, None] * jacobian
    return (weighted_error, weighted_jacobian, float(np.linalg.norm(error[:3])),
            float(np.linalg.norm(error[3:])))

  def _check_target(self, target_position):
    target = np.asarray(target_position, dtype=float)
    if target.shape != (3,) or not np.isfinite(target).all():
      raise ValueError('target_position must be 3 finite numbers (world x, y, '
                       f'z in m), got {np.asarray(target_position).tolist()!r}')
    return target

  def solve(self, target_position, q_init, yaw: float = 0.0) -> IkResult:
    """TCP at target_position, gripper down at `yaw`, starting from q_init.

    With half_turn_symmetric, the yaw or yaw + pi nearer the start's TCP
    heading is tried first, the other if that fails.
    """
    target = self._check_target(target_position)
    if not np.isfinite(yaw):
      raise ValueError(f'yaw must be a finite angle in rad, got {yaw!r}')
    q = self._model.check_q(q_init)
    if self.compiled:   # All of it in one call (ik_kernels).
      q, success, position_error, angle_error, iterations, used = (
          ik_kernels.solve_gripper_down(
              np.ascontiguousarray(q), target, float(yaw),
              self.half_turn_symmetric, *self._kernel_groups))
      return IkResult(q, bool(success), float(position_error),
                      float(angle_error), int(iterations), float(used))
    q = np.minimum(np.maximum(q, self._model.q_min), self._model.q_max)
    if not self.half_turn_symmetric:
      return self._solve_reference(target, q, float(yaw))
    seed_x_axis = self._model.tcp_pose(q)[:2, 0]
    seed_yaw = np.arctan2(seed_x_axis[1], seed_x_axis[0])
    nearer = float(yaw)
    if abs(rotations.wrap_angle(seed_yaw - yaw)) > np.pi / 2:
      nearer = float(rotations.wrap_angle(yaw + np.pi))
    result = self._solve_reference(target, q, nearer)
    if result.success:
      return result
    other = self._solve_reference(
        target, q, float(rotations.wrap_angle(nearer + np.pi)))
    if other.success or other.position_error < result.position_error:
      return dataclasses.replace(
          other, iterations=other.iterations + result.iterations)
    return dataclasses.replace(
        result, iterations=other.iterations + result.iterations)

  def _solve_reference(self, target, q, yaw):
    """One LM run for a fixed target rotation (NumPy, pinocchio)."""
    q_min, q_max = self._model.q_min, self._model.q_max
    rotation = gripper_down_rotation(yaw)
    best, last_progress = None, 0
    for iteration in range(self.max_iterations + 1):
      error, jacobian, position_error, angle_error = self._error(
          q, target, rotation)
      cost = float(error @ error)
      if (position_error <= self.position_tolerance and
          angle_error <= self.orientation_tolerance):
        return IkResult(q, True, position_error, angle_error, iteration, yaw)
      if best is None or cost < best[0]:
        if best is None or cost < (1.0 - STALL_PROGRESS) * best[0]:
          last_progress = iteration
        best = (cost, q.copy(), position_error, angle_error)
      if (iteration == self.max_iterations or
          iteration - last_progress >= STALL_ITERATIONS):
        break
      step = self._step(q, error, jacobian, cost)
      q = np.clip(q + step, q_min, q_max)
    _, q, position_error, angle_error = best
    return IkResult(q, False, position_error, angle_error, iteration, yaw)

  def _step(self, q, error, jacobian, cost):
    """LM step with joints that sit at a limit and push outward frozen."""
    gradient = jacobian.T @ error
    hessian = jacobian.T @ jacobian
    damping = (0.5 * cost + self._base_damping) * self._identity
    step = np.linalg.solve(hessian + damping, gradient)
    frozen = (((q <= self._model.q_min) & (step < 0)) |
              ((q >= self._model.q_max) & (step > 0)))
    if np.any(frozen):
      free = ~frozen
      step = np.zeros_like(step)
      sub = hessian[np.ix_(free, free)] + damping[np.ix_(free, free)]
      step[free] = np.linalg.solve(sub, gradient[free])
    largest = np.max(np.abs(step))
    if largest > self._max_step:
      step *= self._max_step / largest
    return step

  def solve_with_restarts(self, target_position, q_init,
                          random_state: np.random.RandomState,
                          yaw: float = 0.0, restarts: int = 50) -> IkResult:
    """`solve` from q_init, then from uniform random joint vectors.

    Returns the first success, otherwise the failed attempt with the smallest
    position error. Slow; meant for planning-time searches (home poses,
    reachability), not per-step use.
    """
    if not isinstance(random_state, np.random.RandomState):
      raise TypeError('random_state must be a np.random.RandomState, got '
                      f'{type(random_state)!r}')
    best = self.solve(target_position, q_init, yaw)
    for _ in range(restarts):
      if best.success:
        break
      seed = random_state.uniform(self._model.q_min, self._model.q_max)
      result = self.solve(target_position, seed, yaw)
      if result.success or result.position_error < best.position_error:
        best = result
    return best


# Box of TCP targets over the table for evaluating workspace IK, in the base
# frame (base at the table's near edge, table top at base height; layout.py):
# from just above the table top (a 4 cm cube's centre) to 0.4 m above it.
TABLE_WORKSPACE_LOW = (0.25, -0.40, 0.02)   # m
TABLE_WORKSPACE_HIGH = (0.70, 0.40, 0.40)   # m
# TCP of the nominal home pose, base frame, m; robots whose home TCP is
# closer to the base get a box scaled down by the same factor.
NOMINAL_HOME_TCP = (0.45, 0.0, 0.25)


def workspace_scale(model: kinematics.KinematicModel) -> float:
  """Scale of the table workspace boxes about the base: the mount's
  (layout.RobotMount.workspace_scale) or the robot's home-TCP distance over
  NOMINAL_HOME_TCP's (at most 1)."""
  mount = layout.robot_mount(model.description.name)
  if mount.workspace_scale is not None:
    return float(mount.workspace_scale)
  base = model.base_pose
  home = base[:3, :3].T @ (model.tcp_pose(model.description.q_home)[:3, 3] -
                           base[:3, 3])
  home[2] += mount.height_above_table   # Measured from the table top.
  return min(1.0, np.linalg.norm(home) / np.linalg.norm(NOMINAL_HOME_TCP))


def table_workspace_box(model: kinematics.KinematicModel):
  """(low, high) corners of the robot's table workspace box, base frame, m.

  TABLE_WORKSPACE_LOW/HIGH scaled about the base by `workspace_scale`; the
  heights count from the table top, which lies the mount's
  height_above_table below the base.
  """
  scale = workspace_scale(model)
  drop = np.array([0.0, 0.0,
                   layout.robot_mount(model.description.name)
                   .height_above_table])
  return (scale * np.asarray(TABLE_WORKSPACE_LOW) - drop,
          scale * np.asarray(TABLE_WORKSPACE_HIGH) - drop)


def sample_table_targets(model: kinematics.KinematicModel, num_targets: int,
                         random_state: np.random.RandomState) -> np.ndarray:
  """(num_targets, 3) world TCP targets uniform in `table_workspace_box`."""
  if not isinstance(random_state, np.random.RandomState):
    raise TypeError('random_state must be a np.random.RandomState, got '
                    f'{type(random_state)!r}')
  low, high = table_workspace_box(model)
  local = random_state.uniform(low, high, size=(int(num_targets), 3))
  base = model.base_pose
  return local @ base[:3, :3].T + base[:3, 3]
