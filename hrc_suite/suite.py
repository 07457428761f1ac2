"""Task registry: `suite.load(domain, task)` returns a composer Environment.

Tasks register with the `register` decorator on a factory that takes the
task kwargs and returns an `HrcTask`; tags (e.g. 'coexistence', 'dense')
group them. Names are (domain, task) pairs, e.g. ('reach', 'dense').

  env = suite.load('reach', 'dense', task_kwargs={'robot': 'schunk'},
                   environment_kwargs={'random_state': 0})
"""

import collections
import collections.abc
import importlib

from dm_control import composer
import numpy as np

from hrc_suite.tasks import substeps

# Modules whose import registers tasks (one per benchmark task).
_TASK_MODULES = tuple(f'hrc_suite.tasks.{name}' for name in (
    'reach', 'pick_place', 'handover', 'inspection', 'lifting', 'hammering',
    'hammering_robot', 'stacking'))

TAGS = ('coexistence', 'object_handling', 'handover', 'manufacturing',
        'assembly', 'dense', 'sparse', 'delayed', 'ssm', 'pfl')

_REGISTRY = collections.OrderedDict()   # (domain, task) -> factory
_TAGGED = collections.defaultdict(list)   # tag -> [(domain, task)]
_LOADED = False
# Resets tried when initialising an episode hits a MuJoCo physics error
# (HrcTask raises composer.EpisodeInitializationError; each try draws the
# episode anew from the continuing random_state). A few, because one
# failure is already rare (docs/safety.md, "Physics errors").
MAX_RESET_ATTEMPTS = 3
# Largest seed np.random.RandomState accepts (a 32-bit unsigned integer).
_MAX_SEED = 2**32 - 1


class Environment(composer.Environment):
  """composer.Environment in which a fast-path task runs an RL step's
  physics steps in one composer substep (tasks/substeps.py); extra
  substep hooks then go to the task, which runs them every physics step.
  """

  def __init__(self, task, **kwargs):
    task.use_one_substep()   # Before composer reads the substep count.
    super().__init__(task, **kwargs)

  def _substep(self, action):
    if self.task.one_substep:   # The task runs them with their hooks.
      self.task.run_physics_steps(self._physics_proxy, action,
                                  self._random_state)
    else:
      super()._substep(action)

  def step(self, action):
    # After a LAST step composer resets; a running episode restored since
    # (HrcTask.set_state) continues instead of being discarded.
    if self._reset_next_step and getattr(self.task, 'restored', False):
      self._reset_next_step = False
    return super().step(action)

  def add_extra_hook(self, hook_name, hook_callable):
    if self.task.one_substep and hook_name in substeps.HOOKS:
      self.task.physics_steps.add_extra_hook(hook_name, hook_callable)
    else:
      super().add_extra_hook(hook_name, hook_callable)


def register(domain, task, tags=()):
  """Decorator registering `factory(**task_kwargs) -> HrcTask`."""
  unknown = [t for t in tags if t not in TAGS]
  if unknown:
    raise ValueError(f'Unknown tags {unknown}: expected some of '
                     f'{", ".join(TAGS)}')

  def decorator(factory):
    key = (domain, task)
    if key in _REGISTRY:
      raise ValueError(f'Task {domain}/{task} is already registered')
    _REGISTRY[key] = factory
    for tag in tags:
      _TAGGED[tag].append(key)
    return factory

  return decorator


def fixed_kwargs(task_kwargs, **fixed):
  """task_kwargs with `fixed` values; a conflicting value is an error."""
  for name, value in fixed.items():
    if name in task_kwargs and task_kwargs[name] != value:
      raise ValueError(f'{name}={task_kwargs[name]!r} conflicts with the '
                       f'registered task, which fixes {name}={value!r}')
  return {**task_kwargs, **fixed}


def _load_modules():
  global _LOADED
  if not _LOADED:
    for module in _TASK_MODULES:
      importlib.import_module(module)   # Registers its tasks.
    _LOADED = True


def all_tasks():
  """Tuple of every registered (domain, task)."""
  _load_modules()
  return tuple(_REGISTRY)


def tasks_with_tag(tag):
  """The (domain, task) pairs carrying `tag`."""
  if tag not in TAGS:
    raise ValueError(f'Unknown tag {tag!r}: expected one of '
                     f'{", ".join(TAGS)}')
  _load_modules()
  return tuple(_TAGGED[tag])


def __getattr__(name):
  if name == 'ALL_TASKS':   # Computed on first use (registration imports).
    return all_tasks()
  raise AttributeError(f'module {__name__!r} has no attribute {name!r}')


def build_task(domain, task, task_kwargs=None):
  """The task object of (domain, task) built with task_kwargs."""
  _load_modules()
  domains = sorted({d for d, _ in _REGISTRY})
  if domain not in domains:
    raise ValueError(f'Unknown domain {domain!r}: expected one of '
                     f'{", ".join(domains)}')
  if (domain, task) not in _REGISTRY:
    names = sorted(t for d, t in _REGISTRY if d == domain)
    raise ValueError(f'Unknown task {task!r} for domain {domain!r}: '
                     f'expected one of {", ".join(names)}')
  hrc_task = _REGISTRY[(domain, task)](
      **_kwargs_dict('task_kwargs', task_kwargs))
  hrc_task.suite_name = (domain, task)   # Experts and datasets key on it.
  return hrc_task


def _kwargs_dict(name, kwargs):
  """A copy of `kwargs` (None or a mapping of argument names)."""
  if kwargs is None:
    return {}
  if not isinstance(kwargs, collections.abc.Mapping):
    raise ValueError(f'{name} must be a dict of keyword arguments (e.g. '
                     f"{{'robot': 'panda'}}), got {kwargs!r:.80}")
  return dict(kwargs)


def _seed(seed):
  """None or an integer seed of np.random.RandomState."""
  if seed is None:
    return None
  if (isinstance(seed, bool) or not isinstance(seed, (int, np.integer))
      or not 0 <= seed <= _MAX_SEED):
    raise ValueError(f'seed must be None or an integer in [0, {_MAX_SEED}], '
                     f'got {seed!r}')
  return int(seed)


def load(domain, task, task_kwargs=None, environment_kwargs=None):
  """An `Environment` (a composer.Environment) of the task.

  task_kwargs go to the task (see `hrc_suite.tasks.base.HrcTask`), except
  'seed', which seeds the environment's random_state unless
  environment_kwargs gives one. The time limit comes from the task: it is
  set half an RL step before the task's horizon so that floating-point
  accumulation of physics time cannot add an extra step. Observations have
  no leading buffer axis (strip_singleton_obs_buffer_dim=True).

  A MuJoCo physics error (e.g. mjWARN_BADQACC) in `env.step` ends the
  episode instead of raising (raise_exception_on_physics_error=False): the
  step is LAST with reward 0 and discount 0, and the task's metrics record
  `physics_errors` = 1 (HrcTask). A physics error while initialising an
  episode draws it again, up to MAX_RESET_ATTEMPTS times
  (max_reset_attempts). environment_kwargs may override both.
  """
  task_kwargs = _kwargs_dict('task_kwargs', task_kwargs)
  environment_kwargs = _kwargs_dict('environment_kwargs', environment_kwargs)
  seed = _seed(task_kwargs.pop('seed', None))
  hrc_task = build_task(domain, task, task_kwargs)
  environment_kwargs.setdefault('random_state', seed)
  if 'time_limit' in environment_kwargs:
    raise ValueError('time_limit is a task kwarg (task_kwargs), not an '
                     'environment kwarg')
  environment_kwargs.setdefault('strip_singleton_obs_buffer_dim', True)
  environment_kwargs.setdefault('raise_exception_on_physics_error', False)
  environment_kwargs.setdefault('max_reset_attempts', MAX_RESET_ATTEMPTS)
  # Tasks change nothing in the MJCF between episodes (goals are mocap
  # bodies, the human's capsule sizes are set in the compiled model), so
  # the model is compiled once instead of at every reset (~0.1-0.2 s each).
  environment_kwargs.setdefault('recompile_mjcf_every_episode', False)
  time_limit = (hrc_task.horizon - 0.5) * hrc_task.control_timestep
  return Environment(hrc_task, time_limit=time_limit, **environment_kwargs)
