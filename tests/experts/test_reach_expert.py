"""Reach expert: reaches the goal in both action spaces, plans around the
table when the straight joint path collides, takes over mid-episode."""

import numpy as np
import pytest

from hrc_suite import experts
from hrc_suite import suite
from hrc_suite.experts import reach as reach_expert
from hrc_suite.tasks.runtime import metrics


def _env(robot='schunk', space='joint', reward='sparse', seed=0, **kwargs):
  return suite.load('reach', reward, task_kwargs={
      'robot': robot, 'action_space': space, **kwargs},
                    environment_kwargs={'random_state': seed})


@pytest.mark.parametrize('space', ('joint', 'cartesian'))
def test_schunk_reaches_two_of_three(space):
  successes = 0
  for seed in range(3):
    env = _env('schunk', space, seed=seed)
    expert = experts.make(env)
    assert isinstance(expert, reach_expert.ReachExpert)
    result = metrics.run_episode(env, expert)
    assert result['contacts_human_critical'] == 0
    assert result['self_collisions'] == 0 and result['contacts_static'] == 0
    successes += int(result['success'])
  assert successes >= 2


def test_dense_reward_improves_along_the_way():
  env = _env('panda', 'cartesian', reward='dense', seed=1)
  expert = experts.make(env)
  timestep = env.reset()
  rewards = []
  while not timestep.last():
    timestep = env.step(expert(timestep))
    rewards.append(timestep.reward)
  assert env.task.episode_metrics['success'] == 1.0
  assert rewards[-1] > rewards[0]


def test_via_point_when_the_straight_joint_path_hits_the_table():
  env = _env('panda', 'joint', seed=0)
  env.reset()
  task, physics = env.task, env.physics
  checker = task.collision_checker
  expert = experts.make(env)
  q = task.robot.joint_positions(physics)
  # A goal low in front of the robot, reached from the home pose by a
  # straight joint path that dips the gripper through the table: found by
  # a search over goals the task would sample.
  rs = np.random.RandomState(5)
  for _ in range(400):
    goal, _ = task._sample_goal(rs)   # pylint: disable=protected-access
    if not checker.is_safe(q, goal):
      break
  else:
    pytest.fail('no goal with a colliding straight path in 400 samples')
  via = expert._plan(q, goal)   # pylint: disable=protected-access
  assert via is not None
  assert checker.is_safe(q, via) and checker.is_safe(via, goal)
  # The expert's first aim is the via point, not the goal.
  observation = {'joint_positions': q, 'goal_joint_difference': goal - q,
                 'goal_position': task.kinematics.tcp_pose(goal)[:3, 3],
                 'eef_position': task.robot.tcp_pose(physics)[0]}
  action = expert.action(observation)
  direction = (via - q) / np.abs(via - q).max()
  np.testing.assert_allclose(action, direction, atol=1e-12)


def test_takes_over_from_a_snapshot():
  env = _env('panda', 'joint', seed=2)
  timestep = env.reset()
  rs = np.random.RandomState(0)
  for _ in range(5):   # Someone else drove first.
    timestep = env.step(rs.uniform(-1, 1, env.action_spec().shape))
  expert = experts.make(env)
  while not timestep.last():
    timestep = env.step(expert(timestep))
  assert env.task.episode_metrics['success'] == 1.0


def test_recovers_when_the_planned_first_step_is_rejected():
  # Panda joint seed 43: the goal lies 8 cm above the table; on the way the
  # arm overshoots into a pose whose straight path to the goal is free but
  # whose planned first step collision prevention rejects. Checking the
  # straight path only, the expert repeated that step for the rest of the
  # episode (64 replacements, no success).
  env = _env('panda', 'joint', seed=43)
  result = metrics.run_episode(env, experts.make(env))
  assert result['success'] == 1.0
  assert result['action_replacements'] <= 2


def test_random_via_point_when_no_structured_one_is_free():
  # UR5e joint seed 4: from where the arm stands after 50 RL steps the
  # straight path to the goal brushes the tool past the upper arm, and no
  # via point with some joints at their goal values (nor home) has free
  # paths; with the structured candidates only, collision prevention
  # replaced 68 actions and the arm stood 1.23 rad from the goal (issue 17).
  env = _env('ur5e', 'joint', reward='dense', seed=0)
  env.random_state.seed(4)
  result = metrics.run_episode(env, experts.make(env))
  assert result['success'] == 1.0
  assert result['action_replacements'] == 0


def test_path_stays_on_the_robots_side_of_the_table_edge():
  # Kinova Gen3 joint seed 6: the goal lies high behind the base, but the
  # straight joint path from home swings the arm out over the table edge
  # beside the person (TCP at y 0.68 m), where SSM held it for 83 of the
  # 100 RL steps (no success, issue 17's 30-episode sweep). Paths are now
  # held to the goals' own bound (layout.REACH_GOAL_MAX_Y).
  env = _env('kinova3', 'joint', reward='dense', seed=0)
  env.random_state.seed(6)
  expert = experts.make(env)
  result = metrics.run_episode(env, expert)
  assert result['success'] == 1.0
  assert result['shield_interventions'] <= 5
  assert result['contacts_human_critical'] == 0
