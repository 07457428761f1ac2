"""The public API is typed and documented (Google style: `Args:`).

For every module of DOCUMENTED_MODULES, read from its source: every
public function, every public class (and the classes of the module it
derives from) and their public methods, properties and constructors
(`__init__`, and composer's `_build`) have a docstring; one that takes
arguments other than self/cls documents them under `Args:` (a constructor
may do so in its class docstring); every parameter has a type hint, and
every function but a constructor a return type. A property needs a
docstring and a return type; a property's setter needs its hints.
"""

import ast
import pathlib

import pytest

REPO = pathlib.Path(__file__).resolve().parents[1]

# The modules whose public API a user composes (paths from the repository
# root; a folder stands for its .py files).
DOCUMENTED_MODULES = (
    'hrc_suite/suite.py',
    'hrc_suite/gym_env.py',
    'hrc_suite/tasks/runtime/options.py',
    'hrc_suite/tasks/base.py',
    'hrc_suite/tasks/reach.py',
    'hrc_suite/tasks/pick_place.py',
    'hrc_suite/tasks/stacking.py',
    'hrc_suite/tasks/lifting.py',
    'hrc_suite/tasks/handover.py',
    'hrc_suite/tasks/inspection.py',
    'hrc_suite/tasks/hammering.py',
    'hrc_suite/tasks/hammering_robot.py',
    'hrc_suite/entities/robot.py',
    'hrc_suite/entities/workcell.py',
    'hrc_suite/entities/props.py',
    'hrc_suite/entities/gripper.py',
    'hrc_suite/entities/human.py',
    'hrc_suite/entities/human_segments.py',
    'hrc_suite/entities/nail_board.py',
    'hrc_suite/entities/markers.py',
    'hrc_suite/safety/shield/shield.py',
    'hrc_suite/safety/shield/modes.py',
    'hrc_suite/safety/shield/shield_state.py',
    'hrc_suite/safety/shield/batch.py',
    'hrc_suite/safety/shield/cycle_terms.py',
    'hrc_suite/safety/shield/path_check.py',
    'hrc_suite/safety/shield/tracking.py',
    'hrc_suite/safety/shield/energy_setup.py',
    'hrc_suite/safety/shield/pfl_tables.py',
    'hrc_suite/safety/shield/state_io.py',
    'hrc_suite/safety/collision_prevention/prevention.py',
    'hrc_suite/experts',
    'agents',
    'agents/sac',
    'agents/sac_lag',
    'agents/imitation',
)
# Classes of other modules whose public API a user composes: the bases of
# HrcTask that show a part of a task ('path:Class').
DOCUMENTED_CLASSES = (
    'hrc_suite/tasks/runtime/scene.py:SceneParts',
    'hrc_suite/tasks/runtime/stepped_task.py:SteppedTask',
    'hrc_suite/tasks/runtime/snapshots.py:SnapshottedTask',
    'hrc_suite/tasks/runtime/episode.py:ProgressOfTask',
    'hrc_suite/tasks/runtime/defaults.py:TaskConstants',
    'hrc_suite/tasks/runtime/options.py:OptionNames',
    'hrc_suite/tasks/runtime/reward_bounds.py:RewardBounds',
)
# Methods documented as constructors: their arguments may be documented in
# the class docstring, and they need no return type.
CONSTRUCTORS = ('__init__', '_build')
# Special methods that are public API.
PUBLIC_SPECIAL = CONSTRUCTORS + ('__call__',)


def _paths():
  paths = []
  for name in DOCUMENTED_MODULES:
    path = REPO / name
    paths.extend(sorted(path.glob('*.py')) if path.is_dir() else [path])
  return paths


def _decorator_names(function):
  names = set()
  for decorator in function.decorator_list:
    if isinstance(decorator, ast.Call):
      decorator = decorator.func
    if isinstance(decorator, ast.Name):
      names.add(decorator.id)
    elif isinstance(decorator, ast.Attribute):
      names.add(decorator.attr)
  return names


def _parameters(function, is_method):
  arguments = function.args
  parameters = arguments.posonlyargs + arguments.args + arguments.kwonlyargs
  if arguments.vararg:
    parameters.append(arguments.vararg)
  if arguments.kwarg:
    parameters.append(arguments.kwarg)
  if (is_method and parameters and 'staticmethod' not in
      _decorator_names(function)):
    parameters = parameters[1:]   # self or cls
  return parameters


def _function_problems(function, name, class_doc=None):
  """Problems of one function or method (class_doc: its class's
  docstring, for methods)."""
  is_method = class_doc is not None
  decorators = _decorator_names(function)
  parameters = _parameters(function, is_method)
  doc = ast.get_docstring(function)
  problems = []
  if 'setter' in decorators:
    pass   # Documented by its property.
  elif not doc and not (function.name in CONSTRUCTORS and class_doc
                        and 'Args:' in class_doc):
    problems.append(f'{name}: no docstring')
  elif (parameters and not {'property', 'cached_property'} & decorators
        and 'Args:' not in (doc or '')
        and not (function.name in CONSTRUCTORS
                 and 'Args:' in (class_doc or ''))):
    problems.append(f'{name}: no Args: section for its arguments')
  missing = [p.arg for p in parameters if p.annotation is None]
  if missing:
    problems.append(f'{name}: no type hints on {", ".join(missing)}')
  if (function.returns is None and function.name not in CONSTRUCTORS
      and 'setter' not in decorators):
    problems.append(f'{name}: no return type')
  return problems


def _public(name):
  return not name.startswith('_')


def api_problems(source, module='<module>'):
  """Problems of the public API in a module's source text."""
  tree = ast.parse(source)
  functions = (ast.FunctionDef, ast.AsyncFunctionDef)
  classes = {node.name: node for node in tree.body
             if isinstance(node, ast.ClassDef)}
  documented = {name for name in classes if _public(name)}
  # A public class's bases of this module are part of its API.
  todo = list(documented)
  while todo:
    for base in classes[todo.pop()].bases:
      if isinstance(base, ast.Name) and base.id in classes and (
          base.id not in documented):
        documented.add(base.id)
        todo.append(base.id)
  problems = []
  for node in tree.body:
    if isinstance(node, functions) and _public(node.name):
      problems += _function_problems(node, f'{module}.{node.name}')
    elif isinstance(node, ast.ClassDef) and node.name in documented:
      problems += _class_problems(node, module)
  return problems


def _class_problems(node, module):
  """Problems of a class (its ast node) and its methods."""
  class_doc = ast.get_docstring(node) or ''
  problems = []
  if _public(node.name) and not class_doc:
    problems.append(f'{module}.{node.name}: no docstring')
  for item in node.body:
    if isinstance(item, (ast.FunctionDef, ast.AsyncFunctionDef)) and (
        _public(item.name) or item.name in PUBLIC_SPECIAL):
      problems += _function_problems(
          item, f'{module}.{node.name}.{item.name}', class_doc)
  return problems


def class_api_problems(source, name, module='<module>'):
  """Problems of the public API of the class `name` in a module's source
  text (ValueError if there is no such class)."""
  for node in ast.parse(source).body:
    if isinstance(node, ast.ClassDef) and node.name == name:
      return _class_problems(node, module)
  raise ValueError(f'No class {name!r} in {module}')


def test_the_documented_modules_exist():
  for name in DOCUMENTED_MODULES:
    assert (REPO / name).exists(), name


@pytest.mark.parametrize(
    'path', _paths(), ids=lambda path: str(path.relative_to(REPO)))
def test_public_api_is_typed_and_documented(path):
  module = '.'.join(path.relative_to(REPO).with_suffix('').parts)
  problems = api_problems(path.read_text(), module)
  assert not problems, 'Public API without docs or type hints:\n' + (
      '\n'.join(problems))


@pytest.mark.parametrize('entry', DOCUMENTED_CLASSES)
def test_public_classes_of_other_modules_are_typed_and_documented(entry):
  name, class_name = entry.split(':')
  path = REPO / name
  module = '.'.join(path.relative_to(REPO).with_suffix('').parts)
  problems = class_api_problems(path.read_text(), class_name, module)
  assert not problems, 'Public API without docs or type hints:\n' + (
      '\n'.join(problems))


def test_the_check_finds_what_is_missing():
  source = '''
def undocumented(x):
  return x

def no_args(x: int) -> int:
  """Doubles x."""
  return 2 * x

def fine(x: int) -> int:
  """Doubles x.

  Args:
    x: a number.
  """
  return 2 * x

def _private(x):
  return x

class _Base:
  def inherited(self, y):
    return y

class Thing(_Base):
  """A thing.

  Args:
    size: its size.
  """

  def __init__(self, size: int):
    self.size = size

  @property
  def area(self):
    return self.size ** 2

  def scaled(self, factor: float) -> 'Thing':
    """A scaled copy.

    Args:
      factor: the scale.
    """
    return Thing(self.size * factor)

  def _helper(self, z):
    return z
'''
  assert api_problems(source, 'm') == [
      'm.undocumented: no docstring',
      'm.undocumented: no type hints on x',
      'm.undocumented: no return type',
      'm.no_args: no Args: section for its arguments',
      'm._Base.inherited: no docstring',
      'm._Base.inherited: no type hints on y',
      'm._Base.inherited: no return type',
      'm.Thing.area: no docstring',
      'm.Thing.area: no return type',
  ]
