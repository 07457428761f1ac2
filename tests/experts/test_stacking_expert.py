"""Stacking expert: stacks on the Schunk (2 of 3 seeds), reads only the
state (takes over from any state), fetches and lifts its cube quickly,
tolerates the noisy expert."""

import numpy as np
import pytest

from hrc_suite import experts
from hrc_suite import suite
from hrc_suite.experts import noise as noise_lib
from hrc_suite.experts import stacking as stacking_expert
from hrc_suite.tasks.runtime import metrics
from hrc_suite.tasks import stacking

import expert_checks   # tests/experts/expert_checks.py


def _env(robot='schunk', space='cartesian', seed=0, **kwargs):
  return suite.load('stacking', 'default', task_kwargs={
      'robot': robot, 'action_space': space, **kwargs},
                    environment_kwargs={'random_state': seed})


def _successes(robot, space, seeds=(0, 1, 2)):
  successes = 0
  for seed in seeds:
    env = _env(robot, space, seed)
    result = metrics.run_episode(env, experts.make(env))
    assert result['contacts_human_critical'] == 0
    assert result['contacts_static'] == 0 and result['self_collisions'] == 0
    if result['success']:
      assert env.task.stacked.all() and result['cubes_placed'] == 4
      assert env.task.step_metrics['reward'] == stacking.REWARD_SUCCESS
    successes += int(result['success'])
  return successes


@pytest.mark.slow
@pytest.mark.parametrize('space', ('cartesian', 'joint'))
def test_schunk_two_of_three(space):
  assert _successes('schunk', space) >= 2


@pytest.mark.slow
@pytest.mark.parametrize('space', ('cartesian', 'joint'))
def test_panda_two_of_three(space):
  assert _successes('panda', space) >= 2


@pytest.mark.parametrize('space', ('cartesian', 'joint'))
def test_fetches_and_lifts_cube_2_first(space):
  env = _env('schunk', space, seed=1)
  expert = experts.make(env)
  assert isinstance(expert, stacking_expert.StackingExpert)
  task = env.task
  start = task.cubes[1].position(env.physics)
  timestep, phases = env.reset(), []
  while 'park' not in phases and 'place' not in phases:
    timestep = env.step(expert(timestep))
    phases.append(expert.phase)
    assert len(phases) < 120, phases
  assert phases[0] == 'fetch' and 'grasp' in phases and 'lift' in phases
  assert task.step_metrics['object_gripped'] == 1.0
  assert task.episode_metrics['contacts_human_critical'] == 0
  # Cube 2 (not cube 4) is in the gripper, lifted clear of the table.
  assert task.cubes[1].position(env.physics)[2] > start[2] + 0.03
  assert task.gripper.is_grasping(env.physics, task.cubes[1].body)


def test_a_fresh_expert_takes_over_with_the_same_actions():
  """The phase comes from the state: an expert that did not see the
  episode acts as the one that did, e.g. after a snapshot restore."""
  env = _env('panda', 'cartesian', seed=2)
  expert = experts.make(env)
  timestep = env.reset()
  for _ in range(40):
    timestep = env.step(expert(timestep))
  state = env.task.get_state(env.physics)
  seen = [expert(timestep)]
  fresh = experts.make(env)
  fresh._callables = None   # pylint: disable=protected-access
  taken_over = [fresh.action(fresh.observe())]
  for _ in range(20):
    timestep = env.step(seen[-1])
    seen.append(expert(timestep))
  env.task.set_state(env.physics, state)
  for _ in range(20):
    timestep = env.step(taken_over[-1])
    taken_over.append(fresh.action(fresh.observe()))
  np.testing.assert_array_equal(np.array(seen), np.array(taken_over))


def test_waits_with_its_cube_until_the_cube_below_is_stacked():
  # Seed 0: the robot holds cube 2 before the person has put cube 1 down.
  env = _env('panda', 'cartesian', seed=0)
  expert = experts.make(env)
  task = env.task
  timestep, parked = env.reset(), 0
  while expert.phase != 'place':
    timestep = env.step(expert(timestep))
    if not task.stacked[0] and task.step_metrics['object_gripped']:
      parked += expert.phase == 'park'
      # Cube 2 stays away from the person's stack meanwhile.
      cube = task.cubes[1].position(env.physics)
      assert np.linalg.norm(cube[:2] - task.slots[1][:2]) > 0.15
    assert task.episode_metrics['steps'] < 200
  assert parked > 0 and task.stacked[0]


@pytest.mark.slow
def test_stacks_cube_3_the_person_let_go_off_the_stack():
  env = _env('panda', 'cartesian', seed=2)
  expert = experts.make(env)
  task = env.task
  timestep = env.reset()
  while not task.stacked[1]:
    timestep = env.step(expert(timestep))
  # The person's cube 3 lies on the table next to the stack (let go).
  beside = task.slots[0] + [-0.03, 0.1, 0.0]
  task.cubes[2].set_pose(env.physics, beside, np.array([1.0, 0, 0, 0]))
  task._human_state[2] = stacking.RELEASED   # pylint: disable=protected-access
  env.physics.forward()
  gripped = []
  while not timestep.last():
    timestep = env.step(expert(timestep))
    gripped += [i for i in (2, 3) if task.gripper.is_grasping(
        env.physics, task.cubes[i].body) and i not in gripped]
  result = task.episode_metrics
  assert result['success'] == 1.0 and task.stacked.all()
  assert result['contacts_human_critical'] == 0
  assert gripped == [2, 3]   # The robot took cube 3 first, then its cube 4.


def test_same_seed_same_actions():
  expert_checks.assert_same_seed_same_actions(
      lambda: _env('schunk', 'joint', seed=5, time_limit=3.0))


@pytest.mark.slow
def test_noisy_expert_still_stacks():
  successes = 0
  for seed in (0, 1):
    env = _env('panda', 'cartesian', seed)
    noise = noise_lib.OrnsteinUhlenbeckNoise.reference(
        env.action_spec().shape[0], 'cartesian')
    result = metrics.run_episode(env, experts.make(env, noise=noise))
    assert result['contacts_human_critical'] == 0
    successes += int(result['success'])
  assert successes >= 1
