"""Structure rules checked on the package's source (by its syntax tree).

* A module changes the private state (attributes starting with `_`) of
  its own objects only: no `shield._plan = ...`, `plan._filled = ...`,
  `setattr(x, '_y', ...)` or `x.__dict__[...] = ...` on an object other
  than `self` / `cls`; another object's state changes through its public
  methods and properties.
* A numba-compiled function takes at most MAX_KERNEL_PARAMETERS
  parameters: more travel as named groups (typing.NamedTuple, structured
  arrays), e.g. safety/shield/cycle_kernels.py.
* HrcTask (tasks/base.py) is a composer-sized task: composer's hooks, the
  hooks tasks override, the scene and the reward, in at most
  MAX_TASK_LINES lines; what else a task shows lives in the runtime
  module whose idea it is (tasks/runtime/scene.py,
  tasks/runtime/shielded_stepping.py, tasks/runtime/snapshots.py, ...).
"""

import ast
import pathlib

import pytest

PACKAGE = pathlib.Path(__file__).resolve().parents[1] / 'hrc_suite'
MAX_KERNEL_PARAMETERS = 15
MAX_TASK_LINES = 400   # HrcTask's class, from `class` to its last line
# Decorator names that compile a function with numba.
_JIT_NAMES = frozenset(('jit', 'njit', 'generated_jit'))


def _modules():
  return sorted(PACKAGE.rglob('*.py'))


def _relative(path):
  return path.relative_to(PACKAGE.parent).as_posix()


def _is_own(node):
  return isinstance(node, ast.Name) and node.id in ('self', 'cls')


def _private(name):
  return name.startswith('_') and not (name.startswith('__')
                                       and name.endswith('__'))


def _targets(node):
  """The assigned (or deleted) expressions of a statement, tuples
  unpacked."""
  if isinstance(node, (ast.Assign, ast.Delete)):
    targets = list(node.targets)
  elif isinstance(node, (ast.AugAssign, ast.AnnAssign)):
    targets = [node.target]
  else:
    return []
  flat = []
  while targets:
    target = targets.pop()
    if isinstance(target, (ast.Tuple, ast.List)):
      targets.extend(target.elts)
    elif isinstance(target, ast.Starred):
      targets.append(target.value)
    else:
      flat.append(target)
  return flat


def foreign_private_writes(source):
  """(line, expression) of each write to another object's private state in
  `source` (module text)."""
  found = []
  for node in ast.walk(ast.parse(source)):
    for target in _targets(node):
      if (isinstance(target, ast.Attribute) and _private(target.attr)
          and not _is_own(target.value)):
        found.append((target.lineno, ast.unparse(target)))
      if (isinstance(target, ast.Subscript)
          and isinstance(target.value, ast.Attribute)
          and target.value.attr == '__dict__'
          and not _is_own(target.value.value)):
        found.append((target.lineno, ast.unparse(target)))
    if (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
        and node.func.id in ('setattr', 'delattr') and len(node.args) >= 2
        and not _is_own(node.args[0])
        and isinstance(node.args[1], ast.Constant)
        and isinstance(node.args[1].value, str)
        and _private(node.args[1].value)):
      found.append((node.lineno, ast.unparse(node)))
  return found


def _jit_aliases(tree):
  """Module-level names bound to a numba decorator (`_jit = numba.njit(
  ...)`, `_jit = kernels._jit`)."""
  aliases = set()
  for node in tree.body:
    if isinstance(node, ast.Assign) and len(node.targets) == 1 and (
        isinstance(node.targets[0], ast.Name)):
      value = node.value.func if isinstance(node.value, ast.Call) else (
          node.value)
      name = _base_name(value)
      if name in _JIT_NAMES or name in ('_jit', '_inline'):
        aliases.add(node.targets[0].id)
  return aliases


def _base_name(node):
  if isinstance(node, ast.Attribute):
    return node.attr
  if isinstance(node, ast.Name):
    return node.id
  return None


def wide_kernels(source):
  """(line, name, parameter count) of each numba-compiled function in
  `source` with more than MAX_KERNEL_PARAMETERS parameters."""
  tree = ast.parse(source)
  jit = _JIT_NAMES | _jit_aliases(tree)
  found = []
  for node in ast.walk(tree):
    if not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
      continue
    decorators = [d.func if isinstance(d, ast.Call) else d
                  for d in node.decorator_list]
    if not any(_base_name(d) in jit for d in decorators):
      continue
    args = node.args
    count = (len(args.posonlyargs) + len(args.args) + len(args.kwonlyargs)
             + (args.vararg is not None) + (args.kwarg is not None))
    if count > MAX_KERNEL_PARAMETERS:
      found.append((node.lineno, node.name, count))
  return found


def class_lines(source, name):
  """Lines of the module-level class `name` in `source`, from its `class`
  line to its last (ast: end_lineno - lineno + 1)."""
  for node in ast.parse(source).body:
    if isinstance(node, ast.ClassDef) and node.name == name:
      return node.end_lineno - node.lineno + 1
  raise ValueError(f'No class {name!r} in the source')


def test_no_module_writes_another_objects_private_state():
  bad = [f'{_relative(path)}:{line}: {text}' for path in _modules()
         for line, text in foreign_private_writes(path.read_text())]
  assert not bad, ('Private state of another object written (use its '
                   'public methods):\n' + '\n'.join(bad))


def test_kernels_take_named_groups_not_long_parameter_lists():
  bad = [f'{_relative(path)}:{line}: {name} takes {count} parameters'
         for path in _modules()
         for line, name, count in wide_kernels(path.read_text())]
  assert not bad, (f'Kernels with more than {MAX_KERNEL_PARAMETERS} '
                   'parameters (pass named groups):\n' + '\n'.join(bad))


@pytest.mark.parametrize('source, expected', [
    ('shield._plan = 1', [(1, 'shield._plan')]),
    ('a, plan._filled = 1, 2', [(1, 'plan._filled')]),
    ('x.y._z += 1', [(1, 'x.y._z')]),
    ("shield.__dict__['_k'] = 1", [(1, "shield.__dict__['_k']")]),
    ("setattr(plan, '_goal', 1)", [(1, "setattr(plan, '_goal', 1)")]),
    ('self._plan = 1\ncls._n = 2\nx.public = 3\nx.__doc__ = ""', []),
])
def test_the_private_write_check_finds_what_it_should(source, expected):
  assert foreign_private_writes(source) == expected


def test_the_kernel_check_finds_wide_kernels():
  params = ', '.join(f'a{i}' for i in range(MAX_KERNEL_PARAMETERS + 1))
  narrow = ', '.join(f'a{i}' for i in range(MAX_KERNEL_PARAMETERS))
  source = (f'import numba\n_jit = numba.njit(cache=True)\n'
            f'@_jit\ndef wide({params}):\n  pass\n'
            f'@numba.njit\ndef also({params}):\n  pass\n'
            f'@_jit\ndef fine({narrow}):\n  pass\n'
            f'def plain({params}):\n  pass\n')
  count = MAX_KERNEL_PARAMETERS + 1
  assert wide_kernels(source) == [(4, 'wide', count), (7, 'also', count)]


def test_hrc_task_is_composer_sized():
  lines = class_lines((PACKAGE / 'tasks' / 'base.py').read_text(), 'HrcTask')
  assert lines <= MAX_TASK_LINES, (
      f'HrcTask has {lines} lines, more than {MAX_TASK_LINES}: move what is '
      'not a composer hook, a hook tasks override, the scene or the reward '
      'to the runtime module whose idea it is')


def test_the_class_size_check_counts_the_class_lines():
  source = ('x = 1\n\n\nclass Big:\n  """Doc."""\n\n  def f(self):\n'
            '    return 1\n\n\ny = 2\n')
  assert class_lines(source, 'Big') == 5
  with pytest.raises(ValueError, match='Small'):
    class_lines(source, 'Small')
