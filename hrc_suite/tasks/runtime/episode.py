"""EpisodeProgress: where an HrcTask's episode stands between RL steps.

The task's own state of a running episode (besides its entities, the
shield, the stepping and the metrics): the joint goal of the last action,
the RL steps taken, the reward and discount of the last one and the task
rewards still owed (reward_delay), whether the episode ends, collision
prevention's random state and the person's clip count. Snapshots save and
restore it (tasks/runtime/snapshots.py). `ProgressOfTask` shows it on the task.
"""

import collections
import dataclasses

from dm_control import mjcf
import numpy as np


@dataclasses.dataclass(eq=False)   # identity: q_goal is an array
class EpisodeProgress:
  """An episode's progress; a new one starts every episode."""
  q_goal: np.ndarray         # the joint goal given to the shield
  steps: int = 0             # RL steps so far
  reward: float = 0.0        # of the last RL step
  pending_rewards: collections.deque = dataclasses.field(
      default_factory=collections.deque)   # task rewards owed, oldest first
  terminate: bool = False    # the last RL step ends the episode
  discount: float = 1.0      # of the last RL step
  cp_random: np.random.RandomState = dataclasses.field(   # collision
      default_factory=lambda: np.random.RandomState(0))   # prevention's
  clip_index: int = 0        # the person's clips completed
  clip_ended: bool = False   # a clip ended in the last RL step

  def follow_clips(self, clip_index: int) -> None:
    """Notes the person's clips completed after an RL step.

    Args:
      clip_index: the player's count of completed clips now.
    """
    self.clip_ended = clip_index != self.clip_index
    self.clip_index = clip_index

  def finish_step(self, task_reward: float, success: bool, failed: bool,
                  illegal: bool, options) -> None:
    """Ends an RL step: whether the episode ends, the reward paid (`pay`,
    and collision_reward at an illegal contact) and the discount.

    Args:
      task_reward: the task's reward for this RL step.
      success: whether the task succeeded at this RL step.
      failed: whether the episode ends in failure now.
      illegal: whether the RL step had a static, self or critical human
        contact.
      options: the task's `options.TaskOptions` (done_at_success, horizon,
        reward_delay, collision_reward).
    """
    self.terminate = failed or (success and options.done_at_success)
    last = self.terminate or self.steps >= options.horizon
    reward = self.pay(task_reward, last, options.reward_delay)
    if illegal:
      reward += options.collision_reward
    self.reward = float(reward)
    self.discount = 0.0 if self.terminate else 1.0

  def stop_at_physics_error(self) -> None:
    """Ends the episode at an RL step cut short by a physics error: reward
    0, discount 0, the rewards still owed forfeited."""
    self.terminate = True
    self.discount = 0.0
    self.reward = 0.0
    self.pending_rewards.clear()
    self.clip_ended = False

  def pay(self, task_reward: float, last: bool, delay: int) -> float:
    """The task reward paid at this RL step: the one earned `delay` RL
    steps ago (0 before), and at the episode's last step every reward
    still owed.

    Args:
      task_reward: the task's reward for this RL step.
      last: whether this RL step is the episode's last.
      delay: RL steps by which task rewards are paid late.
    """
    self.pending_rewards.append(task_reward)
    if last:
      reward = sum(self.pending_rewards)
      self.pending_rewards.clear()
    elif len(self.pending_rewards) > delay:
      reward = self.pending_rewards.popleft()
    else:
      reward = 0.0
    return reward


class ProgressOfTask:
  """An HrcTask's side of its EpisodeProgress (`self._episode`): the joint
  goal, the person's clips, and an episode's robot started elsewhere than
  home."""

  @property
  def q_goal(self) -> np.ndarray:
    """The joint goal given to the shield by the last action."""
    return self._episode.q_goal.copy()

  @property
  def clip_ended(self) -> bool:
    """Whether a clip of the person ended in the RL step just done (the
    player's sequence is endless): with `clips_completed`, "success once
    the person's motion is over" (e.g. after the retreat)."""
    return self._episode.clip_ended

  @property
  def clips_completed(self) -> int:
    """The person's clips completed this episode."""
    return self._episode.clip_index

  def start_robot_at(self, physics: mjcf.Physics, q: np.ndarray) -> None:
    """Starts the episode's robot at rest elsewhere than home (in
    `_initialize_task`): the joints, the joint goal and the shield; forwards
    the physics.

    Args:
      physics: the episode's physics.
      q: (dof,) joint positions.
    """
    physics.data.qpos[self._qpos_index] = q
    self._episode.q_goal = q.copy()
    self._shield.reset(q, 0.0)
    physics.forward()
