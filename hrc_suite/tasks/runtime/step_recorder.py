"""StepRecorder: the metrics an HrcTask records after every RL step.

An RL step's metrics gather the task's own (`_update_task`: 'success' and
the task's counters), the action's (action_replacements, ik_failures:
`actions.StepGoal`), the step's outcome (reward, self_collisions,
goals_reached), the stepping's (shield, tracking and contacts:
`ShieldedStepper.add_step_metrics`) and, where the task has a cost, the
cost's (tasks/runtime/cost.py). The episode metrics (`metrics.EpisodeMetrics`)
accumulate them, and the episode maxima of the robot-human contact
energies (`metrics.CONTACT_ENERGY_MAXIMA`). An RL step cut short by a
physics error records none of the task's metrics, reward 0 and
physics_errors 1 (docs/safety.md, "Physics errors").
"""

from typing import Any, Dict, Optional, Sequence

from hrc_suite.tasks.runtime import actions
from hrc_suite.tasks.runtime import cost as cost_lib
from hrc_suite.tasks.runtime import metrics as metrics_lib


class StepRecorder:
  """Records an HrcTask's RL steps into its episode metrics."""

  def __init__(self, extra_counters: Sequence[str],
               cost: Optional[cost_lib.CostSpec], stepper, shield):
    """Records into new episode metrics.

    Args:
      extra_counters: the task's EXTRA_COUNTERS, step metrics the episode
        metrics sum.
      cost: the task's cost, or None (no cost metrics).
      stepper: the task's `shielded_stepping.ShieldedStepper`.
      shield: the task's `safety.shield.Shield` (its SSM clearance, for
        the cost's separation deficit).
    """
    self.cost = cost
    self.metrics = metrics_lib.EpisodeMetrics(
        tuple(extra_counters)
        + (cost_lib.metric_names() if cost is not None else ()))
    self._stepper = stepper
    self._shield = shield
    self._action = {}   # the metrics of the RL step's action

  def reset(self) -> None:
    """Forgets the last action (an episode's start)."""
    self._action = {}

  def action_taken(self, goal: actions.StepGoal) -> None:
    """Notes what became of the RL step's action.

    Args:
      goal: the action's joint goal (`actions.step_goal`).
    """
    self._action = {'action_replacements': int(goal.replaced),
                    'ik_failures': int(goal.ik_failed)}

  def record(self, step: Dict[str, Any], reward: float,
             self_collision: bool, success: bool) -> None:
    """Records an RL step that ran its physics steps.

    Args:
      step: the task's step metrics (`_update_task`), completed here.
      reward: the reward paid at the RL step.
      self_collision: whether it ended self-colliding.
      success: whether the task succeeded at it.
    """
    step.update(self._action, reward=reward,
                self_collisions=int(self_collision),
                goals_reached=int(success))
    self._record(step)

  def record_physics_error(self) -> None:
    """Records an RL step cut short by a physics error (module doc)."""
    self._record({'success': 0.0, **self._action, 'reward': 0.0,
                  'self_collisions': 0, 'goals_reached': 0,
                  'physics_errors': 1})

  def _record(self, step):
    """Adds the metrics every RL step reports; records the step."""
    self._stepper.add_step_metrics(step)
    if self.cost is not None:
      step.update(self.cost.step_metrics(step, self._shield.reach_distance))
    self.metrics.record(step)
    maxima = self._stepper.contact_energy_maxima()
    if maxima is not None:
      self.metrics.record_episode_maxima(maxima)
