"""The shield's parts (cycle_terms, tracking, energy_setup, state_io): what
they bound, and that the shield's members hand over to them."""

import numpy as np
import pytest

from hrc_suite.safety.shield import cycle_terms
from hrc_suite.safety.shield import shield as shield_lib
from hrc_suite.safety.shield import state_io

TOOL = ((0.0, 0.0, 0.11), (0.0, 0.0, 0.2), 0.05)


@pytest.fixture(scope='module')
def shield():
  return shield_lib.Shield('panda', tool_capsule=TOOL)


def test_every_capsule_stays_in_the_workspace_ball(shield):
  """Every point of the robot's capsules (the tool's included), grown by
  the secure radius, lies within the workspace radius of the base."""
  terms = shield.terms
  limits = shield.limits
  rng = np.random.RandomState(0)
  q = rng.uniform(limits.q_min, limits.q_max, (200, shield.dof))
  p1, p2, radii = shield.robot.capsules(q)
  reach = np.maximum(np.linalg.norm(p1 - terms.base, axis=-1),
                     np.linalg.norm(p2 - terms.base, axis=-1)) + radii
  assert reach.shape == (200, len(radii))
  assert (reach + shield.robot.secure_radius
          <= terms.workspace_radius + 1e-12).all()
  # Not loose by more than the chain's slack: some pose comes near it.
  assert reach.max() > 0.6 * terms.workspace_radius


def test_kernel_constants_are_the_terms(shield):
  constants = shield.kernel_constants
  terms = shield.terms
  assert constants.cycle.workspace == terms.workspace_radius
  assert constants.cycle.same == cycle_terms.SAME_COMMAND
  np.testing.assert_array_equal(constants.joints.q_min, terms.q_min)
  np.testing.assert_array_equal(constants.joints.clip, terms.clip)
  np.testing.assert_array_equal(constants.human.body_ends, terms.body_ends)
  np.testing.assert_array_equal(constants.robot.base, terms.base)


def test_tracking_members_hand_over_to_the_tracking_bounds(shield):
  rng = np.random.RandomState(1)
  q = shield.q + rng.normal(0.0, 0.05, shield.dof)
  tracking = shield.tracking
  assert shield.tracking_tolerance == tracking.tolerance
  assert shield.tracking_levers is tracking.levers
  assert shield.tracking_bound(q) == tracking.bound(q, shield.q)
  assert shield.tracking_error(q) == tracking.error(q, shield.q)
  assert 0.0 < tracking.error(q, shield.q) <= tracking.bound(q, shield.q)
  with pytest.raises(ValueError, match='expected 7 joint positions'):
    tracking.bound(q[:3], shield.q)


def test_energy_members_hand_over_to_the_energy_setup():
  shield = shield_lib.Shield('panda', mode='pfl_energy')
  energy = shield.energy
  assert shield.energy_limits is energy.limits
  assert shield.clamp_geometry is energy.clamp_geometry
  model = shield.energy_model
  assert model is energy.model
  shield.set_payload(None)   # A new model, for the gripper again.
  assert energy.model is not model
  assert energy.model.payload.mass == model.payload.mass
  plan = shield.plan
  assert shield.plan_energies(plan)[0] is energy.plan_energies(plan)[0]
  with pytest.raises(TypeError, match='expected a robot_energy.Payload'):
    energy.set_payload(1.5)


def test_the_state_dict_is_get_state(shield):
  state = state_io.state_dict(shield)
  assert state.keys() == shield.get_state().keys()
  assert state['robot'] == 'panda' and state['mode'] == 'ssm'
  limits = shield.limits
  other = shield_lib.Shield('panda', tool_capsule=TOOL,
                            q_init=0.5 * (limits.q_min + limits.q_max))
  assert not np.array_equal(other.q, shield.q)
  state_io.restore(other, state)
  np.testing.assert_array_equal(other.q, shield.q)
  with pytest.raises(ValueError, match='command: expected shape'):
    state_io.restore(other, dict(state, command=np.zeros((4, 7))))
