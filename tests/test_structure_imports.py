"""No import cycles among the modules of hrc_suite/ and agents/.

The import graph comes from the source text: every `import` and
`from ... import` statement anywhere in a module (at module level, inside
functions, under `if TYPE_CHECKING:`), with `from package import name`
resolved to the submodule `package.name` where there is one. A strongly
connected component of more than one module is a cycle.
"""

import ast
import pathlib

REPO = pathlib.Path(__file__).resolve().parents[1]
PACKAGES = ('hrc_suite', 'agents')

# Cycles that may remain, each a set of the component's modules (none).
ALLOWED_CYCLES = ()


def _modules():
  """{dotted module name: path} of every module of PACKAGES."""
  modules = {}
  for package in PACKAGES:
    for path in sorted((REPO / package).rglob('*.py')):
      parts = path.relative_to(REPO).with_suffix('').parts
      if parts[-1] == '__init__':
        parts = parts[:-1]
      modules['.'.join(parts)] = path
  return modules


def _imported(name, path, tree, modules):
  """The modules of `modules` that the module `name` (at `path`, parsed
  as `tree`) imports."""
  package = name.split('.') if path.name == '__init__.py' else (
      name.split('.')[:-1])
  found = set()
  for node in ast.walk(tree):
    if isinstance(node, ast.Import):
      for alias in node.names:
        target = alias.name
        while target and target not in modules:   # a.b.c: its longest module
          target = target.rpartition('.')[0]
        if target:
          found.add(target)
    elif isinstance(node, ast.ImportFrom):
      if node.level:
        base = package[:len(package) - node.level + 1]
        source = '.'.join(base + ([node.module] if node.module else []))
      else:
        source = node.module
      for alias in node.names:
        submodule = f'{source}.{alias.name}'
        if submodule in modules:
          found.add(submodule)
        elif source in modules:
          found.add(source)
  found.discard(name)
  return found


def import_graph():
  """{module: the modules it imports} of PACKAGES."""
  modules = _modules()
  return {name: _imported(name, path, ast.parse(path.read_text()), modules)
          for name, path in modules.items()}


def strongly_connected(graph):
  """The strongly connected components of `graph` (Tarjan's algorithm,
  iterative), each a frozenset."""
  index, low, on_stack, stack, components = {}, {}, set(), [], []
  counter = 0
  for root in graph:
    if root in index:
      continue
    work = [(root, iter(sorted(graph[root])))]
    index[root] = low[root] = counter
    counter += 1
    stack.append(root)
    on_stack.add(root)
    while work:
      node, successors = work[-1]
      advanced = False
      for successor in successors:
        if successor not in index:
          index[successor] = low[successor] = counter
          counter += 1
          stack.append(successor)
          on_stack.add(successor)
          work.append((successor, iter(sorted(graph[successor]))))
          advanced = True
          break
        if successor in on_stack:
          low[node] = min(low[node], index[successor])
      if advanced:
        continue
      work.pop()
      if work:
        parent = work[-1][0]
        low[parent] = min(low[parent], low[node])
      if low[node] == index[node]:
        component = set()
        while True:
          member = stack.pop()
          on_stack.discard(member)
          component.add(member)
          if member == node:
            break
        components.append(frozenset(component))
  return components


def cycles(graph):
  """The components of more than one module."""
  return [c for c in strongly_connected(graph) if len(c) > 1]


def test_the_graph_sees_imports_inside_functions():
  graph = import_graph()
  # tasks/scene.py imports human_playback at module level; suite.py
  # imports the task modules by name (importlib), which is no edge.
  assert 'hrc_suite.entities.human_playback' in graph[
      'hrc_suite.tasks.scene']
  tree = ast.parse('def f():\n  from hrc_suite.entities import human\n')
  modules = {'hrc_suite.entities.human': None,
             'hrc_suite.entities': None}
  assert _imported('m', REPO / 'm.py', tree, modules) == {
      'hrc_suite.entities.human'}


def test_cycles_are_found():
  graph = {'a': {'b'}, 'b': {'c'}, 'c': {'a'}, 'd': {'a'}, 'e': set()}
  assert cycles(graph) == [frozenset({'a', 'b', 'c'})]
  assert cycles({'a': {'b'}, 'b': set()}) == []


def test_no_import_cycles():
  found = cycles(import_graph())
  unexpected = [sorted(c) for c in found if c not in ALLOWED_CYCLES]
  assert not unexpected, (
      'Import cycles (modules that import each other, directly or through '
      f'others): {unexpected}')


def test_allowed_cycles_still_exist():
  # An allowed cycle that is gone leaves the allow-list: delete it there.
  found = set(cycles(import_graph()))
  gone = [sorted(c) for c in ALLOWED_CYCLES if c not in found]
  assert not gone, f'No longer cycles, remove from ALLOWED_CYCLES: {gone}'
