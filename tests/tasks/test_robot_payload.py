"""What the gripper holds reaches the shield (tasks/runtime/robot_payload.py): a
pick-and-place expert episode in the shield mode 'pfl_energy' grasps the
cube, carries it and lets go."""

import numpy as np
import pytest

from hrc_suite import experts
from hrc_suite import suite
from hrc_suite.safety import robot_energy
from hrc_suite.tasks.runtime import robot_payload

MAX_STEPS = 200


@pytest.fixture(scope='module')
def episode():
  """The environment and, per RL step, (payload, snapshot, plan energy
  tables with the payload and with the gripper alone) while held, and the
  payload after the release."""
  env = suite.load('pick_place', 'default', task_kwargs=dict(
      robot='panda', seed=0, shield='pfl_energy', done_at_success=False))
  expert = experts.make(env)
  timestep = env.reset()
  task = env.task
  assert task.robot_payload is None
  held, released = None, None
  for _ in range(MAX_STEPS):
    timestep = env.step(expert(timestep))
    payload = task.robot_payload
    if held is None and payload is not None:
      shield = task.shield
      plan = shield.state.plan
      with_payload = shield.plan_energies(plan)
      shield.set_payload(None)
      gripper_only = shield.plan_energies(plan)
      shield.set_payload(payload)
      held = (payload, task.get_state(env.physics), with_payload,
              gripper_only, shield.energy_model.payload)
    if held is not None and payload is None:
      released = task.shield.energy_model.payload
      break
  return env, held, released


def test_the_grasp_gives_the_shield_the_cube_mass(episode):
  env, held, _ = episode
  assert held is not None, 'the expert never grasped the cube'
  payload, _, _, _, shield_payload = held
  gripper = robot_energy.gripper_payload('panda')
  cube = float(env.physics.bind(env.task.cube.body).mass)
  assert payload.mass == pytest.approx(gripper.mass + cube, abs=1e-9)
  assert shield_payload is payload


def test_the_release_leaves_the_gripper(episode):
  _, _, released = episode
  gripper = robot_energy.gripper_payload('panda')
  assert released is not None, 'the expert never let the cube go'
  assert released.mass == pytest.approx(gripper.mass)


def test_verified_energy_rises_with_the_payload(episode):
  _, held, _ = episode
  _, _, (window, suffix), (window_gripper, suffix_gripper), _ = held
  moving = window_gripper > 0
  assert moving.any()
  # The last link carries the cube: its energies rise; no link's falls.
  assert np.all(window >= window_gripper)
  assert np.all(window[:, -1][moving[:, -1]]
                > window_gripper[:, -1][moving[:, -1]])
  assert np.all(suffix >= suffix_gripper)


def test_a_snapshot_restores_the_payload(episode):
  env, held, _ = episode
  payload, snapshot, _, _, _ = held
  saved = snapshot['task']['own'][robot_payload.STATE_KEY]
  assert saved['payload']['mass'] == payload.mass
  env.reset()
  assert env.task.robot_payload is None
  env.task.set_state(env.physics, snapshot)
  restored = env.task.robot_payload
  assert restored.mass == payload.mass
  np.testing.assert_array_equal(restored.center_of_mass,
                                payload.center_of_mass)
  np.testing.assert_array_equal(restored.inertia, payload.inertia)
  assert env.task.shield.energy_model.payload.mass == payload.mass
