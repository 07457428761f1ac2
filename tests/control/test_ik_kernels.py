"""The compiled IK (ik_kernels, InverseKinematics(compiled=True)) against
the NumPy/pinocchio reference (compiled=False) on every robot: the same
outcome (success, iterations, the yaw but for a failure's tie) and q to
round-off, from home, along random walks, near the joint limits and for
unreachable targets."""

import numpy as np
import pinocchio as pin
import pytest

from hrc_suite import layout
from hrc_suite import robot_description
from hrc_suite import rotations
from hrc_suite.control import ik
from hrc_suite.control import ik_kernels
from hrc_suite.control import kinematics

# Solutions agree to this (rad): round-off through a few LM iterations.
Q_TOLERANCE = 1e-8


def _solvers(name):
  description = robot_description.load(name)
  model = kinematics.KinematicModel(
      description, layout.robot_mount(name).base_pose())
  return (model, ik.InverseKinematics(model),
          ik.InverseKinematics(model, compiled=False))


def _agree(fast, reference, target, q_init, yaw=0.0):
  a = fast.solve(target, q_init, yaw)
  b = reference.solve(target, q_init, yaw)
  assert a.success == b.success
  assert a.iterations == b.iterations
  assert abs(a.position_error - b.position_error) < 1e-9
  if a.yaw != b.yaw:
    # Only a failure's two runs (yaw and yaw + pi) can tie on the error
    # (a half turn of the last joint): either is reported.
    assert not a.success
    return a
  assert np.max(np.abs(a.q - b.q)) < Q_TOLERANCE
  return a


def _near_limits(model, rs):
  """Joint vectors with about half the joints within 0.05 rad of a limit."""
  q = rs.uniform(model.q_min, model.q_max)
  at = rs.rand(model.dof) < 0.5
  low = rs.rand(model.dof) < 0.5
  edge = np.where(low, model.q_min + rs.uniform(0.0, 0.05, model.dof),
                  model.q_max - rs.uniform(0.0, 0.05, model.dof))
  return np.where(at, edge, q)


@pytest.mark.parametrize('name', robot_description.ROBOT_NAMES)
def test_kinematics_match_pinocchio(name):
  model, fast, _ = _solvers(name)
  rs = np.random.RandomState(0)
  frames = np.empty((model.dof, 3, 4))
  pose = np.empty((3, 4))
  for _ in range(20):
    q = rs.uniform(model.q_min, model.q_max)
    ik_kernels.forward(q, fast._placements, fast._tcp, frames, pose)
    reference, jacobian = model.tcp_pose_and_jacobian(q)
    np.testing.assert_allclose(pose, reference[:3], atol=1e-12)
    error = np.empty(6)
    kernel_jacobian = np.empty((6, model.dof))
    ik_kernels._error(q, np.zeros(3), np.eye(3), fast._placements,
                      fast._tcp, np.ones(6), frames, pose, error,
                      kernel_jacobian)
    np.testing.assert_allclose(kernel_jacobian, jacobian, atol=1e-12)


@pytest.mark.parametrize('name', robot_description.ROBOT_NAMES)
def test_tcp_position_is_pinocchios_bit_for_bit(name):
  # The Cartesian action's TCP (actions.CartesianActionSpace.target) comes
  # from the kernel's forward kinematics: the same operations as
  # pinocchio's, so the same bits, inside the limits, at them and beyond.
  model, fast, reference = _solvers(name)
  rs = np.random.RandomState(2)
  span = model.q_max - model.q_min
  for k in range(400):
    q = rs.uniform(model.q_min - 0.1 * span, model.q_max + 0.1 * span)
    if k % 4 == 0:
      q = _near_limits(model, rs)
    expected = model.tcp_pose(q)[:3, 3]
    assert fast.tcp_position(q).tobytes() == expected.tobytes(), q.tolist()
    assert reference.tcp_position(q).tobytes() == expected.tobytes()
  with pytest.raises(ValueError, match='finite'):
    fast.tcp_position(np.full(model.dof, np.nan))


def test_log3_matches_pinocchio_including_near_pi_and_zero():
  rs = np.random.RandomState(1)
  out = np.empty(3)
  angles = np.concatenate([rs.uniform(0, np.pi, 200), [0.0, 1e-9, 1e-5,
                                                        np.pi - 1e-4,
                                                        np.pi - 1e-7, np.pi]])
  for angle in angles:
    axis = rs.normal(size=3)
    axis /= np.linalg.norm(axis)
    rotation = pin.exp3(angle * axis)
    ik_kernels.log3(rotation, out)
    expected = pin.log3(rotation)
    if angle > np.pi - 1e-6:   # +-axis: the same rotation.
      assert min(np.abs(out - expected).max(),
                 np.abs(out + expected).max()) < 1e-6
    else:
      np.testing.assert_allclose(out, expected, atol=1e-9)


@pytest.mark.parametrize('name', robot_description.ROBOT_NAMES)
def test_compiled_ik_agrees_from_home_and_on_a_walk(name):
  model, fast, reference = _solvers(name)
  rs = np.random.RandomState(2)
  targets = ik.sample_table_targets(model, 30, rs)
  solved = 0
  for target in targets:
    solved += _agree(fast, reference, target,
                     model.description.q_home).success
  assert solved > 20
  q = model.description.q_home
  target = model.tcp_pose(q)[:3, 3]
  low, high = ik.table_workspace_box(model)
  for _ in range(30):
    target = target + rs.uniform(-0.1, 0.1, 3)
    result = _agree(fast, reference, target, q, yaw=rs.uniform(-3, 3))
    if result.success:
      q = result.q


@pytest.mark.parametrize('name', robot_description.ROBOT_NAMES)
def test_compiled_ik_agrees_near_the_joint_limits(name):
  """Seeds and targets' postures near the limits: the active set (frozen
  joints) and the clipping are exercised; both outcomes occur."""
  model, fast, reference = _solvers(name)
  rs = np.random.RandomState(3)
  outcomes = set()
  for _ in range(40):
    seed = _near_limits(model, rs)
    target = model.tcp_pose(_near_limits(model, rs))[:3, 3]
    outcomes.add(_agree(fast, reference, target, seed).success)
  assert outcomes == {True, False}


@pytest.mark.parametrize('name', ['panda', 'schunk'])
def test_compiled_ik_agrees_on_unreachable_targets(name):
  model, fast, reference = _solvers(name)
  base = model.base_pose[:3, 3]
  for offset in ((2.0, 0.0, 0.3), (0.0, -1.5, 0.5), (0.0, 0.0, 1.6)):
    result = _agree(fast, reference, base + offset,
                    model.description.q_home)
    assert not result.success


def _two_runs(solver, target, q_init, yaw):
  """InverseKinematics.solve's half-turn rule around ik_kernels.solve,
  composed in Python (what solve_gripper_down does in one call)."""
  model = solver.model
  q = np.minimum(np.maximum(q_init, model.q_min), model.q_max)
  # The solver's own groups (InverseKinematics builds them once).
  chain = solver._chain   # pylint: disable=protected-access
  settings = solver._settings   # pylint: disable=protected-access
  run = lambda y: ik_kernels.solve(q, target, ik.gripper_down_rotation(y),
                                   chain, settings) + (y,)
  seed = ik_kernels.tcp_pose(q, solver._placements, solver._tcp)   # pylint: disable=protected-access
  nearer = float(yaw)
  if abs(rotations.wrap_angle(np.arctan2(seed[1, 0], seed[0, 0]) - yaw)) > (
      np.pi / 2):
    nearer = float(rotations.wrap_angle(yaw + np.pi))
  first = run(nearer)
  if first[1]:
    return first
  other = run(float(rotations.wrap_angle(nearer + np.pi)))
  count = first[4] + other[4]
  if other[1] or other[2] < first[2]:
    return other[:4] + (count, other[5])
  return first[:4] + (count, first[5])


@pytest.mark.parametrize('name', ['panda', 'schunk'])
def test_one_call_is_the_half_turn_rule_around_the_kernel_bit_for_bit(name):
  """solve_gripper_down (InverseKinematics.solve's compiled path) returns
  what the half-turn rule composed around ik_kernels.solve returns, bit
  for bit: reachable, unreachable and clipped starts, random yaws."""
  model, fast, _ = _solvers(name)
  q_home = robot_description.load(name).q_home
  home = model.tcp_pose(q_home)[:3, 3]
  rng = np.random.RandomState(11)
  outcomes = set()
  for i in range(60):
    # Starts near home (some beyond the limits: clipped) or anywhere.
    q_init = (q_home + rng.uniform(-0.4, 0.4, model.dof) if i % 2 else
              rng.uniform(model.q_min - 0.2, model.q_max + 0.2))
    target = home + rng.uniform(-0.4, 0.4, 3) * (1.0 if i % 3 else 4.0)
    yaw = rng.uniform(-4.0, 4.0)
    expected = _two_runs(fast, target, q_init, yaw)
    got = fast.solve(target, q_init, yaw)
    assert got.q.tobytes() == expected[0].tobytes()
    assert (got.success, got.position_error, got.orientation_error,
            got.iterations, got.yaw) == (bool(expected[1]), expected[2],
                                         expected[3], expected[4],
                                         expected[5])
    outcomes.add(got.success)
  assert outcomes == {True, False}
