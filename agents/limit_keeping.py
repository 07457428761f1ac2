"""Whether the evaluated policies keep the cost limit.

A constrained agent promises an expected cost per episode at or below its
limit d (docs/safe_rl.md). Its final values average a few evaluations;
this module counts, over every evaluation after the first (step 0 is the
untrained policy), how many kept the limit, over the whole run and over
the second half of its budget, and how many had a critical human contact.
Evaluations of a deterministic policy on pick and place swing between no
cost and hundreds per episode from one evaluation to the next: the count
shows whether a limit is kept or a final window was lucky.

Unconstrained agents are judged against the limit of the task's
constrained runs (the grid has one per task) for comparison.
"""

import collections
from typing import Any, Dict, List, Mapping, Sequence

from agents import grids as grids_lib

Row = Dict[str, Any]


def cost_limits(grid: grids_lib.Grid, task: str) -> List[float]:
  """The per-episode cost limits the grid's constrained runs of a task
  keep (their `cost_limit` override, docs/safe_rl.md).

  Args:
    grid: the grid.
    task: 'domain/task'.

  Returns:
    The distinct limits, ascending (empty: no run of the task has one).
  """
  return sorted({float(run.run_config['overrides']['cost_limit'])
                 for run in grid.runs() if run.task == task
                 and 'cost_limit' in (run.run_config.get('overrides') or {})})


def kept_limits(rows: Sequence[Row], grid: grids_lib.Grid
                ) -> List[Dict[str, Any]]:
  """Per (task, agent) of a task with one cost limit: the evaluations
  after the first that kept it.

  Args:
    rows: evaluation rows (`agents.report.evaluation_rows`: task, agent,
      seed, step, cost, critical_contacts_per_1000); rows without a cost
      are left out.
    grid: their grid (the budgets and limits).

  Returns:
    Entries {task, agent, limit, seeds, evaluations, kept,
    evaluations_late, kept_late, with_critical}: 'late' are the
    evaluations in the second half of the budget (step > steps / 2);
    with_critical counts evaluations with a critical human contact.
  """
  limits = {task: cost_limits(grid, task) for task in grid.tasks}
  groups = collections.OrderedDict()
  for row in rows:
    limit = limits.get(row['task'], [])
    if row['step'] <= 0 or row['cost'] is None or len(limit) != 1:
      continue
    entry = groups.setdefault((row['task'], row['agent']), {
        'task': row['task'], 'agent': row['agent'], 'limit': limit[0],
        'seeds': set(), 'evaluations': 0, 'kept': 0,
        'evaluations_late': 0, 'kept_late': 0, 'with_critical': 0})
    kept = row['cost'] <= limit[0]
    late = row['step'] > grid.steps_of(row['task']) / 2
    entry['seeds'].add(row['seed'])
    entry['evaluations'] += 1
    entry['kept'] += kept
    entry['evaluations_late'] += late
    entry['kept_late'] += kept and late
    entry['with_critical'] += bool(row['critical_contacts_per_1000'])
  return [dict(entry, seeds=len(entry['seeds']))
          for entry in groups.values()]


def markdown(entries: Sequence[Mapping[str, Any]],
             labels: Mapping[str, str]) -> List[str]:
  """The report's section "Keeping the cost limit" (empty without
  entries).

  Args:
    entries: of `kept_limits`.
    labels: {agent: its label}.

  Returns:
    The section's lines.
  """
  if not entries:
    return []
  lines = ['', '## Keeping the cost limit', '',
           'Evaluations after the first (every seed\'s) whose cost per '
           'episode is at or below the limit of the task\'s constrained '
           'runs: over the whole run, and in the second half of its '
           'budget; evaluations with a critical human contact.', '',
           '| task | agent | limit | seeds | within the limit | '
           'within, second half | with a critical contact |',
           '|---|---|---|---|---|---|---|']
  for entry in entries:
    lines.append(
        f'| {entry["task"]} | {labels.get(entry["agent"], entry["agent"])}'
        f' | {entry["limit"]:g} | {entry["seeds"]} | '
        f'{entry["kept"]} of {entry["evaluations"]} | '
        f'{entry["kept_late"]} of {entry["evaluations_late"]} | '
        f'{entry["with_critical"]} of {entry["evaluations"]} |')
  return lines
