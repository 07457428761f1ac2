r"""Learning curves over seeds from training runs' eval.csv, as PNG and SVG.

  python -m agents.plot --logdirs=runs/reach/seed0,runs/reach/seed1 \
      --out=curves.png     # writes curves.png, curves.svg and curves.csv

Runs (log directories of `agents.train`) that differ only in their seed are
one curve: at every evaluation step all of them reached, the mean over seeds
with a 95 % percentile-bootstrap confidence interval from 10^4 resamples
(the reference benchmark's protocol). Two panels: the evaluation success
rate and the evaluation return normalised between the task's minimal
episode return (0: the task reward's lowest possible episode return,
HrcTask.min_task_return, from the run's config.json, as in the paper,
whose runs had no collision penalty;
--minimum=total: with the collision penalty, which puts the zero far below
any real return) and the mean expert return (1). The expert return comes
from --expert_return or the experts file (--experts_json, by default
docs/results/experts.json of the repository when present); without either
the raw return is plotted and the axis says so. --per_seed draws one curve
per run instead of the mean, which shows how seeds differ. A curve of one
seed is that run's evaluations, without a band, and the title says so.
Where every run's task has a safety cost (eval.csv's cost_mean: the mean
cost per evaluation episode, hrc_suite/tasks/runtime/cost.py), a third panel
draws it, with each SAC-Lagrangian run's per-episode cost limit dashed.

Experts files read: the output of `python -m hrc_suite.experts.evaluate`
({"rows": [{domain, task, robot, action_space, policy, return, ...}]}: the
deterministic expert's row of the run's task, robot and action space), or
{"<domain>/<task>": E} with E a number, a dict with "return_mean", or a
dict {robot: number or {"return_mean": ...}}.
"""

import collections
import os
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple

from absl import app
from absl import flags
from absl import logging
import numpy as np

from agents import checkpoints
from agents import logging as logging_lib
from hrc_suite import statistics

# Parts of a run config that do not distinguish curves (with --per_seed the
# seed does).
_RUN_LENGTH_KEYS = ('steps', 'checkpoint_every')
_DEFAULT_EXPERTS = os.path.join(os.path.dirname(os.path.abspath(__file__)),
                                '..', 'docs', 'results', 'experts.json')

# Normalisation minimum -> the config.json entry holding it.
MINIMA = {'total': 'min_return', 'task': 'min_task_return'}

Curve = collections.namedtuple(
    'Curve', ['label', 'steps', 'seeds', 'success', 'returns', 'normalised',
              'cost', 'cost_limit'])
# success / returns / cost: (mean, low, high) arrays over steps (cost None
# where a run has no cost); normalised: bool; cost_limit: the constrained
# agent's per-episode limit, or None.
COST_COLUMN = 'cost_mean'


def load_run(logdir: str) -> Tuple[Dict[str, Any], Dict[str, np.ndarray]]:
  """One run's config and evaluations.

  Args:
    logdir: the run's directory.

  Returns:
    (config dict, {column: array} of eval.csv).

  Raises:
    ValueError: a directory without config.json or eval.csv, or without
      evaluations.
  """
  config_path = os.path.join(logdir, 'config.json')
  eval_path = os.path.join(logdir, 'eval.csv')
  for path in (config_path, eval_path):
    if not os.path.exists(path):
      raise ValueError(f'{logdir} is not a training run: {path} is missing')
  config = checkpoints.read_json(config_path)
  names = ('step', 'success_rate', 'return_mean')
  rows = logging_lib.read_csv(eval_path)
  if rows and COST_COLUMN in rows[0]:
    names += (COST_COLUMN,)
  columns = logging_lib.read_csv_columns(eval_path, names)
  if not columns['step']:
    raise ValueError(f'{eval_path} has no evaluations yet')
  return config, {k: np.array(v) for k, v in columns.items()}


def expert_return(config: Mapping[str, Any],
                  experts_json: Optional[str] = None) -> Optional[float]:
  """The mean expert return of the run's task, robot and action space.

  Args:
    config: the run's config.json.
    experts_json: None or an experts file (module doc).

  Returns:
    The return, or None (no file, or no matching entry).

  Raises:
    ValueError: an entry that is not a number.
  """
  if not experts_json or not os.path.exists(experts_json):
    return None
  experts = checkpoints.read_json(experts_json)
  if 'rows' in experts:   # python -m hrc_suite.experts.evaluate
    # Training runs meet the shipped synthetic people behind the task's
    # default shield: rows on recordings or another shield do not compare.
    matches = {row['policy']: row['return'] for row in experts['rows']
               if (row['domain'], row['task'], row['robot'],
                   row['action_space']) == (
                       config['domain'], config['task'], config['robot'],
                       config['action_space'])
               and row.get('people', 'synthetic') == 'synthetic'
               and row.get('shield_choice', 'default') == 'default'}
    # The deterministic expert; the noisy one if that is all there is.
    entry = matches.get('expert', matches.get('noisy_expert'))
  else:
    entry = experts.get(f'{config["domain"]}/{config["task"]}')
    if isinstance(entry, dict) and config['robot'] in entry:
      entry = entry[config['robot']]
    if isinstance(entry, dict):
      entry = entry.get('return_mean')
  if entry is None:
    return None
  if not isinstance(entry, (int, float)):
    raise ValueError(f'{experts_json}: expected a number for '
                     f'{config["domain"]}/{config["task"]}, got {entry!r}')
  return float(entry)


def _group_key(config, per_seed=False):
  ignored = _RUN_LENGTH_KEYS + (() if per_seed else ('seed',))
  return tuple(sorted((k, repr(v)) for k, v in config.items()
                      if k not in ignored))


def _label(config):
  label = f'{config["agent"]} ({config["config"]})'
  if config.get('overrides'):
    label += ' ' + ', '.join(f'{k}={v}' for k, v in
                             sorted(config['overrides'].items()))
  return label


def learning_curves(logdirs: Sequence[str],
                    random_state: np.random.RandomState,
                    expert: Optional[float] = None,
                    experts_json: Optional[str] = None,
                    num_resamples: int = statistics.DEFAULT_RESAMPLES,
                    minimum: str = 'task',
                    per_seed: bool = False) -> List[Curve]:
  """One Curve per group of runs that differ only in their seed.

  Args:
    logdirs: the runs' directories.
    random_state: the bootstrap's random numbers.
    expert: the expert return (None: from experts_json).
    experts_json: None or an experts file.
    num_resamples: bootstrap resamples.
    minimum: the normalisation's 0, 'total' (the lowest possible return,
      collision penalties included) or 'task' (the task reward's alone).
    per_seed: one Curve per run instead (its CI is the run's own values),
      to show how seeds differ where the mean hides it.

  Returns:
    The curves.

  Raises:
    ValueError: an unknown minimum, runs that repeat seeds or share no
      evaluation step, or an expert return not above the minimum.
  """
  if minimum not in MINIMA:
    raise ValueError(f'Unknown minimum {minimum!r}: expected one of '
                     f'{", ".join(MINIMA)}')
  groups = collections.OrderedDict()
  for logdir in logdirs:
    config, columns = load_run(logdir)
    key = _group_key(config, per_seed)
    groups.setdefault(key, []).append((config, columns))
  curves = []
  for runs in groups.values():
    config = runs[0][0]
    seeds = [c['seed'] for c, _ in runs]
    if len(set(seeds)) != len(seeds):
      raise ValueError(f'Runs of {_label(config)} repeat seeds {seeds}: '
                       'give each seed once')
    steps = sorted(set.intersection(*(set(c['step']) for _, c in runs)))
    if not steps:
      raise ValueError(f'The runs of {_label(config)} share no evaluation '
                       'step')

    def table(name):
      rows = []
      for _, columns in runs:
        index = {s: i for i, s in enumerate(columns['step'])}
        rows.append([columns[name][index[s]] for s in steps])
      return np.array(rows)   # (seeds, steps)

    success = table('success_rate')
    returns = table('return_mean')
    has_cost = all(COST_COLUMN in columns for _, columns in runs)
    best = expert if expert is not None else expert_return(config,
                                                           experts_json)
    normalised = best is not None
    if normalised:
      low = config[MINIMA[minimum]]
      if not best > low:
        raise ValueError(f'Expert return {best} must exceed the minimal '
                         f'return {low} of {config["domain"]}/'
                         f'{config["task"]}')
      returns = (returns - low) / (best - low)
    curves.append(Curve(
        label=_label(config), steps=np.array(steps), seeds=seeds,
        success=statistics.bootstrap_ci(success, random_state,
                                        num_resamples=num_resamples),
        returns=statistics.bootstrap_ci(returns, random_state,
                                        num_resamples=num_resamples),
        normalised=normalised,
        cost=(statistics.bootstrap_ci(table(COST_COLUMN), random_state,
                                      num_resamples=num_resamples)
              if has_cost else None),
        cost_limit=config.get('sac_config', {}).get('cost_limit')))
  return curves


def title(config: Mapping[str, Any], curves: Sequence[Curve],
          per_seed: bool = False) -> str:
  """The figure's title: the task, the robot and what the curves show (a
  confidence interval only for curves over several seeds).

  Args:
    config: a run's config.json.
    curves: the curves drawn.
    per_seed: one curve per seed.

  Returns:
    The title.
  """
  head = f'{config["domain"]}/{config["task"]}, {config["robot"]}: '
  one_seed = [len(curve.seeds) == 1 for curve in curves]
  if per_seed:
    return head + 'one curve per seed (no confidence interval)'
  if all(one_seed):
    return head + 'one seed (no confidence interval)'
  if any(one_seed):
    return head + ('mean and 95 % bootstrap CI over seeds (none for the '
                   'curves of one seed)')
  return head + 'mean and 95 % bootstrap CI over seeds'


def draw(curves: Sequence[Curve], out: str, title: str) -> Tuple[str, str]:
  """Writes the curves as `out` (PNG) and the same stem .svg.

  Args:
    curves: the curves.
    out: the PNG's path.
    title: the figure's title.

  Returns:
    The paths written.
  """
  import matplotlib   # pylint: disable=g-import-not-at-top
  matplotlib.use('Agg')
  import matplotlib.pyplot as plt   # pylint: disable=g-import-not-at-top
  with_cost = all(curve.cost is not None for curve in curves)
  panels = 3 if with_cost else 2
  figure, axes = plt.subplots(1, panels, figsize=(5 * panels, 4.5),
                              constrained_layout=True)
  for curve in curves:
    values = (curve.success, curve.returns) + ((curve.cost,) if with_cost
                                               else ())
    for axis, (mean, low, high) in zip(axes, values):
      plural = 's' if len(curve.seeds) > 1 else ''
      seeds = ', '.join(str(seed) for seed in curve.seeds)
      label = f'{curve.label}, seed{plural} {seeds}'
      line, = axis.plot(curve.steps, mean, label=label)
      if len(curve.seeds) > 1:   # One seed has no interval over seeds.
        axis.fill_between(curve.steps, low, high, color=line.get_color(),
                          alpha=0.25, linewidth=0)
      if axis is axes[-1] and with_cost and curve.cost_limit is not None:
        axis.axhline(curve.cost_limit, color=line.get_color(),
                     linestyle='--', linewidth=1)
  axes[0].set_ylabel('evaluation success rate')
  axes[0].set_ylim(-0.02, 1.02)
  normalised = all(c.normalised for c in curves)
  axes[1].set_ylabel('normalised return (0: minimal, 1: expert)'
                     if normalised else
                     'return (not normalised: no expert return)')
  if with_cost:
    axes[2].set_ylabel('evaluation cost per episode (dashed: limit)')
  for axis in axes:
    axis.set_xlabel('environment steps')
    # 1e5-style offsets keep long step counts from running together.
    axis.ticklabel_format(axis='x', style='sci', scilimits=(0, 4))
    axis.grid(alpha=0.3)
  handles, labels = axes[0].get_legend_handles_labels()
  figure.legend(handles, labels, loc='outside lower center',
                ncol=min(len(labels), 2), fontsize='small')
  figure.suptitle(title)
  stem, _ = os.path.splitext(os.fspath(out))
  directory = os.path.dirname(stem)
  if directory:
    os.makedirs(directory, exist_ok=True)
  paths = (stem + '.png', stem + '.svg')
  for path in paths:
    figure.savefig(path, dpi=120)
  plt.close(figure)
  return paths


def write_table(curves: Sequence[Curve], path: str) -> str:
  """Writes the curves as CSV rows (label, step, seed count and ids, mean
  and CI bounds).

  Args:
    curves: the curves.
    path: the CSV file.

  Returns:
    The path.
  """
  logger = logging_lib.CSVLogger(path)
  try:
    for curve in curves:
      for i, step in enumerate(curve.steps):
        row = {'label': curve.label, 'seeds': len(curve.seeds),
               'seed_ids': ' '.join(str(seed) for seed in curve.seeds),
               'normalised': int(curve.normalised)}
        for name, values in (('success', curve.success),
                             ('return', curve.returns),
                             ('cost', curve.cost)):
          if values is None:
            continue
          for bound, array in zip(('mean', 'low', 'high'), values):
            row[f'{name}_{bound}'] = float(np.asarray(array)[i])
        logger.write(row, int(step))
  finally:
    logger.close()
  return path


def define_flags(flag_values: flags.FlagValues = flags.FLAGS) -> None:
  """Defines the binary's flags (only when run as a program).

  Args:
    flag_values: where to define them.
  """
  fv = flag_values
  flags.DEFINE_list('logdirs', None, 'Run directories (comma-separated).',
                    required=True, flag_values=fv)
  flags.DEFINE_string('out', 'curves.png', 'Output PNG; an SVG with the same '
                      'stem is written too.', flag_values=fv)
  flags.DEFINE_float('expert_return', None, 'Mean expert episode return '
                     '(overrides the experts file).', flag_values=fv)
  flags.DEFINE_string('experts_json', _DEFAULT_EXPERTS,
                      'Experts file (used when present).', flag_values=fv)
  flags.DEFINE_integer('resamples', statistics.DEFAULT_RESAMPLES,
                       'Bootstrap resamples.', flag_values=fv)
  flags.DEFINE_integer('seed', 0, 'Seed of the bootstrap resampling.',
                       flag_values=fv)
  flags.DEFINE_enum('minimum', 'task', list(MINIMA), 'Normalisation 0: the '
                    'task reward\'s lowest return (the paper\'s) or the '
                    'lowest possible return with collision penalties.',
                    flag_values=fv)
  flags.DEFINE_bool('per_seed', False, 'One curve per run instead of the '
                    'mean over seeds.', flag_values=fv)


def plot(logdirs: Sequence[str], out: str, seed: int = 0,
         expert: Optional[float] = None,
         experts_json: str = _DEFAULT_EXPERTS,
         num_resamples: int = statistics.DEFAULT_RESAMPLES,
         minimum: str = 'task', per_seed: bool = False) -> List[str]:
  """Writes the runs' curves as `out` (PNG), .svg and .csv.

  Args:
    logdirs: the runs' directories.
    out: the PNG's path.
    seed: the bootstrap's seed.
    expert: the expert return (None: from experts_json).
    experts_json: an experts file (used when present).
    num_resamples: bootstrap resamples.
    minimum: the normalisation's 0, 'task' or 'total'.
    per_seed: one curve per run.

  Returns:
    The paths written.

  Raises:
    ValueError: runs or an expert return `learning_curves` rejects.
  """
  if expert is None and not os.path.exists(experts_json):
    logging.warning('No expert return (%s absent, no --expert_return): '
                    'plotting the raw return', experts_json)
  curves = learning_curves(logdirs, np.random.RandomState(seed),
                           expert=expert, experts_json=experts_json,
                           num_resamples=num_resamples, minimum=minimum,
                           per_seed=per_seed)
  config, _ = load_run(logdirs[0])
  paths = list(draw(curves, out, title(config, curves, per_seed)))
  table = os.path.splitext(out)[0] + '.csv'
  if os.path.exists(table):
    os.remove(table)
  return paths + [write_table(curves, table)]


def main(argv: Sequence[str],
         flag_values: flags.FlagValues = flags.FLAGS) -> None:
  """Plots --logdirs and prints the paths written.

  Args:
    argv: the command line (unused).
    flag_values: the parsed flags.
  """
  del argv
  f = flag_values
  for path in plot(f.logdirs, f.out, f.seed, f.expert_return, f.experts_json,
                   f.resamples, f.minimum, f.per_seed):
    print(path)


if __name__ == '__main__':
  define_flags()
  app.run(main)
