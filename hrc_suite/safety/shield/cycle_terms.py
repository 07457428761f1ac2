"""The constants a shield cycle derives once from its robot and human
models: the readable cycle's terms (`CycleTerms`, `cycle_terms`) and the
compiled cycles' twin of them (`kernel_constants`, cycle_kernels.Constants).

The terms are those of the path limits (docs/shield_maths.md, 3), the
joint limits and clip bounds of a command (docs/shield_maths.md, 2), the
robot's workspace ball and the human bodies of the broad phases
(docs/shield_maths.md, 5.3).
"""

import dataclasses
from typing import Optional, Tuple

import numpy as np

from hrc_suite import robot_description as robot_description_lib
from hrc_suite.human import keypoints
from hrc_suite.safety import robot_reach as robot_reach_lib
from hrc_suite.safety.shield import cycle_kernels
from hrc_suite.safety.shield import human_reach as human_reach_lib

# Subtracted from broad-phase distance bounds (m): covers the round-off of
# computing distances from squared norms.
BROAD_PHASE_SLACK = 1e-6
# Joint-space differences below this count as "the same command" (rad, rad/s).
SAME_COMMAND = 1e-9
# The command is at rest when every joint's velocity (rad/s) and
# acceleration (rad/s^2) is within this of zero (braking ends at exactly
# zero; this only absorbs round-off).
REST_TOLERANCE = 1e-12


@dataclasses.dataclass(frozen=True)
class CycleTerms:
  """The readable cycle's constants of one robot and human model (lists
  where the cycle reads them per joint in Python, arrays where NumPy or a
  kernel reads them)."""
  # Per-joint terms of `path.path_limits` (docs/shield_maths.md, 3).
  den_offset: list
  acc_numerator: list
  jerk_numerator: list
  jerk_acc: list
  q_min: list                # rad, the joint limits.
  q_max: list
  clip: np.ndarray           # (3, dof) |dq|, |ddq|, |dddq| limits.
  clip_low: np.ndarray       # -clip.
  base: np.ndarray           # (3,) m, the robot base: the workspace centre.
  workspace_radius: float    # m, every robot point stays within it.
  body_ends: np.ndarray      # (2, B) keypoints of the bodies' ends.
  half_thickness: np.ndarray   # (B,) m.
  human_v_max: np.ndarray    # (N_kp,) m/s.
  human_delay: float         # s, the human model's measurement delay.
  human_error_pos: float     # m, the human model's position error.


def chain_lengths(description: robot_description_lib.RobotDescription
                  ) -> np.ndarray:
  """Upper bounds on each link frame's distance from the base: the sums
  of the fixed translations up to it (rotations keep lengths).

  Args:
    description: the robot's description.

  Returns:
    (dof,) m.
  """
  return np.cumsum([np.linalg.norm(l.fixed_translation)
                    for l in description.links])


def _joint_list(values):
  return [float(x) for x in values]


def cycle_terms(
    description: robot_description_lib.RobotDescription,
    robot: robot_reach_lib.RobotReach,
    human: human_reach_lib.HumanReach,
    max_s_stop: float,
    tool_capsule: Optional[Tuple[np.ndarray, np.ndarray, float]] = None
) -> CycleTerms:
  """The readable cycle's constants of a robot and a human model.

  Args:
    description: the robot's description.
    robot: the robot's capsules and reach capsules (its base and secure
      radius).
    human: the human's reachable-set model (its bodies and limits).
    max_s_stop: the description's largest stopping path time (s).
    tool_capsule: (p1 (3,), p2 (3,), radius) of the tool's capsule in the
      last link's frame, m (None: no tool).

  Returns:
    The terms.
  """
  limits = description.limits
  dof = description.dof
  a_ltt = np.abs(limits.a_max_ltt)
  den_offset = _joint_list(a_ltt * max_s_stop)
  den_offset[0] += 1e-9
  clip = np.stack([limits.v_max, limits.a_max, limits.j_max])
  # Every robot point stays within this ball around the base (the chain's
  # lengths, plus the capsule's farther end, radius and secure radius).
  lengths = chain_lengths(description)
  p1, p2, radii = description.capsule_arrays()
  extents = [lengths[i] + max(np.linalg.norm(p1[i]), np.linalg.norm(p2[i]))
             + radii[i] for i in range(dof)]
  if tool_capsule is not None:
    t1, t2, t_radius = tool_capsule
    extents.append(lengths[-1] + max(np.linalg.norm(t1), np.linalg.norm(t2))
                   + t_radius)
  config = human.config
  return CycleTerms(
      den_offset=den_offset,
      acc_numerator=_joint_list(limits.a_max - a_ltt),
      jerk_numerator=_joint_list(limits.j_max - np.abs(limits.j_max_ltt)),
      jerk_acc=_joint_list(3.0 * a_ltt),
      q_min=_joint_list(limits.q_min), q_max=_joint_list(limits.q_max),
      clip=clip, clip_low=-clip,
      base=robot.base_pose[:3, 3].copy(),
      workspace_radius=max(extents) + robot.secure_radius,
      # Keypoint indices of the human bodies' proximal and distal ends.
      body_ends=np.ascontiguousarray([
          keypoints.index([b.proximal for b in config.bodies]),
          keypoints.index([b.distal for b in config.bodies])],
                                     dtype=np.int64),
      half_thickness=np.array([b.thickness / 2 for b in config.bodies]),
      human_v_max=np.ascontiguousarray(config.v_max, dtype=float),
      human_delay=float(config.delay),
      human_error_pos=float(config.measurement_error_pos))


def kernel_constants(terms: CycleTerms,
                     limits: robot_description_lib.JointLimits,
                     robot: robot_reach_lib.RobotReach,
                     human: human_reach_lib.HumanReach, cycle_time: float,
                     interval: float) -> cycle_kernels.Constants:
  """The compiled cycles' constants (`cycle_kernels.Constants`) of a
  shield's terms and models.

  Args:
    terms: the shield's `CycleTerms`.
    limits: the robot's joint limits (robot_description.JointLimits).
    robot: the robot's capsules and reach capsules.
    human: the human's reachable-set model.
    cycle_time: the shield's cycle, s.
    interval: a reachability slice's length, s.

  Returns:
    The constants.
  """
  config = human.config
  arrays = lambda *xs: [np.ascontiguousarray(x, dtype=float) for x in xs]
  return cycle_kernels.Constants(
      cycle=cycle_kernels.CycleConstants(
          cycle=cycle_time, interval=float(interval),
          workspace=float(terms.workspace_radius),
          error_pos=float(config.measurement_error_pos),
          error_vel=float(config.measurement_error_vel),
          delay=float(config.delay),
          min_period=human_reach_lib.MIN_SAMPLE_PERIOD,
          same=SAME_COMMAND, slack=BROAD_PHASE_SLACK, rest=REST_TOLERANCE),
      joints=cycle_kernels.JointTerms(*arrays(
          terms.den_offset, terms.acc_numerator, terms.jerk_numerator,
          terms.jerk_acc, terms.q_min, terms.q_max, limits.a_max_ltt,
          terms.clip)),
      robot=cycle_kernels.RobotModel(
          *robot.kernel_model, robot.kernel_frames, robot.kernel_alpha,
          robot.kernel_static, robot.kernel_levers,
          robot.kernel_half_lengths, *arrays(terms.base)),
      human=cycle_kernels.HumanModel(
          human.kernel_v_max, human.kernel_a_max, terms.body_ends,
          human.kernel_ends, *arrays(terms.half_thickness)))
