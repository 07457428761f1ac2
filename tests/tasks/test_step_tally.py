"""An RL step's tally (tasks/runtime/step_tally.py): what its physics steps
add up to and the step metrics from it."""

import numpy as np
import pytest

from hrc_suite.tasks.runtime import contacts
from hrc_suite.tasks.runtime import step_tally

_TYPES = len(contacts.CONTACT_TYPES)


def _flags(*kinds):
  flags = np.zeros(_TYPES, dtype=bool)
  for kind in kinds:
    flags[int(kind)] = True
  return flags


def _metrics(tally):
  step = {}
  tally.add_step_metrics(step, min_human_distance=0.5,
                         max_human_contact_speed=0.1)
  return step


def test_contacts_flag_the_rl_step_and_count_physics_steps():
  tally = step_tally.StepTally()
  tally.begin_step(outside_model=False)
  tally.add_contacts(_flags(contacts.ContactType.human_allowed))
  tally.add_contacts(_flags(contacts.ContactType.human_allowed,
                            contacts.ContactType.robot_object))
  tally.add_contacts(_flags())
  assert tally.step_flags.tolist() == _flags(
      contacts.ContactType.human_allowed,
      contacts.ContactType.robot_object).tolist()
  assert not tally.illegal_contact
  step = _metrics(tally)
  assert step['contacts_human_allowed'] == 2
  assert step['contacts_robot_object'] == 1
  assert step['contacts_static'] == 0
  assert tally.contact_steps.tolist() == [0] * _TYPES   # restarted


def test_illegal_contacts_are_static_and_critical_ones():
  for kind in contacts.ContactType:
    tally = step_tally.StepTally()
    tally.add_contacts(_flags(kind))
    assert tally.illegal_contact == (kind in contacts.ILLEGAL_TYPES)


def test_shield_and_tracking_metrics_of_the_rl_step():
  tally = step_tally.StepTally()
  tally.begin_step(outside_model=True)
  tally.add_intervention(False)
  tally.add_intervention(True)
  tally.add_intervention(False)
  tally.add_tracking_error(0.02)
  tally.add_tracking_error(0.01)
  tally.add_resync()
  tally.add_contacts(_flags(contacts.ContactType.human_critical))
  step = _metrics(tally)
  assert step['shield_interventions'] == 1
  assert step['max_tracking_error'] == 0.02
  assert step['shield_resyncs'] == 1
  assert step['steps_outside_human_model'] == 1
  assert step['contacts_human_critical_outside_model'] == 1
  assert step['min_human_distance'] == 0.5
  assert step['max_human_contact_speed'] == 0.1
  assert step['physics_errors'] == 0
  tally.begin_step(outside_model=False)
  step = _metrics(tally)
  assert step['shield_interventions'] == 0
  assert step['max_tracking_error'] == 0.0
  assert step['shield_resyncs'] == 0
  assert step['contacts_human_critical_outside_model'] == 0


def test_the_compiled_loops_record_is_taken_over():
  tally = step_tally.StepTally()
  tally.add_tracking_error(0.01)
  tally.add_compiled(max_tracking_error=0.03, intervened=True)
  step = _metrics(tally)
  assert step['max_tracking_error'] == 0.03
  assert step['shield_interventions'] == 1


def test_flags_of_older_snapshots_restore_and_too_many_fail():
  tally = step_tally.StepTally()
  tally.add_contacts(_flags(contacts.ContactType.human_pushed))
  tally.set_flags([True, False])
  assert tally.step_flags.tolist() == _flags(
      contacts.ContactType.static).tolist()
  with pytest.raises(ValueError, match='at most'):
    tally.set_flags([False] * (_TYPES + 1))
