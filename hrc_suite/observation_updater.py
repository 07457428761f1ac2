"""composer's observation Updater without its per-step schedule where
every observation is one value per RL step.

On the fast path an RL step is one composer substep (tasks/runtime/substeps.py)
and no enabled observable has a delay, a buffer or an update interval
(HrcTask.use_one_substep checks it). composer's Updater still plans each
observable's schedule before every step (`prepare_for_next_control_step`:
a schedule, a sort, a simulation of the buffer's deques), 15-20 µs per
observable on the development machine (docs/benchmarks.md, "Task code per
RL step").
`OneStepUpdater` inserts each observable's value once per RL step into
the same buffers instead: the same observations
(tests/test_observation_updater.py). With anything else enabled it is
composer's Updater.
"""

from dm_control.composer.observation import updater


def _read_once_per_step(enabled):
  """Whether an enabled observable is read once per control step: default
  update interval, delay and buffer size (no variations)."""
  return (enabled.update_interval == updater.DEFAULT_UPDATE_INTERVAL
          and enabled.delay == updater.DEFAULT_DELAY
          and enabled.buffer_size == updater.DEFAULT_BUFFER_SIZE)


class OneStepUpdater(updater.Updater):
  """updater.Updater; one insertion per observable and RL step when the
  control step is one physics step of composer's and every enabled
  observable is read once per step (decided at each reset)."""

  def __init__(self, *args, **kwargs):
    super().__init__(*args, **kwargs)
    self._once_per_step = False

  def reset(self, physics, random_state):
    super().reset(physics, random_state)
    self._once_per_step = (self._physics_steps_per_control_step == 1 and all(
        _read_once_per_step(enabled) for enabled in self._enabled_list))

  def prepare_for_next_control_step(self):
    if not self._once_per_step:
      super().prepare_for_next_control_step()

  def update(self):
    if not self._once_per_step:
      super().update()
      return
    # composer's schedule would hold exactly this step for each observable.
    self._step_counter += 1
    for enabled in self._enabled_list:
      enabled.buffer.insert(self._step_counter, updater.DEFAULT_DELAY,
                            enabled.observation_callable())
