"""No import cycles among the modules of hrc_suite/ and agents/, and
imports between packages that run one way (docs/architecture.md,
"Packages").

The import graph comes from the source text: every `import` and
`from ... import` statement anywhere in a module (at module level, inside
functions, under `if TYPE_CHECKING:`), with `from package import name`
resolved to the submodule `package.name` where there is one. A strongly
connected component of more than one module is a cycle.
"""

import ast
import importlib
import pathlib

REPO = pathlib.Path(__file__).resolve().parents[1]
PACKAGES = ('hrc_suite', 'agents')

# Cycles that may remain, each a set of the component's modules (none).
ALLOWED_CYCLES = ()
# (package, packages that none of its modules reaches through a chain of
# imports; the modules of those packages themselves are exempt).
ONE_WAY = (
    ('hrc_suite.safety',
     ('hrc_suite.safety.shield', 'hrc_suite.safety.collision_prevention')),
    ('hrc_suite.safety.collision_prevention', ('hrc_suite.safety.shield',)),
    ('hrc_suite.human', ('hrc_suite.tasks', 'hrc_suite.motion_tools')),
)
# Names that users import from a package (the package re-exports them).
REEXPORTS = {
    'hrc_suite.safety.shield': ('hrc_suite.safety.shield.shield',
                                ('Shield',)),
    'hrc_suite.safety.collision_prevention': (
        'hrc_suite.safety.collision_prevention.prevention',
        ('CollisionPrevention', 'FilteredAction', 'POLICIES',
         'workcell_boxes')),
}


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
  # tasks/runtime/scene.py imports human_playback at module level; suite.py
  # imports the task modules by name (importlib), which is no edge.
  assert 'hrc_suite.entities.human_playback' in graph[
      'hrc_suite.tasks.runtime.scene']
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


def _inside(name, package):
  return name == package or name.startswith(package + '.')


def reachable(graph, start):
  """The modules that `start` imports, directly or through others."""
  seen, todo = set(), list(graph[start])
  while todo:
    name = todo.pop()
    if name not in seen:
      seen.add(name)
      todo.extend(graph.get(name, ()))
  return seen


def one_way_violations(graph, rules=ONE_WAY):
  """(importer, reached module) of each module of a rule's package that
  reaches a module of one of the rule's forbidden packages."""
  found = []
  for package, forbidden in rules:
    for name in sorted(graph):
      if not _inside(name, package) or any(_inside(name, f)
                                           for f in forbidden):
        continue
      for target in sorted(reachable(graph, name)):
        if any(_inside(target, f) for f in forbidden):
          found.append((name, target))
  return found


def test_one_way_violations_are_found():
  graph = {'p': set(), 'p.a': {'q.b'}, 'p.sub': set(), 'p.sub.c': {'p.a'},
           'q': set(), 'q.b': {'p.sub.c'}}
  assert one_way_violations(graph, (('p', ('p.sub',)),)) == [
      ('p.a', 'p.sub.c')]
  assert one_way_violations(graph, (('p.sub', ('q',)),)) == [
      ('p.sub.c', 'q.b')]
  assert one_way_violations(graph, (('q', ('x',)),)) == []


def test_packages_import_one_way():
  found = one_way_violations(import_graph())
  assert not found, (
      'Imports against docs/architecture.md\'s "Packages" (importer, '
      f'module it reaches): {found}')


def test_packages_re_export_their_public_names():
  for package, (module, names) in REEXPORTS.items():
    package_module = importlib.import_module(package)
    defining = importlib.import_module(module)
    for name in names:
      assert getattr(package_module, name) is getattr(defining, name), (
          package, name)
    assert sorted(package_module.__all__) == sorted(names), package
