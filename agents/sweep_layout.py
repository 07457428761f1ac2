"""The directory of a sweep (`agents.sweep`): layout, records and status.

  DIR/
    sweep.json                  the grid as run (agents.grids.Grid.to_dict),
                                the commit, time and host of every start
    shared/
      datasets/<domain>-<task>[-split<k>]/
                                expert dataset of RSI, SIR and AIR runs
                                (docs/datasets.md; agents.collect_expert)
      experts/<domain>-<task>.json
                                the deterministic expert's episodes on the
                                grid's task: return_mean (the normalised
                                return's 1), success, per-episode rows
    runs/<domain>-<task>/<agent>/[split<k>-]seed<s>/
      config.json, train.csv, eval.csv, eval_<set>.csv, tensorboard/,
      checkpoints/              agents.train's run directory
      run.log                   the run's log (Python logging, warnings)
      progress.json             {steps, target, start_seconds, updated},
                                rewritten every PROGRESS_SECONDS while it
                                trains (start_seconds: since the run's
                                latest start)
      finished.json             {steps, episodes, evaluations, wall_time
                                (over all starts), start_seconds, host,
                                cores, finished}: the run reached its steps
      error.json                {error, traceback, time} of its last failure

A run is finished when finished.json exists and its steps are at least the
grid's steps for it; a sweep started again skips finished runs and resumes
the others from their latest checkpoint.
"""

import json
import os
import time
from typing import Any, Dict, Optional, Union

from agents import checkpoints

SWEEP_FILE = 'sweep.json'
RUNS = 'runs'
SHARED = 'shared'
FINISHED_FILE = 'finished.json'
PROGRESS_FILE = 'progress.json'
ERROR_FILE = 'error.json'
LOG_FILE = 'run.log'
# Seconds between a running run's progress records.
PROGRESS_SECONDS = 20.0

write_json = checkpoints.write_json   # atomic: temporary file + rename
# A file or folder's path.
Path = Union[str, os.PathLike]


def read_json(path: Path) -> Optional[Dict[str, Any]]:
  """The JSON object at a path.

  Args:
    path: the file.

  Returns:
    The object, or None if there is no file.
  """
  try:
    with open(path) as f:
      return json.load(f)
  except FileNotFoundError:
    return None


def run_directory(root: Path, run_name: str) -> str:
  """A run's directory in a sweep.

  Args:
    root: the sweep's directory.
    run_name: the run's name (`grids.Run.name`).

  Returns:
    root/runs/<run_name>.
  """
  return os.path.join(os.fspath(root), RUNS, run_name)


def task_slug(task: str) -> str:
  """A task's folder name.

  Args:
    task: 'domain/task'.

  Returns:
    'domain-task'.
  """
  return task.replace('/', '-')


def dataset_directory(root: Path, task: str,
                      split: Optional[int] = None) -> str:
  """The shared expert dataset of a task (and motion split).

  Args:
    root: the sweep's directory.
    task: 'domain/task'.
    split: None, or the motion split's index.

  Returns:
    root/shared/datasets/<domain>-<task>[-split<k>].
  """
  name = task_slug(task) + ('' if split is None else f'-split{split}')
  return os.path.join(os.fspath(root), SHARED, 'datasets', name)


def expert_file(root: Path, task: str) -> str:
  """The record of the expert's episodes on a task.

  Args:
    root: the sweep's directory.
    task: 'domain/task'.

  Returns:
    root/shared/experts/<domain>-<task>.json.
  """
  return os.path.join(os.fspath(root), SHARED, 'experts',
                      task_slug(task) + '.json')


def is_finished(directory: Path, steps: int) -> bool:
  """Whether a run finished at least `steps` RL steps.

  Args:
    directory: the run's directory.
    steps: the steps it is to reach.

  Returns:
    Whether its finished.json records at least that many.
  """
  record = read_json(os.path.join(directory, FINISHED_FILE))
  return record is not None and int(record['steps']) >= int(steps)


def progress(directory: Path) -> int:
  """Steps done by a run as far as its records say.

  Args:
    directory: the run's directory.

  Returns:
    The steps of finished.json, else of progress.json, else 0.
  """
  for name in (FINISHED_FILE, PROGRESS_FILE):
    record = read_json(os.path.join(directory, name))
    if record is not None:
      return int(record['steps'])
  return 0


class ProgressWriter:
  """Writes a run's progress.json at most every PROGRESS_SECONDS.

  Args:
    directory: the run's directory.
    target: the steps the run is to reach.
  """

  def __init__(self, directory: Path, target: int):
    self._path = os.path.join(directory, PROGRESS_FILE)
    self._target = int(target)
    self._start = time.time()
    self._last = 0.0

  def __call__(self, steps: int, force: bool = False) -> None:
    """Records the steps done (at most every PROGRESS_SECONDS).

    Args:
      steps: the steps done.
      force: write now regardless.
    """
    now = time.time()
    if force or now - self._last >= PROGRESS_SECONDS:
      self._last = now
      write_json(self._path, {'steps': int(steps), 'target': self._target,
                              'start_seconds': now - self._start,
                              'updated': now})
