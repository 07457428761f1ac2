"""CPU time per RL step of a commit against the working tree, in ONE process.

  MUJOCO_GL=egl python scripts/compare_speed.py [--base=COMMIT]
      [--tasks=reach/dense,stacking/default] [--robots=schunk,panda]
      [--action_space=cartesian] [--windows=60]
  python scripts/compare_speed.py --shield=pfl [--scene=close]
      [--robots=jaco,kinova3] [--base=COMMIT] [--windows=60]

On a host whose speed drifts from minute to minute (docs/benchmarks.md,
"The development machine"), runs of two checkouts one after the other differ by more
than the changes they compare. This script loads the commit's package as
`hrc_suite_base` (extracted with `git archive`, its own imports renamed,
kept under ~/.cache/hrc_suite_compare/COMMIT-r2 so numba compiles it once)
beside the working tree's `hrc_suite`, builds the same task in both from
the same seed, and steps them in alternating windows of 10 RL steps with
the same random actions: both see the same host. It prints the medians
of both and the median over windows of their ratio (new / base), and
whether the two ended in the same state (same episodes: a change meant to
keep them bit for bit must print True).

With --shield=ssm or pfl it compares the shield's cycles of an RL step
instead (`python -m hrc_suite.safety.shield.benchmark --rl_step`'s scenes): in
both packages a shield of each robot in the scene, a new random goal
before each RL step (the same goals), the RL step's 25 cycles in
`batch.step_many`, thread CPU time per RL step, in alternating windows;
"same" compares the shields' commands at the end.
"""

import importlib
import os
import pathlib
import re
import subprocess
import sys
import tarfile
import tempfile
import time

from absl import app
from absl import flags
import numpy as np

_BASE = flags.DEFINE_string('base', 'HEAD', 'Commit to compare against.')
_TASKS = flags.DEFINE_list('tasks', ['reach/dense', 'stacking/default'],
                           'domain/task names.')
_ROBOTS = flags.DEFINE_list('robots', ['schunk', 'panda'], 'Robots.')
_ACTION_SPACE = flags.DEFINE_string(
    'action_space', None, "'joint' or 'cartesian' (default: each task's).")
_WINDOWS = flags.DEFINE_integer('windows', 60, 'Windows per package.')
_SHIELD = flags.DEFINE_enum(
    'shield', None, ['ssm', 'pfl'],
    "Compare the shield's RL-step cycles in this mode instead of tasks.")
_SCENE = flags.DEFINE_enum('scene', 'close', ['close', 'across', 'far'],
                           "The shield comparison's scene.")

_WINDOW = 10     # RL steps per window.
_WARM_UP = 30    # RL steps before the first window.
_REPOSITORY = pathlib.Path(__file__).resolve().parent.parent
# An import of the package at the start of a line (what is renamed).
_IMPORT = re.compile(r'^(\s*)(from|import) hrc_suite\b', re.MULTILINE)
# A string naming one of the package's modules (importlib.import_module,
# the registries' module lists before commit 3a3e3ba) is renamed too;
# other strings that start with the package's name (file format names)
# are not.
_MODULE_NAME = r"""(['"])hrc_suite\.(?=(?:{names})\b)"""
# Part of the cache's directory name: extractions renamed by older rules
# are not reused.
_RENAMING = 'r2'


def _base_package(commit):
  """Directory holding `hrc_suite_base`, the package at `commit`."""
  sha = subprocess.run(['git', 'rev-parse', commit], cwd=_REPOSITORY,
                       check=True, capture_output=True,
                       text=True).stdout.strip()
  root = (pathlib.Path.home() / '.cache' / 'hrc_suite_compare'
          / f'{sha}-{_RENAMING}')
  package = root / 'hrc_suite_base'
  if not package.is_dir():
    archive = subprocess.run(['git', 'archive', sha, 'hrc_suite'],
                             cwd=_REPOSITORY, check=True,
                             capture_output=True).stdout
    root.parent.mkdir(parents=True, exist_ok=True)
    # Extracted beside its place, then moved there in one step.
    with tempfile.TemporaryDirectory(dir=root.parent) as scratch:
      path = pathlib.Path(scratch) / 'archive.tar'
      path.write_bytes(archive)
      with tarfile.open(path) as tar:
        tar.extractall(scratch, filter='data')
      extracted = pathlib.Path(scratch) / 'hrc_suite'
      modules = re.compile(_MODULE_NAME.format(names='|'.join(sorted(
          p.stem for p in extracted.iterdir()
          if p.suffix == '.py' or (p / '__init__.py').is_file()))))
      for source in extracted.rglob('*.py'):
        text = _IMPORT.sub(r'\1\2 hrc_suite_base', source.read_text())
        source.write_text(modules.sub(r'\1hrc_suite_base.', text))
      root.mkdir(parents=True, exist_ok=True)
      os.replace(pathlib.Path(scratch) / 'hrc_suite', package)
  return root, sha


def _stepper(suite, domain, task, robot, action_space):
  kwargs = dict(robot=robot, seed=0)
  if action_space:
    kwargs['action_space'] = action_space
  env = suite.load(domain, task, task_kwargs=kwargs)
  spec = env.action_spec()
  rng = np.random.RandomState(0)
  env.reset()

  def steps(count):
    for _ in range(count):
      action = rng.uniform(spec.minimum, spec.maximum).astype(spec.dtype)
      if env.step(action).last():
        env.reset()
  return env, steps


def compare(domain, task, robot, action_space, windows, suites):
  """(base us, new us per RL step (medians), ratio median, IQR, same)."""
  (env_base, base), (env_new, new) = (
      _stepper(s, domain, task, robot, action_space) for s in suites)
  base(_WARM_UP)
  new(_WARM_UP)
  times = {base: [], new: []}
  for w in range(windows):
    for steps in ((base, new) if w % 2 == 0 else (new, base)):
      start = time.process_time()
      steps(_WINDOW)
      times[steps].append((time.process_time() - start) / _WINDOW)
  ratio = np.array(times[new]) / np.array(times[base])
  same = (np.array_equal(env_base.physics.data.qpos,
                         env_new.physics.data.qpos)
          and np.array_equal(env_base.physics.data.qvel,
                             env_new.physics.data.qvel))
  return (1e6 * np.median(times[base]), 1e6 * np.median(times[new]),
          np.median(ratio), np.percentile(ratio, [25, 75]), same)


def _shield_module(package, name):
  """`package`'s shield module `name`: in safety/shield/, or in safety/
  in a base commit that has no shield subpackage."""
  try:
    return importlib.import_module(f'{package}.safety.shield.{name}')
  except ModuleNotFoundError:
    return importlib.import_module(f'{package}.safety.{name}')


def _shield_stepper(package, name, scene, mode):
  """(shield, steps(count)) of the safety benchmark's RL-step timing
  (hrc_suite/safety/shield/benchmark.py, time_rl_steps) in `package`."""
  benchmark = _shield_module(package, 'benchmark')
  batch = _shield_module(package, 'batch')
  description, shield, human = benchmark._scene(name, mode, scene)   # pylint: disable=protected-access
  limits = description.limits
  rng = np.random.RandomState(0)
  cycles = benchmark.RL_STEP_CYCLES
  done = [0]

  def steps(count):
    """Thread CPU time (s) of `count` RL steps' step_many calls."""
    spent = 0.0
    for _ in range(count):
      shield.new_goal(np.clip(description.q_home + rng.uniform(
          -1.0, 1.0, description.dof), limits.q_min, limits.q_max))
      times = (done[0] * cycles + np.arange(cycles)) * shield.cycle_time
      frames = np.array([human(t) for t in times])
      start = time.thread_time()
      batch.step_many(shield, frames, times)
      spent += time.thread_time() - start
      done[0] += 1
    return spent
  return shield, steps


def compare_shield(name, scene, mode, windows):
  """compare's tuple for the shield's RL-step cycles (thread CPU time of
  step_many only, the goal and the frames outside)."""
  (shield_base, base), (shield_new, new) = (
      _shield_stepper(p, name, scene, mode)
      for p in ('hrc_suite_base', 'hrc_suite'))
  base(_WARM_UP)
  new(_WARM_UP)
  times = {base: [], new: []}
  for w in range(windows):
    for steps in ((base, new) if w % 2 == 0 else (new, base)):
      times[steps].append(steps(_WINDOW) / _WINDOW)
  ratio = np.array(times[new]) / np.array(times[base])
  same = (np.array_equal(shield_base.q, shield_new.q)
          and np.array_equal(shield_base.dq, shield_new.dq))
  return (1e6 * np.median(times[base]), 1e6 * np.median(times[new]),
          np.median(ratio), np.percentile(ratio, [25, 75]), same)


def main(argv):
  del argv
  root, sha = _base_package(_BASE.value)
  sys.path.insert(0, str(root))
  if _SHIELD.value:
    print(f'base {sha[:7]} against the working tree; the shield '
          f'({_SHIELD.value}, scene {_SCENE.value}): thread CPU us per RL '
          f'step (medians of {_WINDOWS.value} alternating windows of '
          f'{_WINDOW})')
    print('| robot | base | new | new / base (median, IQR) | same |')
    print('|---|---|---|---|---|')
    for robot in _ROBOTS.value:
      old, new, ratio, (low, high), same = compare_shield(
          robot, _SCENE.value, _SHIELD.value, _WINDOWS.value)
      print(f'| {robot} | {old:.0f} | {new:.0f} | {ratio:.3f} '
            f'({low:.3f}-{high:.3f}) | {same} |', flush=True)
    return
  from hrc_suite import suite as suite_new   # pylint: disable=g-import-not-at-top
  from hrc_suite_base import suite as suite_base   # pylint: disable=g-import-not-at-top
  print(f'base {sha[:7]} against the working tree; CPU us per RL step '
        f'(medians of {_WINDOWS.value} alternating windows of {_WINDOW})')
  print('| task | robot | base | new | new / base (median, IQR) | same '
        'episodes |')
  print('|---|---|---|---|---|---|')
  for name in _TASKS.value:
    domain, task = name.split('/')
    for robot in _ROBOTS.value:
      old, new, ratio, (low, high), same = compare(
          domain, task, robot, _ACTION_SPACE.value, _WINDOWS.value,
          (suite_base, suite_new))
      print(f'| {name} | {robot} | {old:.0f} | {new:.0f} | {ratio:.3f} '
            f'({low:.3f}-{high:.3f}) | {same} |', flush=True)


if __name__ == '__main__':
  app.run(main)
