"""What learning cost: the safety of the episodes a sweep's runs trained on.

An agent that learns to be safe commits violations while it learns; one
kept safe by the shield does not (docs/safe_rl.md, "Learning to be safe
against being kept safe"). The evaluations (`agents.report`) judge the
policies; this module judges training itself, from each run's train.csv
(one row per training episode, `agents.train`): the safety cost, critical
human contacts and shield interventions summed over all the episodes the
run trained on, per 10^3 RL steps.

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
HEADERS = {'cost': 'cost per 10^3 steps',
           'critical_contacts': 'critical contacts per 10^3 steps',
           'shield_interventions': 'shield interventions per 10^3 steps'}

Row = Dict[str, Any]


def training_rows(root: str, grid: grids_lib.Grid
                  ) -> Tuple[List[Row], List[str]]:
  """Each run's training totals.

  Args:
    root: the sweep directory.
    grid: its grid.

  Returns:
    (rows, left out): rows {task, agent, seed, split, steps, episodes,
    cost, critical_contacts, shield_interventions} (sums over the run's
    training episodes so far); the names of the runs without a train.csv
    with a cost.

  Raises:
    ValueError: a train.csv row without episode_length.
  """
  rows, left_out = [], []
  for run in grid.runs():
    path = os.path.join(layout.run_directory(root, run.name), TRAIN_FILE)
    episodes = logging_lib.read_csv(path) if os.path.exists(path) else []
    if not episodes or not episodes[0].get('cost', ''):
      left_out.append(run.name)
      continue
    row = {'task': run.task, 'agent': run.agent, 'seed': run.seed,
           'split': run.split, 'episodes': len(episodes), 'steps': 0}
    row.update({name: 0.0 for _, name in SUMMED})
    for episode in episodes:
      length = episode.get('episode_length', '')
      if length == '':
        raise ValueError(f'{path}: a row without episode_length '
                         f'(step {episode.get("step")})')
      row['steps'] += int(float(length))
      for column, name in SUMMED:
        value = episode.get(column, '')
        row[name] += float(value) if value != '' else 0.0
    rows.append(row)
  return rows, left_out


def summary(rows: Sequence[Row], random_state: np.random.RandomState,
            resamples: int) -> List[Dict[str, Any]]:
  """Per (task, agent): the rates per 10^3 training steps over seeds.

  Args:
    rows: of `training_rows`.
    random_state: the bootstrap's random numbers.
    resamples: bootstrap resamples.

  Returns:
    Entries {task, agent, seeds, steps (the fewest of a seed), and for
    each summed quantity {mean, low, high}: mean [95 % bootstrap CI] over
    seeds of the run's total per 10^3 of its RL steps}.
  """
  groups = collections.OrderedDict()
  for row in rows:
    if row['steps']:
      groups.setdefault((row['task'], row['agent']), []).append(row)
  entries = []
  for (task, agent), runs in groups.items():
    entry = {'task': task, 'agent': agent, 'seeds': len(runs),
             'steps': min(run['steps'] for run in runs)}
    for _, name in SUMMED:
      rates = [1000.0 * run[name] / run['steps'] for run in runs]
      mean, low, high = statistics.bootstrap_ci(
          np.array(rates), random_state, num_resamples=resamples)
      entry[name] = {'mean': float(mean), 'low': float(low),
                     'high': float(high)}
    entries.append(entry)
  return entries


def markdown(entries: Sequence[Mapping[str, Any]],
             labels: Mapping[str, str], left_out: Sequence[str]
             ) -> List[str]:
  """The report's section "During training" (empty without entries).

  Args:
    entries: of `summary`.
    labels: {agent: its label}.
    left_out: runs without a train.csv with a cost.

  Returns:
    The section's lines.
  """
  if not entries:
    return []
  names = [name for _, name in SUMMED]
  lines = ['', '## During training', '',
           'Every training episode of each run so far (train.csv): totals '
           'per 10^3 of the run\'s RL steps, mean [95 % bootstrap CI] over '
           'seeds.', '',
           '| task | agent | seeds | RL steps (fewest) | '
           + ' | '.join(HEADERS[n] for n in names) + ' |',
           '|---|---|---|---|' + '---|' * len(names)]
  for entry in entries:
    cells = ' | '.join(
        f'{entry[n]["mean"]:.2f} [{entry[n]["low"]:.2f}, '
        f'{entry[n]["high"]:.2f}]' for n in names)
    lines.append(f'| {entry["task"]} | '
                 f'{labels.get(entry["agent"], entry["agent"])} | '
                 f'{entry["seeds"]} | {entry["steps"]} | {cells} |')
  if left_out:
    lines += ['', 'Without a train.csv with a cost: '
              + ', '.join(left_out) + '.']
  return lines
