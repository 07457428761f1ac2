"""The arm's link energies (hrc_suite/safety/robot_energy.py) against
MuJoCo's own mass matrix and energy, on every robot."""

import mujoco
import numpy as np
import pytest

from hrc_suite import robot_description
from hrc_suite import suite
from hrc_suite.safety import robot_energy


def _moving_arm(name, seed):
  """(env, physics, robot, q, dq): the reach task's arm at a random pose
  and joint velocity, everything else at rest (keep env: physics needs
  it alive)."""
  env = suite.load('reach', 'dense', task_kwargs={'robot': name, 'seed': 0})
  env.reset()
  physics, robot = env.physics, env.task.robot
  limits = robot.description.limits
  random_state = np.random.RandomState(seed)
  q = random_state.uniform(limits.q_min, limits.q_max)
  dq = random_state.uniform(-1.0, 1.0, robot.description.dof) * np.minimum(
      limits.v_max, 2.0)
  physics.data.qvel[:] = 0.0
  robot.set_joint_positions(physics, q)
  robot.set_joint_velocities(physics, dq)
  physics.forward()
  return env, physics, robot, q, dq


@pytest.mark.parametrize('name', robot_description.ROBOT_NAMES)
def test_energies_equal_mujocos_on_every_robot(name):
  env, physics, robot, q, dq = _moving_arm(name, seed=1)
  payload = robot_energy.payload_from_physics(physics, robot)
  assert payload.mass == pytest.approx(0.9)   # The gripper: 2F-85's mass.
  arm = robot_energy.ArmInertia(robot.description, payload)
  matrix = robot_energy.mujoco_mass_matrix(physics, robot)
  np.testing.assert_allclose(arm.mass_matrix(q), matrix, rtol=1e-9,
                             atol=1e-12)
  model, data = physics.model.ptr, physics.data.ptr
  model.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_ENERGY
  mujoco.mj_forward(model, data)
  mujoco.mj_energyVel(model, data)
  energies = arm.link_energies(q, dq)
  assert energies[-1] == pytest.approx(float(data.energy[1]), rel=1e-9)
  for j in range(1, robot.description.dof + 1):
    assert energies[j - 1] == pytest.approx(
        0.5 * dq[:j] @ matrix[:j, :j] @ dq[:j], rel=1e-9)
  # Without the payload the arm is lighter.
  bare = robot_energy.ArmInertia(robot.description)
  assert bare.link_energies(q, dq)[-1] < energies[-1]
  del env


@pytest.mark.parametrize('name', ['schunk', 'panda', 'ur5e'])
def test_bounds_cover_every_contact_of_the_moving_arm(name):
  """At random points of each link and random directions, the energy of
  the arm's mass reflected there, 1/2 m_u v_u^2 (MuJoCo's Jacobian and
  mass matrix, fingers free), stays within the link's bound."""
  env, physics, robot, q, dq = _moving_arm(name, seed=2)
  arm = robot_energy.ArmInertia(
      robot.description, robot_energy.payload_from_physics(physics, robot))
  bounds = arm.contact_energy_bounds(q, dq)
  model, data = physics.model.ptr, physics.data.ptr
  full = np.zeros((model.nv, model.nv))
  mujoco.mj_fullM(model, data, full)
  inverse = np.linalg.inv(full)
  random_state = np.random.RandomState(3)
  tight = 0.0
  for j, link in enumerate(robot.link_bodies):
    body = int(physics.bind(link).element_id)
    for _ in range(20):
      point = data.xpos[body] + random_state.uniform(-0.1, 0.1, 3)
      direction = random_state.normal(size=3)
      direction /= np.linalg.norm(direction)
      jacobian = np.zeros((3, model.nv))
      mujoco.mj_jac(model, data, jacobian, None, point, body)
      speed = direction @ jacobian @ data.qvel
      mass = 1.0 / (direction @ jacobian @ inverse @ jacobian.T @ direction)
      energy = 0.5 * mass * speed ** 2
      assert energy <= bounds[j] * (1 + 1e-9), (j, energy, bounds[j])
      tight = max(tight, energy / bounds[j])
  assert tight > 0.05   # The bound is not vacuous.
  del env


def test_bad_shapes_are_named():
  description = robot_description.load('panda')
  arm = robot_energy.ArmInertia(description)
  with pytest.raises(ValueError, match=r'q has shape \(3,\)'):
    arm.mass_matrix(np.zeros(3))
  with pytest.raises(ValueError, match=r'dq has shape \(2,\)'):
    arm.link_energies(np.zeros(description.dof), np.zeros(2))
