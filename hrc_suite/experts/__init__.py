"""Hand-crafted experts per task, and noisy experts.

  env = suite.load('pick_place', 'default', task_kwargs={'robot': 'schunk'})
  expert = experts.make(env)                  # deterministic
  noise = experts.noise.OrnsteinUhlenbeckNoise.reference(4, 'cartesian')
  noisy = experts.make(env, noise=noise, seed=0)   # reference OU noise
  timestep = env.reset(); action = expert(timestep)

An expert registers with a decorator on its class,
`@experts.register('reach', 'dense', 'sparse')`; the registry imports
every module of this package (those with experts register them), then
the extension modules (`hrc_suite.extensions`; docs/extending.md).
"""

import importlib
import sys
from typing import Callable, Optional, Union

from dm_control import composer

from hrc_suite import extensions
from hrc_suite.experts import base
from hrc_suite.experts import noise as noise_lib

_EXPERTS = {}          # (domain, task) -> expert class
_IMPORT_ERRORS = {}    # module -> error of an expert module that failed
_LOADED = False


def register(domain: str, *tasks: str) -> Callable[[type], type]:
  """Class decorator: the class is the expert of domain/task for each of
  `tasks` (built as cls(env) by `make`).

  Args:
    domain: the suite domain, e.g. 'pick_place'.
    *tasks: the domain's tasks the class solves, at least one.

  Returns:
    The decorator, which returns the class unchanged.

  Raises:
    ValueError: no task named, or (when decorating) another class is
      registered for one of them.
  """
  if not tasks:
    raise ValueError(f'experts.register({domain!r}): name at least one task')

  def decorator(cls):
    for task in tasks:
      key = (domain, task)
      if key in _EXPERTS and _EXPERTS[key] is not cls:
        raise ValueError(f'An expert for {domain}/{task} is already '
                         f'registered ({_EXPERTS[key].__name__})')
      _EXPERTS[key] = cls
    return cls

  return decorator


def unregister(domain: str, task: str) -> None:
  """Removes a registered expert (e.g. one a test registered).

  Args:
    domain: the suite domain.
    task: the task.

  Raises:
    ValueError: no expert is registered for domain/task.
  """
  if (domain, task) not in _EXPERTS:
    raise ValueError(f'No expert for {domain}/{task} is registered')
  del _EXPERTS[(domain, task)]


def _load():
  """Imports the modules of this package (those with experts register
  them with the decorator; one that fails to import is recorded) and the
  extension modules (`extensions`)."""
  global _LOADED
  if not _LOADED:
    _LOADED = True
    for module in extensions.package_modules(sys.modules[__name__]):
      try:
        importlib.import_module(module)
      except ImportError as e:
        _IMPORT_ERRORS[module] = f'{type(e).__name__}: {e}'
  extensions.load()


def registered() -> tuple[tuple[str, str], ...]:
  """The (domain, task) pairs with an expert, sorted."""
  _load()
  return tuple(sorted(_EXPERTS))


def expert_class(domain: str, task: str) -> type[base.Expert]:
  """The expert class registered for domain/task.

  Args:
    domain: the suite domain.
    task: the task.

  Returns:
    The class (a `base.Expert` subclass), built as cls(env).

  Raises:
    ValueError: no expert is registered for domain/task.
    ImportError: none is, and an expert module failed to import.
  """
  _load()
  key = (domain, task)
  if key not in _EXPERTS:
    valid = ', '.join(f'{d}/{t}' for d, t in sorted(_EXPERTS))
    message = f'No expert for {domain}/{task}: experts exist for {valid}'
    if _IMPORT_ERRORS:   # It may be in a module that did not import.
      raise ImportError(message + ''.join(
          f'; {m} did not import ({e})' for m, e in _IMPORT_ERRORS.items()))
    raise ValueError(message)
  return _EXPERTS[key]


def make(env: composer.Environment,
         noise: Optional[noise_lib.OrnsteinUhlenbeckNoise] = None,
         seed: int = 0) -> Union[base.Expert, noise_lib.NoisyExpert]:
  """The expert of the environment's task (`env.task.suite_name`), wrapped
  in `noise.NoisyExpert` (noise seeded by `seed`) when `noise` is given.

  Args:
    env: an environment of `hrc_suite.suite.load`.
    noise: a noise process (e.g.
      `noise.OrnsteinUhlenbeckNoise.reference(size, space)`), or None.
    seed: the seed of the noise.

  Returns:
    The expert (`base.Expert`), or the `noise.NoisyExpert` around it:
    action = expert(timestep).

  Raises:
    ValueError: the environment is not of suite.load, or its task has no
      expert.
  """
  name = getattr(env.task, 'suite_name', None)
  if name is None:
    raise ValueError('make(env) needs an environment from hrc_suite.suite.'
                     'load (its task carries suite_name = (domain, task))')
  expert = expert_class(*name)(env)
  if noise is None:
    return expert
  return noise_lib.NoisyExpert(expert, noise, seed=seed)
