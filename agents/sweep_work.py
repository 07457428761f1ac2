"""What a sweep's Ray tasks do (`agents.sweep`): one function per kind.

* `prepare_node`: compiles (or loads) hrc_suite's numba kernels once on a
  machine before its runs start (`agents.precompile`), so that parallel runs
  load them from numba's cache instead of each compiling them.
* `collect_dataset`: the noisy-expert dataset of a task (RSI, SIR and AIR
  runs start from and imitate it); resumes a partial one.
* `expert_returns`: the deterministic expert's episodes on a task, whose
  mean return is the normalised return's 1.
* `train_run`: one training run (`agents.train.train`), resumed from its
  latest checkpoint; writes finished.json when it has all its steps.

A run keeps to its CPUs: `thread_environment` gives the worker the thread
counts of XLA, numba and BLAS before they are imported, and `train_run` pins
its process to a slot of `cpus` cores of its machine (a file lock per slot
below the temporary folder, so runs of different sweeps on one machine do
not share cores either). Heavy modules are imported inside the functions,
after the pinning, so that XLA sizes its thread pool to the pinned cores.
"""

import contextlib
import fcntl
import logging
import os
import socket
import tempfile
import time
import traceback
from typing import Any, Dict, Iterator, List, Mapping, Optional, Tuple

from agents import sweep_layout as layout

_SLOT_DIRECTORY = os.path.join(tempfile.gettempdir(),
                               f'hrc_suite_cpu_slots_{os.getuid()}')
_RUN_LOCK = '.lock'


def thread_environment(cpus: int) -> Dict[str, str]:
  """Environment variables that keep a run's thread pools to `cpus` cores:
  XLA's intra-op pool (a single-threaded Eigen for one core), numba's
  parallel pool and BLAS/OpenMP pools.

  Args:
    cpus: the run's cores.

  Returns:
    {variable: value}.
  """
  cpus = int(cpus)
  xla = '--xla_force_host_platform_device_count=1'
  if cpus == 1:
    xla += (' --xla_cpu_multi_thread_eigen=false'
            ' intra_op_parallelism_threads=1')
  return {'XLA_FLAGS': xla, 'NUMBA_NUM_THREADS': str(cpus),
          'OMP_NUM_THREADS': str(cpus), 'OPENBLAS_NUM_THREADS': str(cpus),
          'MKL_NUM_THREADS': str(cpus)}


@contextlib.contextmanager
def cpu_slot(cpus: int, directory: str = _SLOT_DIRECTORY
             ) -> Iterator[Optional[List[int]]]:
  """Pins this process to a free slot of `cpus` cores of this machine
  (slot i: the i-th group of `cpus` cores this process may run on) and
  holds the slot's lock (a file in `directory`) until exit.

  Args:
    cpus: cores per slot.
    directory: the slots' lock files.

  Yields:
    The slot's cores; None without a free slot (more runs than slots: a
    scheduler that oversubscribes), the process then not pinned.
  """
  allowed = sorted(os.sched_getaffinity(0))
  slots = len(allowed) // int(cpus)
  os.makedirs(directory, exist_ok=True)
  handle = None
  cores = None
  for i in range(slots):
    path = os.path.join(directory, f'cpus{cpus}-slot{i}.lock')
    candidate = open(path, 'w')
    try:
      fcntl.flock(candidate, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
      candidate.close()
      continue
    handle, cores = candidate, allowed[i * cpus:(i + 1) * cpus]
    break
  try:
    if cores is not None:
      os.sched_setaffinity(0, cores)
    yield cores
  finally:
    if handle is not None:
      handle.close()


@contextlib.contextmanager
def run_lock(directory: str) -> Iterator[None]:
  """Holds an exclusive lock on a run directory.

  Args:
    directory: the run's directory (created if absent).

  Yields:
    None, while the lock is held.

  Raises:
    ValueError: if another process holds it (the same run started twice,
      e.g. by two sweeps).
  """
  os.makedirs(directory, exist_ok=True)
  handle = open(os.path.join(directory, _RUN_LOCK), 'w')
  try:
    fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
  except BlockingIOError:
    handle.close()
    raise ValueError(f'{directory} is being trained by another process '
                     '(its .lock is held): is another sweep running on the '
                     'same directory?') from None
  try:
    yield
  finally:
    handle.close()


@contextlib.contextmanager
def _log_to(path):
  """Sends Python logging (absl's included) and warnings to `path`."""
  handler = logging.FileHandler(path)
  handler.setFormatter(logging.Formatter(
      '%(asctime)s %(levelname)s %(name)s: %(message)s'))
  root = logging.getLogger()
  root.addHandler(handler)
  level = root.level
  root.setLevel(logging.INFO)
  logging.captureWarnings(True)
  try:
    yield
  finally:
    root.removeHandler(handler)
    root.setLevel(level)
    handler.close()


def prepare_node(robot: str) -> Tuple[str, float]:
  """Compiles (or loads) the numba kernels on this machine.

  Args:
    robot: a robot the kernels are warmed up with.

  Returns:
    (host, seconds).
  """
  from agents import precompile   # pylint: disable=g-import-not-at-top
  return socket.gethostname(), precompile.warm_up(robot)


def collect_dataset(directory: str, task: str,
                    task_kwargs: Mapping[str, Any], episodes: int) -> str:
  """The noisy-expert dataset of a task, resumed where it stopped.

  Args:
    directory: the dataset's directory.
    task: 'domain/task'.
    task_kwargs: the task's kwargs.
    episodes: episodes the dataset holds.

  Returns:
    The directory.
  """
  from hrc_suite.experts import dataset   # pylint: disable=g-import-not-at-top
  domain, name = task.split('/')
  dataset.collect(directory, domain, name, task_kwargs,
                  policy='noisy_expert', episodes=int(episodes), seed=0)
  return directory


def expert_returns(path: str, task: str, task_kwargs: Mapping[str, Any],
                   episodes: int) -> Dict[str, Any]:
  """Runs the deterministic expert on a task (seeds 0..) and records it.

  An existing file with as many episodes is returned as it is.

  Args:
    path: the record's file.
    task: 'domain/task'.
    task_kwargs: the task's kwargs.
    episodes: episodes to run.

  Returns:
    The record {task, task_kwargs, policy, episodes, return_mean,
    return_std, success, rows}.
  """
  import numpy as np   # pylint: disable=g-import-not-at-top
  from hrc_suite import experts   # pylint: disable=g-import-not-at-top
  from hrc_suite import suite   # pylint: disable=g-import-not-at-top
  from hrc_suite.tasks.runtime import metrics   # pylint: disable=g-import-not-at-top
  record = layout.read_json(path)
  if record is not None and record['episodes'] >= episodes:
    return record
  domain, name = task.split('/')
  env = suite.load(domain, name, task_kwargs=dict(task_kwargs),
                   environment_kwargs={'random_state': 0})
  policy = experts.make(env)
  rows = []
  for seed in range(int(episodes)):
    env.random_state.seed(seed)
    if hasattr(policy, 'set_episode'):
      policy.set_episode(seed)
    episode = metrics.run_episode(env, policy)
    rows.append({'seed': seed, 'return': float(episode['return']),
                 'success': float(episode['success']),
                 'steps': int(episode['steps'])})
  returns = np.array([r['return'] for r in rows])
  record = {'task': task, 'task_kwargs': dict(task_kwargs),
            'policy': 'expert', 'episodes': len(rows),
            'return_mean': float(returns.mean()),
            'return_std': float(returns.std()),
            'success': float(np.mean([r['success'] for r in rows])),
            'rows': rows}
  os.makedirs(os.path.dirname(path), exist_ok=True)
  layout.write_json(path, record)
  return record


def train_run(root: str, run_name: str, run_config: Mapping[str, Any],
              cpus: int, dataset: Optional[str] = None) -> Dict[str, Any]:
  """Trains (or resumes) one run of a sweep to its steps.

  Args:
    root: the sweep directory.
    run_name: the run's name (its directory below root/runs).
    run_config: agents.grids.Run.run_config.
    cpus: cores this run is pinned to.
    dataset: the expert dataset's directory (RSI, SIR, AIR), or None.

  Returns:
    The run's finished.json record.
  """
  directory = layout.run_directory(root, run_name)
  with run_lock(directory), cpu_slot(cpus) as cores, _log_to(
      os.path.join(directory, layout.LOG_FILE)):
    try:
      from agents import train   # pylint: disable=g-import-not-at-top
      start = time.time()
      config = train.make_run_config(dataset=dataset, **run_config)
      progress = layout.ProgressWriter(directory, config['steps'])
      progress(0 if train.checkpoints.latest(directory) is None else
               layout.progress(directory), force=True)
      logging.info('Run %s on %s, cores %s', run_name, socket.gethostname(),
                   cores)
      _, state = train.train(config, directory, resume=True,
                             on_step=progress)
      steps = int(state['counter']['steps'])
      progress(steps, force=True)
      record = {'steps': steps, 'episodes': int(state['counter']['episodes']),
                'evaluations': int(state['evaluations']),
                'wall_time': float(state['wall_time']),
                'start_seconds': time.time() - start,
                'host': socket.gethostname(), 'cores': cores,
                'finished': time.strftime('%Y-%m-%dT%H:%M:%SZ',
                                          time.gmtime())}
      layout.write_json(os.path.join(directory, layout.FINISHED_FILE),
                        record)
      if os.path.exists(os.path.join(directory, layout.ERROR_FILE)):
        os.remove(os.path.join(directory, layout.ERROR_FILE))
      return record
    except BaseException as e:
      if interrupted(e):   # Not a failure: the run resumes from its
        logging.warning(   # last checkpoint when the sweep starts again.
            'Run %s interrupted (%s); it resumes from its last checkpoint',
            run_name, type(e).__name__)
      else:
        layout.write_json(os.path.join(directory, layout.ERROR_FILE), {
            'error': f'{type(e).__name__}: {e}',
            'traceback': traceback.format_exc(), 'time': time.time()})
      raise


def interrupted(error: BaseException) -> bool:
  """Whether `error` is an interruption (Ctrl-C, a cancelled or exiting
  worker) rather than a failure of the run: a KeyboardInterrupt or
  SystemExit, or an error raised while one propagated (a C extension
  that got Ctrl-C inside a call raises SystemError with the interrupt as
  its context).

  Args:
    error: what the run raised.

  Returns:
    True for an interruption.
  """
  seen = set()
  while error is not None and id(error) not in seen:
    if isinstance(error, (KeyboardInterrupt, SystemExit)):
      return True
    seen.add(id(error))
    error = error.__cause__ or error.__context__
  return False
