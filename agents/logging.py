"""Loggers of scalar rows: CSV files and TensorBoard (tensorboardX).

Every logger has `write(row, step)` and `close()`. A row is a flat dict of
numbers (and strings for the CSV). `CSVLogger` takes its columns from the
first row (or from an existing file's header), widens the file when a later
row brings new columns (a run resumed by a version that logs more metrics:
the earlier rows keep those cells empty), and can truncate a file to the rows
up to a step, which a resumed training run does so that the rows it
re-creates are not logged twice. `TensorBoardLogger` purges events after the
resume step the same way (TensorBoard's purge_step).
"""

import csv
import math
import numbers
import os
from typing import Any, Dict, List, Mapping, Optional, Sequence, Union

# A file or folder's path.
Path = Union[str, os.PathLike]


def _number(value):
  if isinstance(value, bool):
    return int(value)
  if isinstance(value, numbers.Integral):
    return int(value)
  if isinstance(value, numbers.Real):
    return float(value)
  return value


class CSVLogger:
  """Appends one row per `write` to a CSV file, flushing each row.

  Args:
    path: the CSV file (an existing file's header fixes the columns).
    step_key: the column of the step.
  """

  def __init__(self, path: Path, step_key: str = 'step'):
    self.path = os.fspath(path)
    self._step_key = step_key
    self._columns = None
    if os.path.exists(self.path) and os.path.getsize(self.path) > 0:
      with open(self.path, newline='') as f:
        self._columns = next(csv.reader(f))
    self._file = None

  @property
  def columns(self) -> Optional[List[str]]:
    """The columns, or None before the first row of a new file."""
    return None if self._columns is None else list(self._columns)

  def _rewrite(self, columns: List[str], rows: List[Dict[str, str]]) -> None:
    """Replaces the file by `rows` under `columns` (missing cells empty)."""
    self.close()
    temporary = self.path + '.tmp'
    with open(temporary, 'w', newline='') as f:
      writer = csv.DictWriter(f, fieldnames=columns)
      writer.writeheader()
      for row in rows:
        writer.writerow({k: _format(row.get(k, '')) for k in columns})
    os.replace(temporary, self.path)
    self._columns = list(columns)

  def truncate(self, max_step: float) -> None:
    """Drops the rows whose step is larger than max_step (a resumed run
    logs them again).

    Args:
      max_step: the last step kept.

    Raises:
      ValueError: a file without the step column.
    """
    if self._columns is None:
      return
    if self._step_key not in self._columns:
      raise ValueError(f'{self.path} has no {self._step_key!r} column to '
                       f'truncate by; columns: {self._columns}')
    rows = read_csv(self.path)
    kept = [row for row in rows if float(row[self._step_key]) <= max_step]
    self._rewrite(self._columns, kept)

  def write(self, row: Mapping[str, Any],
            step: Optional[int] = None) -> None:
    """Appends a row (the first row sets the columns of a new file; a row
    with columns the file lacks widens it, earlier rows empty there).

    Args:
      row: {column: number or string}; missing columns stay empty.
      step: None, or the row's step column.
    """
    row = dict(row)
    if step is not None:
      row[self._step_key] = step
    if self._columns is None:
      self._columns = list(row)
      if self._step_key in row:   # The step first, as a reader expects.
        self._columns.remove(self._step_key)
        self._columns.insert(0, self._step_key)
    unknown = sorted(set(row) - set(self._columns))
    if unknown:
      earlier = (read_csv(self.path) if os.path.exists(self.path)
                 and os.path.getsize(self.path) > 0 else [])
      self._rewrite(self._columns + unknown, earlier)
    if self._file is None:
      new = not os.path.exists(self.path) or os.path.getsize(self.path) == 0
      directory = os.path.dirname(self.path)
      if directory:
        os.makedirs(directory, exist_ok=True)
      self._file = open(self.path, 'a', newline='')
      self._writer = csv.DictWriter(self._file, fieldnames=self._columns)
      if new:
        self._writer.writeheader()
    self._writer.writerow({k: _format(row.get(k, '')) for k in self._columns})
    self._file.flush()

  def close(self) -> None:
    """Closes the file (a later write reopens it)."""
    if self._file is not None:
      self._file.close()
      self._file = None


def _format(value):
  value = _number(value)
  if isinstance(value, float):
    return repr(value)   # Shortest exact round trip.
  return value


def read_csv(path: Path) -> List[Dict[str, str]]:
  """Rows of a CSV file as dicts of strings.

  Args:
    path: the file.

  Returns:
    The rows.
  """
  with open(path, newline='') as f:
    return list(csv.DictReader(f))


def read_csv_columns(path: Path,
                     columns: Sequence[str]) -> Dict[str, List[float]]:
  """Columns of a CSV file as floats (empty cells become NaN).

  Args:
    path: the file.
    columns: the columns to read.

  Returns:
    {column: list of floats}.

  Raises:
    ValueError: columns the file lacks.
  """
  rows = read_csv(path)
  if rows:
    missing = [c for c in columns if c not in rows[0]]
    if missing:
      raise ValueError(f'{path} lacks columns {missing}; it has '
                       f'{list(rows[0])}')
  return {c: [float(row[c]) if row[c] != '' else math.nan for row in rows]
          for c in columns}


def summary_writer(directory: Path, purge_step: Optional[int] = None
                   ) -> Any:
  """A tensorboardX SummaryWriter.

  Args:
    directory: the events' directory.
    purge_step: None, or drop the directory's events at and after that step
      (a resumed run re-creates them).

  Returns:
    The writer.
  """
  from tensorboardX import SummaryWriter   # pylint: disable=g-import-not-at-top
  return SummaryWriter(os.fspath(directory), purge_step=purge_step)


class TensorBoardLogger:
  """Scalars tagged '<prefix>/<key>' through a SummaryWriter (shared by
  several loggers, closed by its owner). Non-numeric values are skipped.

  Args:
    writer: a tensorboardX SummaryWriter (`summary_writer`).
    prefix: the tags' prefix.
  """

  def __init__(self, writer: Any, prefix: str):
    self._writer = writer
    self._prefix = prefix

  def write(self, row: Mapping[str, Any], step: int) -> None:
    """Adds the row's finite numbers as scalars.

    Args:
      row: {key: value}.
      step: the scalars' step.
    """
    for key, value in row.items():
      value = _number(value)
      if isinstance(value, (int, float)) and math.isfinite(value):
        self._writer.add_scalar(f'{self._prefix}/{key}', value, step)
    self._writer.flush()

  def close(self) -> None:
    """Does nothing: the writer's owner closes it."""


class Dispatcher:
  """Writes each row to several loggers.

  Args:
    loggers: each with write(row, step) and close().
  """

  def __init__(self, loggers: Sequence[Any]):
    self._loggers = tuple(loggers)

  def write(self, row: Mapping[str, Any], step: int) -> None:
    """Writes the row to every logger.

    Args:
      row: {key: value}.
      step: the row's step.
    """
    for logger in self._loggers:
      logger.write(row, step)

  def close(self) -> None:
    """Closes every logger."""
    for logger in self._loggers:
      logger.close()
