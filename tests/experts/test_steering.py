"""Steering: world aims and joint goals become actions that move the robot
there, in both action spaces."""

import numpy as np
import pytest

from hrc_suite import suite
from hrc_suite.experts import steering
from hrc_suite.tasks.runtime import actions


def _env(domain, task, robot, space, seed=0):
  return suite.load(domain, task, task_kwargs={
      'robot': robot, 'action_space': space, 'time_limit': 5.0},
                    environment_kwargs={'random_state': seed})


def test_cartesian_action_keeps_the_direction_and_scales():
  env = _env('pick_place', 'default', 'panda', 'cartesian')
  env.reset()
  steer = steering.Steering(env.task)
  tcp = np.array([0.5, 0.0, 1.0])
  np.testing.assert_allclose(steer.action(tcp + (0.05, 0, -0.02), tcp, None,
                                          gripper=-1.0), [0.5, 0, -0.2, -1])
  far = steer.action(tcp + (0.4, 0.2, 0.0), tcp, None, gripper=1.0)
  np.testing.assert_allclose(far, [1.0, 0.5, 0.0, 1.0])
  with pytest.raises(ValueError, match='gripper'):
    steer.action(tcp, tcp, None)
  with pytest.raises(ValueError, match='aim must be 3 finite'):
    steer.action([np.nan, 0, 0], tcp, None, gripper=0.0)


def test_reach_has_no_gripper_dimension():
  env = _env('reach', 'dense', 'panda', 'joint')
  env.reset()
  steer = steering.Steering(env.task)
  q = env.task.robot.joint_positions(env.physics)
  goal = q + 0.1
  arm = steer.joint_goal_action(goal, q, None)
  np.testing.assert_allclose(arm, 0.1 / actions.JOINT_STEP)
  with pytest.raises(ValueError, match='no gripper action'):
    steer.joint_goal_action(goal, q, None, gripper=1.0)


@pytest.mark.parametrize('robot', ('panda', 'schunk'))
@pytest.mark.parametrize('space', ('cartesian', 'joint'))
def test_aim_is_reached_gripper_down(robot, space):
  env = _env('pick_place', 'default', robot, space, seed=1)
  env.reset()
  task, physics = env.task, env.physics
  steer = steering.Steering(task)
  start = task.robot.tcp_pose(physics)[0]
  aim = start + (0.0, 0.15, -0.1)
  for _ in range(25):
    tcp = task.robot.tcp_pose(physics)[0]
    q = task.robot.joint_positions(physics)
    env.step(steer.action(aim, tcp, q, gripper=-1.0))
  tcp, quat = task.robot.tcp_pose(physics)
  assert np.linalg.norm(tcp - aim) < 0.01
  # Gripper still down: the TCP z axis along world -z.
  z_axis = physics.bind(task.robot.tcp_site).xmat.reshape(3, 3)[:, 2]
  assert z_axis[2] < -0.99
  assert task.episode_metrics['ik_failures'] == 0


def test_gain_asks_for_part_of_the_way():
  env = _env('pick_place', 'default', 'panda', 'cartesian')
  env.reset()
  steer = steering.Steering(env.task)
  tcp = np.array([0.5, 0.0, 1.0])
  np.testing.assert_allclose(
      steer.action(tcp + (0.06, 0, 0), tcp, None, gripper=0.0, gain=0.5),
      [0.3, 0, 0, 0])
  with pytest.raises(ValueError, match='gain must be in'):
    steer.action(tcp, tcp, None, gripper=0.0, gain=0.0)


@pytest.mark.parametrize('space', ('cartesian', 'joint'))
def test_joint_goals_stay_within_what_the_robot_can_follow(space):
  env = _env('pick_place', 'default', 'schunk', space, seed=1)
  env.reset()
  task, physics = env.task, env.physics
  steer = steering.Steering(task)
  limit = steer.max_joint_step
  np.testing.assert_allclose(
      limit, steering.SPEED_HEADROOM * 0.1
      * np.asarray(task.robot.description.limits.v_max))
  # Down onto the table in front of the base: the arm folds, and a 0.1 m
  # Cartesian step would need more than the limit in some joint.
  aim = task.object_position(physics) + (0, 0, 0.01)
  for _ in range(12):
    q = task.robot.joint_positions(physics)
    tcp = task.robot.tcp_pose(physics)[0]
    env.step(steer.action(aim, tcp, q, gripper=-1.0))
    # Cartesian: the step is scaled linearly from the predicted IK, so the
    # limit holds to first order (a few percent).
    assert np.all(np.abs(task.q_goal - q) <= 1.05 * limit)
  unlimited = steering.Steering(task, limit_speed=False)
  assert unlimited.max_joint_step is None
