r"""Baseline tables: experts, noisy experts and test policies per task.

  python -m hrc_suite.experts.evaluate --episodes=50 --robots=schunk,panda \
      --workers=2
  python -m hrc_suite.experts.evaluate \
      --pairs=schunk:expert,schunk:noisy_expert,panda:expert --workers=2
  python -m hrc_suite.experts.evaluate --policies=random --shield=default,off \
      --motions=DIR --motions_label=real --episodes=10 \
      --out=docs/results/safety_real.md
  python -m hrc_suite.experts.evaluate --policies=chase --action_spaces=joint \
      --shield=default,off --motions=DIR --motions_label=real --episodes=5 \
      --out=docs/results/safety_real.md --update

(DIR: a folder of recordings, e.g. the reference's human-robot-animations
folder as it is.)

Runs episodes with seeds 0..N-1 of each registered expert's task on each
robot and policy, or on the given robot:policy pairs, with each --shield
(the task's default unless given; action space: the task's default unless
given) and writes docs/results/experts.md (one row per task, robot,
policy, people and shield: success rate with a 95 % bootstrap confidence
interval, return, episode length, shield interventions, contacts by type,
steps outside the shield's human model, shield resyncs and physics errors
per episode, wall time) and the per-episode results, row by row
(hrc_suite/experts/results_file.py), as docs/results/experts.json.

People: the shipped synthetic library, or with --motions=DIR the task's
motions from DIR (task_kwargs['motions']; the reference's layout, one
sub-folder per task: hrc_suite/human/recording_cache.py), played with
outside_human_model='allow' (recordings may move faster than the shield's
human model; steps_outside_human_model counts those RL steps). Tasks
without motions in DIR are listed as not evaluated. Rows name their
people by --motions_label (default: DIR's name).

The bar (listed under "Rows below the bar"): an expert succeeds in at
least 80 % of its episodes; no policy has a critical human contact with
the shield on, which for the test policies is the whole bar: `random`
(uniform actions) and `chase` (the TCP driven at the person's nearest
keypoint at full speed, experts/adversary.py). Rows with
the shield off have no safety bar: their critical contacts show the check
can fail, and the table counts their episodes.

Finished episodes are logged to <json>.partial.jsonl as they come: a
killed run started again with the same flags skips them (the file is
removed once the table is written; delete it to start afresh).
With --update the episodes of the rows this run produces replace those
rows in the existing JSON (other rows stay), e.g. after a fix to one task:
the table then names every run (command, date, commit) and its rows.
--rewrite_only writes the table again from the JSON without running
episodes (after a change of the table's format).
Episode `seed` runs in an environment whose random_state is seeded `seed`;
the noisy expert uses the noise of episode `seed` of NoisyExpert(seed=0),
as a dataset collected with --seed=0 does; the random policy draws from
np.random.default_rng(seed); the chaser is deterministic. Experts whose
module does not import yet are listed as not evaluated.
"""

import datetime
import pathlib
import shlex
import sys
import time
from typing import Sequence

from absl import app
from absl import flags

from hrc_suite import experts
from hrc_suite import registry_flags
from hrc_suite import suite
from hrc_suite.experts import evaluation_episodes as episodes_lib
from hrc_suite.experts import evaluation_report as report_lib
from hrc_suite.experts import evaluation_rows as rows_lib
from hrc_suite.safety.shield import modes as modes_lib


def _parse_task(name):
  if name.count('/') != 1:
    raise ValueError(f'Tasks are domain/task, got {name!r}')
  return tuple(name.split('/'))


def define_flags(flag_values: flags.FlagValues = flags.FLAGS) -> None:
  """Defines the command's flags (only when run as a program, so that the
  module can be imported next to other binaries).

  Args:
    flag_values: where they are defined.
  """
  fv = flag_values
  flags.DEFINE_integer('episodes', 50, 'Episodes (seeds 0..N-1) per task, '
                       'robot, policy and shield.', lower_bound=1,
                       flag_values=fv)
  flags.DEFINE_list('robots', ['schunk', 'panda'], 'Robots.', flag_values=fv)
  flags.DEFINE_list('pairs', [], 'robot:policy pairs to run instead of '
                    '--robots x --policies, e.g. schunk:expert,'
                    'schunk:noisy_expert,panda:expert.', flag_values=fv)
  flags.DEFINE_list('tasks', [], 'domain/task names (default: every '
                    'registered expert).', flag_values=fv)
  flags.DEFINE_list('policies', list(episodes_lib.EXPERT_POLICIES),
                    f'Some of {", ".join(episodes_lib.POLICIES)}.',
                    flag_values=fv)
  flags.DEFINE_list('shield', [rows_lib.DEFAULT_SHIELD], 'Shield modes, each '
                    f'a row: {rows_lib.DEFAULT_SHIELD} (the task\'s own) or '
                    'registered modes (ssm, pfl, off, ...).', flag_values=fv)
  registry_flags.check_shield('shield', fv, extra=(rows_lib.DEFAULT_SHIELD,))
  registry_flags.check_robot('robots', fv)
  flags.DEFINE_string('motions', None, 'A folder of motions for every task '
                      "(task_kwargs['motions'], e.g. the reference's "
                      'human-robot-animations folder; played with '
                      "outside_human_model='allow'). Default: the shipped "
                      'synthetic library.', flag_values=fv)
  flags.DEFINE_string('motions_label', None, "The people column's name for "
                      "--motions (default: the folder's name).",
                      flag_values=fv)
  flags.DEFINE_list('action_spaces', [], 'cartesian and/or joint (default: '
                    "each task's default).", flag_values=fv)
  flags.DEFINE_float('time_limit', None, 'Episode length in s (default: '
                     "each task's horizon).", flag_values=fv)
  flags.DEFINE_integer('workers', 1, 'Parallel processes.', lower_bound=1,
                       flag_values=fv)
  flags.DEFINE_string('out', 'docs/results/experts.md', 'Markdown table '
                      '(relative to the current directory: run from the '
                      'repository root).', flag_values=fv)
  flags.DEFINE_string('json_out', None, 'Per-episode results (default: '
                      '--out with .json).', flag_values=fv)
  flags.DEFINE_bool('update', False, 'Replace only the rows this run '
                    'produces in the existing --json_out (and table); '
                    'other rows stay.', flag_values=fv)
  flags.DEFINE_bool('rewrite_only', False, 'Run nothing: write the table '
                    'of the existing --json_out again (and the JSON in the '
                    'current format).', flag_values=fv)
  flags.DEFINE_string('notes', None, 'A Markdown file whose text goes under '
                      '"Notes" (kept in the JSON; default: the notes '
                      'already there with --update or --rewrite_only).',
                      flag_values=fv)
  flags.DEFINE_bool('progress', True, 'Show a progress bar.', flag_values=fv)


def _print_below_bar(rows):
  for row in rows:
    for reason in rows_lib.below_bar(row):
      print(f'BELOW THE BAR: {rows_lib.row_name(row)}: {reason}')


def _policies(f):
  """(policies, [(robot, policy)] pairs) of the flags."""
  unknown = [p for p in f.policies if p not in episodes_lib.POLICIES]
  if unknown:
    raise app.UsageError(f'Unknown policies {unknown}: expected some of '
                         f'{", ".join(episodes_lib.POLICIES)}')
  pairs = []
  for pair in f.pairs:
    robot, _, policy = pair.partition(':')
    if policy not in episodes_lib.POLICIES or not robot:
      raise app.UsageError(
          f'--pairs entry {pair!r}: expected robot:policy with policy one '
          f'of {", ".join(episodes_lib.POLICIES)}')
    pairs.append((robot, policy))
  return ([policy for _, policy in pairs] if pairs else f.policies), pairs


def _tasks(f, policies, motions):
  """(tasks to run, {task key: reason} of those not evaluated)."""
  try:
    requested = [_parse_task(t) for t in f.tasks] or None
  except ValueError as e:
    raise app.UsageError(str(e)) from e
  need_expert = any(p in episodes_lib.EXPERT_POLICIES for p in policies)
  known = set(experts.registered() if need_expert else suite.all_tasks())
  for task in requested or ():
    if task not in known:
      valid = ', '.join(sorted('/'.join(t) for t in known))
      what = 'expert' if need_expert else 'task'
      raise app.UsageError(f'No {what} for {"/".join(task)}: {what}s exist '
                           f'for {valid}')
  if need_expert:
    tasks, missing = episodes_lib.available_tasks(requested)
  else:
    tasks, missing = tuple(requested or experts.registered()), {}
  if motions is not None:
    robot = f.pairs[0].partition(':')[0] if f.pairs else f.robots[0]
    tasks, no_motions = episodes_lib.tasks_with_motions(tasks, motions, robot)
    missing.update(no_motions)
  return tasks, {rows_lib.task_key(*task, motions): reason
                 for task, reason in missing.items()}


def _read_notes(path):
  if path is None:
    return None
  try:
    return pathlib.Path(path).read_text()
  except OSError as e:
    raise app.UsageError(f'--notes: {e}') from e


def main(argv: Sequence[str],
         flag_values: flags.FlagValues = flags.FLAGS) -> None:
  """The command (module doc).

  Args:
    argv: the command line (no positional arguments).
    flag_values: the flags of `define_flags`.

  Raises:
    app.UsageError: bad arguments.
  """
  f = flag_values
  if len(argv) > 1:
    raise app.UsageError(f'Unexpected arguments: {argv[1:]}')
  json_out = f.json_out or str(pathlib.Path(f.out).with_suffix('.json'))
  notes = _read_notes(f.notes)
  if f.rewrite_only:
    try:
      rows = report_lib.rewrite(f.out, json_out, notes)
    except ValueError as e:
      raise app.UsageError(str(e)) from e
    print(f'Wrote {f.out} ({len(rows)} rows) and {json_out} from '
          f'{json_out}')
    _print_below_bar(rows)
    return
  policies, pairs = _policies(f)
  if not f.shield:
    raise app.UsageError(f'--shield: expected some of '
                         f'{rows_lib.DEFAULT_SHIELD}, '
                         f'{", ".join(modes_lib.names())}')
  shields = [None if s == rows_lib.DEFAULT_SHIELD else s for s in f.shield]
  motions = None
  if f.motions is not None:
    folder = pathlib.Path(f.motions)
    if not folder.is_dir():
      raise app.UsageError(f'--motions {f.motions}: not a folder')
    motions = (f.motions_label or folder.resolve().name, f.motions)
  tasks, not_evaluated = _tasks(f, policies, motions)
  spaces = tuple(f.action_spaces) or (None,)
  job_list = episodes_lib.jobs(tasks, f.robots, f.policies, f.episodes,
                               spaces, f.time_limit, pairs, motions, shields)
  if not job_list:
    raise app.UsageError('Nothing to run: ' + '; '.join(
        f'{key}: {reason}' for key, reason in not_evaluated.items()))
  try:
    previous, runs, old_missing, old_notes = (
        report_lib.load_results(json_out) if f.update else ([], [], {}, None))
  except ValueError as e:
    raise app.UsageError(str(e)) from e
  partial = pathlib.Path(json_out + '.partial.jsonl')
  partial.parent.mkdir(parents=True, exist_ok=True)
  start = time.perf_counter()
  commit = report_lib.git_commit()   # The code this run loads.
  results = episodes_lib.run(job_list, workers=f.workers,
                             progress=f.progress, partial=partial)
  run_info = {
      'command': ' '.join(shlex.quote(a) for a in
                          ['python', '-m', 'hrc_suite.experts.evaluate']
                          + sys.argv[1:]),
      'date': datetime.datetime.now(datetime.timezone.utc).strftime(
          '%Y-%m-%d %H:%M UTC'),
      'machine': report_lib.machine(), 'workers': f.workers,
      'wall_time': time.perf_counter() - start, 'commit': commit,
      'rows': list(dict.fromkeys(rows_lib.row_key(r) for r in results)),
  }
  not_evaluated = report_lib.merge_not_evaluated(old_missing, not_evaluated,
                                                 results)
  results = report_lib.merge(previous, results)
  runs = report_lib.merge_runs(runs, run_info)
  rows = report_lib.write(results, f.out, json_out, runs, not_evaluated,
                          old_notes if notes is None else notes)
  partial.unlink()
  print(f'Wrote {f.out} ({len(rows)} rows) and {json_out}')
  _print_below_bar(rows)


if __name__ == '__main__':
  define_flags()
  app.run(main)
