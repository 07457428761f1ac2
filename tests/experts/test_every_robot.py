"""Every robot in every task (issue 17): each robot x task name loads,
resets and its expert drives a few RL steps without error (fast); a few full
expert episodes per robot succeed (slow)."""

import numpy as np
import pytest

from hrc_suite import experts
from hrc_suite import robot_description
from hrc_suite import suite
from hrc_suite.tasks.runtime import metrics

SHORT_STEPS = 3     # RL steps of the fast check
# Slow: full expert episodes per robot on these tasks (seeds 0..n-1);
# docs/results/experts.md: every episode of theirs succeeds (30 per
# robot, the Schunk and the Panda 50).
FULL_TASKS = (('pick_place', 'default'), ('lifting', 'default'))
FULL_SEEDS = 2


def _env(domain, task, robot, seed=0):
  return suite.load(domain, task, task_kwargs={'robot': robot},
                    environment_kwargs={'random_state': seed})


@pytest.mark.parametrize('domain, task', suite.ALL_TASKS)
@pytest.mark.parametrize('robot', robot_description.ROBOT_NAMES)
def test_loads_resets_and_the_expert_steps(robot, domain, task):
  env = _env(domain, task, robot)
  expert = experts.make(env)
  timestep = env.reset()
  q_before = env.physics.data.qpos.copy()
  spec = env.action_spec()
  for _ in range(SHORT_STEPS):
    action = expert(timestep)
    assert action.shape == spec.shape and np.all(np.abs(action) <= 1.0)
    timestep = env.step(action)
    assert np.all(np.isfinite(env.physics.data.qpos))
  assert env.task.episode_metrics['physics_errors'] == 0
  assert env.task.episode_metrics['contacts_human_critical'] == 0
  assert not np.array_equal(q_before, env.physics.data.qpos)  # It ran.


@pytest.mark.slow
@pytest.mark.parametrize('domain, task', FULL_TASKS)
@pytest.mark.parametrize('robot', robot_description.ROBOT_NAMES)
def test_expert_succeeds_on_every_robot(robot, domain, task):
  env = _env(domain, task, robot)
  expert = experts.make(env)
  for seed in range(FULL_SEEDS):
    env.random_state.seed(seed)
    result = metrics.run_episode(env, expert)
    assert result['success'] == 1.0, (robot, domain, task, seed, result)
    assert result['contacts_human_critical'] == 0
    assert result['self_collisions'] == 0


# Reach with joint actions (the task's default): the expert reaches the
# goal in at least REACH_MIN_SUCCESSES of seeds 0..REACH_SEEDS-1 on every
# robot. Misses left are SSM holds with the person at the goal and goals
# no via point reaches (docs/robots.md, "Reach goals"); before the goal
# rules the UR5e reached none and the Gen3 2 of seeds 0-4.
REACH_SEEDS = 8
REACH_MIN_SUCCESSES = 6


@pytest.mark.slow
@pytest.mark.parametrize('robot', robot_description.ROBOT_NAMES)
def test_reach_expert_on_every_robot(robot):
  env = _env('reach', 'dense', robot)
  expert = experts.make(env)
  successes = 0
  for seed in range(REACH_SEEDS):
    env.random_state.seed(seed)
    result = metrics.run_episode(env, expert)
    successes += int(result['success'])
    assert result['contacts_human_critical'] == 0
    assert result['self_collisions'] == 0 and result['contacts_static'] == 0
  assert successes >= REACH_MIN_SUCCESSES, (robot, successes)
