"""What learning cost: the safety of the episodes a sweep's runs trained on.

An agent that learns to be safe commits violations while it learns; one
kept safe by the shield does not (docs/safe_rl.md, "Learning to be safe
against being kept safe"). The evaluations (`agents.report`) judge the
policies; this module judges training itself, from each run's train.csv
(one row per training episode, `agents.train`): the safety cost, critical
human contacts and shield interventions summed over all the episodes the
run trained on, and over each quarter of its budget, per 10^3 RL steps.

train.csv is a run's local log (sweeps keep it out of git): runs without
one, or whose task has no cost, are left out and named.
"""

import collections
import os
from typing import Any, Dict, List, Mapping, Sequence, Tuple

import numpy as np

from agents import grids as grids_lib
from agents import logging as logging_lib
from agents import sweep_layout as layout
from hrc_suite import statistics

TRAIN_FILE = 'train.csv'   # agents.train's per-episode log.
# (train.csv column, name in the results): summed over a run's episodes.
SUMMED = (('cost', 'cost'), ('contacts_human_critical', 'critical_contacts'),
          ('shield_interventions', 'shield_interventions'))
# Training is also judged by quarters of each run's budget: whether the
# violations fall as the agent learns.
QUARTERS = 4
HEADERS = {'cost': 'cost per 10^3 steps',
           'critical_contacts': 'critical contacts per 10^3 steps',
           'shield_interventions': 'shield interventions per 10^3 steps'}

Row = Dict[str, Any]


def _episodes(root: str, run: grids_lib.Run) -> List[Row]:
  """The run's train.csv rows (none without the file)."""
  path = os.path.join(layout.run_directory(root, run.name), TRAIN_FILE)
  return logging_lib.read_csv(path) if os.path.exists(path) else []


def _total(run: grids_lib.Run, quarter: Any, episodes: Sequence[Row],
           lengths: Sequence[int]) -> Row:
  row = {'task': run.task, 'agent': run.agent, 'seed': run.seed,
         'split': run.split, 'quarter': quarter, 'episodes': len(episodes),
         'steps': int(sum(lengths))}
  for column, name in SUMMED:
    row[name] = float(sum(float(episode.get(column, '') or 0.0)
                          for episode in episodes))
  return row


def training_rows(root: str, grid: grids_lib.Grid
                  ) -> Tuple[List[Row], List[str]]:
  """Each run's training totals, over all its episodes and per quarter.

  An episode belongs to the quarter of the run's budget of RL steps
  (`grid.steps_of`) in which it ends; the quarters of a run not finished
  yet are empty (steps 0) where it has not been.

  Args:
    root: the sweep directory.
    grid: its grid.

  Returns:
    (rows, left out): rows {task, agent, seed, split, quarter ('all', or
    1 to QUARTERS), episodes, steps, cost, critical_contacts,
    shield_interventions} (sums over the run's training episodes so far;
    a run's 'all' row, then its quarters); the names of the runs without
    a train.csv with a cost.

  Raises:
    ValueError: a train.csv row without episode_length.
  """
  rows, left_out = [], []
  for run in grid.runs():
    episodes = _episodes(root, run)
    if not episodes or not episodes[0].get('cost', ''):
      left_out.append(run.name)
      continue
    lengths = []
    for episode in episodes:
      length = episode.get('episode_length', '')
      if length == '':
        raise ValueError(
            f'{layout.run_directory(root, run.name)}/{TRAIN_FILE}: a row '
            f'without episode_length (step {episode.get("step")})')
      lengths.append(int(float(length)))
    rows.append(_total(run, 'all', episodes, lengths))
    budget = grid.steps_of(run.task)
    ends = np.cumsum(lengths)
    quarters = np.clip(np.ceil(QUARTERS * ends / budget), 1,
                       QUARTERS).astype(int)
    for quarter in range(1, QUARTERS + 1):
      chosen = np.flatnonzero(quarters == quarter)
      rows.append(_total(run, quarter, [episodes[i] for i in chosen],
                         [lengths[i] for i in chosen]))
  return rows, left_out


def summary(rows: Sequence[Row], random_state: np.random.RandomState,
            resamples: int) -> List[Dict[str, Any]]:
  """Per (task, agent, quarter): the rates per 10^3 training steps.

  Args:
    rows: of `training_rows`.
    random_state: the bootstrap's random numbers.
    resamples: bootstrap resamples.

  Returns:
    Entries {task, agent, quarter, seeds, steps (the fewest of a seed),
    and for each summed quantity {mean, low, high}: mean [95 % bootstrap
    CI] over seeds of the run's total per 10^3 of its RL steps}: the
    whole runs' ('all') first, then the quarters'. Runs with no step in
    a quarter are left out of it.
  """
  groups = collections.OrderedDict()
  for whole in (True, False):
    for row in rows:
      if row['steps'] and (row['quarter'] == 'all') == whole:
        key = (row['task'], row['agent'], row['quarter'])
        groups.setdefault(key, []).append(row)
  entries = []
  for (task, agent, quarter), runs in groups.items():
    entry = {'task': task, 'agent': agent, 'quarter': quarter,
             'seeds': len(runs),
             'steps': min(run['steps'] for run in runs)}
    for _, name in SUMMED:
      rates = [1000.0 * run[name] / run['steps'] for run in runs]
      mean, low, high = statistics.bootstrap_ci(
          np.array(rates), random_state, num_resamples=resamples)
      entry[name] = {'mean': float(mean), 'low': float(low),
                     'high': float(high)}
    entries.append(entry)
  return entries


def _cell(value: Mapping[str, float]) -> str:
  return f'{value["mean"]:.2f} [{value["low"]:.2f}, {value["high"]:.2f}]'


def markdown(entries: Sequence[Mapping[str, Any]],
             labels: Mapping[str, str], left_out: Sequence[str]
             ) -> List[str]:
  """The report's section "During training" (empty without entries): the
  whole runs, then each quantity by quarter of training.

  Args:
    entries: of `summary`.
    labels: {agent: its label}.
    left_out: runs without a train.csv with a cost.

  Returns:
    The section's lines.
  """
  whole = [e for e in entries if e['quarter'] == 'all']
  if not whole:
    return []
  names = [name for _, name in SUMMED]
  lines = ['', '## During training', '',
           'Every training episode of each run so far (train.csv): totals '
           'per 10^3 of the run\'s RL steps, mean [95 % bootstrap CI] over '
           'seeds.', '',
           '| task | agent | seeds | RL steps (fewest) | '
           + ' | '.join(HEADERS[n] for n in names) + ' |',
           '|---|---|---|---|' + '---|' * len(names)]
  for entry in whole:
    cells = ' | '.join(_cell(entry[n]) for n in names)
    lines.append(f'| {entry["task"]} | '
                 f'{labels.get(entry["agent"], entry["agent"])} | '
                 f'{entry["seeds"]} | {entry["steps"]} | {cells} |')
  by_quarter = {(e['task'], e['agent'], e['quarter']): e for e in entries}
  quarters = range(1, QUARTERS + 1)
  for name in names:
    lines += ['', f'By quarter of each run\'s budget (an episode counts in '
              f'the quarter it ends in): {HEADERS[name]}.', '',
              '| task | agent | '
              + ' | '.join(f'quarter {q}' for q in quarters) + ' |',
              '|---|---|' + '---|' * QUARTERS]
    for entry in whole:
      cells = [by_quarter.get((entry['task'], entry['agent'], q))
               for q in quarters]
      lines.append(f'| {entry["task"]} | '
                   f'{labels.get(entry["agent"], entry["agent"])} | '
                   + ' | '.join(_cell(c[name]) if c else '-'
                                for c in cells) + ' |')
  if left_out:
    lines += ['', 'Without a train.csv with a cost: '
              + ', '.join(left_out) + '.']
  return lines
