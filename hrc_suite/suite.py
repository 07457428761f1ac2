"""Task registry: `suite.load(domain, task)` returns a composer Environment.

Tasks register with the `register` decorator, on an `HrcTask` subclass
(with the task kwargs it fixes) or on a factory that takes the task kwargs
and returns an `HrcTask`; tags (e.g. 'coexistence', 'dense', a shield mode)
group them. Names are (domain, task) pairs, e.g. ('reach', 'dense').

  env = suite.load('reach', 'dense', task_kwargs={'robot': 'schunk'},
                   environment_kwargs={'random_state': 0})

The registry finds its tasks itself: it imports every module of the
hrc_suite.tasks package (those that register tasks do so at import), then
the extension modules named by HRC_SUITE_EXTENSIONS (`extensions`); adding
a task edits no list (docs/extending.md).
"""

import collections
import collections.abc
import importlib
from typing import Any, Callable, Mapping, Optional, Sequence, Tuple

from dm_control import composer
import dm_env
import numpy as np

from hrc_suite import extensions
from hrc_suite import observation_updater
from hrc_suite import tasks as tasks_package
from hrc_suite.safety.shield import modes
from hrc_suite.tasks import base
from hrc_suite.tasks.runtime import substeps

# Tags of what a task is about and of its reward; each shield mode's name
# (safety/shield/modes.py) is a tag too (`tags()`).
TASK_TAGS = ('coexistence', 'object_handling', 'handover', 'manufacturing',
             'assembly', 'dense', 'sparse', 'delayed')

_REGISTRY = collections.OrderedDict()   # (domain, task) -> factory
_CLASSES = {}   # (domain, task) -> HrcTask subclass (class registrations)
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
  physics steps in one composer substep (tasks/runtime/substeps.py); extra
  substep hooks then go to the task, which runs them every physics step.
  """

  def __init__(self, task: base.HrcTask, **kwargs: Any):
    """Initializes the environment.

    Args:
      task: the task; a fast-path task is set to run an RL step as one
        composer substep before composer reads the substep count.
      **kwargs: composer.Environment's keyword arguments.
    """
    task.use_one_substep()   # Before composer reads the substep count.
    super().__init__(task, **kwargs)

  def _make_observation_updater(self):
    # composer's Updater, without its schedule where an RL step reads each
    # observable once (observation_updater).
    # (composer.Environment._make_observation_updater's arguments.)
    padding = composer.ObservationPadding.INITIAL_VALUE
    return observation_updater.OneStepUpdater(
        self._task.observables, self._task.physics_steps_per_control_step,
        self._strip_singleton_obs_buffer_dim,
        self._delayed_observation_padding == padding)

  def _substep(self, action):
    if self.task.one_substep:   # The task runs them with their hooks.
      self.task.run_physics_steps(self._physics_proxy, action,
                                  self._random_state)
    else:
      super()._substep(action)

  def step(self, action: np.ndarray) -> dm_env.TimeStep:
    """Steps the environment (composer.Environment.step).

    A running episode restored after a LAST step (HrcTask.set_state)
    continues instead of being reset.

    Args:
      action: the agent's action, of the task's action_spec.

    Returns:
      The time step.
    """
    # After a LAST step composer resets; a running episode restored since
    # (HrcTask.set_state) continues instead of being discarded.
    if self._reset_next_step and getattr(self.task, 'restored', False):
      self._reset_next_step = False
    return super().step(action)

  def add_extra_hook(self, hook_name: str,
                     hook_callable: Callable[..., Any]) -> None:
    """Adds a hook that runs after the task's hook of the same name.

    On the fast path the physics-step hooks (tasks/runtime/substeps.py's HOOKS)
    go to the task, which runs them every physics step.

    Args:
      hook_name: composer's hook name (e.g. 'before_substep').
      hook_callable: called with the hook's arguments.
    """
    if self.task.one_substep and hook_name in substeps.HOOKS:
      self.task.physics_steps.add_extra_hook(hook_name, hook_callable)
    else:
      super().add_extra_hook(hook_name, hook_callable)


def tags() -> Tuple[str, ...]:
  """Every valid tag: TASK_TAGS and the shield modes' names."""
  return TASK_TAGS + modes.names()


def _name(what, value):
  if not (isinstance(value, str) and value.isidentifier()):
    raise ValueError(f'{what} must be an identifier string (e.g. '
                     f"'reach'), got {value!r}")
  return value


def register(domain: str, task: str, tags: Sequence[str] = (),
             **fixed: Any) -> Callable[[Any], Any]:
  """Decorator registering the task `domain`/`task`.

  On an HrcTask subclass: the task is the class built with the task kwargs
  and `fixed` (kwargs the name fixes, e.g. reward='dense'; a conflicting
  task kwarg is an error); the class is returned, so decorators stack.
  On a function: `factory(**task_kwargs) -> HrcTask` (no `fixed`).

  Args:
    domain: the domain's name, an identifier (e.g. 'reach').
    task: the task's name in the domain, an identifier (e.g. 'dense').
    tags: tags of the task, each one of `tags()`.
    **fixed: task kwargs the name fixes (class registrations only).

  Returns:
    The decorator; it returns what it decorates.

  Raises:
    ValueError: a name that is not an identifier, tags given as a string,
      an unknown tag; from the decorator, a name already registered or a
      target that is neither an HrcTask subclass nor (without `fixed`) a
      function.
  """
  key = (_name('domain', domain), _name('task', task))
  if isinstance(tags, str):
    raise ValueError(f'tags must be a tuple of tags, got the string '
                     f'{tags!r}')
  valid = TASK_TAGS + modes.names()   # tags(), which `tags` shadows here.
  unknown = [t for t in tags if t not in valid]
  if unknown:
    raise ValueError(f'Unknown tags {unknown}: expected some of '
                     f'{", ".join(valid)}')

  def decorator(target):
    if key in _REGISTRY:
      raise ValueError(f'Task {domain}/{task} is already registered')
    if isinstance(target, type):
      # Its class constants, checked (tasks/runtime/defaults.py).
      target.defaults()
      _CLASSES[key] = target

      def factory(**task_kwargs):
        return target(**fixed_kwargs(task_kwargs, **fixed))
      factory.__doc__ = target.__doc__
    elif callable(target) and not fixed:
      factory = target
    else:
      raise ValueError(f'register({domain!r}, {task!r}) decorates an '
                       f'HrcTask subclass or a factory function (fixed '
                       f'kwargs only with a class), got {target!r}')
    _REGISTRY[key] = factory
    for tag in tags:
      _TAGGED[tag].append(key)
    return target

  return decorator


def unregister(domain: str, task: str) -> None:
  """Removes a registered task (e.g. one a test registered).

  Args:
    domain: the task's domain.
    task: the task's name.

  Raises:
    ValueError: if domain/task is not registered.
  """
  key = (domain, task)
  if key not in _REGISTRY:
    raise ValueError(f'Task {domain}/{task} is not registered')
  del _REGISTRY[key]
  _CLASSES.pop(key, None)
  for keys in _TAGGED.values():
    if key in keys:
      keys.remove(key)


def fixed_kwargs(task_kwargs: Mapping[str, Any],
                 **fixed: Any) -> dict[str, Any]:
  """task_kwargs with `fixed` values; a conflicting value is an error.

  Args:
    task_kwargs: the user's task kwargs.
    **fixed: the kwargs a registered name fixes.

  Returns:
    A new dict: task_kwargs updated with `fixed`.

  Raises:
    ValueError: if task_kwargs gives a fixed kwarg another value.
  """
  for name, value in fixed.items():
    if name in task_kwargs and task_kwargs[name] != value:
      raise ValueError(f'{name}={task_kwargs[name]!r} conflicts with the '
                       f'registered task, which fixes {name}={value!r}')
  return {**task_kwargs, **fixed}


def _load_modules():
  global _LOADED
  if not _LOADED:
    for module in extensions.package_modules(tasks_package):
      importlib.import_module(module)   # Registers its tasks, if any.
    _LOADED = True
  extensions.load()


def all_tasks() -> Tuple[Tuple[str, str], ...]:
  """Tuple of every registered (domain, task)."""
  _load_modules()
  return tuple(_REGISTRY)


def tasks_with_tag(tag: str) -> Tuple[Tuple[str, str], ...]:
  """The (domain, task) pairs carrying `tag`.

  Args:
    tag: one of `tags()`.

  Returns:
    The registered (domain, task) pairs with that tag, in registration
    order.

  Raises:
    ValueError: if `tag` is unknown.
  """
  _load_modules()
  if tag not in tags():
    raise ValueError(f'Unknown tag {tag!r}: expected one of '
                     f'{", ".join(tags())}')
  return tuple(_TAGGED[tag])


def __getattr__(name):
  if name == 'ALL_TASKS':   # Computed on first use (registration imports).
    return all_tasks()
  if name == 'TAGS':   # Shield modes may register later.
    return tags()
  raise AttributeError(f'module {__name__!r} has no attribute {name!r}')


def _registered(domain, task):
  """(domain, task), registered; else a ValueError listing the names."""
  _load_modules()
  domains = sorted({d for d, _ in _REGISTRY})
  if domain not in domains:
    raise ValueError(f'Unknown domain {domain!r}: expected one of '
                     f'{", ".join(domains)}')
  if (domain, task) not in _REGISTRY:
    names = sorted(t for d, t in _REGISTRY if d == domain)
    raise ValueError(f'Unknown task {task!r} for domain {domain!r}: '
                     f'expected one of {", ".join(names)}')
  return domain, task


def task_class(domain: str, task: str) -> Optional[type[base.HrcTask]]:
  """The HrcTask subclass registered as domain/task.

  Args:
    domain: a registered domain.
    task: a registered task of the domain.

  Returns:
    The class (its class constants are its facts: MOTIONS, EVENTS, ...),
    or None where a factory function was registered.

  Raises:
    ValueError: an unknown domain or task (the message lists the names).
  """
  return _CLASSES.get(_registered(domain, task))


def build_task(domain: str, task: str,
               task_kwargs: Optional[Mapping[str, Any]] = None
               ) -> base.HrcTask:
  """The task object of (domain, task) built with task_kwargs.

  Args:
    domain: a registered domain.
    task: a registered task of the domain.
    task_kwargs: None or the task's keyword arguments
      (`hrc_suite.tasks.base.HrcTask`).

  Returns:
    The task, its `suite_name` set to (domain, task).

  Raises:
    ValueError: an unknown domain or task, task_kwargs that are not a
      mapping, or a task kwarg the task rejects.
  """
  hrc_task = _REGISTRY[_registered(domain, task)](
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


def load(domain: str, task: str,
         task_kwargs: Optional[Mapping[str, Any]] = None,
         environment_kwargs: Optional[Mapping[str, Any]] = None
         ) -> Environment:
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

  Args:
    domain: a registered domain (`all_tasks()`).
    task: a registered task of the domain.
    task_kwargs: None or the task's keyword arguments
      (`hrc_suite.tasks.base.HrcTask`, `hrc_suite.tasks.runtime.options`), plus
      'seed': None or an integer in [0, 2**32 - 1].
    environment_kwargs: None or composer.Environment's keyword arguments
      (not 'time_limit', which is a task kwarg).

  Returns:
    The environment.

  Raises:
    ValueError: an unknown domain or task, kwargs that are not mappings,
      a bad seed, 'time_limit' in environment_kwargs, or a task kwarg the
      task rejects.
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
