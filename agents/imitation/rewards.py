"""Imitation similarities and rewards (docs/reference_benchmark.md,
Imitation; Human-Robot Gym, ICRA 2024, Sec. V).

similarity(d, iota) = 2^(-(d / iota)^2): 1 at d = 0, 1/2 at d = iota.
Vectors with a gripper part mix a position and a gripper similarity:
beta * s(|dx_pos|, iota_pos) + (1 - beta) * s(|dx_grip|, iota_grip).
The imitation reward replaces a share varsigma of the environment's:
r = (1 - varsigma) r_env + varsigma * similarity.
"""

import dataclasses
from typing import Union

import numpy as np

# Reference values (docs/reference_benchmark.md, Imitation): imitation
# weight, distance scales, and the position/gripper mixing weight of
# Cartesian tasks.
IMITATION_WEIGHT = 0.25        # varsigma (the paper's alpha)
DISTANCE_SCALE = 0.1           # iota: joints (rad), positions (m), actions
SIR_GRIPPER_SCALE = 0.01       # iota of the gripper part, state-based
AIR_GRIPPER_SCALE = 0.5        # iota of the gripper part, action-based
POSITION_WEIGHT = 0.7          # beta


def similarity(distance: Union[float, np.ndarray], scale: float
               ) -> np.ndarray:
  """2^(-(distance / scale)^2), elementwise.

  Args:
    distance: distances, >= 0.
    scale: the distance of similarity 1/2 (iota), > 0.

  Returns:
    The similarities, in (0, 1], shaped as distance.

  Raises:
    ValueError: scale is not positive.
  """
  if not scale > 0:
    raise ValueError(f'scale must be > 0, got {scale!r}')
  distance = np.asarray(distance, dtype=np.float64)
  return np.exp2(-np.square(distance / scale))


@dataclasses.dataclass(frozen=True)
class ImitationReward:
  """Similarity of a vector x to a reference x~ and the mixed reward.

  The last `gripper_size` entries (0 or 1) are the gripper part; the rest
  is the position part (a TCP position, joint positions or an arm action).
  """
  weight: float = IMITATION_WEIGHT
  scale: float = DISTANCE_SCALE
  gripper_scale: float = AIR_GRIPPER_SCALE
  position_weight: float = POSITION_WEIGHT
  gripper_size: int = 0

  def __post_init__(self):
    if not 0.0 <= self.weight <= 1.0:
      raise ValueError(f'weight must be in [0, 1], got {self.weight!r}')
    if not 0.0 <= self.position_weight <= 1.0:
      raise ValueError('position_weight must be in [0, 1], got '
                       f'{self.position_weight!r}')
    for name in ('scale', 'gripper_scale'):
      if not getattr(self, name) > 0:
        raise ValueError(f'{name} must be > 0, got {getattr(self, name)!r}')
    if self.gripper_size not in (0, 1):
      raise ValueError(f'gripper_size must be 0 or 1, got '
                       f'{self.gripper_size!r}')

  def similarity(self, x: np.ndarray, reference: np.ndarray) -> float:
    """The similarity of x to a reference: of the whole vector, or mixed
    from the position and the gripper part (see the module).

    Args:
      x: the vector (n,).
      reference: the reference vector (n,).

    Returns:
      The similarity, in (0, 1].

    Raises:
      ValueError: x and reference differ in shape.
    """
    x = np.asarray(x, dtype=np.float64)
    reference = np.asarray(reference, dtype=np.float64)
    if x.shape != reference.shape:
      raise ValueError(f'shapes differ: {x.shape} vs reference '
                       f'{reference.shape}')
    delta = x - reference
    if not self.gripper_size:
      return float(similarity(np.linalg.norm(delta), self.scale))
    arm, grip = delta[:-1], delta[-1]
    return float(self.position_weight *
                 similarity(np.linalg.norm(arm), self.scale) +
                 (1.0 - self.position_weight) *
                 similarity(abs(grip), self.gripper_scale))

  def reward(self, env_reward: float, x: np.ndarray,
             reference: np.ndarray) -> float:
    """(1 - weight) env_reward + weight * similarity(x, reference).

    Args:
      env_reward: the environment's reward.
      x: the vector (n,).
      reference: the reference vector (n,).

    Returns:
      The mixed reward.
    """
    return ((1.0 - self.weight) * float(env_reward) +
            self.weight * self.similarity(x, reference))
