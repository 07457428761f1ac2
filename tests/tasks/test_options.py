"""An environment's options, checked in one place (tasks/runtime/options.py)."""

import pytest

from hrc_suite.tasks.runtime import contacts
from hrc_suite.tasks.runtime import options
from hrc_suite.tasks import reach
from hrc_suite.tasks import stacking


def _of(task_class=reach.Reach, **arguments):
  return options.TaskOptions.of(task_class.defaults(), **arguments)


def test_none_takes_the_task_default():
  chosen = _of(stacking.Stacking)
  defaults = stacking.Stacking.defaults()
  assert chosen.shield == defaults.shield
  assert chosen.action_space == defaults.action_space
  assert chosen.reward == defaults.rewards[0]
  assert chosen.reward_delay == defaults.reward_delay
  assert chosen.horizon == defaults.horizon
  assert chosen.time_limit == pytest.approx(
      defaults.horizon * options.DEFAULT_CONTROL_TIMESTEP)


def test_critical_speed_follows_the_shield_mode():
  assert _of(shield='pfl').critical_speed == options.DEFAULT_V_SAFE
  assert _of(shield='pfl', v_safe=0.1).critical_speed == 0.1
  assert _of(shield='ssm').critical_speed == contacts.SSM_STOPPED_SPEED
  assert _of(shield='ssm', critical_speed=0.3).critical_speed == 0.3


def test_options_are_frozen_and_a_task_keeps_them():
  task = reach.Reach(robot='schunk', time_limit=2.0)
  assert task.options.robot == 'schunk'
  assert task.options.horizon == task.horizon == 20
  with pytest.raises(AttributeError):
    task.options.horizon = 3


@pytest.mark.parametrize('arguments,message', [
    (dict(shield_substeps=True), 'shield_substeps must be a positive'),
    (dict(shield_substeps=0), 'shield_substeps must be a positive'),
    (dict(physics_timestep=True), 'physics_timestep must be a positive'),
    (dict(control_timestep=0.2), r'control_timestep \(0.2 s\) must equal'),
    (dict(reward='fast'), "Unknown reward 'fast': expected one of"),
    (dict(reward_delay=False), 'reward_delay must be an integer >= 0'),
    (dict(reward_delay=-1), 'reward_delay must be an integer >= 0'),
    (dict(done_at_success=1), 'done_at_success must be True or False'),
    (dict(collision_prevention='stop'),
     "Unknown collision_prevention 'stop'"),
    (dict(time_limit=float('inf')), 'time_limit must be a positive'),
    (dict(v_safe=-0.1), 'v_safe must be a positive'),
    (dict(critical_speed='fast'), 'critical_speed must be a positive'),
    (dict(collision_reward=1.0), 'collision_reward must be a finite number'),
    (dict(collision_reward=True), 'collision_reward must be a finite number'),
    (dict(fast_path='yes'), 'fast_path must be True or False'),
    (dict(action_space='polar'), "Unknown action_space 'polar'"),
    (dict(shield='maybe'), "Unknown shield 'maybe'"),
])
def test_bad_options_are_named(arguments, message):
  with pytest.raises(ValueError, match=message):
    _of(**arguments)
