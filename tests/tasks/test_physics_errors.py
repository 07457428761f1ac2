"""MuJoCo physics errors end the episode instead of escaping env.step
(docs/safety.md, "Physics errors")."""

from dm_control import composer
from dm_control.rl import control
import dm_env
import numpy as np
import pytest

from hrc_suite import suite
from hrc_suite.tasks.runtime import metrics

BAD_SUBSTEP = 60    # The 11th physics step of the third RL step.


def _env(environment_kwargs=None, **task_kwargs):
  kwargs = {'robot': 'panda', 'action_space': 'joint', 'seed': 0,
            'time_limit': 2.0, 'reward_delay': 2}
  kwargs.update(task_kwargs)
  return suite.load('reach', 'dense', task_kwargs=kwargs,
                    environment_kwargs=environment_kwargs)


def _break_physics_at(env, substep):
  """Before the `substep`-th physics step of the environment (once), a
  joint velocity of 1e9 rad/s: the physics step after it finds
  accelerations beyond MuJoCo's limit (mjWARN_BADQACC), and MuJoCo resets
  the simulation."""
  count = []

  def hook(physics, action, random_state):
    del action, random_state
    count.append(1)
    if len(count) == substep:
      physics.data.qvel[env.task._qvel_index[1]] = 1e9

  env.add_extra_hook('before_substep', hook)


def test_without_the_suite_setting_the_error_escapes():
  env = _env({'raise_exception_on_physics_error': True})
  _break_physics_at(env, BAD_SUBSTEP)
  env.reset()
  env.step(np.zeros(7))
  env.step(np.zeros(7))
  with pytest.raises(control.PhysicsError, match='mjWARN_BADQACC'):
    env.step(np.zeros(7))


def test_a_physics_error_ends_the_episode_with_discount_zero():
  env = _env()
  _break_physics_at(env, BAD_SUBSTEP)
  observer = metrics.EpisodeMetricsObserver()
  timestep = env.reset()
  observer.observe_first(env, timestep)
  steps = []
  while not timestep.last():
    timestep = env.step(np.zeros(7))
    observer.observe(env, timestep)
    steps.append(timestep)
  assert len(steps) == 3
  assert [t.discount for t in steps] == [1.0, 1.0, 0.0]
  assert steps[-1].step_type == dm_env.StepType.LAST
  assert steps[-1].reward == 0.0
  task = env.task
  assert task.step_metrics['physics_errors'] == 1
  assert task.step_metrics['reward'] == 0.0
  episode = observer.episodes[-1]
  assert episode['physics_errors'] == 1 and episode['steps'] == 3
  assert episode['success'] == 0.0
  # The return is what the environment paid (the delayed rewards owed are
  # forfeited); the task's logic was skipped on the reset state.
  assert episode['return'] == pytest.approx(sum(t.reward for t in steps))
  assert episode['self_collisions'] == 0
  # The next step starts a fresh episode that runs normally.
  timestep = env.step(np.zeros(7))
  assert timestep.first()
  for _ in range(3):
    timestep = env.step(np.zeros(7))
    assert timestep.discount == 1.0 and np.isfinite(timestep.reward)
  assert task.episode_metrics['physics_errors'] == 0
  assert task.episode_metrics['steps'] == 3


def test_a_physics_error_in_reset_draws_the_episode_again():
  """Lifting-style settling steps in the episode's initialisation hit a
  physics error: the environment draws the episode again (the next random
  state); with one attempt allowed the error is reported clearly."""
  for attempts, fails in ((suite.MAX_RESET_ATTEMPTS, False), (1, True)):
    env = _env({'max_reset_attempts': attempts})
    task = env.task
    initialize = task._initialize_task
    calls = []

    def broken_once(physics, random_state, initialize=initialize,
                    calls=calls):
      calls.append(1)
      initialize(physics, random_state)
      if len(calls) == 1:
        physics.data.qvel[task._qvel_index[1]] = 1e9
        physics.step(2)   # The second step's accelerations are bad.

    task._initialize_task = broken_once
    if fails:
      with pytest.raises(composer.EpisodeInitializationError,
                         match='physics error.*mjWARN'):
        env.reset()
      continue
    timestep = env.reset()
    assert timestep.first() and len(calls) == 2
    timestep = env.step(np.zeros(7))
    assert timestep.discount == 1.0
    assert task.episode_metrics['physics_errors'] == 0
