"""The shield's compiled energy PFL tables of a plan
(hrc_suite/safety/shield/energy_table_kernels.py) against their reference
a sample at a time (arm_energy.ArmEnergyModel.plan_tables), bit for bit."""

import numpy as np
import pytest

from hrc_suite import robot_description
from hrc_suite.safety import arm_energy
from hrc_suite.safety import energy_kernels
from hrc_suite.safety import long_term_plan as ltp
from hrc_suite.safety import robot_energy
from hrc_suite.safety.shield import energy_table_kernels as etk
from hrc_suite.safety.shield import shield as shield_lib

WIDTH = shield_lib.PFL_WINDOW
STEP = 0.004


def _payload(rng):
  axes = np.linalg.qr(rng.normal(size=(3, 3)))[0]
  return robot_energy.Payload(
      mass=rng.uniform(0.5, 2.0), center_of_mass=rng.normal(0, 0.05, 3),
      inertia=axes @ np.diag(rng.uniform(1e-3, 2e-2, 3)) @ axes.T)


def _same_bits(got, expected):
  got, expected = np.asarray(got), np.asarray(expected)
  assert got.shape == expected.shape
  assert got.tobytes() == expected.tobytes()


def _random_samples(description, rng, count):
  limits = description.limits
  samples = rng.uniform(-3, 3, (count, 4, description.dof))
  samples[:, 0] = rng.uniform(limits.q_min, limits.q_max,
                              (count, description.dof))
  return samples


@pytest.mark.parametrize('name', robot_description.names())
def test_tables_equal_the_reference_on_plans_and_random_states(name):
  description = robot_description.load(name)
  limits = description.limits
  rng = np.random.RandomState(7)
  for payload in (None, _payload(rng)):
    model = arm_energy.ArmEnergyModel(description, payload)
    for _ in range(3):
      goal = np.clip(description.q_home + rng.uniform(
          -1.5, 1.5, description.dof), limits.q_min, limits.q_max)
      plan = ltp.plan_to_goal(description.q_home, np.zeros(description.dof),
                              np.zeros(description.dof), goal, limits, STEP)
      samples = plan._all()
      expected = model.plan_tables(samples, STEP, WIDTH)
      got = etk.plan_energy_tables(samples, model.kernel_arrays, STEP, WIDTH)
      for got_table, expected_table in zip(got, expected):
        _same_bits(got_table, expected_table)
    # Random states (velocities, accelerations and jerks of both signs,
    # at rest joints included): the bounds themselves.
    samples = _random_samples(description, rng, 300)
    samples[::7, 1:] = 0.0
    _same_bits(etk.plan_energy_bounds(samples, model.kernel_arrays, STEP),
               model.energy_bounds(samples, STEP))


@pytest.mark.parametrize('count', [
    1, etk.BLOCK - 1, etk.BLOCK, etk.BLOCK + 1, 3 * etk.BLOCK + 5])
def test_tables_across_block_edges(count):
  # Samples are computed a block at a time: every length, a partial last
  # block included, gives the tables of the bounds one sample at a time.
  description = robot_description.load('ur5e')
  model = arm_energy.ArmEnergyModel(description)
  samples = _random_samples(description, np.random.RandomState(count), count)
  samples.flags.writeable = False   # Plans' samples may be read-only.
  got = etk.plan_energy_tables(samples, model.kernel_arrays, STEP, WIDTH)
  expected = energy_kernels.energy_tables(model.energy_bounds(samples, STEP),
                                          WIDTH)
  for got_table, expected_table in zip(got, expected):
    _same_bits(got_table, expected_table)


def test_the_shield_keeps_the_tables_of_its_model():
  description = robot_description.load('panda')
  shield = shield_lib.Shield(description, mode='pfl_energy')
  limits = description.limits
  goal = np.clip(description.q_home + 0.7, limits.q_min, limits.q_max)
  plan = ltp.plan_to_goal(description.q_home, np.zeros(7), np.zeros(7), goal,
                          limits, shield.cycle_time)
  window, suffix = shield.plan_energies(plan)
  expected = shield.energy_model.plan_tables(plan.samples(),
                                             shield.cycle_time, WIDTH)
  _same_bits(window, expected[0])
  _same_bits(suffix, expected[1])
  assert shield.plan_energies(plan)[0] is window   # Kept on the plan.
