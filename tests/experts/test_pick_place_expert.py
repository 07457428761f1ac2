"""Pick-and-place expert: picks and places on the Schunk (2 of 3 seeds),
phases follow the state, recovers from a dropped cube and from noise."""

import numpy as np
import pytest

from hrc_suite import experts
from hrc_suite import suite
from hrc_suite.experts import noise as noise_lib
from hrc_suite.experts import pick_place as pick_place_expert
from hrc_suite.tasks.runtime import metrics
from hrc_suite.tasks import pick_place

import expert_checks   # tests/experts/expert_checks.py


def _env(robot='schunk', space='cartesian', variant='default', seed=0,
         **kwargs):
  return suite.load('pick_place', variant, task_kwargs={
      'robot': robot, 'action_space': space, **kwargs},
                    environment_kwargs={'random_state': seed})


def _successes(robot, space, variant, seeds=3):
  successes = 0
  for seed in range(seeds):
    env = _env(robot, space, variant, seed)
    result = metrics.run_episode(env, experts.make(env))
    assert result['contacts_human_critical'] == 0
    assert result['contacts_static'] == 0 and result['self_collisions'] == 0
    if result['success']:
      assert result['grasps'] >= 1
      assert env.task.step_metrics['reward'] == pick_place.REWARD_SUCCESS
    successes += int(result['success'])
  return successes


def test_cone_aim_rises_first_then_descends_inside_the_cone():
  point = np.array([0.4, 0.2, 0.85])
  far_low = np.array([0.4, -0.2, 0.86])
  aim = pick_place_expert.cone_aim(point, far_low, hover=0.2)
  np.testing.assert_allclose(aim, [0.4, -0.2, 1.05])   # Straight up.
  # 4 cm off: the cone allows slope x (4 - 2) cm above the point.
  high = np.array([0.4, 0.16, 0.95])
  aim = pick_place_expert.cone_aim(point, high, hover=0.2)
  np.testing.assert_allclose(aim[:2], point[:2])
  assert aim[2] == pytest.approx(0.85 + pick_place_expert.CONE_SLOPE * (
      0.04 - pick_place_expert.CONE_RADIUS))
  above = np.array([0.4, 0.2, 1.0])
  np.testing.assert_allclose(
      pick_place_expert.cone_aim(point, above, hover=0.2), point)


@pytest.mark.parametrize('variant', ('default', 'close'))
def test_schunk_cartesian_two_of_three(variant):
  assert _successes('schunk', 'cartesian', variant) >= 2


@pytest.mark.slow
@pytest.mark.parametrize('variant', ('default', 'close'))
@pytest.mark.parametrize('robot', ('schunk', 'panda'))
def test_joint_space_two_of_three(robot, variant):
  assert _successes(robot, 'joint', variant) >= 2


def test_phases_follow_the_state_and_a_dropped_cube_is_picked_again():
  env = _env('panda', 'cartesian', seed=3, done_at_success=False)
  expert = experts.make(env)
  timestep = env.reset()
  task, physics = env.task, env.physics
  phases = []
  while 'carry' not in phases or task.object_position(physics)[2] < 0.93:
    timestep = env.step(expert(timestep))
    phases.append(expert.phase)
    assert len(phases) < 200
  assert phases[0] == 'approach' and 'close' in phases
  assert timestep.observation['object_gripped'][0] == 1.0
  # The cube falls out of the hand back onto the table, away from the TCP:
  # the expert sees it is not in the hand and picks it up again.
  start = task.object_position(physics)
  task.cube.set_pose(physics, position=np.array([start[0] - 0.05, start[1],
                                                 0.84]))
  env.physics.forward()
  for _ in range(150):
    timestep = env.step(expert(timestep))
    if task.episode_metrics['grasps'] >= 2:
      break
  assert task.episode_metrics['grasps'] >= 2
  assert expert.phase in ('carry', 'close', 'release')


def test_noisy_expert_still_succeeds():
  env = _env('panda', 'cartesian', seed=4)
  noise = noise_lib.OrnsteinUhlenbeckNoise.reference(
      env.action_spec().shape[0], 'cartesian')
  noisy = experts.make(env, noise=noise)
  result = metrics.run_episode(env, noisy)
  assert result['success'] == 1.0 and result['contacts_human_critical'] == 0


def test_same_seed_same_actions():
  expert_checks.assert_same_seed_same_actions(
      lambda: _env('panda', 'joint', seed=5, time_limit=3.0))


def test_iiwa_carries_the_cube_across_its_centre_line():
  # KUKA iiwa seed 4 from the tasks' own region (x 0.30-0.45 m): the cube
  # at x 0.33 m, carried at the hover across y = 0, where the iiwa's
  # gripper-down IK reaches only from x 0.375 m: every step failed IK for
  # the rest of the episode. Its layout's cube region (x 0.40-0.55 m) lies
  # where the carry is reachable (issue 17).
  env = suite.load('pick_place', 'default', task_kwargs={'robot': 'iiwa'},
                   environment_kwargs={'random_state': 0})
  env.random_state.seed(4)
  result = metrics.run_episode(env, experts.make(env))
  assert result['success'] == 1.0
  assert result['ik_failures'] == 0
