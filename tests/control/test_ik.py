"""Tests for the gripper-down workspace inverse kinematics."""

import numpy as np
import pytest

from hrc_suite import layout
from hrc_suite import robot_description
from hrc_suite.control import ik
from hrc_suite.control import kinematics

ROBOTS = robot_description.ROBOT_NAMES
ACCURACY = 5e-3  # m, issue 2's requirement on reachable table targets.


def _world_model(name):
  return kinematics.KinematicModel(
      robot_description.load(name),
      base_pose=layout.robot_mount(name).base_pose())


def _assert_within_limits(model, q):
  assert np.all(q >= model.q_min) and np.all(q <= model.q_max), q


def _assert_gripper_down(model, result, yaw):
  pose = model.tcp_pose(result.q)
  np.testing.assert_allclose(pose[:3, 2], (0, 0, -1), atol=0.02)
  # The x axis is along yaw or yaw + pi (the gripper is half-turn symmetric).
  x_axis = pose[:2, 0] / np.linalg.norm(pose[:2, 0])
  assert abs(np.cross(x_axis, (np.cos(yaw), np.sin(yaw)))) < 0.02


def _success_rate(model, targets, random_state):
  """(fast-solver successes within ACCURACY, reachable count) from q_home.

  A target the fast solver misses is reachable if a thorough restart search
  solves it; targets it hits are reachable by its own (checked) solution.
  """
  fast = ik.InverseKinematics(model)
  reference = ik.InverseKinematics(model, max_iterations=300)
  q_home = model.description.q_home
  solved = reachable = 0
  for target in targets:
    result = fast.solve(target, q_home)
    _assert_within_limits(model, result.q)
    if result.success:
      assert result.position_error <= ACCURACY
      np.testing.assert_allclose(model.tcp_pose(result.q)[:3, 3], target,
                                 atol=fast.position_tolerance)
      solved += 1
      reachable += 1
    elif reference.solve_with_restarts(target, q_home, random_state,
                                       restarts=40).success:
      reachable += 1
  return solved, reachable


@pytest.mark.parametrize('name', ROBOTS)
def test_reaches_table_targets_from_home(name):
  model = _world_model(name)
  random_state = np.random.RandomState(0)
  targets = ik.sample_table_targets(model, 20, random_state)
  solved, reachable = _success_rate(model, targets, random_state)
  assert reachable >= 8
  # 20 targets is a small sample; the slow test checks 95 % on 200.
  assert solved >= 0.9 * reachable, (solved, reachable)


@pytest.mark.slow
@pytest.mark.parametrize('name', ROBOTS)
def test_reaches_95_percent_of_reachable_table_targets(name):
  model = _world_model(name)
  random_state = np.random.RandomState(1)
  targets = ik.sample_table_targets(model, 200, random_state)
  solved, reachable = _success_rate(model, targets, random_state)
  print(f'{name}: {solved}/{reachable} reachable targets solved '
        f'({len(targets)} sampled)')
  assert solved >= 0.95 * reachable, (solved, reachable)


@pytest.mark.parametrize('name', ROBOTS)
def test_small_steps_from_previous_solution(name):
  model = _world_model(name)
  solver = ik.InverseKinematics(model)
  q = model.description.q_home
  start = model.tcp_pose(q)[:3, 3]
  # A 10 cm square around the home TCP, in 2.5 cm steps, each seeded with the
  # previous solution, as per RL step.
  corners = start + np.array([[0.05, 0.05, 0], [0.05, -0.05, 0],
                              [-0.05, -0.05, -0.05], [-0.05, 0.05, 0],
                              [0, 0, 0]])
  path = [start]
  for corner in corners:
    path.extend(np.linspace(path[-1], corner, 5)[1:])
  for target in path[1:]:
    result = solver.solve(target, q)
    assert result.success, (target, result)
    assert result.iterations <= 10
    _assert_gripper_down(model, result, 0.0)
    q = result.q


@pytest.mark.parametrize('name', ROBOTS)
def test_unreachable_target_reports_failure(name):
  model = _world_model(name)
  solver = ik.InverseKinematics(model)
  q_home = model.description.q_home
  far = model.base_pose[:3, 3] + [3.0, 0.0, 0.3]   # 3 m ahead of the base.
  result = solver.solve(far, q_home)
  assert not result.success
  assert result.position_error > 1.0
  _assert_within_limits(model, result.q)
  # The reported error is the true one for the returned q.
  assert result.position_error == pytest.approx(
      np.linalg.norm(model.tcp_pose(result.q)[:3, 3] - far), abs=1e-9)
  # Straight up, out of reach, from a random seed.
  above = model.base_pose[:3, 3] + [0.0, 0.0, 2.5]   # 2.5 m above the base.
  seed = np.random.RandomState(6).uniform(model.q_min, model.q_max)
  result = solver.solve(above, seed)
  assert not result.success and result.position_error > 1.0
  _assert_within_limits(model, result.q)


@pytest.mark.parametrize('name', ROBOTS)
def test_joint_limits_respected_in_every_solution(name):
  model = _world_model(name)
  solver = ik.InverseKinematics(model, max_iterations=30)
  random_state = np.random.RandomState(3)
  # Targets well beyond the workspace too, and seeds anywhere in the limits,
  # so that iterations push against the limits.
  targets = random_state.uniform((-1.5, -1.5, 0.0), (1.5, 1.5, 2.5),
                                 size=(30, 3))
  for target in targets:
    seed = random_state.uniform(model.q_min, model.q_max)
    result = solver.solve(target, seed)
    _assert_within_limits(model, result.q)
    if result.success:
      _assert_gripper_down(model, result, 0.0)
  # A seed outside the limits is brought inside first.
  result = solver.solve(targets[0], model.q_max + 1.0)
  _assert_within_limits(model, result.q)


def test_yaw_is_respected():
  model = _world_model('panda')
  q_home = model.description.q_home
  target = model.tcp_pose(q_home)[:3, 3] + (0.05, 0.05, -0.05)
  for yaw in (0.5, -1.0, 2.0):
    result = ik.InverseKinematics(model).solve(target, q_home, yaw=yaw)
    assert result.success
    _assert_gripper_down(model, result, yaw)
    strict = ik.InverseKinematics(model, half_turn_symmetric=False)
    result = strict.solve(target, q_home, yaw=yaw)
    assert result.success and result.yaw == yaw
    x_axis = model.tcp_pose(result.q)[:3, 0]
    np.testing.assert_allclose(x_axis, (np.cos(yaw), np.sin(yaw), 0),
                               atol=0.02)


def test_schunk_uses_the_half_turn_its_wrist_allows():
  # The Schunk's joints 1, 4 and 6 stop at +-2.9 rad, so in front of the
  # robot its gripper can point down only with the x axis backwards.
  model = _world_model('schunk')
  q_home = model.description.q_home
  target = model.tcp_pose(q_home)[:3, 3] + (0.03, 0.0, -0.03)
  strict = ik.InverseKinematics(model, half_turn_symmetric=False)
  assert not strict.solve(target, q_home, yaw=0.0).success
  result = ik.InverseKinematics(model).solve(target, q_home, yaw=0.0)
  assert result.success
  assert abs(abs(result.yaw) - np.pi) < 1e-9


def test_home_pose_solves_at_once_and_is_deterministic():
  model = _world_model('iiwa')
  solver = ik.InverseKinematics(model)
  q_home = model.description.q_home
  result = solver.solve(model.tcp_pose(q_home)[:3, 3], q_home)
  assert result.success and result.iterations == 0
  np.testing.assert_array_equal(result.q, q_home)
  target = model.tcp_pose(q_home)[:3, 3] + (0.1, -0.2, 0.05)
  first = solver.solve(target, q_home)
  second = solver.solve(target, q_home)
  np.testing.assert_array_equal(first.q, second.q)
  a = solver.solve_with_restarts((0.2, 0.5, 1.0), q_home,
                                 np.random.RandomState(4), restarts=3)
  b = solver.solve_with_restarts((0.2, 0.5, 1.0), q_home,
                                 np.random.RandomState(4), restarts=3)
  np.testing.assert_array_equal(a.q, b.q)


def test_sample_table_targets_lie_over_the_table():
  for name in ROBOTS:
    model = _world_model(name)
    targets = ik.sample_table_targets(model, 500, np.random.RandomState(5))
    assert targets.shape == (500, 3)
    assert np.all(targets[:, 0] > layout.TABLE_X[0])
    assert np.all(targets[:, 0] < layout.TABLE_X[1])
    assert np.all(np.abs(targets[:, 1]) < layout.TABLE_Y[1])
    assert np.all(targets[:, 2] > layout.TABLE_TOP_Z)


def test_bad_input_raises_clear_errors():
  model = _world_model('ur5e')
  solver = ik.InverseKinematics(model)
  q_home = model.description.q_home
  with pytest.raises(ValueError, match='target_position'):
    solver.solve((0.4, 0.0), q_home)
  with pytest.raises(ValueError, match='target_position'):
    solver.solve((0.4, np.nan, 1.0), q_home)
  with pytest.raises(ValueError, match='yaw'):
    solver.solve((0.4, 0.0, 1.0), q_home, yaw=np.inf)
  with pytest.raises(ValueError, match=r'shape \(6,\)'):
    solver.solve((0.4, 0.0, 1.0), np.zeros(7))
  with pytest.raises(ValueError, match='max_iterations'):
    ik.InverseKinematics(model, max_iterations=0)
  with pytest.raises(ValueError, match='position_tolerance'):
    ik.InverseKinematics(model, position_tolerance=-1e-3)
  with pytest.raises(TypeError, match='KinematicModel'):
    ik.InverseKinematics('ur5e')
  with pytest.raises(TypeError, match='RandomState'):
    solver.solve_with_restarts((0.4, 0.0, 1.0), q_home, random_state=0)
