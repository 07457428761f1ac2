r"""Runs a grid of training runs on Ray, resumably.

  python -m agents.sweep --grid=smoke --out=sweeps/smoke     # a minute
  python -m agents.sweep --grid=paper_reduced --out=sweeps/paper_reduced
  python -m agents.sweep --grid=paper --out=/shared/paper \
      --ray_address=auto                          # an existing Ray cluster
  python -m agents.report --sweep=sweeps/paper_reduced

The grid (`agents.grids`: paper, paper_reduced, overfitting, safe_rl, smoke) says
which runs to train; each of its fields can be replaced by the flag of the
same name (--tasks, --agents, --seeds, --steps, --eval_every, ...). The
sweep directory's layout is `agents.sweep_layout`'s.

Ray is the engine: each run is a Ray task that declares --cpus_per_run CPUs
(and --gpus_per_run GPUs), pinned to its cores (`agents.sweep_work`). By
default the sweep starts an embedded Ray on this machine with all its
cores (no dashboard, a small object store) and stops it at the end;
--ray_address=auto or HOST:PORT joins an existing cluster instead, whose
machines must have hrc_suite installed and --out on storage they share.

Before any run starts, every machine compiles hrc_suite's kernels once,
and each task's shared inputs are made once: the expert dataset of RSI,
SIR and AIR runs (their runs wait for it) and the expert's return for the
normalised return (`agents.report`).

Starting the same command again resumes the sweep: finished runs are
skipped, the others continue from their latest checkpoint, a partial
dataset is completed. A run's steps may grow between starts (--steps);
any other change of the grid is refused (a new --out is a new sweep). A
worker that dies (killed, out of memory) is retried --max_retries times;
a run that raises is reported (its error.json) and the others go on; the
command exits with status 1 if any run failed. Ctrl-C or SIGTERM (a
scheduler's preemption, `kill`) stops it the same way: runs resume from
their checkpoints when the command starts again.

Progress is printed every --report_every seconds: runs done, running and
left, steps, the recent rate and the estimated time to finish.
"""

import dataclasses
import json
import os
import signal
import socket
import subprocess
import sys
import time
from typing import Any, Dict, List, Optional, Sequence, TextIO

from absl import app
from absl import flags

from agents import grids as grids_lib
from agents import sweep_layout as layout
from agents import sweep_work

# The embedded Ray's object store: runs pass only paths and small records.
# Ray's smallest allowed store is 75 MiB.
OBJECT_STORE_BYTES = 100 * 1024 ** 2
# Grid fields that may change when a sweep is started again.
RESUMABLE_CHANGES = ('steps',)
# Seconds to wait for an existing cluster's address to answer.
CONNECT_TIMEOUT_S = 10
# Exit status after Ctrl-C: 128 + SIGINT, the shells' convention.
INTERRUPTED_STATUS = 130
# After SIGTERM: 128 + SIGTERM.
TERMINATED_STATUS = 143

# Grid fields whose flags take lists, integers, JSON or plain strings.
_LIST_FIELDS = ('tasks', 'agents')
_INT_LIST_FIELDS = ('seeds', 'splits')
_INT_FIELDS = ('eval_every', 'eval_episodes', 'dataset_episodes',
               'expert_episodes', 'checkpoint_every', 'test_clips')
_JSON_FIELDS = ('overrides', 'task_kwargs', 'imitation_kwargs', 'variants')
_STRING_FIELDS = ('robot', 'config', 'motions')


def define_flags(flag_values: flags.FlagValues = flags.FLAGS) -> None:
  """Defines the binary's flags (only when run as a program).

  Args:
    flag_values: where to define them.
  """
  fv = flag_values
  flags.DEFINE_string('grid', None, 'Grid name: ' + ', '.join(grids_lib.GRIDS),
                      flag_values=fv)
  flags.DEFINE_string('out', None, 'Sweep directory (shared storage on a '
                      'cluster).', flag_values=fv)
  flags.DEFINE_string('ray_address', None, 'None: an embedded Ray on this '
                      'machine; auto or HOST:PORT: an existing cluster.',
                      flag_values=fv)
  flags.DEFINE_integer('num_cpus', None, 'CPUs of the embedded Ray '
                       '(default: all of this machine\'s).', flag_values=fv)
  flags.DEFINE_integer('cpus_per_run', 1, 'CPUs each run declares and is '
                       'pinned to (docs/results/paper_grid.md: 1 run per '
                       'core trains faster in all than 1 run on 2).',
                       flag_values=fv)
  flags.DEFINE_float('gpus_per_run', 0.0, 'GPUs each run declares.',
                     flag_values=fv)
  flags.DEFINE_integer('max_retries', 2, 'Restarts of a run whose worker '
                       'died.', flag_values=fv)
  flags.DEFINE_float('report_every', 60.0, 'Seconds between progress '
                     'lines.', flag_values=fv)
  flags.DEFINE_bool('dry_run', False, 'List the runs and their state, '
                    'start nothing.', flag_values=fv)
  for field in _LIST_FIELDS:
    flags.DEFINE_list(field, None, f'Grid field {field} (comma-separated).',
                      flag_values=fv)
  for field in _INT_LIST_FIELDS:
    flags.DEFINE_list(field, None, f'Grid field {field}: integers, '
                      'comma-separated, or a range a-b.', flag_values=fv)
  for field in _INT_FIELDS:
    flags.DEFINE_integer(field, None, f'Grid field {field}.',
                         flag_values=fv)
  flags.DEFINE_string('steps', None, 'Grid field steps: N for every task, or '
                      'task=N,task=N (every task of the grid).',
                      flag_values=fv)
  for field in _JSON_FIELDS:
    flags.DEFINE_string(field, None, f'Grid field {field} as a JSON object.',
                        flag_values=fv)
  for field in _STRING_FIELDS:
    flags.DEFINE_string(field, None, f'Grid field {field}.', flag_values=fv)


def _integers(field, items):
  values = []
  for item in items:
    low, dash, high = item.partition('-')
    try:
      if dash:
        values.extend(range(int(low), int(high) + 1))
      else:
        values.append(int(item))
    except ValueError:
      raise ValueError(f'--{field}={",".join(items)}: expected integers or '
                       f'ranges a-b, got {item!r}') from None
  return tuple(values)


def _steps(text):
  """--steps: N (every task) or task=N,task=N."""
  def number(value, item):
    try:
      steps = float(value)
    except ValueError:
      steps = None
    if steps is None or steps != int(steps):
      raise ValueError(f'--steps={text}: {item!r} is not an integer (N, or '
                       'task=N,task=N)')
    return int(steps)
  if '=' not in text:
    return number(text, text)
  steps = {}
  for item in text.split(','):
    task, _, value = item.partition('=')
    steps[task.strip()] = number(value, item)
  return steps


def grid_from_flags(f: flags.FlagValues) -> grids_lib.Grid:
  """The grid named by --grid with the fields its flags replace.

  Args:
    f: the parsed flags.

  Returns:
    The grid.

  Raises:
    ValueError: no --grid, a flag's bad value, or a bad grid.
  """
  if f.grid is None:
    raise ValueError('--grid is required: one of ' + ', '.join(grids_lib.GRIDS))
  grid = grids_lib.get(f.grid)
  changes = {}
  for field in _LIST_FIELDS:
    if f[field].value is not None:
      changes[field] = tuple(f[field].value)
  for field in _INT_LIST_FIELDS:
    if f[field].value is not None:
      changes[field] = _integers(field, f[field].value)
  for field in _INT_FIELDS + _STRING_FIELDS:
    if f[field].value is not None:
      changes[field] = f[field].value
  for field in _JSON_FIELDS:
    if f[field].value is not None:
      try:
        value = json.loads(f[field].value)
      except json.JSONDecodeError as e:
        raise ValueError(f'--{field}: not valid JSON ({e})') from None
      if not isinstance(value, dict):
        raise ValueError(f'--{field}={f[field].value}: expected a JSON '
                         'object')
      changes[field] = value
  if f.steps is not None:
    changes['steps'] = _steps(f.steps)
  if 'tasks' in changes and 'steps' not in changes and isinstance(
      grid.steps, dict):
    # Tasks outside the paper's figure take the longest budget.
    default = max(grid.steps.values())
    changes['steps'] = {t: grid.steps.get(t, default)
                        for t in changes['tasks']}
  return grid.replace(**changes)


def _git_commit():
  try:
    return subprocess.run(
        ['git', 'rev-parse', 'HEAD'], capture_output=True, text=True,
        cwd=os.path.dirname(os.path.abspath(__file__)),
        check=True).stdout.strip()
  except (OSError, subprocess.CalledProcessError):
    return None


def open_sweep(out: str, grid: grids_lib.Grid) -> Dict[str, Any]:
  """Creates the sweep directory or checks that it holds the same grid
  (but for RESUMABLE_CHANGES); writes sweep.json with this start (commit,
  time, host) appended to its starts.

  Args:
    out: the sweep directory.
    grid: the grid.

  Returns:
    The sweep record written.

  Raises:
    ValueError: a directory holding a sweep of another grid.
  """
  os.makedirs(os.path.join(out, layout.RUNS), exist_ok=True)
  path = os.path.join(out, layout.SWEEP_FILE)
  stored = layout.read_json(path)
  if stored is not None:
    old = grids_lib.Grid.from_dict(stored['grid']).to_dict()
    new = grid.to_dict()
    changed = sorted(k for k in new if k not in RESUMABLE_CHANGES
                     and old.get(k) != new[k])
    if changed:
      details = '; '.join(f'{k}: {old.get(k)!r} -> {new[k]!r}'
                          for k in changed)
      raise ValueError(f'{out} holds a sweep of another grid ({details}); '
                       f'only {list(RESUMABLE_CHANGES)} may change: choose '
                       'a new --out for a new grid')
  commit, now = _git_commit(), time.time()
  starts = list((stored or {}).get('starts', []))
  starts.append({'commit': commit, 'time': now,
                 'host': socket.gethostname()})
  record = {'grid': grid.to_dict(), 'commit': commit,
            'started': (stored or {}).get('started', now), 'updated': now,
            'starts': starts}
  layout.write_json(path, record)
  return record


def start_ray(address: Optional[str] = None,
              num_cpus: Optional[int] = None) -> Any:
  """Connects to the cluster at `address`, or starts an embedded Ray.

  Args:
    address: None (an embedded Ray), 'auto' or a cluster's HOST:PORT.
    num_cpus: CPUs of the embedded Ray (None: all of this machine's).

  Returns:
    The ray module, initialised.

  Raises:
    ValueError: num_cpus with an address, or a bad address.
    ConnectionError: a cluster that cannot be reached.
  """
  import ray   # pylint: disable=g-import-not-at-top
  if address is None:
    # 'local': a new Ray of this process even where a cluster started by
    # `ray start` (or another sweep's) runs on the machine, which ray.init
    # without an address would join.
    ray.init(address='local', num_cpus=num_cpus or os.cpu_count(),
             include_dashboard=False,
             object_store_memory=OBJECT_STORE_BYTES, log_to_driver=False,
             configure_logging=False)
    return ray
  if num_cpus is not None:
    raise ValueError('--num_cpus is for the embedded Ray; a cluster has '
                     'its own CPUs')
  check_reachable(address)
  try:
    ray.init(address=address, log_to_driver=False, configure_logging=False)
  except (ConnectionError, RuntimeError, ValueError) as e:
    hint = ''
    if 'RAY_AUTH_MODE' not in os.environ:
      # Clusters of Ray >= 2.5x authenticate by token by default; a driver
      # given an address does not send one unless told to.
      hint = ('; if the cluster uses token authentication (Ray prints '
              '"Token authentication is enabled" at `ray start`), set '
              'RAY_AUTH_MODE=token with its token in ~/.ray/auth_token or '
              'RAY_AUTH_TOKEN')
    raise ConnectionError(f'Cannot reach a Ray cluster at --ray_address='
                          f'{address!r}: {e}{hint}') from None
  return ray


def check_reachable(address: str, timeout: float = CONNECT_TIMEOUT_S
                    ) -> None:
  """Checks that a TCP connection to a cluster address opens in time;
  ray.init itself waits without end for an address nobody answers at.
  'auto' is left to Ray, which fails at once when it finds no cluster.

  Args:
    address: 'auto', HOST:PORT or ray://HOST:PORT.
    timeout: seconds.

  Raises:
    ValueError: an address of another form.
    ConnectionError: no answer within `timeout`.
  """
  if address == 'auto':
    return
  host, sep, port = address.split('://', 1)[-1].rpartition(':')
  if not sep or not host or not port.isdigit():
    raise ValueError(f'--ray_address={address!r}: expected auto, HOST:PORT '
                     'or ray://HOST:PORT')
  try:
    socket.create_connection((host, int(port)), timeout=timeout).close()
  except OSError as e:
    raise ConnectionError(
        f'Cannot reach a Ray cluster at --ray_address={address!r}: no '
        f'answer from {host}:{port} within {timeout} s ({e}); start one '
        'with `ray start --head` or leave --ray_address unset for an '
        'embedded Ray') from None


@dataclasses.dataclass
class _Status:
  done: int = 0
  failed: int = 0
  steps_total: int = 0


def _format_seconds(seconds):
  seconds = int(seconds)
  if seconds >= 3600:
    return f'{seconds // 3600} h {seconds % 3600 // 60:02d} min'
  if seconds >= 60:
    return f'{seconds // 60} min {seconds % 60:02d} s'
  return f'{seconds} s'


class ProgressReporter:
  """Counts runs and steps from the run directories' records and prints a
  line: runs done/running/left, steps, rate and estimated time to finish.

  Args:
    out: the sweep directory.
    runs: the grid's runs.
    stream: where the lines go.
  """

  def __init__(self, out: str, runs: Sequence[grids_lib.Run],
               stream: TextIO = sys.stdout):
    self.out = out
    self._runs = runs
    self._stream = stream
    self._start = time.time()
    self._first = self.steps_done()
    self.failed = set()

  def steps_done(self) -> int:
    """Steps the runs' records count (each at most its run's steps)."""
    return sum(min(layout.progress(layout.run_directory(self.out, r.name)),
                   int(r.run_config['steps'])) for r in self._runs)

  def line(self, running: int) -> str:
    """The progress line.

    Args:
      running: the runs training now.

    Returns:
      The line.
    """
    done = sum(1 for r in self._runs if layout.is_finished(
        layout.run_directory(self.out, r.name), r.run_config['steps']))
    total = sum(int(r.run_config['steps']) for r in self._runs)
    steps = self.steps_done()
    elapsed = time.time() - self._start
    rate = (steps - self._first) / elapsed if elapsed > 0 else 0.0
    left = len(self._runs) - done - running - len(self.failed)
    text = (f'[sweep] runs: {done} done, {running} running, {left} waiting'
            f'{f", {len(self.failed)} failed" if self.failed else ""} of '
            f'{len(self._runs)} | steps {steps:.3g} of {total:.3g} '
            f'({100.0 * steps / max(total, 1):.1f} %)')
    if rate > 0:
      text += (f' | {rate:.0f} steps/s | about '
               f'{_format_seconds((total - steps) / rate)} left')
    return text

  def report(self, running: int) -> None:
    """Prints the progress line to the stream.

    Args:
      running: the runs training now.
    """
    print(self.line(running), file=self._stream, flush=True)


def run_sweep(out: str, grid: grids_lib.Grid,
              ray_address: Optional[str] = None,
              num_cpus: Optional[int] = None, cpus_per_run: int = 1,
              gpus_per_run: float = 0.0, max_retries: int = 2,
              report_every: float = 60.0,
              stream: TextIO = sys.stdout) -> List[str]:
  """Trains every unfinished run of `grid` in `out`; returns the names of
  the runs that failed.

  Args:
    out: the sweep directory.
    grid: an agents.grids.Grid.
    ray_address: None (an embedded Ray) or a cluster's address.
    num_cpus: CPUs of the embedded Ray (None: all).
    cpus_per_run: CPUs each run declares and is pinned to.
    gpus_per_run: GPUs each run declares.
    max_retries: restarts of a run whose worker died.
    report_every: seconds between progress lines.
    stream: where progress goes.

  Returns:
    The names of the runs that failed.

  Raises:
    ValueError: a directory holding another grid, or bad Ray settings.
    ConnectionError: a cluster that cannot be reached.
  """
  if int(cpus_per_run) != cpus_per_run or cpus_per_run < 1:
    raise ValueError(f'cpus_per_run={cpus_per_run!r}: expected an integer '
                     '>= 1')
  if gpus_per_run < 0:
    raise ValueError(f'gpus_per_run={gpus_per_run!r}: expected >= 0')
  out = os.path.abspath(out)
  open_sweep(out, grid)
  runs = grid.runs()
  # Seed by seed: a sweep stopped early has every task and agent on its
  # first seeds rather than some tasks on all seeds.
  todo = sorted((r for r in runs if not layout.is_finished(
      layout.run_directory(out, r.name), r.run_config['steps'])),
                key=lambda r: (grid.seeds.index(r.seed),
                               grid.tasks.index(r.task)))
  reporter = ProgressReporter(out, runs, stream)
  print(f'[sweep] {grid.name}: {len(runs)} runs, {len(runs) - len(todo)} '
        f'finished before, in {out}', file=stream, flush=True)
  experts_left = [task for task in grid.tasks
                  if not _expert_done(out, task, grid.expert_episodes)]
  if not todo and not experts_left:
    return []
  ray = start_ray(ray_address, num_cpus)
  try:
    cpus = int(cpus_per_run)
    environment = {'env_vars': sweep_work.thread_environment(cpus)}
    _prepare_nodes(ray, grid.robot, stream)
    # Shared inputs first.
    datasets = {}
    for run in todo:
      if grid.needs_dataset(run.agent):
        key = (run.task, run.split)
        if key not in datasets:
          directory = layout.dataset_directory(out, *key)
          datasets[key] = ray.remote(sweep_work.collect_dataset).options(
              num_cpus=1, max_retries=max_retries,
              runtime_env=environment).remote(
                  directory, run.task, _shared_task_kwargs(grid, run),
                  grid.dataset_episodes)
    experts = [ray.remote(sweep_work.expert_returns).options(
        num_cpus=1, max_retries=max_retries, runtime_env=environment).remote(
            layout.expert_file(out, task), task,
            _shared_task_kwargs(grid, None, task), grid.expert_episodes)
               for task in experts_left]
    # A fresh worker process per run (max_calls=1): its pinning, thread
    # pools and memory end with it.
    train = ray.remote(num_cpus=cpus, num_gpus=gpus_per_run,
                       max_retries=max_retries, max_calls=1,
                       runtime_env=environment)(sweep_work.train_run)
    # The runs go in once the datasets are there: Ray queues a task whose
    # arguments are not ready behind those submitted with theirs, which
    # would put every SAC run before the first imitation run.
    datasets = _wait_for_datasets(ray, datasets, stream)
    pending = {}
    for run in todo:
      dataset = (datasets.get((run.task, run.split))
                 if grid.needs_dataset(run.agent) else None)
      pending[train.remote(out, run.name, dict(run.run_config), cpus,
                           dataset)] = run
    for ref in experts:
      pending[ref] = None
    failures = _wait(ray, pending, reporter, report_every, stream)
  finally:
    if ray_address is None:
      ray.shutdown()
  reporter.report(0)
  return failures


def _wait_for_datasets(ray, datasets, stream):
  """{(task, split): directory} once every dataset task has finished; a
  RuntimeError naming the dataset that could not be made."""
  ready = {}
  for key, ref in datasets.items():
    try:
      ready[key] = ray.get(ref)
    except Exception as e:   # pylint: disable=broad-except
      cause = getattr(e, 'cause', None) or e
      raise RuntimeError(f'The expert dataset of {key[0]} (split {key[1]}) '
                         f'could not be made: {type(cause).__name__}: '
                         f'{cause}') from None
  if ready:
    print(f'[sweep] expert datasets ready: {len(ready)}', file=stream,
          flush=True)
  return ready


def _shared_task_kwargs(grid, run, task=None):
  """Task kwargs (robot and action space included) of a task's dataset or
  expert episodes: the grid's, on the train side of the run's split."""
  task = task or run.task
  domain, name = task.split('/')
  kwargs = grid.task_kwargs_of(None if run is None else run.split)
  kwargs.update(robot=grid.robot,
                action_space=grids_lib.default_action_space(domain, name))
  return kwargs


def _expert_done(out, task, episodes):
  record = layout.read_json(layout.expert_file(out, task))
  return record is not None and record['episodes'] >= episodes


def _prepare_nodes(ray, robot, stream):
  """Compiles the kernels once on every alive machine of the cluster."""
  from ray.util import scheduling_strategies   # pylint: disable=g-import-not-at-top
  nodes = [n['NodeID'] for n in ray.nodes() if n.get('Alive')]
  task = ray.remote(sweep_work.prepare_node)
  refs = [task.options(num_cpus=0, scheduling_strategy=(
      scheduling_strategies.NodeAffinitySchedulingStrategy(node, soft=False))
                       ).remote(robot) for node in nodes]
  for host, seconds in ray.get(refs):
    print(f'[sweep] kernels ready on {host} in {seconds:.0f} s',
          file=stream, flush=True)


def _wait(ray, pending, reporter, report_every, stream):
  failures = []
  last = 0.0
  running = 0
  while pending:
    ready, _ = ray.wait(list(pending), num_returns=1,
                        timeout=min(report_every, 5.0))
    for ref in ready:
      run = pending.pop(ref)
      try:
        result = ray.get(ref)
      except Exception as e:   # pylint: disable=broad-except
        name = run.name if run is not None else 'expert returns'
        reporter.failed.add(name)
        failures.append(name)
        cause = getattr(e, 'cause', None) or e
        print(f'[sweep] {name} failed: {type(cause).__name__}: '
              f'{str(cause).splitlines()[-1] if str(cause) else ""}',
              file=stream, flush=True)
        continue
      if run is not None:
        print(f'[sweep] {run.name} finished: {result["steps"]} steps in '
              f'{_format_seconds(result["start_seconds"])}', file=stream,
              flush=True)
    running = _running(reporter, pending)
    if time.time() - last >= report_every:
      reporter.report(running)
      last = time.time()
  return failures


def _running(reporter, pending):
  """Runs whose progress record was written within the last two periods."""
  now = time.time()
  count = 0
  for run in pending.values():
    if run is None:
      continue
    record = layout.read_json(os.path.join(
        layout.run_directory(reporter.out, run.name), layout.PROGRESS_FILE))
    if record is not None and now - record['updated'] < (
        2 * layout.PROGRESS_SECONDS + 5):
      count += 1
  return count


def dry_run(out: str, grid: grids_lib.Grid,
            stream: TextIO = sys.stdout) -> None:
  """Prints the grid's runs and whether each is finished.

  Args:
    out: the sweep directory.
    grid: the grid.
    stream: where the lines go.
  """
  for run in grid.runs():
    directory = layout.run_directory(out, run.name)
    steps = layout.progress(directory)
    state = ('finished' if layout.is_finished(directory,
                                              run.run_config['steps'])
             else f'{steps} steps')
    print(f'{run.name}: {run.run_config["steps"]} steps, {state}',
          file=stream)
  summary = grids_lib.describe(grid)
  print(f'{summary["runs"]} runs, {summary["steps"]:.3g} RL steps in all',
        file=stream)


def main(argv: Sequence[str],
         flag_values: flags.FlagValues = flags.FLAGS) -> int:
  """Runs (or with --dry_run lists) the sweep the flags describe.

  Args:
    argv: the command line (no arguments).
    flag_values: the parsed flags.

  Returns:
    The exit status: 0, 1 where runs failed, 2 on bad settings,
    INTERRUPTED_STATUS after Ctrl-C, TERMINATED_STATUS after SIGTERM.

  Raises:
    app.UsageError: arguments, or bad or missing flags.
  """
  if len(argv) > 1:
    raise app.UsageError(f'Unexpected arguments: {argv[1:]}')
  f = flag_values
  try:
    grid = grid_from_flags(f)
  except ValueError as e:
    raise app.UsageError(str(e)) from None
  if f.out is None:
    raise app.UsageError('--out is required: the sweep directory')
  if f.dry_run:
    dry_run(f.out, grid)
    return 0
  terminated = []
  def stop(signum, frame):   # SIGTERM: stop as Ctrl-C does.
    del signum, frame
    terminated.append(True)
    raise KeyboardInterrupt
  previous = signal.signal(signal.SIGTERM, stop)
  try:
    failures = run_sweep(f.out, grid, ray_address=f.ray_address,
                         num_cpus=f.num_cpus, cpus_per_run=f.cpus_per_run,
                         gpus_per_run=f.gpus_per_run,
                         max_retries=f.max_retries,
                         report_every=f.report_every)
  except (ValueError, ConnectionError, RuntimeError) as e:
    print(f'agents.sweep: {e}', file=sys.stderr)
    return 2
  except KeyboardInterrupt:
    print(f'[sweep] {"terminated" if terminated else "interrupted"}: '
          'finished runs are kept and the others resume from their last '
          'checkpoint when the same command starts again', file=sys.stderr)
    return TERMINATED_STATUS if terminated else INTERRUPTED_STATUS
  finally:
    signal.signal(signal.SIGTERM, previous)
  if failures:
    print(f'[sweep] {len(failures)} failed: {", ".join(failures)} (their '
          'error.json); start the command again to retry them',
          file=sys.stderr)
    return 1
  return 0


if __name__ == '__main__':
  define_flags()
  app.run(lambda argv: sys.exit(main(argv)))
