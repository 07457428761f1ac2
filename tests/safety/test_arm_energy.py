"""The compiled arm energy model (hrc_suite/safety/arm_energy.py,
energy_kernels.py) against pinocchio (robot_energy.ArmInertia) and MuJoCo,
its bound between plan samples, and its energy tables."""

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from hrc_suite import robot_description
from hrc_suite import suite
from hrc_suite.safety import arm_energy
from hrc_suite.safety import energy_kernels
from hrc_suite.safety import long_term_plan as ltp
from hrc_suite.safety import robot_energy

WIDTH = 6   # The shield's PFL_WINDOW.


def _payload(rng):
  axes = np.linalg.qr(rng.normal(size=(3, 3)))[0]
  return robot_energy.Payload(
      mass=rng.uniform(0.5, 2.0), center_of_mass=rng.normal(0, 0.05, 3),
      inertia=axes @ np.diag(rng.uniform(1e-3, 2e-2, 3)) @ axes.T)


def _states(description, rng, count):
  limits = description.limits
  q = rng.uniform(limits.q_min, limits.q_max, (count, description.dof))
  dq = rng.uniform(-1, 1, (count, description.dof)) * limits.v_max
  return q, dq


@pytest.mark.parametrize('name', robot_description.names())
def test_kernel_equals_pinocchio_on_every_robot(name):
  description = robot_description.load(name)
  rng = np.random.RandomState(0)
  for payload in (None, _payload(rng)):
    model = arm_energy.ArmEnergyModel(description, payload)
    q, dq = _states(description, rng, 50)
    got = model.link_energies(q, dq)
    expected = model.link_energies(q, dq, compiled=False)
    np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(
        model.contact_energy_bounds(q, dq),
        np.minimum(expected, expected[:, -1:]), rtol=1e-9, atol=1e-12)
    # Energies are quadratic in the joint velocity.
    np.testing.assert_allclose(model.link_energies(q, 0.5 * dq), 0.25 * got,
                               rtol=1e-12)
  # Only joints 1..j count for E_j: a velocity of the last joint alone
  # leaves every E_j with j < n at zero.
  alone = np.zeros(description.dof)
  alone[-1] = 1.0
  energies = model.link_energies(q[0], alone)
  np.testing.assert_array_equal(energies[:-1], 0.0)
  assert energies[-1] > 0.0


@pytest.mark.parametrize('name', robot_description.names())
def test_kernel_equals_mujoco_on_every_robot(name):
  """With the gripper's inertia read from MuJoCo, E_n is MuJoCo's kinetic
  energy and every E_j the arm block of its mass matrix's quadratic form
  (as tests/safety/test_robot_energy.py checks for pinocchio)."""
  env = suite.load('reach', 'dense', task_kwargs={'robot': name, 'seed': 0})
  env.reset()
  physics, robot = env.physics, env.task.robot
  rng = np.random.RandomState(4)
  q, dq = _states(robot.description, rng, 1)
  q, dq = q[0], np.minimum(np.abs(dq[0]), 2.0) * np.sign(dq[0])
  physics.data.qvel[:] = 0.0
  robot.set_joint_positions(physics, q)
  robot.set_joint_velocities(physics, dq)
  physics.forward()
  model = arm_energy.ArmEnergyModel(
      robot.description, robot_energy.payload_from_physics(physics, robot))
  energies = model.link_energies(q, dq)
  matrix = robot_energy.mujoco_mass_matrix(physics, robot)
  mj_model, mj_data = physics.model.ptr, physics.data.ptr
  mj_model.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_ENERGY
  mujoco.mj_forward(mj_model, mj_data)
  mujoco.mj_energyVel(mj_model, mj_data)
  assert energies[-1] == pytest.approx(float(mj_data.energy[1]), rel=1e-9)
  for j in range(1, robot.description.dof + 1):
    assert energies[j - 1] == pytest.approx(
        0.5 * dq[:j] @ matrix[:j, :j] @ dq[:j], rel=1e-9)
  del env


def test_merged_payload_equals_pinocchios_sum():
  rng = np.random.RandomState(1)
  a, b = _payload(rng), _payload(rng)
  mass, centre, inertia = arm_energy.merge_inertia(
      a.mass, a.center_of_mass, a.inertia, b.mass, b.center_of_mass,
      b.inertia)
  total = a.to_pinocchio() + b.to_pinocchio()
  assert mass == pytest.approx(total.mass, rel=1e-14)
  np.testing.assert_allclose(centre, total.lever, atol=1e-15)
  np.testing.assert_allclose(inertia, total.inertia, atol=1e-15)
  assert isinstance(total, pin.Inertia)


@pytest.mark.parametrize('name', robot_description.names())
def test_bounds_cover_the_plan_between_samples(name):
  """Evaluated as the shield evaluates a plan (Taylor polynomial from the
  sample at or before s), the contact energy bound of every link at 20
  points per cycle stays within the bound of the piece's sample, and the
  bounds are at least the energies at the samples."""
  description = robot_description.load(name)
  limits = description.limits
  rng = np.random.RandomState(2)
  model = arm_energy.ArmEnergyModel(description, _payload(rng))
  tight = 0.0
  for _ in range(2):
    goal = np.clip(description.q_home + rng.uniform(-1.5, 1.5,
                                                    description.dof),
                   limits.q_min, limits.q_max)
    plan = ltp.plan_to_goal(description.q_home, np.zeros(description.dof),
                            np.zeros(description.dof), goal, limits, 0.004)
    samples = plan._all()
    bounds = model.energy_bounds(samples, plan.cycle_time)
    at_samples = model.contact_energy_bounds(samples[:, 0], samples[:, 1])
    assert (bounds >= at_samples).all()
    s = plan.start_time + np.linspace(
        0.0, plan.end_time - plan.start_time + 0.02, 20 * len(samples))
    q, v = plan.nominal(s)[:2]
    energies = model.contact_energy_bounds(q, v)
    covering = bounds[plan.index(s)]
    assert (energies <= covering).all()
    moving = covering > 1e-3 * covering.max()
    tight = max(tight, (energies[moving] / covering[moving]).max())
  assert tight > 0.9   # The bound is close somewhere.


def test_bound_is_the_energy_at_rest_and_at_constant_speed_grows():
  description = robot_description.load('panda')
  model = arm_energy.ArmEnergyModel(description)
  samples = np.zeros((3, 4, description.dof))
  samples[:, 0] = description.q_home
  np.testing.assert_array_equal(model.energy_bounds(samples, 0.004), 0.0)
  samples[:, 1] = 0.5   # Moving, no acceleration: only q changes.
  bounds = model.energy_bounds(samples, 0.004)
  energies = model.contact_energy_bounds(samples[:, 0], samples[:, 1])
  assert (bounds > energies).all()
  assert (bounds < 1.2 * energies).all()
  # A shorter step, a smaller inflation.
  closer = model.energy_bounds(samples, 0.001)
  assert (closer < bounds).all() and (closer > energies).all()


def _brute_tables(bounds, width):
  count = len(bounds)
  window = np.array([bounds[i:min(i + width + 1, count)].max(axis=0)
                     for i in range(count)])
  suffix = np.array([bounds[i:].max() for i in range(count)])
  return window, suffix


def test_tables_equal_brute_force():
  rng = np.random.RandomState(3)
  for count in (1, 2, 6, 7, 8, 50):
    for dof in (6, 7):
      bounds = rng.uniform(0.0, 2.0, (count, dof))
      for width in (0, 1, WIDTH):
        got = energy_kernels.energy_tables(bounds, width)
        for got_table, expected in zip(got, _brute_tables(bounds, width)):
          np.testing.assert_array_equal(got_table, expected)


def test_plan_tables_are_tables_of_the_bounds():
  description = robot_description.load('ur5e')
  model = arm_energy.ArmEnergyModel(description)
  limits = description.limits
  plan = ltp.plan_to_goal(description.q_home, np.zeros(6), np.zeros(6),
                          description.q_home + 0.8, limits, 0.004)
  window, suffix = model.plan_tables(plan._all(), plan.cycle_time, WIDTH)
  expected = _brute_tables(model.energy_bounds(plan._all(), plan.cycle_time),
                           WIDTH)
  np.testing.assert_array_equal(window, expected[0])
  np.testing.assert_array_equal(suffix, expected[1])
  assert window.shape == (plan.num_samples, 6) and suffix[0] > 0.0


def test_bad_input_is_named():
  description = robot_description.load('panda')
  model = arm_energy.ArmEnergyModel(description)
  with pytest.raises(ValueError, match=r'q: expected shape \(\.\.\., 7\)'):
    model.link_energies(np.zeros(3), np.zeros(7))
  with pytest.raises(ValueError, match=r'samples: expected shape'):
    model.energy_bounds(np.zeros((3, 3, 7)), 0.004)
  with pytest.raises(ValueError, match='cycle_time=0'):
    model.energy_bounds(np.zeros((3, 4, 7)), 0)
  with pytest.raises(ValueError, match='width=-1'):
    model.plan_tables(np.zeros((3, 4, 7)), 0.004, -1)
  with pytest.raises(ValueError, match='payload.mass=-1'):
    arm_energy.ArmEnergyModel(description, robot_energy.Payload(
        -1.0, np.zeros(3), np.eye(3)))
