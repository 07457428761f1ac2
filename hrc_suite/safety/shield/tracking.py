"""How far the robot is from the shield's command: the tracking bounds.

The shield assumes the robot stays within the secure radius of its
command (docs/safety.md, Assumptions: Tracking); `TrackingBounds` says
how far joint positions put the robot's capsules from those of a
reference: a cheap upper bound from lever arms (`bound`, checked every
physics step) and the exact largest displacement (`error`, forward
kinematics, when the bound exceeds the tolerance).
"""

from typing import Optional, Tuple

import numpy as np

from hrc_suite import robot_description as robot_description_lib
from hrc_suite.safety import kernels
from hrc_suite.safety import robot_reach as robot_reach_lib
from hrc_suite.safety.shield import cycle_terms


def lever_arms(description: robot_description_lib.RobotDescription,
               tool_capsule: Optional[Tuple[np.ndarray, np.ndarray, float]]
               = None) -> np.ndarray:
  """Lever arms (m/rad): turning joint i by dq moves no point of a capsule
  axis after it (links i.. and the tool) by more than lever_i |dq| (an arc
  is longer than its chord; distances are bounded along the chain,
  cycle_terms.chain_lengths).

  Args:
    description: the robot's description.
    tool_capsule: (p1 (3,), p2 (3,), radius) of the tool's capsule in the
      last link's frame, m (None: no tool).

  Returns:
    (dof,) m/rad, read-only.
  """
  dof = description.dof
  lengths = cycle_terms.chain_lengths(description)
  p1, p2, _ = description.capsule_arrays()
  axis_ends = [max(np.linalg.norm(p1[i]), np.linalg.norm(p2[i]))
               for i in range(dof)]
  if tool_capsule is not None:
    t1, t2, _ = tool_capsule
    axis_ends[-1] = max(axis_ends[-1], np.linalg.norm(t1),
                        np.linalg.norm(t2))
  levers = np.array([
      max(lengths[j] - lengths[i] + axis_ends[j]
          for j in range(i, dof)) for i in range(dof)])
  levers.flags.writeable = False
  return levers


class TrackingBounds:
  """How far joint positions put a robot's capsules from where they are
  at reference joint positions.

  Args:
    robot: the robot's capsules (its secure radius is the tolerance).
    description: the robot's description.
    tool_capsule: (p1 (3,), p2 (3,), radius) of the tool's capsule in the
      last link's frame, m (None: no tool).
  """

  def __init__(self, robot: robot_reach_lib.RobotReach,
               description: robot_description_lib.RobotDescription,
               tool_capsule: Optional[Tuple[np.ndarray, np.ndarray, float]]
               = None):
    self._robot = robot
    self._name = description.name
    self._dof = description.dof
    self._levers = lever_arms(description, tool_capsule)

  @property
  def tolerance(self) -> float:
    """How far (m) the robot may be from its command: the secure radius,
    by which every robot reach capsule is enlarged (docs/safety.md,
    Assumptions: Tracking)."""
    return self._robot.secure_radius

  @property
  def levers(self) -> np.ndarray:
    """Lever arms (dof,) in m/rad, read-only: sum_i lever_i |q_i - p_i|
    (`bound`) bounds `error(q, p)`."""
    return self._levers

  def bound(self, q: np.ndarray, reference: np.ndarray) -> float:
    """A cheap upper bound (m) on `error(q, reference)`: the joint errors
    times `levers`.

    Args:
      q: joint positions (dof,), e.g. the measured ones.
      reference: joint positions (dof,) to compare with.

    Returns:
      The bound, m.

    Raises:
      ValueError: q or reference is not dof joint positions.
    """
    q, reference = self._joint_pair(q, reference)
    return float(np.abs(q - reference) @ self._levers)

  def error(self, q: np.ndarray, reference: np.ndarray) -> float:
    """How far (m) the robot's capsules at joint positions q are from where
    they are at `reference`: the largest displacement of a capsule axis
    end. Capsules move rigidly, so no point of a capsule moves farther
    than its farther end. (kernels.tracking_error, which
    tasks/runtime/physics_loop.py calls too; its NumPy reference is in
    tests/safety/safety_references.py, equal to round-off.)

    Args:
      q: joint positions (dof,), e.g. the measured ones.
      reference: joint positions (dof,) to compare with.

    Returns:
      The largest displacement, m.

    Raises:
      ValueError: q or reference is not dof joint positions.
    """
    q, reference = self._joint_pair(q, reference)
    robot = self._robot
    return float(kernels.tracking_error(q, reference, *robot.kernel_model,
                                        robot.kernel_frames))

  def _joint_pair(self, q, reference):
    q = np.asarray(q, dtype=float)
    reference = np.asarray(reference, dtype=float)
    if q.shape != (self._dof,) or reference.shape != (self._dof,):
      raise ValueError(f'q, reference: expected {self._dof} joint positions '
                       f'each for {self._name}, got shapes '
                       f'{q.shape} and {reference.shape}')
    return q, reference
