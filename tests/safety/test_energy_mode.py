"""The shield mode 'pfl_energy' (safety/shield/modes.py, PflEnergy): its inputs
(payload, static boxes), tables and failsafe target. Its guarantee:
test_energy_guarantee.py; compiled against readable cycles:
test_step_many.py."""

import numpy as np
import pytest

from hrc_suite import layout
from hrc_suite.safety import collision_prevention
from hrc_suite.safety import long_term_plan as ltp
from hrc_suite.safety import robot_energy
from hrc_suite.safety import shield as shield_lib
from hrc_suite.safety.shield import energy_verification
from hrc_suite.safety.shield import modes


def _plan(shield):
  limits = shield.limits
  goal = np.clip(shield.description.q_home + 0.8, limits.q_min + 0.1,
                 limits.q_max - 0.1)
  return ltp.plan_to_goal(shield.q, np.zeros(shield.dof),
                          np.zeros(shield.dof), goal, limits,
                          shield.cycle_time, 0.0)


def test_the_mode_is_registered_and_allows_contact():
  mode = modes.get('pfl_energy')
  assert mode.gates and mode.allows_contact
  assert 'pfl_energy' in modes.names()
  assert shield_lib.Shield('panda', mode='pfl_energy').speed_limit is None


def test_default_inputs_are_the_gripper_and_the_workcell():
  shield = shield_lib.Shield('schunk', mode='pfl_energy')
  gripper = robot_energy.gripper_payload('schunk')
  assert gripper.mass > 0.1
  assert shield.energy_model.payload is gripper
  boxes = collision_prevention.workcell_boxes(
      mount=layout.robot_mount('schunk'))
  np.testing.assert_array_equal(shield.clamp_geometry.box_min,
                                [low for low, _ in boxes.values()])


def test_a_heavier_payload_raises_the_plan_energies():
  shield = shield_lib.Shield('panda', mode='pfl_energy', static_boxes={})
  assert shield.clamp_geometry.box_min.shape == (0, 3)
  plan = _plan(shield)
  window, suffix = shield.plan_energies(plan)
  assert window.shape == (plan.num_samples, shield.dof)
  assert shield.plan_energies(plan)[0] is window   # Kept on the plan.
  light = suffix[0]
  payload = robot_energy.gripper_payload('panda')
  shield.set_payload(robot_energy.Payload(
      payload.mass + 2.0, payload.center_of_mass, payload.inertia))
  assert shield.plan_energies(plan)[1][0] > light
  shield.set_payload(None)
  assert shield.plan_energies(plan)[1][0] == light
  with pytest.raises(TypeError, match='robot_energy.Payload'):
    shield.set_payload(2.0)


def test_failsafe_target_is_the_coasting_speed():
  shield = shield_lib.Shield('iiwa', mode='pfl_energy')
  plan = _plan(shield)
  suffix = shield.plan_energies(plan)[1]
  limits = shield.energy_limits
  assert suffix[0] > limits.coasting   # The plan is too fast to coast.
  target = modes.get('pfl_energy').failsafe_target(shield, plan,
                                                   plan.start_time)
  assert target == energy_verification.coasting_speed(suffix[0], limits)
  assert target ** 2 * suffix[0] == pytest.approx(limits.coasting)
