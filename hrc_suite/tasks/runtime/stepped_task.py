"""SteppedTask: an HrcTask's side of its ShieldedStepper.

The task owns a `shielded_stepping.ShieldedStepper`
(tasks/runtime/shielded_stepping.py) that runs its physics steps. This
class is what the task adds for it: the attributes composer and
suite.Environment read about the physics steps (one composer substep per
RL step or shield_substeps), the entry point of the RL step's physics
steps as suite.Environment's only substep, and the hooks the stepper
calls on the task around every physics step, which tasks override: the
task's own work before each step and, for the compiled loop
(tasks/runtime/physics_loop.py), what that work writes.
"""

from dm_control import mjcf
import numpy as np

from hrc_suite.tasks.runtime import substeps as substeps_lib


class SteppedTask:
  """An HrcTask's side of its ShieldedStepper (`self._stepper`): what
  composer and suite.Environment ask about the physics steps, and the
  hooks the stepper calls on the task around every physics step (the
  task's own work before each and, for the compiled loop,
  tasks/runtime/physics_loop.py, what that work writes), which tasks
  override. In them the stepper's `physics_step` is the index of the coming
  physics step, its `controller` the joint tracking controller (e.g. for
  settling steps at an episode's start)."""

  @property
  def one_substep(self) -> bool:
    """Whether the RL step's physics steps run as composer's one substep
    (`ShieldedStepper.one_substep`)."""
    return self._stepper.one_substep

  @property
  def physics_steps(self) -> substeps_lib.PhysicsSteps:
    """The hooks of every physics step (`substeps.PhysicsSteps`)."""
    return self._stepper.physics_steps

  @property
  def physics_steps_per_control_step(self) -> int:
    """Composer's substeps per RL step: shield_substeps, or 1 when the
    task runs the RL step's physics steps itself (`one_substep`)."""
    return (1 if self._stepper.one_substep
            else super().physics_steps_per_control_step)

  def use_one_substep(self) -> bool:
    """`ShieldedStepper.use_one_substep` with the task's observables (call
    before the environment is built).

    Returns:
      Whether it is used.
    """
    return self._stepper.use_one_substep(self.observables)

  def run_physics_steps(self, physics: mjcf.Physics, action: np.ndarray,
                        random_state: np.random.RandomState) -> None:
    """The RL step's physics steps as suite.Environment's only substep
    (`one_substep`; `ShieldedStepper.run_physics_steps`).

    Args:
      physics: the environment's physics (its proxy).
      action: the RL step's action.
      random_state: the environment's random state.
    """
    self._stepper.run_physics_steps(physics, action, random_state)

  def _before_physics_step(self, physics):
    """A task's own work before every physics step (e.g. a grip)."""

  def _works_before_physics_steps(self):
    """Whether `_before_physics_step` has work in this RL step (a task
    that overrides it may say when it has none)."""
    return (type(self)._before_physics_step
            is not SteppedTask._before_physics_step)

  def _physics_step_writes(self, physics):
    """What `_before_physics_step` writes before each of this RL step's
    physics steps, for the compiled loop: up to two (target (n,), indices
    (m,), values (L, m)), target[indices] = values[k] before physics step
    k; None: the Python loop runs."""
    del physics
    return None

  def _physics_step_hold(self, physics):
    """The compliant hold (tool_hold.CompliantHold.kernel_arguments) that
    `_before_physics_step` applies after its writes before every physics
    step, for the compiled loop; None if there is none."""
    del physics
    return None
