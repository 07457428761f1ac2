"""Extension modules: tasks, experts, robots and shield modes defined
outside the package, registered by importing their modules.

The environment variable HRC_SUITE_EXTENSIONS lists them, comma-separated:
each entry is a module name (imported, so its decorators register what it
defines) or 'module:function' (imported, then function() is called), e.g.

  HRC_SUITE_EXTENSIONS=my_tasks,my_lab.shields:register \\
    python -m hrc_suite.rendering.episode --domain=toy --task=default

The registries (`suite`, `experts`, `robot_description`, `safety.shield.modes`)
load them the first time they are asked for names, so every binary and
each of its worker processes sees them (docs/extending.md).
"""

import importlib
import os
import pkgutil

ENV_VAR = 'HRC_SUITE_EXTENSIONS'

_loaded = set()   # entries imported (or being imported) in this process


def entries():
  """The entries named by HRC_SUITE_EXTENSIONS, in order."""
  return [e.strip() for e in os.environ.get(ENV_VAR, '').split(',')
          if e.strip()]


def package_modules(package):
  """The names of every module of `package` (an imported package), in
  name order: a registry imports them all, so that their decorators
  register what they define (only the folder's file names are read)."""
  return tuple(f'{package.__name__}.{info.name}'
               for info in pkgutil.iter_modules(package.__path__))


def load():
  """Imports the extension modules not yet imported in this process."""
  for entry in entries():
    if entry in _loaded:
      continue
    _loaded.add(entry)   # First: an extension may ask a registry itself.
    module_name, _, function = entry.partition(':')
    try:
      module = importlib.import_module(module_name)
    except ImportError as e:
      _loaded.discard(entry)
      raise ImportError(f'{ENV_VAR} entry {entry!r}: cannot import '
                        f'{module_name!r} ({e})') from e
    if function:
      register = getattr(module, function, None)
      if not callable(register):
        raise ValueError(f'{ENV_VAR} entry {entry!r}: {module_name} has no '
                         f'function {function!r}')
      register()
