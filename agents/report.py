r"""The report of a sweep: the paper's figure, final values, overfitting.

  python -m agents.report --sweep=sweeps/paper_reduced [--out=DIR]

Reads a sweep directory (`agents.sweep_layout`), finished or still running
(what is there so far), and writes to --out (default: DIR/report):

* success.png / return.png (and .svg): one panel per task, one line per
  agent: the evaluation success rate and the normalised return against RL
  steps, mean over seeds with a 95 % percentile-bootstrap confidence
  interval (10^4 resamples), the expert as a dashed reference line
  (docs/reference_benchmark.md, Training and evaluation). A curve runs to
  the last evaluation every seed of its group reached.
* final.csv and report.md: per task and agent, the final values (at the
  last evaluation step every seed reached; with --final_window=k each
  seed's mean over its last k evaluations) with their CIs; the runs that
  are missing or unfinished; the overfitting comparison where the grid has
  motion splits (seen: the train side the run trained on, unseen: the test
  side), also drawn as overfitting.png.
* evaluations.json: every evaluation, one row per (task, agent, seed,
  split, motions, step): success rate, return, normalised return, episode
  length, the evaluation's seconds, and safety: the safety cost per episode
  (runs whose task has one, hrc_suite/tasks/runtime/cost.py), critical human
  contacts per 10^3 RL steps and shield interventions per episode; where
  runs have a cost, cost.png draws it like the success, with the
  constrained runs' cost limits dotted; report.md's "Keeping the cost
  limit" counts the evaluations within them (`agents.limit_keeping`).
* training.csv and report.md's "During training": where runs log a cost,
  what their training episodes cost, over the whole run and by quarter of
  its budget (`agents.training_safety`).

Normalised return (the paper's): (R - R_min) / (R_expert - R_min), R_min
the task reward's lowest possible episode return without collision
penalties (`HrcTask.min_task_return` of the grid's task and robot) and
R_expert the mean return of the deterministic expert's episodes on the
grid's task (the sweep's shared/experts/<task>.json).
"""

import collections
import csv
import json
import math
import os
import shutil
import sys
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple

from absl import app
from absl import flags
import numpy as np

from agents import grids as grids_lib
from agents import limit_keeping
from agents import logging as logging_lib
from agents import sweep_layout as layout
from agents import training_safety
from hrc_suite import statistics
from hrc_suite import suite

SEEN = 'seen'
UNSEEN = 'unseen'
# Columns of an evaluation row, in order.
ROW_KEYS = ('task', 'agent', 'seed', 'split', 'motions', 'step', 'success',
            'return', 'normalised_return', 'length', 'eval_seconds',
            'wall_time', 'cost', 'critical_contacts_per_1000',
            'shield_interventions')
# Final values: what the runs learn, then their safety.
FINAL_KEYS = ('success', 'normalised_return', 'return')
SAFETY_KEYS = ('cost', 'critical_contacts_per_1000', 'shield_interventions')
SAFETY_HEADERS = {'cost': 'cost per episode',
                  'critical_contacts_per_1000': 'critical contacts per 10^3 '
                                                'steps',
                  'shield_interventions': 'shield interventions per episode'}

Summary = collections.namedtuple('Summary', ['mean', 'low', 'high'])
# An evaluation row (ROW_KEYS) and a final-values entry.
Row = Dict[str, Any]
Entry = Dict[str, Any]


def load_sweep(root: str) -> Tuple[grids_lib.Grid, Dict[str, Any]]:
  """A sweep's grid and record.

  Args:
    root: the sweep directory.

  Returns:
    (grid, sweep record).

  Raises:
    ValueError: a directory that holds no sweep.
  """
  record = layout.read_json(os.path.join(root, layout.SWEEP_FILE))
  if record is None:
    raise ValueError(f'{root} is not a sweep directory: it has no '
                     f'{layout.SWEEP_FILE} (python -m agents.sweep makes it)')
  return grids_lib.Grid.from_dict(record['grid']), record


def expert_return(root: str, task: str) -> Optional[float]:
  """The deterministic expert's mean return on a task.

  Args:
    root: the sweep directory.
    task: 'domain/task'.

  Returns:
    The mean return, or None where it was not recorded.
  """
  record = layout.read_json(layout.expert_file(root, task))
  return None if record is None else float(record['return_mean'])


def _number(value):
  if value in (None, ''):
    return None
  value = float(value)
  return value if math.isfinite(value) else None


def task_minimum(grid: grids_lib.Grid, task: str) -> float:
  """R_min of a task in a grid: HrcTask.min_task_return of the task built
  with the grid's robot, action space and kwargs (its people aside: the
  minimum does not depend on them).

  Args:
    grid: the grid.
    task: 'domain/task' of the grid.

  Returns:
    R_min.
  """
  domain, name = task.split('/')
  kwargs = {k: v for k, v in grid.task_kwargs_of(None).items()
            if k != 'motions'}
  env = suite.load(domain, name, task_kwargs=dict(
      kwargs, robot=grid.robot,
      action_space=grids_lib.default_action_space(domain, name)))
  try:
    return float(env.task.min_task_return)
  finally:
    env.close()


def evaluation_rows(root: str, grid: Optional[grids_lib.Grid] = None,
                    minima: Optional[Mapping[str, float]] = None
                    ) -> Tuple[List[Row], Dict[str, str]]:
  """Every evaluation of a sweep's runs.

  Args:
    root: the sweep directory.
    grid: its grid (None: read from the sweep).
    minima: {task: R_min}, by default `task_minimum` of each task.

  Returns:
    (rows, missing): the evaluations as dicts with ROW_KEYS, and {run
    name: state} of the runs without all their steps ('no data', or 'k of
    n steps').
  """
  if grid is None:
    grid, _ = load_sweep(root)
  rows, missing = [], {}
  experts = {task: expert_return(root, task) for task in grid.tasks}
  if minima is None:
    minima = {task: task_minimum(grid, task) for task in grid.tasks}
  for run in grid.runs():
    directory = layout.run_directory(root, run.name)
    target = int(run.run_config['steps'])
    if not layout.is_finished(directory, target):
      done = layout.progress(directory)
      missing[run.name] = (f'{done} of {target} steps' if done else
                           'no data')
    config = layout.read_json(os.path.join(directory, 'config.json'))
    if config is None:
      continue
    low = minima[run.task]
    best = experts[run.task]
    files = [(SEEN if run.split is not None else None, 'eval.csv')]
    files += [(name, f'eval_{name}.csv')
              for name in sorted(run.run_config.get('eval_sets', {}))]
    for motions, name in files:
      path = os.path.join(directory, name)
      if not os.path.exists(path):
        continue
      for row in logging_lib.read_csv(path):
        returned = float(row['return_mean'])
        normalised = None
        if best is not None and low is not None and best > low:
          normalised = (returned - low) / (best - low)
        length = _number(row.get('length_mean'))
        critical = _number(row.get('contacts_human_critical_mean'))
        rows.append({
            'task': run.task, 'agent': run.agent, 'seed': run.seed,
            'split': run.split, 'motions': motions,
            'step': int(float(row['step'])),
            'success': float(row['success_rate']), 'return': returned,
            'normalised_return': normalised,
            'length': length,
            'eval_seconds': _number(row.get('eval_seconds')),
            'wall_time': _number(row.get('wall_time')),
            'cost': _number(row.get('cost_mean')),
            'critical_contacts_per_1000': (
                1000.0 * critical / length if critical is not None
                and length else None),
            'shield_interventions': _number(
                row.get('shield_interventions_mean'))})
  return rows, missing


def _groups(rows, motions=None):
  """{(task, agent): {seed key: {step: row}}} of the rows of one motions
  side (None: runs without splits; a split's seed key is (split, seed))."""
  groups = collections.OrderedDict()
  for row in rows:
    if row['motions'] != motions:
      continue
    key = (row['task'], row['agent'])
    seed = (row['split'], row['seed'])
    groups.setdefault(key, {}).setdefault(seed, {})[row['step']] = row
  return groups


def curve(runs: Mapping[Any, Mapping[int, Row]], name: str,
          random_state: np.random.RandomState, resamples: int
          ) -> Optional[Tuple[np.ndarray, Summary]]:
  """One group's metric over its seeds, at the evaluation steps every seed
  reached.

  Args:
    runs: {seed key: {step: row}} of one (task, agent).
    name: a metric of the rows.
    random_state: the bootstrap's random numbers.
    resamples: bootstrap resamples.

  Returns:
    (steps, Summary of arrays), or None if no step or a value is missing.
  """
  steps = sorted(set.intersection(*(set(r) for r in runs.values())))
  if not steps:
    return None
  table = np.array([[runs[seed][step][name] for step in steps]
                    for seed in sorted(runs)], dtype=object)
  if any(v is None for v in table.ravel()):
    return None
  mean, low, high = statistics.bootstrap_ci(
      table.astype(float), random_state, num_resamples=resamples)
  return np.array(steps), Summary(np.atleast_1d(mean), np.atleast_1d(low),
                                  np.atleast_1d(high))


def final_values(rows: Sequence[Row], random_state: np.random.RandomState,
                 resamples: int, motions: Optional[str] = None,
                 window: int = 1) -> List[Entry]:
  """The final values of each (task, agent).

  Args:
    rows: of `evaluation_rows`.
    random_state: the bootstrap's random numbers.
    resamples: bootstrap resamples.
    motions: the rows' motions side (None: runs without splits).
    window: each seed's value is the mean of its last `window` evaluations
      that every seed reached (1: the last one alone); a single
      evaluation of 10 episodes is noisy.

  Returns:
    Per (task, agent): the last step every seed reached, the seeds, and
    the Summary of FINAL_KEYS and SAFETY_KEYS there (None where missing).

  Raises:
    ValueError: window is not a positive integer.
  """
  if int(window) != window or window < 1:
    raise ValueError(f'window: expected a positive number of evaluations, '
                     f'got {window!r}')
  table = []
  for (task, agent), runs in _groups(rows, motions).items():
    entry = {'task': task, 'agent': agent, 'seeds': len(runs)}
    for name in FINAL_KEYS + SAFETY_KEYS:
      found = (curve(runs, name, random_state, resamples) if window == 1
               else _window_mean(runs, name, int(window), random_state,
                                 resamples))
      if found is None:
        entry[name] = None
        continue
      steps, summary = found
      entry['step'] = int(steps[-1])
      entry[name] = Summary(float(summary.mean[-1]), float(summary.low[-1]),
                            float(summary.high[-1]))
    table.append(entry)
  return table


def _window_mean(runs, name, window, random_state, resamples):
  """`curve`'s result at its last step for the mean of each seed's last
  `window` evaluations every seed reached (the steps: the last one)."""
  steps = sorted(set.intersection(*(set(r) for r in runs.values())))
  if not steps:
    return None
  values = [[runs[seed][step][name] for step in steps[-window:]]
            for seed in sorted(runs)]
  if any(v is None for seed in values for v in seed):
    return None
  mean, low, high = statistics.bootstrap_ci(
      np.mean(np.array(values, dtype=float), axis=1), random_state,
      num_resamples=resamples)
  return np.array(steps[-1:]), Summary(np.atleast_1d(mean),
                                       np.atleast_1d(low),
                                       np.atleast_1d(high))


def draw(rows: Sequence[Row], grid: grids_lib.Grid, root: str, name: str,
         ylabel: str, path: str, random_state: np.random.RandomState,
         resamples: int, motions: Optional[str] = None) -> List[str]:
  """One panel per task, one line per agent (mean and 95 % CI band), the
  expert dashed.

  Args:
    rows: of `evaluation_rows`.
    grid: the grid.
    root: the sweep directory (the expert's records).
    name: the metric drawn.
    ylabel: its axis label.
    path: the .png to write (and .svg beside it).
    random_state: the bootstrap's random numbers.
    resamples: bootstrap resamples.
    motions: the rows' motions side (None: runs without splits).

  Returns:
    The paths written.
  """
  import matplotlib   # pylint: disable=g-import-not-at-top
  matplotlib.use('Agg')
  import matplotlib.pyplot as plt   # pylint: disable=g-import-not-at-top
  groups = _groups(rows, motions)
  columns = min(3, len(grid.tasks))
  lines = math.ceil(len(grid.tasks) / columns)
  figure, axes = plt.subplots(lines, columns, squeeze=False,
                              figsize=(4.2 * columns, 3.4 * lines),
                              constrained_layout=True)
  colours = {agent: f'C{i}' for i, agent in enumerate(grid.agents)}
  for axis, task in zip(axes.ravel(), grid.tasks):
    for agent in grid.agents:
      runs = groups.get((task, agent))
      found = runs and curve(runs, name, random_state, resamples)
      if not found:
        continue
      steps, summary = found
      label = f'{grid.label_of(agent)} ({len(runs)})'
      axis.plot(steps, summary.mean, color=colours[agent], label=label,
                marker='.' if len(steps) < 12 else None)
      if len(runs) > 1:
        axis.fill_between(steps, summary.low, summary.high,
                          color=colours[agent], alpha=0.2, linewidth=0)
    reference = _expert_reference(root, task, name)
    if reference is not None:
      axis.axhline(reference, color='k', linestyle='--', linewidth=1,
                   label='expert')
    if name == 'cost':
      for limit in limit_keeping.cost_limits(grid, task):
        axis.axhline(limit, color='k', linestyle=':', linewidth=1,
                     label=f'cost limit {limit:g}')
    axis.set_title(task)
    axis.set_xlim(0, grid.steps_of(task))
    axis.set_xlabel('RL steps')
    axis.set_ylabel(ylabel)
    axis.ticklabel_format(axis='x', style='sci', scilimits=(0, 4))
    axis.grid(alpha=0.3)
    axis.legend(fontsize='x-small')
  for axis in axes.ravel()[len(grid.tasks):]:
    axis.set_visible(False)
  figure.suptitle(f'{grid.name}: mean over seeds (in brackets) with 95 % '
                  'bootstrap CI')
  return _save(figure, path)


def _save(figure, path):
  """Writes the figure as path's stem .png and .svg; returns the paths."""
  import matplotlib.pyplot as plt   # pylint: disable=g-import-not-at-top
  stem = os.path.splitext(path)[0]
  written = [stem + '.png', stem + '.svg']
  for name in written:
    figure.savefig(name, dpi=110)
  plt.close(figure)
  return written


def _expert_reference(root, task, name):
  if name not in ('success', 'return', 'normalised_return'):
    return None
  if name == 'normalised_return':
    return 1.0 if expert_return(root, task) is not None else None
  record = layout.read_json(layout.expert_file(root, task))
  if record is None:
    return None
  return float(record['success'] if name == 'success' else
               record['return_mean'])


def draw_overfitting(rows: Sequence[Row], grid: grids_lib.Grid, path: str,
                     random_state: np.random.RandomState,
                     resamples: int) -> List[str]:
  """Seen against unseen motions: per task and agent, success and
  normalised return over steps (mean over splits and seeds).

  Args:
    rows: of `evaluation_rows`.
    grid: the grid (with splits).
    path: the .png to write (and .svg beside it).
    random_state: the bootstrap's random numbers.
    resamples: bootstrap resamples.

  Returns:
    The paths written.
  """
  import matplotlib   # pylint: disable=g-import-not-at-top
  matplotlib.use('Agg')
  import matplotlib.pyplot as plt   # pylint: disable=g-import-not-at-top
  figure, axes = plt.subplots(1, 2, figsize=(10, 4), constrained_layout=True)
  for side, style in ((SEEN, '-'), (UNSEEN, '--')):
    for (task, agent), runs in _groups(rows, side).items():
      for axis, name in zip(axes, ('success', 'normalised_return')):
        found = curve(runs, name, random_state, resamples)
        if not found:
          continue
        steps, summary = found
        line, = axis.plot(steps, summary.mean, linestyle=style,
                          label=f'{task} {agent}: {side} ({len(runs)} runs)')
        axis.fill_between(steps, summary.low, summary.high,
                          color=line.get_color(), alpha=0.15, linewidth=0)
  for axis, label in zip(axes, ('success rate', 'normalised return')):
    axis.set_xlabel('RL steps')
    axis.set_ylabel(label)
    axis.grid(alpha=0.3)
    axis.legend(fontsize='x-small')
  figure.suptitle(f'{grid.name}: seen against unseen motions, mean over '
                  'splits and seeds, 95 % bootstrap CI')
  return _save(figure, path)


def _cell(summary, digits=2):
  if summary is None:
    return '-'
  return (f'{summary.mean:.{digits}f} [{summary.low:.{digits}f}, '
          f'{summary.high:.{digits}f}]')


def evaluation_cost(rows: Sequence[Row]) -> Dict[str, Dict[str, float]]:
  """Per task: seconds of evaluation and evaluated episode steps per
  evaluation, mean over the evaluations that timed themselves.

  Args:
    rows: of `evaluation_rows`.

  Returns:
    {task: {'seconds', 'mean_episode_length', 'evaluations'}}.
  """
  cost = collections.OrderedDict()
  for row in rows:
    if row['eval_seconds'] is None:
      continue
    entry = cost.setdefault(row['task'], [0.0, 0.0, 0])
    entry[0] += row['eval_seconds']
    entry[1] += row['length'] or 0.0
    entry[2] += 1
  return {task: {'seconds': s / n, 'mean_episode_length': l / n,
                 'evaluations': n}
          for task, (s, l, n) in cost.items()}


def markdown(grid: grids_lib.Grid, record: Mapping[str, Any],
             final: Sequence[Entry], missing: Mapping[str, str],
             overfitting: Mapping[str, Sequence[Entry]],
             cost: Mapping[str, Mapping[str, float]],
             normalisation: Mapping[str, Tuple[float, Optional[float]]],
             window: int = 1, sections: Sequence[str] = ()) -> str:
  """report.md's text.

  Args:
    grid: the grid.
    record: the sweep record (its commit).
    final: of `final_values`.
    missing: the runs not finished, {run name: state}.
    overfitting: {side: `final_values` of that side} (empty without
      splits).
    cost: of `evaluation_cost`.
    normalisation: {task: (R_min, R_expert or None)}.
    window: the evaluations each seed's final value averages
      (`final_values`).
    sections: the lines of the sections after the final values (keeping
      the cost limit, `limit_keeping.markdown`; training's safety,
      `training_safety.markdown`).

  Returns:
    The markdown.
  """
  safety = [k for k in SAFETY_KEYS
            if any(entry[k] is not None for entry in final)]
  lines = [f'# Sweep {grid.name}', '',
           f'{len(grid.runs())} runs ({len(grid.tasks)} tasks x '
           f'{len(grid.agents)} agents x {len(grid.seeds)} seeds'
           + (f' x {len(grid.splits)} motion splits' if grid.splits else '')
           + f'), robot {grid.robot}, SAC preset {grid.config}; commit '
           f'{record.get("commit")}.', '',
           '## Final values', '',
           ('At the last evaluation every seed reached: mean [95 % '
            'bootstrap CI] over seeds.' if window == 1 else
            f'Each seed\'s mean over its last {window} evaluations that '
            'every seed reached (up to the step shown): mean [95 % '
            'bootstrap CI] over seeds.'), '',
           '| task | agent | seeds | step | success | normalised return | '
           'return |' + ''.join(f' {SAFETY_HEADERS[k]} |' for k in safety),
           '|---|---|---|---|---|---|---|' + '---|' * len(safety)]
  for entry in final:
    lines.append(
        f'| {entry["task"]} | {grid.label_of(entry["agent"])} | '
        f'{entry["seeds"]} | {entry.get("step", "-")} | '
        f'{_cell(entry["success"])} | '
        f'{_cell(entry["normalised_return"])} | '
        f'{_cell(entry["return"], 1)} |'
        + ''.join(f' {_cell(entry[k])} |' for k in safety))
  lines += ['', 'Normalised return: (R - R_min) / (R_expert - R_min).', '',
            '| task | R_min (lowest possible) | R_expert (expert mean) |',
            '|---|---|---|']
  for task, (low, best) in normalisation.items():
    expert = '-' if best is None else f'{best:.2f}'
    lines.append(f'| {task} | {low:.2f} | {expert} |')
  lines += list(sections)
  if overfitting:
    lines += ['', '## Seen against unseen motions', '',
              '| task | agent | motions | runs | step | success | '
              'normalised return |', '|---|---|---|---|---|---|---|']
    for side, entries in overfitting.items():
      for entry in entries:
        lines.append(f'| {entry["task"]} | {entry["agent"]} | {side} | '
                     f'{entry["seeds"]} | {entry.get("step", "-")} | '
                     f'{_cell(entry["success"])} | '
                     f'{_cell(entry["normalised_return"])} |')
  if cost:
    lines += ['', '## Evaluation cost', '',
              '| task | seconds per evaluation | mean episode length '
              '(RL steps) | evaluations |', '|---|---|---|---|']
    for task, entry in cost.items():
      lines.append(f'| {task} | {entry["seconds"]:.1f} | '
                   f'{entry["mean_episode_length"]:.0f} | '
                   f'{entry["evaluations"]} |')
  lines += ['', '## Runs not finished', '']
  if missing:
    lines += [f'* {name}: {state}' for name, state in missing.items()]
  else:
    lines.append('None: every run has all its steps.')
  return '\n'.join(lines) + '\n'


def _jsonable(entry):
  return {k: (v._asdict() if isinstance(v, Summary) else v)
          for k, v in entry.items()}


def report(root: str, out: Optional[str] = None, seed: int = 0,
           resamples: int = statistics.DEFAULT_RESAMPLES, plots: bool = True,
           minima: Optional[Mapping[str, float]] = None,
           final_window: int = 1) -> Dict[str, Any]:
  """Writes the report of a sweep.

  Args:
    root: the sweep directory.
    out: the report's directory (default root/report).
    seed: seed of the bootstrap resampling.
    resamples: bootstrap resamples.
    plots: draw the figures.
    minima: {task: R_min} of the normalised return (default: each task's
      `task_minimum`).
    final_window: the evaluations each seed's final value averages
      (`final_values`' window).

  Returns:
    {'rows', 'final', 'training', 'missing', 'overfitting', 'cost',
    'normalisation', 'paths'}.

  Raises:
    ValueError: a directory that holds no sweep.
  """
  root = os.path.abspath(root)
  out = out or os.path.join(root, 'report')
  os.makedirs(out, exist_ok=True)
  grid, record = load_sweep(root)
  if minima is None:
    minima = {task: task_minimum(grid, task) for task in grid.tasks}
  normalisation = {task: (minima[task], expert_return(root, task))
                   for task in grid.tasks}
  rows, missing = evaluation_rows(root, grid, minima)
  motions = SEEN if grid.splits else None
  final = final_values(rows, np.random.RandomState(seed), resamples,
                       motions, final_window)
  overfitting = {}
  if grid.splits:
    overfitting = {side: final_values(rows, np.random.RandomState(seed),
                                      resamples, side, final_window)
                   for side in (SEEN, UNSEEN)}
  cost = evaluation_cost([r for r in rows if r['motions'] == motions])
  paths = []
  if plots and rows:
    paths += draw(rows, grid, root, 'success', 'evaluation success rate',
                  os.path.join(out, 'success.png'),
                  np.random.RandomState(seed), resamples, motions)
    paths += draw(rows, grid, root, 'normalised_return',
                  'normalised return (1: expert)',
                  os.path.join(out, 'return.png'),
                  np.random.RandomState(seed), resamples, motions)
    if any(row['cost'] is not None for row in rows):
      paths += draw(rows, grid, root, 'cost', 'evaluation cost per episode',
                    os.path.join(out, 'cost.png'),
                    np.random.RandomState(seed), resamples, motions)
    if grid.splits:
      paths += draw_overfitting(rows, grid, os.path.join(
          out, 'overfitting.png'), np.random.RandomState(seed), resamples)
  evaluations = os.path.join(out, 'evaluations.json')
  with open(evaluations, 'w') as f:
    json.dump({'grid': grid.name, 'commit': record.get('commit'),
               'rows': [{k: row[k] for k in ROW_KEYS} for row in rows]},
              f, indent=1)
    f.write('\n')
  final_csv = os.path.join(out, 'final.csv')
  if os.path.exists(final_csv):   # Written anew, with this run's columns.
    os.remove(final_csv)
  logger = logging_lib.CSVLogger(final_csv, step_key='step')
  try:
    for entry in final:
      flat = {'task': entry['task'], 'agent': entry['agent'],
              'seeds': entry['seeds']}
      for name in FINAL_KEYS + SAFETY_KEYS:
        for bound in Summary._fields:
          value = entry[name]
          flat[f'{name}_{bound}'] = (getattr(value, bound)
                                     if value is not None else '')
      logger.write(flat, entry.get('step', ''))
  finally:
    logger.close()
  training_rows, left_out = training_safety.training_rows(root, grid)
  training = training_safety.summary(
      training_rows, np.random.RandomState(seed), resamples)
  if training_rows:
    training_csv = os.path.join(out, 'training.csv')
    # One row per run and quarter (training_safety.training_rows).
    with open(training_csv, 'w', newline='') as f:
      writer = csv.DictWriter(f, fieldnames=list(training_rows[0]))
      writer.writeheader()
      writer.writerows(training_rows)
    paths.append(training_csv)
  labels = {a: grid.label_of(a) for a in grid.agents}
  limits = limit_keeping.kept_limits(
      [r for r in rows if r['motions'] == motions], grid)
  text = markdown(grid, record, final, missing, overfitting, cost,
                  normalisation, final_window,
                  limit_keeping.markdown(limits, labels)
                  + training_safety.markdown(training, labels, left_out))
  with open(os.path.join(out, 'report.md'), 'w') as f:
    f.write(text)
  paths += [evaluations, final_csv, os.path.join(out, 'report.md')]
  return {'rows': rows, 'final': [_jsonable(e) for e in final],
          'limits': limits, 'training': training,
          'missing': missing, 'normalisation': normalisation,
          'overfitting': {k: [_jsonable(e) for e in v]
                          for k, v in overfitting.items()},
          'cost': cost, 'paths': paths}


def define_flags(flag_values: flags.FlagValues = flags.FLAGS) -> None:
  """Defines the binary's flags (only when run as a program).

  Args:
    flag_values: where to define them.
  """
  fv = flag_values
  flags.DEFINE_string('sweep', None, 'Sweep directory (agents.sweep --out).',
                      flag_values=fv)
  flags.DEFINE_string('out', None, 'Report directory (default: '
                      'SWEEP/report).', flag_values=fv)
  flags.DEFINE_integer('resamples', statistics.DEFAULT_RESAMPLES,
                       'Bootstrap resamples.', flag_values=fv)
  flags.DEFINE_integer('seed', 0, 'Seed of the bootstrap resampling.',
                       flag_values=fv)
  flags.DEFINE_integer('final_window', 1, 'Final values: each seed\'s mean '
                       'over its last this many evaluations (1: the last).',
                       flag_values=fv)
  flags.DEFINE_string('json', None, 'Also write every evaluation row here '
                      '(e.g. docs/results/paper_grid.json).', flag_values=fv)


def main(argv: Sequence[str],
         flag_values: flags.FlagValues = flags.FLAGS) -> int:
  """Writes and prints the report of --sweep.

  Args:
    argv: the command line (no arguments).
    flag_values: the parsed flags.

  Returns:
    The exit status: 0, or 2 where --sweep holds no sweep.

  Raises:
    app.UsageError: arguments, or no --sweep.
  """
  if len(argv) > 1:
    raise app.UsageError(f'Unexpected arguments: {argv[1:]}')
  f = flag_values
  if f.sweep is None:
    raise app.UsageError('--sweep is required: a sweep directory')
  try:
    result = report(f.sweep, f.out, f.seed, f.resamples,
                    final_window=f.final_window)
  except ValueError as e:
    print(f'agents.report: {e}', file=sys.stderr)
    return 2
  if f.json:
    shutil.copyfile(next(p for p in result['paths']
                         if p.endswith('evaluations.json')), f.json)
    result['paths'].append(f.json)
  print(open(next(p for p in result['paths']
                  if p.endswith('report.md'))).read())
  for path in result['paths']:
    print(f'Wrote {path}')
  return 0


if __name__ == '__main__':
  define_flags()
  app.run(lambda argv: sys.exit(main(argv)))
