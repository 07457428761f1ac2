r"""The wall time of a grid on M machines of C cores, from a measured sweep.

  python -m agents.grid_cost --sweep=sweeps/paper_reduced --grid=paper \
      --cores=16 --machines=1,2,4,8,16

The model. From the measured sweep's finished runs (one run per core, as
the sweep runs them) it takes, per task and agent:

* the training rate r_train: RL steps per second of training alone (the
  run's wall time less its evaluations' own seconds), environment, actor
  and SAC updates on one core;
* the evaluation rate r_eval: evaluation episode steps per second, and the
  mean evaluation episode length L (RL steps).

A run of the target grid with S steps, evaluated every E steps with K
episodes, then takes S / r_train + (floor(S / E) + 1) K L / r_eval seconds
(plus its start, about 20 s, neglected). Runs go to M x C cores, one per
core, longest first (the sweep starts them in about the order given; the
longest-first order is what a user gets by listing long tasks first and
bounds what any order gives from below by at most the longest run). The
wall time is the last core's finishing time; it can never be below the
longest single run, whatever M.

Assumptions: a core of the target machine runs a run as fast as a core of
the measured machine did with every core busy; rates at the target's
budget equal the rates measured at the sweep's (the replay buffer and the
policy change over a run: evaluation episode lengths shrink as success
grows); a (task, agent) the sweep did not measure takes its task's mean
over the agents measured. Per-run actors are not modelled.
"""

import collections
import os
import sys
from typing import Any, Dict, Mapping, Optional, Sequence, Tuple

from absl import app
from absl import flags

from agents import grids as grids_lib
from agents import logging as logging_lib
from agents import sweep_layout as layout
from agents import report as report_lib

Rates = collections.namedtuple('Rates', ['train', 'evaluation',
                                         'episode_length', 'runs'])
# {(task, agent): Rates}.
RateTable = Mapping[Tuple[str, str], Rates]


def measured_rates(root: str) -> Dict[Tuple[str, str], Rates]:
  """The rates of a sweep's finished runs (their finished.json: steps and
  the run's wall time over all its starts, less the work a restart did
  again).

  Args:
    root: the sweep's directory.

  Returns:
    {(task, agent): Rates}.
  """
  grid, _ = report_lib.load_sweep(root)
  totals = collections.defaultdict(lambda: [0.0, 0.0, 0.0, 0.0, 0.0, 0])
  for run in grid.runs():
    directory = layout.run_directory(root, run.name)
    record = layout.read_json(os.path.join(directory, layout.FINISHED_FILE))
    path = os.path.join(directory, 'eval.csv')
    if record is None or not os.path.exists(path) or not record['steps']:
      continue
    rows = [r for r in logging_lib.read_csv(path)
            if r.get('eval_seconds') not in (None, '')
            and float(r['step']) <= record['steps']]
    if not rows:
      continue
    eval_seconds = sum(float(r['eval_seconds']) for r in rows)
    eval_steps = sum(float(r['episodes']) * float(r['length_mean'])
                     for r in rows)
    episodes = sum(float(r['episodes']) for r in rows)
    total = totals[(run.task, run.agent)]
    total[0] += record['steps']
    total[1] += record['wall_time'] - eval_seconds
    total[2] += eval_steps
    total[3] += eval_seconds
    total[4] += episodes
    total[5] += 1
  return {key: Rates(train=steps / train, evaluation=eval_steps / seconds,
                     episode_length=eval_steps / episodes, runs=runs)
          for key, (steps, train, eval_steps, seconds, episodes, runs)
          in totals.items() if train > 0 and seconds > 0}


def _rates_of(rates, task, agent):
  if (task, agent) in rates:
    return rates[(task, agent)]
  same_task = [r for (t, _), r in rates.items() if t == task]
  if not same_task:
    return None
  return Rates(*(sum(getattr(r, f) for r in same_task) / len(same_task)
                 for f in ('train', 'evaluation', 'episode_length')),
               runs=0)


def run_seconds(grid: grids_lib.Grid, run: grids_lib.Run,
                rates: RateTable) -> Optional[float]:
  """Predicted seconds of one run of a grid.

  Args:
    grid: the grid.
    run: one of its runs.
    rates: the measured rates.

  Returns:
    The seconds, or None where its task was not measured.
  """
  measured = _rates_of(rates, run.task, run.agent)
  if measured is None:
    return None
  steps = grid.steps_of(run.task)
  evaluations = steps // grid.eval_every + 1
  return (steps / measured.train + evaluations * grid.eval_episodes *
          measured.episode_length / measured.evaluation)


def makespan(durations: Sequence[float], cores: int) -> float:
  """Seconds until the cores, each running one run at a time, finish all
  runs, longest first onto the core free soonest.

  Args:
    durations: each run's seconds.
    cores: the cores.

  Returns:
    The seconds.
  """
  free = [0.0] * int(cores)
  for duration in sorted(durations, reverse=True):
    i = min(range(len(free)), key=free.__getitem__)
    free[i] += duration
  return max(free) if durations else 0.0


def predict(grid: grids_lib.Grid, rates: RateTable, cores: int,
            machines: Sequence[int]) -> Dict[str, Any]:
  """The predicted cost of a grid.

  Args:
    grid: the grid.
    rates: the measured rates.
    cores: cores per machine.
    machines: machine counts to predict the wall time of.

  Returns:
    {'run_seconds': {run name: s}, 'unmeasured': [tasks], 'core_seconds',
    'longest', 'wall': {machines: s}}.
  """
  seconds, unmeasured = {}, set()
  for run in grid.runs():
    value = run_seconds(grid, run, rates)
    if value is None:
      unmeasured.add(run.task)
    else:
      seconds[run.name] = value
  return {'run_seconds': seconds, 'unmeasured': sorted(unmeasured),
          'core_seconds': sum(seconds.values()),
          'longest': max(seconds.values(), default=0.0),
          'wall': {m: makespan(list(seconds.values()), cores * m)
                   for m in machines}}


def _hours(seconds):
  return f'{seconds / 3600:.1f} h'


def table(grid: grids_lib.Grid, rates: RateTable, cores: int,
          machines: Sequence[int]) -> str:
  """Markdown: the rates, then the prediction.

  Args:
    grid: the grid.
    rates: the measured rates.
    cores: cores per machine.
    machines: machine counts.

  Returns:
    The markdown.
  """
  lines = ['| task | agent | runs measured | training (RL steps/s) | '
           'evaluation (steps/s) | evaluation episode (RL steps) |',
           '|---|---|---|---|---|---|']
  for (task, agent), r in sorted(rates.items()):
    lines.append(f'| {task} | {agent} | {r.runs} | {r.train:.0f} | '
                 f'{r.evaluation:.0f} | {r.episode_length:.0f} |')
  result = predict(grid, rates, cores, machines)
  lines += ['', f'Grid {grid.name}: {len(grid.runs())} runs, '
            f'{grids_lib.describe(grid)["steps"]:.3g} RL steps; '
            f'{_hours(result["core_seconds"])} of one core in all, the '
            f'longest run {_hours(result["longest"])}.', '',
            f'| machines of {cores} cores | cores | wall time |',
            '|---|---|---|']
  for m, wall in result['wall'].items():
    lines.append(f'| {m} | {m * cores} | {_hours(wall)} |')
  if result['unmeasured']:
    lines += ['', 'Not measured (left out): ' +
              ', '.join(result['unmeasured'])]
  return '\n'.join(lines) + '\n'


def define_flags(flag_values: flags.FlagValues = flags.FLAGS) -> None:
  """Defines the binary's flags (only when run as a program).

  Args:
    flag_values: where to define them.
  """
  fv = flag_values
  flags.DEFINE_string('sweep', None, 'Measured sweep directory.',
                      flag_values=fv)
  flags.DEFINE_string('grid', 'paper', 'Grid to predict.', flag_values=fv)
  flags.DEFINE_integer('cores', 16, 'Cores per machine (one run each).',
                       flag_values=fv)
  flags.DEFINE_list('machines', ['1', '2', '4', '8', '16'],
                    'Machine counts.', flag_values=fv)


def main(argv: Sequence[str],
         flag_values: flags.FlagValues = flags.FLAGS) -> int:
  """Prints the prediction of --grid from the rates of --sweep.

  Args:
    argv: the command line (no arguments).
    flag_values: the parsed flags.

  Returns:
    The exit status: 0, or 2 on a bad grid or sweep.

  Raises:
    app.UsageError: arguments, or no --sweep.
  """
  if len(argv) > 1:
    raise app.UsageError(f'Unexpected arguments: {argv[1:]}')
  f = flag_values
  if f.sweep is None:
    raise app.UsageError('--sweep is required')
  try:
    grid = grids_lib.get(f.grid)
    machines = [int(m) for m in f.machines]
    rates = measured_rates(f.sweep)
  except ValueError as e:
    print(f'agents.grid_cost: {e}', file=sys.stderr)
    return 2
  if not rates:
    print(f'agents.grid_cost: no run of {f.sweep} has timed evaluations yet',
          file=sys.stderr)
    return 2
  print(table(grid, rates, f.cores, machines))
  return 0


if __name__ == '__main__':
  define_flags()
  app.run(lambda argv: sys.exit(main(argv)))
