"""Robot-human contacts judged by energy (tasks/runtime/contact_energies.py):
the per-body maxima in the episode metrics in every mode, and the energy
judgement of the shield mode 'pfl_energy', with a person standing in the
robot's sweep (checks.human_in_robot_env)."""

import dataclasses

import numpy as np
import pytest

from hrc_suite.safety import body_regions
from hrc_suite.safety import contact_energy
from hrc_suite.safety import robot_energy
from hrc_suite.tasks.runtime import contact_energies
from hrc_suite.tasks.runtime import contacts
from hrc_suite.tasks.runtime import metrics

import checks    # tests/tasks/checks.py

RATIOS = tuple(f'contact_energy_ratio/{b}' for b in contact_energies.BODIES)


def test_an_episode_without_contact_reports_zero_maxima():
  env = checks.human_in_robot_env('ssm')
  result = metrics.run_episode(
      env, lambda timestep: np.zeros(env.action_spec().shape))
  assert result['contacts_human_allowed'] == 0
  for name in metrics.CONTACT_ENERGY_MAXIMA:
    assert result[name] == 0.0, name


def test_unshielded_push_reports_the_energies_of_the_touched_bodies():
  result = checks.push_towards_human(checks.human_in_robot_env('off'))
  assert result['contacts_human_critical'] > 0
  assert result['max_contact_energy_ratio'] == max(result[r] for r in RATIOS)
  touched = [r for r in RATIOS if result[r] > 0.0]
  assert touched
  for ratio in touched:
    assert result[ratio.replace('_ratio', '')] > 0.0
  assert result['max_contact_energy'] > 0.0


def _scaled_table(factor):
  """The body-region table with every body's limits times `factor`."""
  table = body_regions.load()
  bodies = {name: dataclasses.replace(
      limits, energy_transient=factor * limits.energy_transient,
      energy_clamped=factor * limits.energy_clamped)
            for name, limits in table.bodies.items()}
  return dataclasses.replace(table, bodies=bodies)


@pytest.mark.parametrize('factor, critical', [(1.0, False), (0.01, True)])
def test_energy_judgement_flags_contacts_over_the_limit(factor, critical):
  """A monitor judging by energy (as in 'pfl_energy') over the unshielded
  push: within the limits no contact is critical, against limits far
  below the push's energies every contact is (the check can fail)."""
  env = checks.human_in_robot_env('off')
  env.reset()
  task, physics = env.task, env.physics
  joints = physics.bind(task.robot.joints)
  shield = task.shield
  clamp = shield.clamp_geometry
  static = list(task.arena.static_geoms)
  energies = contact_energies.ContactEnergies(
      contact_energy.ContactEnergyMeter(
          task.robot.description,
          robot_energy.gripper_payload(task.robot.description.name),
          table=_scaled_table(factor)),
      physics.model.ngeom,
      physics.bind(list(task.robot.link_geoms)).element_id,
      physics.bind(list(task.gripper.geoms)).element_id,
      physics.bind(list(task.human.geoms)).element_id,
      physics.bind(static).element_id, clamp.clampable,
      shield.robot.frame_index, physics.data.ptr, physics.model.geom_size,
      clamp.box_min, clamp.box_max)
  monitor = contacts.ContactMonitor(
      physics, static, list(task.robot.link_geoms) + list(task.gripper.geoms),
      [], task.human.geoms, robot_dofs=np.array(joints.dofadr),
      robot_qpos=np.array(joints.qposadr), energies=energies,
      critical_by_energy=True)
  seen = np.zeros(len(contacts.CONTACT_TYPES), dtype=int)

  def judge(physics, random_state):
    del physics, random_state
    seen[:] += monitor.update(task._stepper.command_dq)

  env.add_extra_hook('after_substep', judge)
  checks.push_towards_human(env)
  human = seen[contacts.TYPE_INDEX['human_allowed']] + seen[
      contacts.TYPE_INDEX['human_critical']]
  assert human > 0
  assert (seen[contacts.TYPE_INDEX['human_critical']] > 0) == critical


@pytest.mark.parametrize('fast_path', [True, False])
def test_pfl_energy_keeps_the_push_within_the_limits(fast_path):
  """With the shield in 'pfl_energy' the same push touches the person
  (the mode allows contact) within every body's limit: no critical
  contact."""
  result = checks.push_towards_human(
      checks.human_in_robot_env('pfl_energy', fast_path=fast_path))
  assert result['contacts_human_critical'] == 0
  assert 0.0 < result['max_contact_energy_ratio'] <= 1.0
  assert result['contacts_human_allowed'] + result['contacts_human_pushed'] > 0


def test_fast_path_equals_the_reference_in_pfl_energy():
  """The compiled loop hands robot-human contacts to the monitor: the
  same episode metrics as the Python loop, bit for bit."""
  results = [dict(checks.push_towards_human(
      checks.human_in_robot_env('pfl_energy', fast_path=fast_path)))
             for fast_path in (True, False)]
  assert results[0] == results[1]
