r"""The expert baseline table: every expert (and noisy expert) per task.

  python -m hrc_suite.experts.evaluate --episodes=50 --robots=schunk,panda \
      --workers=2
  python -m hrc_suite.experts.evaluate \
      --pairs=schunk:expert,schunk:noisy_expert,panda:expert --workers=2

Runs episodes with seeds 0..N-1 of each registered expert's task on each
robot and policy, or on the given robot:policy pairs (shield and action
space: the task's defaults unless given) and writes docs/results/experts.md (one row per task, robot and
policy: success rate with a 95 % bootstrap confidence interval, return,
episode length, shield interventions and contacts by type per episode,
wall time) and the raw per-episode results as docs/results/experts.json.
Finished episodes are logged to <json>.partial.jsonl as they come: a
killed run started again with the same flags skips them (the file is
removed once the table is written; delete it to start afresh).
With --update the episodes of the rows this run produces replace those
rows in the existing JSON (other rows stay), e.g. after a fix to one task:
the table then names every run (command, date, commit) and its rows.
Episode `seed` runs in an environment whose random_state is seeded `seed`;
the noisy expert uses the noise of episode `seed` of NoisyExpert(seed=0),
as a dataset collected with --seed=0 does. Experts whose module does not
import yet are listed as not evaluated.
"""

import collections
import datetime
import json
import multiprocessing
import os
import pathlib
import platform
import shlex
import subprocess
import sys
import time

from absl import app
from absl import flags
import numpy as np

from hrc_suite import statistics
from hrc_suite import experts
from hrc_suite import suite
from hrc_suite.experts import noise as noise_lib
from hrc_suite.tasks import metrics as metrics_lib

POLICIES = ('expert', 'noisy_expert')
# The bar every expert must reach (issue 6): success in at least 80 % of
# the episodes of its task, with no critical human contact.
SUCCESS_BAR = 0.8
# Seed of every row's bootstrap resampling (rows are reproducible alone).
BOOTSTRAP_SEED = 0
# Per-episode metrics reported as means per episode, in table order.
CONTACT_COLUMNS = (('static', 'contacts_static'), ('self', 'self_collisions'),
                   ('human safe', 'contacts_human_allowed'),
                   ('human critical', 'contacts_human_critical'),
                   ('human pushed', 'contacts_human_pushed'))
_REPOSITORY = pathlib.Path(__file__).resolve().parents[2]


def _parse_task(name):
  if name.count('/') != 1:
    raise ValueError(f'Tasks are domain/task, got {name!r}')
  return tuple(name.split('/'))


def available_tasks(tasks=None):
  """(tasks whose expert imports, {task: error} of those that do not)."""
  tasks = experts.registered() if tasks is None else tuple(tasks)
  ok, missing = [], {}
  for task in tasks:
    try:
      experts.expert_class(*task)
    except ImportError as e:
      missing[task] = f'{type(e).__name__}: {e}'
    else:
      ok.append(task)
  return tuple(ok), missing


# ------------------------------------------------------------- episodes

_ENV_CACHE = {}   # job key -> (env, policy); one per process, the last.


def _environment(domain, task, robot, action_space, policy, time_limit):
  key = (domain, task, robot, action_space, policy, time_limit)
  if key not in _ENV_CACHE:
    _ENV_CACHE.clear()
    task_kwargs = {'robot': robot}
    if action_space is not None:
      task_kwargs['action_space'] = action_space
    if time_limit is not None:
      task_kwargs['time_limit'] = time_limit
    env = suite.load(domain, task, task_kwargs=task_kwargs,
                     environment_kwargs={'random_state': 0})
    noise = None
    if policy == 'noisy_expert':
      noise = noise_lib.OrnsteinUhlenbeckNoise.reference(
          env.action_spec().shape[0], env.task.action_space_name)
    _ENV_CACHE[key] = (env, experts.make(env, noise=noise))
  return _ENV_CACHE[key]


def _json_number(value):
  value = float(value)
  return value if np.isfinite(value) else None


def run_job(job):
  """One episode: job = (domain, task, robot, action_space, policy,
  time_limit, seed). Returns its result dict (JSON-able). An exception in
  the expert or the task does not stop the run: the episode's result then
  carries 'error' (the exception) and counts as a failure."""
  domain, task, robot, action_space, policy_name, time_limit, seed = job
  result = {'job': list(job), 'domain': domain, 'task': task, 'robot': robot,
            'action_space': action_space, 'shield': None,
            'policy': policy_name, 'seed': seed, 'control_timestep': None,
            'wall_time': 0.0, 'metrics': None, 'error': None}
  start = time.perf_counter()
  try:
    env, policy = _environment(domain, task, robot, action_space,
                               policy_name, time_limit)
    result.update(action_space=env.task.action_space_name,
                  shield=env.task.shield_mode,
                  control_timestep=env.task.control_timestep)
    env.random_state.seed(seed)
    if hasattr(policy, 'set_episode'):
      policy.set_episode(seed)
    start = time.perf_counter()
    episode = metrics_lib.run_episode(env, policy)
    result['metrics'] = {name: _json_number(value)
                         for name, value in episode.items()}
  except Exception as e:   # pylint: disable=broad-except
    _ENV_CACHE.clear()   # Its state is unknown now.
    result['error'] = f'{type(e).__name__}: {e}'
  result['wall_time'] = time.perf_counter() - start
  return result


def jobs(tasks, robots, policies, episodes, action_spaces=(None,),
         time_limit=None, pairs=None):
  """Every episode to run, grouped by environment: robots x policies, or
  the (robot, policy) `pairs` when given."""
  pairs = pairs or [(robot, policy) for robot in robots
                    for policy in policies]
  return [(domain, task, robot, space, policy, time_limit, seed)
          for domain, task in tasks for robot, policy in pairs
          for space in action_spaces for seed in range(episodes)]


def _job_key(job):
  return json.dumps(list(job))


def load_partial(path):
  """{job key: result} of the episodes a previous run logged to `path`
  (one JSON object per line; a torn last line is ignored)."""
  done = {}
  path = pathlib.Path(path)
  if not path.exists():
    return done
  for line in path.read_text().splitlines():
    try:
      result = json.loads(line)
    except json.JSONDecodeError:
      continue   # The line a killed run was writing.
    if isinstance(result, dict) and 'job' in result:
      done[_job_key(result['job'])] = result
  return done


def run(job_list, workers=1, progress=False, partial=None):
  """Results of `job_list`, in its order; workers > 1 runs them in spawned
  processes. With `partial` (a path), every finished episode is appended
  to it as a JSON line, and episodes already logged there are not run
  again (a killed run resumes)."""
  done = load_partial(partial) if partial is not None else {}
  results = [done.get(_job_key(job)) for job in job_list]
  todo = [(i, job) for i, job in enumerate(job_list) if results[i] is None]
  bar = None
  if progress:
    import tqdm   # pylint: disable=g-import-not-at-top
    bar = tqdm.tqdm(total=len(job_list), initial=len(job_list) - len(todo),
                    unit='episode')
  log = None
  if partial is not None:
    log = open(partial, 'a')   # pylint: disable=consider-using-with
    if log.tell() and not pathlib.Path(partial).read_text().endswith('\n'):
      log.write('\n')   # After a torn line.

  def finished(i, result):
    results[i] = result
    if log is not None:
      log.write(json.dumps(result) + '\n')
      log.flush()
    if bar is not None:
      bar.update(1)

  try:
    if workers <= 1:
      for item in todo:
        finished(*_run_indexed(item))
    else:
      context = multiprocessing.get_context('spawn')
      with context.Pool(workers) as pool:
        for i, result in pool.imap_unordered(_run_indexed, todo):
          finished(i, result)
  finally:
    for handle in (bar, log):
      if handle is not None:
        handle.close()
  return results


def _run_indexed(item):
  index, job = item
  return index, run_job(job)


# ---------------------------------------------------------------- summary


def success_ci(successes, seed=BOOTSTRAP_SEED):
  """(rate, low, high): mean and 95 % percentile-bootstrap CI (10^4
  resamples, seeded) of 0/1 outcomes."""
  return statistics.bootstrap_ci(np.asarray(successes, dtype=float),
                                 np.random.RandomState(seed))


def _mean(results, name):
  values = [r['metrics'].get(name) for r in results if r['metrics']]
  values = [v for v in values if v is not None]
  return float(np.mean(values)) if values else float('nan')


def summarise(results):
  """One row per (task, robot, action space, policy), in first-seen order."""
  groups = collections.OrderedDict()
  for result in results:
    key = (result['domain'], result['task'], result['robot'],
           result['action_space'], result['policy'])
    groups.setdefault(key, []).append(result)
  rows = []
  for (domain, task, robot, space, policy), group in groups.items():
    done = [r for r in group if r['metrics']]
    errors = [r for r in group if not r['metrics']]
    # An episode that raised counts as a failure.
    success = [r['metrics']['success'] if r['metrics'] else 0.0
               for r in group]
    rate, low, high = success_ci(success)
    steps = _mean(group, 'steps')
    timestep = next((r['control_timestep'] for r in done), float('nan'))
    row = {
        'domain': domain, 'task': task, 'robot': robot,
        'action_space': space, 'policy': policy,
        'shield': done[0]['shield'] if done else None,
        'episodes': len(group), 'errors': len(errors),
        'first_error': errors[0]['error'] if errors else None,
        'success': rate, 'success_low': low, 'success_high': high,
        'return': _mean(group, 'return'), 'steps': steps,
        'seconds': steps * timestep,
        'shield_interventions': _mean(group, 'shield_interventions'),
        'critical_episodes': sum(
            1 for r in done if r['metrics']['contacts_human_critical']),
        'wall_time': float(np.mean([r['wall_time'] for r in group])),
    }
    for _, name in CONTACT_COLUMNS:
      row[name] = _mean(group, name)
    rows.append(row)
  return rows


def below_bar(row):
  """Reasons a row misses the bar (empty if it passes)."""
  reasons = []
  if row['success'] < SUCCESS_BAR:
    reasons.append(f'success {row["success"]:.2f} < {SUCCESS_BAR:.2f}')
  if row['critical_episodes']:
    reasons.append(f'critical human contacts in {row["critical_episodes"]} '
                   f'of {row["episodes"]} episodes')
  if row['errors']:
    reasons.append(f'{row["errors"]} episodes raised ({row["first_error"]})')
  return reasons


def _cpu_model():
  try:
    with open('/proc/cpuinfo') as f:
      for line in f:
        if line.startswith('model name'):
          return line.split(':', 1)[1].strip()
  except OSError:
    pass
  return platform.processor() or platform.machine()


def machine():
  """A short description of the machine."""
  return {'cpus': os.cpu_count(), 'platform': platform.platform(),
          'processor': _cpu_model(), 'python': platform.python_version()}


def _git_commit():
  try:
    out = subprocess.run(['git', 'rev-parse', '--short', 'HEAD'],
                         cwd=_REPOSITORY, capture_output=True, text=True,
                         timeout=10, check=True)
  except (OSError, subprocess.SubprocessError):
    return None
  return out.stdout.strip() or None


HEADER = ('| task | robot | policy | action space | episodes | success '
          '[95 % CI] | return | length (steps) | length (s) | shield '
          'interventions | ' + ' | '.join(f'contacts {label}' for label, _ in
                                          CONTACT_COLUMNS)
          + ' | wall time / episode (s) |')


def row_key(result):
  """The table row an episode belongs to: 'domain/task robot policy
  action_space' (job's action space: None = the task's default)."""
  domain, task, robot, space, policy = result['job'][:5]
  return f'{domain}/{task} {robot} {policy} {space or "default"}'


def merge(old, new):
  """`old` episodes with the rows `new` re-ran replaced in place (rows
  only in `new` at the end)."""
  fresh = collections.OrderedDict()
  for result in new:
    fresh.setdefault(row_key(result), []).append(result)
  merged, placed = [], set()
  for result in old:
    key = row_key(result)
    if key not in fresh:
      merged.append(result)
    elif key not in placed:
      merged.extend(fresh[key])
      placed.add(key)
  for key, results in fresh.items():
    if key not in placed:
      merged.extend(results)
  return merged


def merge_runs(old_runs, run):
  """The runs behind a merged table: `run` (with its 'rows') last, older
  runs keeping only the rows it did not redo (runs left without rows
  dropped)."""
  redone = set(run['rows'])
  kept = []
  for old in old_runs:
    rows = [key for key in old['rows'] if key not in redone]
    if rows:
      kept.append(dict(old, rows=rows))
  return kept + [run]


def load_previous(path):
  """(episodes, runs) of an existing results JSON, ([], []) if none. A
  file written before runs were recorded (one 'info') counts as one run
  of all its rows."""
  path = pathlib.Path(path)
  if not path.exists():
    return [], []
  try:
    payload = json.loads(path.read_text())
    episodes = payload['episodes']
    runs = payload.get('runs')
    if runs is None:
      rows = list(dict.fromkeys(row_key(e) for e in episodes))
      runs = [dict(payload['info'], rows=rows)]
  except (ValueError, KeyError, TypeError) as e:
    raise ValueError(f'{path}: not a results file of this command ({e}); '
                     'run without --update to write it afresh') from e
  return episodes, runs


def _run_line(run):
  tasks = ', '.join(dict.fromkeys(key.split()[0] for key in run['rows']))
  return (f'* Command: `{run["command"]}` ({run["date"]}, commit '
          f'{run["commit"] or "unknown"}, {run["workers"]} worker '
          f'process(es), wall time {run["wall_time"]:.0f} s): '
          f'{len(run["rows"])} rows of {tasks}')


def markdown(rows, runs, not_evaluated=()):
  """The table and its provenance (`runs`, oldest first) as Markdown."""
  latest = runs[-1]
  lines = [
      '# Expert baseline', '',
      'Generated by `python -m hrc_suite.experts.evaluate` '
      '(hrc_suite/experts/evaluate.py); do not edit by hand.', '',
      *[_run_line(run) for run in runs],
      f'* Machine: {latest["machine"]["cpus"]} CPUs, '
      f'{latest["machine"]["processor"]}, {latest["machine"]["platform"]}, '
      f'Python {latest["machine"]["python"]}',
      f'* Episodes: seeds 0..N-1 per row; shield and action space: '
      "the task's defaults unless the row says otherwise; noisy expert: "
      'reference Ornstein-Uhlenbeck noise (hrc_suite/experts/noise.py).',
      '* Success: the goal reached at least once; CI: 95 % percentile '
      f'bootstrap over episodes, 10^4 resamples, seed {BOOTSTRAP_SEED}. '
      'Shield interventions: RL steps per episode in which the shield '
      'overrode the motion. Contacts: physics steps per episode with a '
      'contact of the type (self: RL steps ending self-colliding).',
      '', HEADER,
      '|' + '---|' * (HEADER.count('|') - 1),
  ]
  for row in rows:
    contacts = ' | '.join(f'{row[name]:.2f}' for _, name in CONTACT_COLUMNS)
    lines.append(
        f'| {row["domain"]}/{row["task"]} | {row["robot"]} | '
        f'{row["policy"]} | {row["action_space"]} | {row["episodes"]} | '
        f'{row["success"]:.2f} [{row["success_low"]:.2f}, '
        f'{row["success_high"]:.2f}] | {row["return"]:.1f} | '
        f'{row["steps"]:.1f} | {row["seconds"]:.1f} | '
        f'{row["shield_interventions"]:.1f} | {contacts} | '
        f'{row["wall_time"]:.1f} |')
  lines += ['', f'## Rows below the bar (success >= {SUCCESS_BAR:.0%}, no '
            'critical human contact)', '']
  failing = [(row, below_bar(row)) for row in rows if below_bar(row)]
  for row, reasons in failing:
    lines.append(f'* BELOW THE BAR: {row["domain"]}/{row["task"]} '
                 f'{row["robot"]} {row["policy"]}: {"; ".join(reasons)}')
  if not failing:
    lines.append('* None: every row reaches the bar.')
  if not_evaluated:
    lines += ['', '## Not evaluated', '']
    lines += [f'* {domain}/{task}: {error}'
              for (domain, task), error in sorted(not_evaluated.items())]
  return '\n'.join(lines) + '\n'


def write(results, out, json_out, runs, not_evaluated=()):
  """Writes the Markdown table and the JSON results; returns the rows."""
  rows = summarise(results)
  out, json_out = pathlib.Path(out), pathlib.Path(json_out)
  for path in (out, json_out):
    path.parent.mkdir(parents=True, exist_ok=True)
  out.write_text(markdown(rows, runs, not_evaluated))
  finite = [{k: _json_number(v) if isinstance(v, float) else v
             for k, v in row.items()} for row in rows]
  payload = {'runs': runs, 'rows': finite, 'episodes': results,
             'not_evaluated': {f'{d}/{t}': error for (d, t), error in
                               sorted(dict(not_evaluated).items())}}
  json_out.write_text(json.dumps(payload, indent=1, allow_nan=False) + '\n')
  return rows


# -------------------------------------------------------------------- main

def define_flags(flag_values=flags.FLAGS):
  """Defines the command's flags (only when run as a program, so that the
  module can be imported next to other binaries)."""
  fv = flag_values
  flags.DEFINE_integer('episodes', 50, 'Episodes (seeds 0..N-1) per task, '
                       'robot and policy.', lower_bound=1, flag_values=fv)
  flags.DEFINE_list('robots', ['schunk', 'panda'], 'Robots.', flag_values=fv)
  flags.DEFINE_list('pairs', [], 'robot:policy pairs to run instead of '
                    '--robots x --policies, e.g. schunk:expert,'
                    'schunk:noisy_expert,panda:expert.', flag_values=fv)
  flags.DEFINE_list('tasks', [], 'domain/task names (default: every '
                    'registered expert).', flag_values=fv)
  flags.DEFINE_list('policies', list(POLICIES),
                    'expert and/or noisy_expert.', flag_values=fv)
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
  flags.DEFINE_bool('progress', True, 'Show a progress bar.', flag_values=fv)


def main(argv, flag_values=flags.FLAGS):
  f = flag_values
  if len(argv) > 1:
    raise app.UsageError(f'Unexpected arguments: {argv[1:]}')
  unknown = [p for p in f.policies if p not in POLICIES]
  if unknown:
    raise app.UsageError(f'Unknown policies {unknown}: expected some of '
                         f'{", ".join(POLICIES)}')
  try:
    requested = [_parse_task(t) for t in f.tasks] or None
  except ValueError as e:
    raise app.UsageError(str(e)) from e
  registered = set(experts.registered())
  for task in requested or ():
    if task not in registered:
      valid = ', '.join(sorted('/'.join(t) for t in registered))
      raise app.UsageError(f'No expert for {"/".join(task)}: experts exist '
                           f'for {valid}')
  tasks, not_evaluated = available_tasks(requested)
  spaces = tuple(f.action_spaces) or (None,)
  pairs = []
  for pair in f.pairs:
    robot, _, policy = pair.partition(':')
    if policy not in POLICIES or not robot:
      raise app.UsageError(f'--pairs entry {pair!r}: expected robot:policy '
                           f'with policy one of {", ".join(POLICIES)}')
    pairs.append((robot, policy))
  job_list = jobs(tasks, f.robots, f.policies, f.episodes,
                  spaces, f.time_limit, pairs)
  json_out = f.json_out or str(pathlib.Path(f.out).with_suffix(
      '.json'))
  try:
    previous, runs = (load_previous(json_out) if f.update else ([], []))
  except ValueError as e:
    raise app.UsageError(str(e)) from e
  partial = pathlib.Path(json_out + '.partial.jsonl')
  partial.parent.mkdir(parents=True, exist_ok=True)
  start = time.perf_counter()
  results = run(job_list, workers=f.workers, progress=f.progress,
                partial=partial)
  run_info = {
      'command': ' '.join(shlex.quote(a) for a in
                          ['python', '-m', 'hrc_suite.experts.evaluate']
                          + sys.argv[1:]),
      'date': datetime.datetime.now(datetime.timezone.utc).strftime(
          '%Y-%m-%d %H:%M UTC'),
      'machine': machine(), 'workers': f.workers,
      'wall_time': time.perf_counter() - start, 'commit': _git_commit(),
      'rows': list(dict.fromkeys(row_key(r) for r in results)),
  }
  results = merge(previous, results)
  runs = merge_runs(runs, run_info)
  rows = write(results, f.out, json_out, runs, not_evaluated)
  partial.unlink()
  print(f'Wrote {f.out} ({len(rows)} rows) and {json_out}')
  for row in rows:
    for reason in below_bar(row):
      print(f'BELOW THE BAR: {row["domain"]}/{row["task"]} {row["robot"]} '
            f'{row["policy"]}: {reason}')


if __name__ == '__main__':
  define_flags()
  app.run(main)
