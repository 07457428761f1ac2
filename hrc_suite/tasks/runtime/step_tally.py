"""StepTally: what an RL step's physics steps add up to, and its metrics.

Over the physics steps of one RL step (tasks/runtime/shielded_stepping.py)
the tally keeps whether the shield intervened, the shield's resyncs (a
pushed robot; docs/safety.md, "Pushed robots"), the largest tracking
error, whether the person moved faster than the shield's human model, and
the contacts: the RL step's flags (contacts.CONTACT_TYPES; observables and
the reward read them) and the physics steps with each contact type (the
step metrics' contacts_<type>, tasks/runtime/metrics.py). The compiled
physics loop (tasks/runtime/physics_loop.py) writes the flags and counts
in place.
"""

from typing import Optional

import numpy as np

from hrc_suite.tasks.runtime import contacts
from hrc_suite.tasks.runtime import metrics as metrics_lib

# Flag positions of the contacts that cost collision_reward.
_ILLEGAL_FLAGS = tuple(int(kind) for kind in contacts.ILLEGAL_TYPES)
# The step metrics of the contact counts, in contacts.CONTACT_TYPES' order.
_CONTACT_METRICS = tuple(f'contacts_{name}' for name in contacts.CONTACT_TYPES)


class StepTally:
  """The shield, tracking and contact record of the current RL step."""

  def __init__(self):
    self._step_flags = np.zeros(len(contacts.CONTACT_TYPES), dtype=bool)
    self._contact_steps = np.zeros(len(contacts.CONTACT_TYPES), dtype=int)
    self.reset()

  def reset(self) -> None:
    """The record of an episode's start."""
    self.begin_step(outside_model=False)
    self._contact_steps[:] = 0

  def begin_step(self, outside_model: bool) -> None:
    """Starts an RL step's record (the contact counts run on until
    `add_step_metrics`).

    Args:
      outside_model: whether the person moves faster than the shield's
        human model in this RL step.
    """
    self._intervened = False
    self._step_flags[:] = False
    self._resyncs = 0
    self._max_tracking_error = 0.0
    self._outside_model = outside_model

  @property
  def step_flags(self) -> np.ndarray:
    """Contact flags of this RL step (contacts.CONTACT_TYPES), updated in
    place (observables read the array)."""
    return self._step_flags

  @property
  def contact_steps(self) -> np.ndarray:
    """Physics steps with each contact type (contacts.CONTACT_TYPES) since
    the last `add_step_metrics`, updated in place."""
    return self._contact_steps

  @property
  def max_tracking_error(self) -> float:
    """m, the largest tracking error of this RL step's physics steps."""
    return self._max_tracking_error

  @property
  def illegal_contact(self) -> bool:
    """Whether this RL step had a static or critical human contact
    (contacts.ILLEGAL_TYPES: with self-collisions, what costs
    collision_reward)."""
    flags = self._step_flags
    for kind in _ILLEGAL_FLAGS:
      if flags[kind]:
        return True
    return False

  def add_intervention(self, intervened: bool) -> None:
    """Adds a physics step's shield cycle.

    Args:
      intervened: whether the shield overrode the intended motion in it.
    """
    self._intervened |= intervened

  def add_tracking_error(self, distance: float) -> None:
    """Adds a physics step's tracking error.

    Args:
      distance: m, how far the robot is from where the command puts it.
    """
    if distance > self._max_tracking_error:
      self._max_tracking_error = distance

  def add_contacts(self, flags: np.ndarray) -> None:
    """Adds a physics step's contact flags (contacts.ContactMonitor.update).

    Args:
      flags: (len(contacts.CONTACT_TYPES),) bool.
    """
    if flags.any():
      self._step_flags |= flags
      self._contact_steps += flags

  def add_resync(self) -> None:
    """Adds a resynchronisation of the shield (a pushed robot)."""
    self._resyncs += 1

  def add_compiled(self, max_tracking_error: float, intervened: bool) -> None:
    """Adds what the compiled physics loop recorded of its physics steps
    (physics_loop.CompiledSteps.record, which started from
    `max_tracking_error`); it wrote the contact flags and counts in place.

    Args:
      max_tracking_error: m, the largest tracking error so far.
      intervened: whether the shield intervened in its physics steps.
    """
    self._max_tracking_error = max_tracking_error
    self._intervened |= intervened

  def set_flags(self, step_flags) -> None:
    """Restores the contact flags a snapshot keeps.

    Args:
      step_flags: contact flags; a snapshot from before a contact type was
        added holds fewer (new types go last: contacts.CONTACT_TYPES).

    Raises:
      ValueError: more flags than contact types.
    """
    flags = np.asarray(step_flags, dtype=bool)
    if flags.shape[0] > self._step_flags.shape[0]:
      raise ValueError(f'step_flags: expected at most '
                       f'{self._step_flags.shape[0]} contact flags '
                       f'({", ".join(contacts.CONTACT_TYPES)}), got '
                       f'{flags.shape[0]}')
    self._step_flags[:] = False
    self._step_flags[:flags.shape[0]] = flags

  def add_step_metrics(self, step: dict, min_human_distance: float,
                       max_human_contact_speed: float) -> None:
    """Adds the RL step's shield, tracking and contact metrics to `step`
    and restarts the contact counts.

    Args:
      step: the RL step's metrics so far.
      min_human_distance: m, the shield's `min_distance`.
      max_human_contact_speed: m/s, the contact monitor's.
    """
    step['shield_interventions'] = int(self._intervened)
    step['min_human_distance'] = min_human_distance
    step['steps_outside_human_model'] = int(self._outside_model)
    step['max_human_contact_speed'] = max_human_contact_speed
    step['shield_resyncs'] = self._resyncs
    step['max_tracking_error'] = self._max_tracking_error
    step.setdefault('physics_errors', 0)
    step.update(zip(_CONTACT_METRICS, self._contact_steps.tolist()))
    critical = step['contacts_human_critical']
    step['contacts_human_critical_outside_model'] = (
        critical if self._outside_model else 0)
    self._contact_steps[:] = 0


def contact_energy_maxima(monitor: contacts.ContactMonitor) -> Optional[dict]:
  """An RL step's largest robot-human contact energies and ratios
  (metrics.contact_energy_maxima), or None where it measured none (no
  robot-human contact, or a monitor without energies): all zeros, which
  raise no episode maximum.

  Args:
    monitor: the contact monitor of the RL step.

  Returns:
    {name: value} of metrics.CONTACT_ENERGY_MAXIMA, or None.
  """
  energies = monitor.energies
  if (energies is None or not energies.measured
      or not (energies.max_energy.any() or energies.max_ratio.any())):
    return None
  return metrics_lib.contact_energy_maxima(energies.max_energy,
                                           energies.max_ratio)
