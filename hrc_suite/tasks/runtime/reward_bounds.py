"""RewardBounds: the bounds of a task's rewards, from the task's hooks.

`reward_range` is the (lowest, highest) reward of one RL step, the
collision penalty included; `min_task_return` the lowest episode return
of the task's reward alone (no collision penalty: the paper's runs had
none), the 0 of the paper's normalised return. A task states the range
of its step reward (`_task_reward_range`) and, where failure ends an
episode with the task's lowest reward (lifting, stacking), that reward
(`_task_failure_reward`).
"""

from typing import Optional, Tuple


class RewardBounds:
  """The reward bounds of an HrcTask (which has `collision_reward` and
  `horizon`); subclasses override the two hooks."""

  @property
  def reward_range(self) -> Tuple[float, float]:
    """(lowest, highest) reward of one RL step."""
    low, high = self._task_reward_range()
    return low + min(self.collision_reward, 0.0), high

  def _task_reward_range(self):
    """(lowest, highest) reward of the task for one RL step."""
    return (0.0, 0.0)

  @property
  def min_task_return(self) -> float:
    """The lowest possible episode return of the task's reward, the 0 of
    the paper's normalised return (`min_task_return`)."""
    return min_task_return(self._task_reward_range()[0],
                           self._task_failure_reward(), self.horizon)

  def _task_failure_reward(self):
    """None, or (the reward of the step that ends an episode in failure,
    the lowest reward of any other step) where the failure's reward is the
    task's lowest and ends the episode (lifting, stacking), so that it can
    be earned once only."""
    return None


def min_task_return(lowest: float,
                    failure: Optional[Tuple[float, float]],
                    horizon: int) -> float:
  """The lowest possible episode return of a task's reward (no collision
  penalty: the paper's runs had none), the 0 of the paper's normalised
  return (docs/reference_benchmark.md, Training and evaluation).

  Without a failure reward, the lowest step reward L for every step of
  the horizon H; with one, F, and the other steps' lowest reward L, also F
  after H - 1 steps of L (or at once where L > 0):
  min(L H, F + min(L, 0) (H - 1)).

  Args:
    lowest: the lowest reward of one RL step
      (`RewardBounds._task_reward_range`).
    failure: None, or (F, L) (`RewardBounds._task_failure_reward`).
    horizon: H, RL steps.
  """
  if failure is None:
    return lowest * horizon
  failed, lowest = failure
  return min(lowest * horizon, failed + min(lowest, 0.0) * (horizon - 1))
