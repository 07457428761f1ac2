"""The task registry: names, tags, errors and environment construction."""

import pathlib
import sys

from dm_control import composer
import numpy as np
import pytest

from hrc_suite import extensions
from hrc_suite import suite
from hrc_suite import tasks as tasks_package
from hrc_suite.tasks import reach


def test_reach_tasks_are_registered():
  assert ('reach', 'dense') in suite.ALL_TASKS
  assert ('reach', 'sparse') in suite.ALL_TASKS
  assert ('reach', 'dense') in suite.tasks_with_tag('dense')
  assert ('reach', 'sparse') in suite.tasks_with_tag('sparse')
  assert ('reach', 'sparse') not in suite.tasks_with_tag('dense')
  assert ('reach', 'dense') in suite.tasks_with_tag('coexistence')


def test_every_module_of_the_tasks_package_is_imported():
  suite.all_tasks()
  folder = pathlib.Path(tasks_package.__file__).parent
  names = extensions.package_modules(tasks_package)
  files = [path.stem for path in folder.glob('*.py')
           if path.stem != '__init__']
  subpackages = [path.parent.name for path in folder.glob('*/__init__.py')]
  assert 'runtime' in subpackages
  assert names == tuple(sorted(f'hrc_suite.tasks.{name}'
                               for name in files + subpackages))
  assert all(name in sys.modules for name in names)
  # Each shipped task is registered by a module of the package.
  modules = {suite.task_class(*name).__module__ for name in suite.ALL_TASKS}
  shipped = {m for m in modules if m.startswith('hrc_suite.')}
  assert 'hrc_suite.tasks.reach' in shipped and shipped <= set(names)
  assert suite.task_class('reach', 'dense') is reach.Reach


def test_unknown_names_list_the_valid_ones():
  with pytest.raises(ValueError, match=r"Unknown domain 'walk'.*reach"):
    suite.load('walk', 'dense')
  with pytest.raises(ValueError, match=r"Unknown task 'shaped'.*dense, "
                     r"sparse"):
    suite.load('reach', 'shaped')
  with pytest.raises(ValueError, match=r"Unknown task 'shaped'.*dense, "
                     r"sparse"):
    suite.task_class('reach', 'shaped')
  with pytest.raises(ValueError, match='Unknown tag'):
    suite.tasks_with_tag('fun')


def test_register_rejects_duplicates_and_unknown_tags():
  with pytest.raises(ValueError, match='already registered'):
    suite.register('reach', 'dense')(lambda **kwargs: None)
  with pytest.raises(ValueError, match='Unknown tags'):
    suite.register('x', 'y', tags=('fast',))


def test_load_builds_an_environment_with_the_task_time_limit():
  env = suite.load('reach', 'sparse', task_kwargs={'time_limit': 0.5,
                                                   'seed': 1})
  assert isinstance(env, composer.Environment)
  assert isinstance(env.task, reach.Reach)
  timestep = env.reset()
  assert timestep.observation['goal_difference'].shape == (7,)  # no buffer
  steps = 0
  while not timestep.last():
    timestep = env.step(np.zeros(7))
    steps += 1
  assert steps == 5
  assert timestep.discount == 1.0   # Truncation, not termination.


def test_seed_in_task_kwargs_makes_runs_repeatable():
  goals = []
  for seed in (7, 7, 8):
    env = suite.load('reach', 'dense', task_kwargs={'seed': seed})
    env.reset()
    goals.append(env.task.goal_position)
  np.testing.assert_array_equal(goals[0], goals[1])
  assert not np.array_equal(goals[0], goals[2])


def test_time_limit_belongs_to_the_task():
  with pytest.raises(ValueError, match='task kwarg'):
    suite.load('reach', 'dense', environment_kwargs={'time_limit': 3.0})


def test_episodes_reuse_the_compiled_model():
  env = suite.load('reach', 'dense', task_kwargs={'time_limit': 0.2})
  env.reset()
  data = env.physics.data.ptr
  first_goal = env.task.goal_position
  for _ in range(2):
    env.step(np.zeros(7))
  env.reset()
  assert env.physics.data.ptr is data
  assert not np.array_equal(env.task.goal_position, first_goal)


@pytest.mark.parametrize('kwargs, message', [
    ({'task_kwargs': 'robot=panda'},
     "task_kwargs must be a dict of keyword arguments.*got 'robot=panda'"),
    ({'environment_kwargs': [1]},
     r'environment_kwargs must be a dict.*got \[1\]'),
    ({'task_kwargs': {'seed': 'abc'}},
     r"seed must be None or an integer in \[0, 4294967295\], got 'abc'"),
    ({'task_kwargs': {'seed': -1}}, 'seed must be.*got -1'),
    ({'task_kwargs': {'seed': 1.5}}, 'seed must be.*got 1.5'),
])
def test_bad_load_arguments_raise_clearly(kwargs, message):
  with pytest.raises(ValueError, match=message):
    suite.load('reach', 'dense', **kwargs)
