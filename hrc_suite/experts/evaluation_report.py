"""What an expert evaluation writes: the Markdown table with its
provenance (the runs behind its rows, the machine) and the results JSON
(episodes row by row: results_file.py), and how a run's episodes merge
into an existing table (--update).
"""

import collections
import json
import os
import pathlib
import platform
import subprocess
from typing import Any, Iterable, Mapping, Optional, Sequence, Union

import numpy as np

from hrc_suite.experts import evaluation_episodes as episodes_lib
from hrc_suite.experts import evaluation_rows as rows_lib
from hrc_suite.experts import results_file

# A mean of a metric no episode of the row recorded (run before it existed).
MISSING = '—'
_REPOSITORY = pathlib.Path(__file__).resolve().parents[2]


def _cpu_model():
  try:
    with open('/proc/cpuinfo') as f:
      for line in f:
        if line.startswith('model name'):
          return line.split(':', 1)[1].strip()
  except OSError:
    pass
  return platform.processor() or platform.machine()


def machine() -> dict[str, Any]:
  """A short description of the machine: cpus, platform, processor,
  python."""
  return {'cpus': os.cpu_count(), 'platform': platform.platform(),
          'processor': _cpu_model(), 'python': platform.python_version()}


def git_commit() -> Optional[str]:
  """The repository's commit (`git rev-parse --short HEAD`), None where
  git cannot tell."""
  try:
    out = subprocess.run(['git', 'rev-parse', '--short', 'HEAD'],
                         cwd=_REPOSITORY, capture_output=True, text=True,
                         timeout=10, check=True)
  except (OSError, subprocess.SubprocessError):
    return None
  return out.stdout.strip() or None


HEADER = ('| task | robot | policy | people | shield | action space | '
          'episodes | success [95 % CI] | return | length (steps) | '
          'length (s) | shield interventions | '
          + ' | '.join(f'contacts {label}'
                       for label, _ in rows_lib.CONTACT_COLUMNS)
          + ' | ' + ' | '.join(label for label, _ in rows_lib.SAFETY_COLUMNS)
          + ' | wall time / episode (s) |')


def merge(old: Sequence[episodes_lib.Result],
          new: Sequence[episodes_lib.Result]) -> list[episodes_lib.Result]:
  """Episodes of a table with the rows a new run redid replaced.

  Args:
    old: the table's episodes.
    new: the new run's episodes.

  Returns:
    `old` with the rows of `new` replaced in place (rows only in `new` at
    the end).
  """
  fresh = collections.OrderedDict()
  for result in new:
    fresh.setdefault(rows_lib.row_key(result), []).append(result)
  merged, placed = [], set()
  for result in old:
    key = rows_lib.row_key(result)
    if key not in fresh:
      merged.append(result)
    elif key not in placed:
      merged.extend(fresh[key])
      placed.add(key)
  for key, results in fresh.items():
    if key not in placed:
      merged.extend(results)
  return merged


def merge_runs(old_runs: Sequence[Mapping[str, Any]],
               run: Mapping[str, Any]) -> list[dict[str, Any]]:
  """The runs behind a merged table.

  Args:
    old_runs: the table's runs, each with its 'rows' (row keys).
    run: the new run, with its 'rows'.

  Returns:
    The older runs keeping only the rows `run` did not redo (runs left
    without rows dropped), then `run`.
  """
  redone = set(run['rows'])
  kept = []
  for old in old_runs:
    rows = [key for key in old['rows'] if key not in redone]
    if rows:
      kept.append(dict(old, rows=rows))
  return kept + [run]


def merge_not_evaluated(old: Mapping[str, str], new: Mapping[str, str],
                        results: Iterable[Mapping[str, Any]]
                        ) -> dict[str, str]:
  """The tasks not evaluated after a run.

  Args:
    old: {task key: reason} of the table.
    new: {task key: reason} of the run.
    results: the run's episodes.

  Returns:
    {task key: reason}: `old` less the tasks (with their people) that
    `results` evaluated, then `new`, sorted by key.
  """
  done = {rows_lib.task_key(r['domain'], r['task'],
                            episodes_lib.job_fields(r['job'])[7])
          for r in results}
  merged = {key: reason for key, reason in old.items() if key not in done}
  merged.update(new)
  return dict(sorted(merged.items()))


def load_previous(path: Union[str, os.PathLike]
                  ) -> tuple[list[episodes_lib.Result], list[dict[str, Any]]]:
  """The episodes and runs of a results JSON. A file written before
  runs were recorded (one 'info') counts as one run of all its rows.

  Args:
    path: the JSON; it need not exist.

  Returns:
    (episodes, runs), ([], []) if there is no file.

  Raises:
    ValueError: a file that is not a results file.
  """
  return load_results(path)[:2]


def load_results(
    path: Union[str, os.PathLike]
) -> tuple[list[episodes_lib.Result], list[dict[str, Any]], dict[str, str],
           Optional[str]]:
  """What a results JSON holds.

  Args:
    path: the JSON; it need not exist.

  Returns:
    (episodes, runs, {task key: reason not evaluated}, notes or None);
    ([], [], {}, None) if there is no file.

  Raises:
    ValueError: a file that is not a results file.
  """
  path = pathlib.Path(path)
  if not path.exists():
    return [], [], {}, None
  try:
    payload = json.loads(path.read_text())
    episodes = results_file.episodes(payload)
    runs = payload.get('runs')
    if runs is None:
      rows = list(dict.fromkeys(rows_lib.row_key(e) for e in episodes))
      runs = [dict(payload['info'], rows=rows)]
    not_evaluated = dict(payload.get('not_evaluated') or {})
  except (ValueError, KeyError, TypeError, AttributeError) as e:
    raise ValueError(f'{path}: not a results file of this command ({e}); '
                     'run without --update to write it afresh') from e
  return episodes, runs, not_evaluated, payload.get('notes')


def _run_line(run):
  tasks = ', '.join(dict.fromkeys(key.split()[0] for key in run['rows']))
  return (f'* Command: `{run["command"]}` ({run["date"]}, commit '
          f'{run["commit"] or "unknown"}, {run["workers"]} worker '
          f'process(es), wall time {run["wall_time"]:.0f} s): '
          f'{len(run["rows"])} rows of {tasks}')


def _cell(value, digits=2):
  return MISSING if not np.isfinite(value) else f'{value:.{digits}f}'


def _people_lines(results):
  """What each label of `results`' people is."""
  folders = {}
  for result in results:
    motions = episodes_lib.job_fields(result.get('job', ()))[7]
    if motions is not None:
      folders.setdefault(motions[0], motions[1])
  lines = []
  if any(episodes_lib.people(r) == episodes_lib.SYNTHETIC for r in results):
    lines.append(f'{episodes_lib.SYNTHETIC}: the shipped motion library')
  lines += [f'{label}: the task\'s motions in `{folder}` (its sub-folder '
            "there), played with outside_human_model='allow'"
            for label, folder in folders.items()]
  return lines


def _policy_lines(rows):
  policies = {row['policy'] for row in rows}
  lines = []
  if 'noisy_expert' in policies:
    lines.append('noisy expert: reference Ornstein-Uhlenbeck noise '
                 '(hrc_suite/experts/noise.py)')
  if 'random' in policies:
    lines.append('random: uniform actions in the action spec, drawn from '
                 'np.random.default_rng(seed)')
  if 'chase' in policies:
    lines.append('chase: the TCP driven at the person\'s nearest keypoint '
                 'as fast as the action space allows, gripper closed '
                 '(hrc_suite/experts/adversary.py)')
  return lines


def _shield_off_lines(rows):
  """The rows with the shield off and their critical contacts."""
  lines = []
  for row in rows:
    if rows_lib.shield_gates(row['shield']):
      continue
    closest = _cell(row['min_human_distance'], 3)
    if row['critical_episodes']:
      found = (f'critical human contacts in {row["critical_episodes"]} of '
               f'{row["episodes"]} episodes '
               f'({row["contacts_human_critical"]:.1f} physics steps per '
               'episode)')
    else:
      found = (f'NO critical human contact in {row["episodes"]} episodes '
               '(the check did not fail here)')
    lines.append(f'* {rows_lib.row_name(row)}: {found}; closest approach '
                 f'{closest} m')
  return lines


def markdown(rows: Sequence[Mapping[str, Any]],
             runs: Sequence[Mapping[str, Any]],
             not_evaluated: Union[Mapping[str, str], Sequence] = (),
             results: Sequence[Mapping[str, Any]] = (),
             notes: Optional[str] = None) -> str:
  """The table and its provenance as Markdown.

  Args:
    rows: rows of `evaluation_rows.summarise`.
    runs: the runs behind them, oldest first.
    not_evaluated: {task key: reason}.
    results: the episodes (to name the people's folders).
    notes: Markdown put under "Notes".

  Returns:
    The document.
  """
  latest = runs[-1]
  described = [f'Episodes: seeds 0..N-1 per row; shield and action '
               "space: the task's defaults unless the row says otherwise"]
  described += _policy_lines(rows)
  people_lines = _people_lines(results)
  lines = [
      f'# {rows_lib.title(rows)}', '',
      'Generated by `python -m hrc_suite.experts.evaluate` '
      '(hrc_suite/experts/evaluate.py); do not edit by hand.', '',
      *[_run_line(run) for run in runs],
      f'* Machine: {latest["machine"]["cpus"]} CPUs, '
      f'{latest["machine"]["processor"]}, {latest["machine"]["platform"]}, '
      f'Python {latest["machine"]["python"]}',
      f'* {"; ".join(described)}.',
      *([f'* People: {"; ".join(people_lines)}.'] if people_lines else []),
      '* Success: the goal reached at least once; CI: 95 % percentile '
      'bootstrap over episodes, 10^4 resamples, seed '
      f'{rows_lib.BOOTSTRAP_SEED}. '
      'Shield interventions: RL steps per episode in which the shield '
      'overrode the motion. Contacts: physics steps per episode with a '
      'contact of the type (self: RL steps ending self-colliding; human '
      'pushed: the person had pushed the robot off its command, '
      'docs/safety.md "Pushed robots"). Steps outside human model: RL '
      "steps per episode in which the person moved faster than the shield's "
      'human model (outside its guarantee). Human critical outside model: '
      'the physics steps of human critical contacts in those RL steps. '
      'Shield resyncs: physics steps '
      'per episode after which the shield restarted at the pushed '
      "robot's pose. Physics errors: the share of episodes a MuJoCo "
      'physics error ended (docs/safety.md "Physics errors"). '
      f'{MISSING}: not recorded (episodes run before the metric existed).',
      '', HEADER,
      '|' + '---|' * (HEADER.count('|') - 1),
  ]
  for row in rows:
    counts = ' | '.join(_cell(row[name]) for _, name in
                        rows_lib.CONTACT_COLUMNS + rows_lib.SAFETY_COLUMNS)
    lines.append(
        f'| {row["domain"]}/{row["task"]} | {row["robot"]} | '
        f'{row["policy"]} | {row["people"]} | {row["shield"]} | '
        f'{row["action_space"]} | {row["episodes"]} | '
        f'{row["success"]:.2f} [{row["success_low"]:.2f}, '
        f'{row["success_high"]:.2f}] | {row["return"]:.1f} | '
        f'{row["steps"]:.1f} | {row["seconds"]:.1f} | '
        f'{row["shield_interventions"]:.1f} | {counts} | '
        f'{row["wall_time"]:.1f} |')
  lines += ['', f'## Rows below the bar ({rows_lib.bar_text(rows)})', '']
  failing = [(row, rows_lib.below_bar(row)) for row in rows
             if rows_lib.below_bar(row)]
  for row, reasons in failing:
    lines.append(f'* BELOW THE BAR: {rows_lib.row_name(row)}: '
                 f'{"; ".join(reasons)}')
  if not failing:
    lines.append('* None: every row reaches the bar.')
  off = _shield_off_lines(rows)
  if off:
    lines += [
        '', '## Shield off: the check can fail', '',
        'Without the shield nothing slows the robot down near the person, '
        'so critical human contacts are expected: these rows show that the '
        'contact check reports them (they have no safety bar). Closest '
        "approach: the least distance of the robot's capsules at its "
        "command to the person's over the row's episodes (m; below 0: "
        'overlapping).', '', *off]
  if notes:
    lines += ['', '## Notes', '', notes.strip()]
  if not_evaluated:
    lines += ['', '## Not evaluated', '']
    for key, reason in sorted(dict(not_evaluated).items()):
      task, _, who = key.partition(' people=')
      name = f'{task} ({who} people)' if who else task
      lines.append(f'* {name}: {reason}')
  return '\n'.join(lines) + '\n'


def write(results: Sequence[Mapping[str, Any]],
          out: Union[str, os.PathLike], json_out: Union[str, os.PathLike],
          runs: Sequence[Mapping[str, Any]],
          not_evaluated: Union[Mapping[str, str], Sequence] = (),
          notes: Optional[str] = None) -> list[rows_lib.Row]:
  """Writes the Markdown table and the JSON results. The table is that of
  the episodes as stored (rounded: results_file), so that writing it
  again from the JSON gives the same table.

  Args:
    results: the episodes (`evaluation_episodes.run_job`).
    out: the Markdown file.
    json_out: the JSON file.
    runs: the runs behind the episodes, oldest first.
    not_evaluated: {task key (`evaluation_rows.task_key`): reason}.
    notes: Markdown put under "Notes".

  Returns:
    The rows (`evaluation_rows.summarise`).
  """
  results = results_file.unpack(results_file.pack(results))
  rows = rows_lib.summarise(results)
  not_evaluated = dict(sorted(dict(not_evaluated).items()))
  out, json_out = pathlib.Path(out), pathlib.Path(json_out)
  for path in (out, json_out):
    path.parent.mkdir(parents=True, exist_ok=True)
  out.write_text(markdown(rows, runs, not_evaluated, results, notes))
  payload = {'runs': runs, 'rows': [results_file.round_row(row)
                                    for row in rows],
             'episode_groups': results_file.pack(results),
             'not_evaluated': not_evaluated}
  if notes:
    payload['notes'] = notes
  json_out.write_text(results_file.dumps(payload) + '\n')
  return rows


def rewrite(out: Union[str, os.PathLike], json_out: Union[str, os.PathLike],
            notes: Optional[str] = None) -> list[rows_lib.Row]:
  """Writes the table of an existing results JSON again (and the JSON, in
  the current format) without running episodes.

  Args:
    out: the Markdown file.
    json_out: the existing JSON.
    notes: replace its notes if given.

  Returns:
    The rows (`evaluation_rows.summarise`).

  Raises:
    ValueError: no results file, or none of this command.
  """
  episodes, runs, not_evaluated, old_notes = load_results(json_out)
  if not runs:
    raise ValueError(f'{json_out}: no results to rewrite')
  return write(episodes, out, json_out, runs, not_evaluated,
               old_notes if notes is None else notes)
