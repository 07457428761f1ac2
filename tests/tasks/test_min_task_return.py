"""HrcTask.min_task_return: the lowest possible episode return, the 0 of
the paper's normalised return."""

import pytest

from hrc_suite import suite


@pytest.mark.parametrize('domain,task,time_limit,expected', [
    # -1 every step of the horizon.
    ('pick_place', 'default', None, -1000.0),
    ('handover', 'human_to_robot', 20.0, -200.0),
    # Lifting: the failure (-10) ends the episode; every other step pays
    # at least 0, so failing at once is the lowest.
    ('lifting', 'default', None, -10.0),
    # Stacking: -1 for 2999 steps, then toppling (-10).
    ('stacking', 'default', None, -3009.0),
    ('stacking', 'default', 10.0, -109.0),
])
def test_lowest_possible_return(domain, task, time_limit, expected):
  kwargs = {} if time_limit is None else {'time_limit': time_limit}
  env = suite.load(domain, task, task_kwargs=kwargs)
  assert env.task.min_task_return == expected
  # The collision penalty is not part of it (the paper's runs had none).
  penalised = suite.load(domain, task, task_kwargs=dict(
      kwargs, collision_reward=-50.0))
  assert penalised.task.min_task_return == expected
