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
import traceback
from typing import Any, Iterable, Mapping, Optional, Sequence, Union

from absl import app
from absl import flags
import dm_env
from dm_env import specs
import numpy as np

from hrc_suite import statistics
from hrc_suite import experts
from hrc_suite import suite
from hrc_suite.experts import adversary
from hrc_suite.experts import noise as noise_lib
from hrc_suite.experts import pace
from hrc_suite.experts import results_file
from hrc_suite.human import clip as clip_lib
from hrc_suite import registry_flags
from hrc_suite.safety.shield import modes as modes_lib
from hrc_suite.tasks.runtime import metrics as metrics_lib
from hrc_suite.tasks.runtime import motions as task_motions

EXPERT_POLICIES = ('expert', 'noisy_expert')
TEST_POLICIES = ('random', 'chase')   # Safety checks, no success bar.
POLICIES = EXPERT_POLICIES + TEST_POLICIES
# --shield values: the task's default (DEFAULT_SHIELD) or a registered
# shield mode (hrc_suite/safety/shield/modes.py).
DEFAULT_SHIELD = 'default'
# The people of rows run without --motions: the shipped library.
SYNTHETIC = 'synthetic'
# The bar every expert must reach: success in at least 80 % of
# the episodes of its task, with no critical human contact.
SUCCESS_BAR = 0.8
# Seed of every row's bootstrap resampling (rows are reproducible alone).
BOOTSTRAP_SEED = 0
# Per-episode metrics reported as means per episode, in table order
# (hrc_suite/tasks/runtime/metrics.py).
CONTACT_COLUMNS = (('static', 'contacts_static'), ('self', 'self_collisions'),
                   ('human safe', 'contacts_human_allowed'),
                   ('human critical', 'contacts_human_critical'),
                   ('human pushed', 'contacts_human_pushed'))
SAFETY_COLUMNS = (('steps outside human model', 'steps_outside_human_model'),
                  ('shield resyncs', 'shield_resyncs'),
                  ('physics errors', 'physics_errors'))
# Innermost frames of an episode's exception kept in its result.
TRACEBACK_FRAMES = 8
# A mean of a metric no episode of the row recorded (run before it existed).
MISSING = '—'
_REPOSITORY = pathlib.Path(__file__).resolve().parents[2]

# An episode to run: (domain, task, robot, action_space, policy, time_limit,
# seed, motions, shield) (`job_fields`), a list once stored in JSON.
Job = Sequence[Any]
# An episode's result (`run_job`) and a table row (`summarise`), JSON-able.
Result = dict[str, Any]
Row = dict[str, Any]
# People: (label, folder) of recorded motions, None for the shipped library.
Motions = Optional[Sequence[str]]


def _parse_task(name):
  if name.count('/') != 1:
    raise ValueError(f'Tasks are domain/task, got {name!r}')
  return tuple(name.split('/'))


def available_tasks(
    tasks: Optional[Iterable[tuple[str, str]]] = None
) -> tuple[tuple[tuple[str, str], ...], dict[tuple[str, str], str]]:
  """The tasks whose expert imports.

  Args:
    tasks: (domain, task) pairs; None: every registered expert's.

  Returns:
    (tasks whose expert imports, {task: error} of those that do not).
  """
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


def _people_kwargs(motions):
  """task_kwargs of people `motions` ((label, folder) or None)."""
  return task_motions.recorded_people_kwargs(
      None if motions is None else motions[1])


def tasks_with_motions(
    tasks: Iterable[tuple[str, str]], motions: Motions, robot: str
) -> tuple[tuple[tuple[str, str], ...], dict[tuple[str, str], str]]:
  """The tasks that build with the given people. Building each task once
  also converts its recordings into the cache before workers start.

  Args:
    tasks: (domain, task) pairs.
    motions: the people, (label, folder), or None.
    robot: the robot the tasks are built with.

  Returns:
    (tasks that build, {task: reason} of those that do not, e.g. no
    sub-folder of theirs in the folder).
  """
  ok, missing = [], {}
  for domain, task in tasks:
    try:
      suite.build_task(domain, task, dict(_people_kwargs(motions),
                                          robot=robot))
    except clip_lib.ClipError as e:
      missing[(domain, task)] = f'skipped: {type(e).__name__}: {e}'
    else:
      ok.append((domain, task))
  return tuple(ok), missing


# ------------------------------------------------------------- policies


class RandomPolicy:
  """Uniform actions in the action spec's bounds. Episode `seed` draws from
  its own generator, np.random.default_rng(seed) (`set_episode`), never
  from numpy's global state.

  Args:
    action_spec: the environment's action spec (finite bounds).

  Raises:
    ValueError: a bound that is not finite.
  """

  def __init__(self, action_spec: specs.BoundedArray):
    low = np.broadcast_to(action_spec.minimum, action_spec.shape)
    high = np.broadcast_to(action_spec.maximum, action_spec.shape)
    if not (np.all(np.isfinite(low)) and np.all(np.isfinite(high))):
      raise ValueError(f'{action_spec}: a uniform action needs finite '
                       'bounds')
    self._low, self._high = low.astype(float), high.astype(float)
    self._dtype = action_spec.dtype
    self._rng = None
    self.set_episode(0)

  def set_episode(self, seed: int) -> None:
    """Starts episode `seed`'s draws.

    Args:
      seed: the episode's seed.
    """
    self._rng = np.random.default_rng(seed)

  def __call__(self, timestep: dm_env.TimeStep) -> np.ndarray:
    """A uniform action (the timestep is not read).

    Args:
      timestep: the environment's current timestep.

    Returns:
      The action, of the spec's shape and dtype.
    """
    del timestep
    return self._rng.uniform(self._low, self._high).astype(self._dtype)


# ------------------------------------------------------------- episodes

_ENV_CACHE = {}   # job key -> (env, policy); one per process, the last.


def _environment(domain, task, robot, action_space, policy, time_limit,
                 motions=None, shield=None):
  motions = None if motions is None else tuple(motions)
  key = (domain, task, robot, action_space, policy, time_limit, motions,
         shield)
  if key not in _ENV_CACHE:
    _ENV_CACHE.clear()
    task_kwargs = dict(_people_kwargs(motions), robot=robot)
    if action_space is not None:
      task_kwargs['action_space'] = action_space
    if time_limit is not None:
      task_kwargs['time_limit'] = time_limit
    if shield is not None:
      task_kwargs['shield'] = shield
    env = suite.load(domain, task, task_kwargs=task_kwargs,
                     environment_kwargs={'random_state': 0})
    if policy == 'random':
      agent = RandomPolicy(env.action_spec())
    elif policy == 'chase':
      agent = adversary.PersonChaser(env)
    else:
      noise = None
      if policy == 'noisy_expert':
        noise = noise_lib.OrnsteinUhlenbeckNoise.reference(
            env.action_spec().shape[0], env.task.action_space_name)
      agent = experts.make(env, noise=noise)
    _ENV_CACHE[key] = (env, agent)
  return _ENV_CACHE[key]


class _ClipObserver(pace.PaceObserver):
  """Episode metrics (with experts/pace.py's) and the name of the clip the
  episode starts with."""

  clip = None

  def observe_first(self, env, timestep):
    super().observe_first(env, timestep)
    self.clip = env.task.player.clip.name


def _json_number(value):
  value = float(value)
  return value if np.isfinite(value) else None


def job_fields(job: Job) -> tuple[Any, ...]:
  """The fields of a job.

  Args:
    job: a job; jobs of files written before people and shields were
      choices lack the last two fields.

  Returns:
    (domain, task, robot, action_space, policy, time_limit, seed, motions,
    shield), missing ones None (synthetic people, default shield).
  """
  job = list(job)
  return tuple(job + [None] * (9 - len(job)))


def people(result: Mapping[str, Any]) -> str:
  """The label of an episode's people.

  Args:
    result: the episode's result (`run_job`).

  Returns:
    SYNTHETIC or the motions' label (--motions_label).
  """
  motions = job_fields(result.get('job', ()))[7]
  return SYNTHETIC if motions is None else motions[0]


def run_job(job: Job) -> Result:
  """One episode. An exception in the policy or the task does not stop
  the run: the episode's result then carries 'error' (the exception) and
  'traceback' (its innermost frames) and counts as a failure.

  Args:
    job: (domain, task, robot, action_space, policy, time_limit, seed,
      motions, shield); motions: None (the shipped library) or (label,
      folder); shield: None (the task's default) or a mode.

  Returns:
    Its result (JSON-able; 'metrics' the episode metrics, None if it
    raised; 'clip' names the person's first clip).
  """
  (domain, task, robot, action_space, policy_name, time_limit, seed,
   motions, shield) = job_fields(job)
  result = {'job': list(job), 'domain': domain, 'task': task, 'robot': robot,
            'action_space': action_space, 'shield': None,
            'policy': policy_name, 'seed': seed, 'control_timestep': None,
            'wall_time': 0.0, 'metrics': None, 'error': None}
  result['people'] = people(result)
  start = time.perf_counter()
  try:
    env, policy = _environment(domain, task, robot, action_space,
                               policy_name, time_limit, motions, shield)
    result.update(action_space=env.task.action_space_name,
                  shield=env.task.shield_mode,
                  control_timestep=env.task.control_timestep)
    env.random_state.seed(seed)
    if hasattr(policy, 'set_episode'):
      policy.set_episode(seed)
    start = time.perf_counter()
    observer = _ClipObserver()
    episode = metrics_lib.run_episode(env, policy, observer)
    result['clip'] = observer.clip
    result['metrics'] = {name: _json_number(value)
                         for name, value in episode.items()}
  except Exception as e:   # pylint: disable=broad-except
    _ENV_CACHE.clear()   # Its state is unknown now.
    result['error'] = f'{type(e).__name__}: {e}'
    result['traceback'] = traceback.format_exc(limit=-TRACEBACK_FRAMES)
  result['wall_time'] = time.perf_counter() - start
  return result


def jobs(tasks: Iterable[tuple[str, str]], robots: Sequence[str],
         policies: Sequence[str], episodes: int,
         action_spaces: Sequence[Optional[str]] = (None,),
         time_limit: Optional[float] = None,
         pairs: Optional[Sequence[tuple[str, str]]] = None,
         motions: Motions = None,
         shields: Sequence[Optional[str]] = (None,)) -> list[tuple]:
  """Every episode to run, grouped by environment.

  Args:
    tasks: (domain, task) pairs.
    robots: robot names (with `policies`, unless `pairs`).
    policies: policy names (POLICIES).
    episodes: episodes (seeds 0..episodes-1) per combination.
    action_spaces: action spaces (None: the task's default).
    time_limit: episode length in s (None: the task's horizon).
    pairs: (robot, policy) pairs run instead of robots x policies.
    motions: the people, (label, folder), or None.
    shields: shield modes (None: the task's default).

  Returns:
    The jobs: tasks x pairs x shields x action spaces x seeds.
  """
  pairs = pairs or [(robot, policy) for robot in robots
                    for policy in policies]
  motions = None if motions is None else list(motions)
  return [(domain, task, robot, space, policy, time_limit, seed, motions,
           shield)
          for domain, task in tasks for robot, policy in pairs
          for shield in shields for space in action_spaces
          for seed in range(episodes)]


def _job_key(job):
  return json.dumps(list(job))


def load_partial(path: Union[str, os.PathLike]) -> dict[str, Result]:
  """The episodes a previous run logged.

  Args:
    path: the log, one JSON object per line (a torn last line is
      ignored); it need not exist.

  Returns:
    {job key (the job as JSON): result}.
  """
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


def run(job_list: Sequence[Job], workers: int = 1, progress: bool = False,
        partial: Optional[Union[str, os.PathLike]] = None) -> list[Result]:
  """Runs episodes (`run_job`).

  Args:
    job_list: the jobs.
    workers: processes; more than 1 runs the jobs in spawned processes.
    progress: show a tqdm progress bar.
    partial: a path or None; every finished episode is appended to it as
      a JSON line, and episodes already logged there are not run again
      (a killed run resumes).

  Returns:
    The results, in the jobs' order.
  """
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


def success_ci(successes: Sequence[float],
               seed: int = BOOTSTRAP_SEED) -> tuple[float, float, float]:
  """The success rate and its 95 % percentile-bootstrap CI (10^4
  resamples, seeded).

  Args:
    successes: 0/1 outcomes.
    seed: the resampling's seed.

  Returns:
    (rate, low, high).
  """
  return statistics.bootstrap_ci(np.asarray(successes, dtype=float),
                                 np.random.RandomState(seed))


def _values(results, name):
  values = [r['metrics'].get(name) for r in results if r['metrics']]
  return [v for v in values if v is not None]


def _mean(results, name):
  values = _values(results, name)
  return float(np.mean(values)) if values else float('nan')


def _episodes_with(results, name):
  """How many episodes have a nonzero `name`; None if none recorded it."""
  values = _values(results, name)
  return sum(1 for v in values if v) if values else None


def summarise(results: Sequence[Mapping[str, Any]]) -> list[Row]:
  """The table's rows.

  Args:
    results: episode results (`run_job`).

  Returns:
    One row per (task, robot, action space, policy, people, shield), in
    first-seen order.
  """
  groups = collections.OrderedDict()
  for result in results:
    choice = job_fields(result.get('job', ()))[8]
    key = (result['domain'], result['task'], result['robot'],
           result['action_space'], result['policy'], people(result), choice)
    groups.setdefault(key, []).append(result)
  rows = []
  for (domain, task, robot, space, policy, who, choice), group in (
      groups.items()):
    done = [r for r in group if r['metrics']]
    errors = [r for r in group if not r['metrics']]
    # An episode that raised counts as a failure.
    success = [r['metrics']['success'] if r['metrics'] else 0.0
               for r in group]
    rate, low, high = success_ci(success)
    steps = _mean(group, 'steps')
    timestep = next((r['control_timestep'] for r in done), float('nan'))
    distances = _values(group, 'min_human_distance')
    row = {
        'domain': domain, 'task': task, 'robot': robot,
        'action_space': space, 'policy': policy, 'people': who,
        'shield': done[0]['shield'] if done else choice,
        'shield_choice': choice or DEFAULT_SHIELD,
        'episodes': len(group), 'errors': len(errors),
        'first_error': errors[0]['error'] if errors else None,
        'success': rate, 'success_low': low, 'success_high': high,
        'return': _mean(group, 'return'), 'steps': steps,
        'seconds': steps * timestep,
        'shield_interventions': _mean(group, 'shield_interventions'),
        'critical_episodes': sum(
            1 for r in done if r['metrics']['contacts_human_critical']),
        'pushed_episodes': _episodes_with(group, 'contacts_human_pushed'),
        'physics_error_episodes': _episodes_with(group, 'physics_errors'),
        # m, robot capsules at the command to the person's, over episodes.
        'min_human_distance': min(distances) if distances else float('nan'),
        'wall_time': float(np.mean([r['wall_time'] for r in group])),
    }
    for _, name in CONTACT_COLUMNS + SAFETY_COLUMNS:
      row[name] = _mean(group, name)
    rows.append(row)
  return rows


def _gates(shield):
  """Whether the row's shield mode decides the robot's motion (not 'off';
  None, a row whose episodes raised before reporting it, counts as on)."""
  return shield is None or modes_lib.get(shield).gates


def below_bar(row: Mapping[str, Any]) -> list[str]:
  """Reasons a row misses the bar: experts must succeed (SUCCESS_BAR);
  with the shield on no policy may touch the person critically; no
  episode may raise.

  Args:
    row: a row of `summarise`.

  Returns:
    The reasons, empty if it passes.
  """
  reasons = []
  if row['policy'] in EXPERT_POLICIES and row['success'] < SUCCESS_BAR:
    reasons.append(f'success {row["success"]:.2f} < {SUCCESS_BAR:.2f}')
  if _gates(row['shield']) and row['critical_episodes']:
    reasons.append(f'critical human contacts in {row["critical_episodes"]} '
                   f'of {row["episodes"]} episodes')
  if row['errors']:
    reasons.append(f'{row["errors"]} episodes raised ({row["first_error"]})')
  return reasons


def bar_text(rows: Iterable[Mapping[str, Any]]) -> str:
  """The bar of the rows' policies, in words.

  Args:
    rows: rows of `summarise`.

  Returns:
    The text.
  """
  policies = {row['policy'] for row in rows}
  parts = []
  if policies & set(EXPERT_POLICIES):
    parts.append(f'experts: success >= {SUCCESS_BAR:.0%} and no critical '
                  'human contact with the shield on')
  tests = sorted(policies & set(TEST_POLICIES))
  if tests:
    parts.append(f'{" and ".join(tests)} policy: zero critical human '
                 'contacts with the shield on')
  return '; '.join(parts)


def title(rows: Sequence[Mapping[str, Any]]) -> str:
  """The table's title: its policies and, if not synthetic, its people.

  Args:
    rows: the table's rows.

  Returns:
    The title.
  """
  policies = {row['policy'] for row in rows}
  if policies <= set(EXPERT_POLICIES):
    text = 'Expert baseline'
  elif policies <= set(TEST_POLICIES):
    text = 'Test-policy safety check'
  else:
    text = 'Expert baseline and test-policy safety check'
  who = list(dict.fromkeys(row['people'] for row in rows))
  if who and who != [SYNTHETIC]:
    text += f' (people: {", ".join(who)})'
  return text


def row_name(row: Mapping[str, Any]) -> str:
  """A row's name in the text.

  Args:
    row: a row of `summarise`.

  Returns:
    'domain/task robot policy', with its people and shield unless they
    are the synthetic library and the task's default.
  """
  name = f'{row["domain"]}/{row["task"]} {row["robot"]} {row["policy"]}'
  if row['people'] != SYNTHETIC or row['shield_choice'] != DEFAULT_SHIELD:
    name += f' ({row["people"]} people, shield {row["shield"]})'
  return name


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


def _git_commit():
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
          + ' | '.join(f'contacts {label}' for label, _ in CONTACT_COLUMNS)
          + ' | ' + ' | '.join(label for label, _ in SAFETY_COLUMNS)
          + ' | wall time / episode (s) |')


def row_key(result: Mapping[str, Any]) -> str:
  """The table row an episode belongs to.

  Args:
    result: the episode's result (`run_job`).

  Returns:
    'domain/task robot policy action_space' (the job's action space:
    'default' for the task's default), then ' people=<label>' unless
    synthetic and ' shield=<mode>' if chosen.
  """
  domain, task, robot, space, policy, _, _, motions, shield = job_fields(
      result['job'])
  key = f'{domain}/{task} {robot} {policy} {space or "default"}'
  if motions is not None:
    key += f' people={motions[0]}'
  if shield is not None:
    key += f' shield={shield}'
  return key


def task_key(domain: str, task: str, motions: Motions = None) -> str:
  """The key of a task not evaluated.

  Args:
    domain: the task's domain.
    task: the task.
    motions: the people, (label, folder), or None.

  Returns:
    'domain/task', then ' people=<label>' with motions.
  """
  key = f'{domain}/{task}'
  return key if motions is None else f'{key} people={motions[0]}'


def merge(old: Sequence[Result], new: Sequence[Result]) -> list[Result]:
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
  done = {task_key(r['domain'], r['task'], job_fields(r['job'])[7])
          for r in results}
  merged = {key: reason for key, reason in old.items() if key not in done}
  merged.update(new)
  return dict(sorted(merged.items()))


def load_previous(path: Union[str, os.PathLike]
                  ) -> tuple[list[Result], list[dict[str, Any]]]:
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
) -> tuple[list[Result], list[dict[str, Any]], dict[str, str],
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
      rows = list(dict.fromkeys(row_key(e) for e in episodes))
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
    motions = job_fields(result.get('job', ()))[7]
    if motions is not None:
      folders.setdefault(motions[0], motions[1])
  lines = []
  if any(people(r) == SYNTHETIC for r in results):
    lines.append(f'{SYNTHETIC}: the shipped motion library')
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
    if _gates(row['shield']):
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
    lines.append(f'* {row_name(row)}: {found}; closest approach '
                 f'{closest} m')
  return lines


def markdown(rows: Sequence[Mapping[str, Any]],
             runs: Sequence[Mapping[str, Any]],
             not_evaluated: Union[Mapping[str, str], Sequence] = (),
             results: Sequence[Mapping[str, Any]] = (),
             notes: Optional[str] = None) -> str:
  """The table and its provenance as Markdown.

  Args:
    rows: rows of `summarise`.
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
      f'# {title(rows)}', '',
      'Generated by `python -m hrc_suite.experts.evaluate` '
      '(hrc_suite/experts/evaluate.py); do not edit by hand.', '',
      *[_run_line(run) for run in runs],
      f'* Machine: {latest["machine"]["cpus"]} CPUs, '
      f'{latest["machine"]["processor"]}, {latest["machine"]["platform"]}, '
      f'Python {latest["machine"]["python"]}',
      f'* {"; ".join(described)}.',
      *([f'* People: {"; ".join(people_lines)}.'] if people_lines else []),
      '* Success: the goal reached at least once; CI: 95 % percentile '
      f'bootstrap over episodes, 10^4 resamples, seed {BOOTSTRAP_SEED}. '
      'Shield interventions: RL steps per episode in which the shield '
      'overrode the motion. Contacts: physics steps per episode with a '
      'contact of the type (self: RL steps ending self-colliding; human '
      'pushed: the person had pushed the robot off its command, '
      'docs/safety.md "Pushed robots"). Steps outside human model: RL '
      "steps per episode in which the person moved faster than the shield's "
      'human model (outside its guarantee). Shield resyncs: physics steps '
      'per episode after which the shield restarted at the pushed '
      "robot's pose. Physics errors: the share of episodes a MuJoCo "
      'physics error ended (docs/safety.md "Physics errors"). '
      f'{MISSING}: not recorded (episodes run before the metric existed).',
      '', HEADER,
      '|' + '---|' * (HEADER.count('|') - 1),
  ]
  for row in rows:
    counts = ' | '.join(_cell(row[name]) for _, name in
                        CONTACT_COLUMNS + SAFETY_COLUMNS)
    lines.append(
        f'| {row["domain"]}/{row["task"]} | {row["robot"]} | '
        f'{row["policy"]} | {row["people"]} | {row["shield"]} | '
        f'{row["action_space"]} | {row["episodes"]} | '
        f'{row["success"]:.2f} [{row["success_low"]:.2f}, '
        f'{row["success_high"]:.2f}] | {row["return"]:.1f} | '
        f'{row["steps"]:.1f} | {row["seconds"]:.1f} | '
        f'{row["shield_interventions"]:.1f} | {counts} | '
        f'{row["wall_time"]:.1f} |')
  lines += ['', f'## Rows below the bar ({bar_text(rows)})', '']
  failing = [(row, below_bar(row)) for row in rows if below_bar(row)]
  for row, reasons in failing:
    lines.append(f'* BELOW THE BAR: {row_name(row)}: {"; ".join(reasons)}')
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
          notes: Optional[str] = None) -> list[Row]:
  """Writes the Markdown table and the JSON results. The table is that of
  the episodes as stored (rounded: results_file), so that writing it
  again from the JSON gives the same table.

  Args:
    results: the episodes (`run_job`).
    out: the Markdown file.
    json_out: the JSON file.
    runs: the runs behind the episodes, oldest first.
    not_evaluated: {task key (`task_key`): reason}.
    notes: Markdown put under "Notes".

  Returns:
    The rows (`summarise`).
  """
  results = results_file.unpack(results_file.pack(results))
  rows = summarise(results)
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
            notes: Optional[str] = None) -> list[Row]:
  """Writes the table of an existing results JSON again (and the JSON, in
  the current format) without running episodes.

  Args:
    out: the Markdown file.
    json_out: the existing JSON.
    notes: replace its notes if given.

  Returns:
    The rows (`summarise`).

  Raises:
    ValueError: no results file, or none of this command.
  """
  episodes, runs, not_evaluated, old_notes = load_results(json_out)
  if not runs:
    raise ValueError(f'{json_out}: no results to rewrite')
  return write(episodes, out, json_out, runs, not_evaluated,
               old_notes if notes is None else notes)


# -------------------------------------------------------------------- main

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
  flags.DEFINE_list('policies', list(EXPERT_POLICIES),
                    f'Some of {", ".join(POLICIES)}.', flag_values=fv)
  flags.DEFINE_list('shield', [DEFAULT_SHIELD], 'Shield modes, each a row: '
                    f'{DEFAULT_SHIELD} (the task\'s own) or registered modes '
                    '(ssm, pfl, off, ...).', flag_values=fv)
  registry_flags.check_shield('shield', fv, extra=(DEFAULT_SHIELD,))
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
    for reason in below_bar(row):
      print(f'BELOW THE BAR: {row_name(row)}: {reason}')


def _policies(f):
  """(policies, [(robot, policy)] pairs) of the flags."""
  unknown = [p for p in f.policies if p not in POLICIES]
  if unknown:
    raise app.UsageError(f'Unknown policies {unknown}: expected some of '
                         f'{", ".join(POLICIES)}')
  pairs = []
  for pair in f.pairs:
    robot, _, policy = pair.partition(':')
    if policy not in POLICIES or not robot:
      raise app.UsageError(f'--pairs entry {pair!r}: expected robot:policy '
                           f'with policy one of {", ".join(POLICIES)}')
    pairs.append((robot, policy))
  return ([policy for _, policy in pairs] if pairs else f.policies), pairs


def _tasks(f, policies, motions):
  """(tasks to run, {task key: reason} of those not evaluated)."""
  try:
    requested = [_parse_task(t) for t in f.tasks] or None
  except ValueError as e:
    raise app.UsageError(str(e)) from e
  need_expert = any(p in EXPERT_POLICIES for p in policies)
  known = set(experts.registered() if need_expert else suite.all_tasks())
  for task in requested or ():
    if task not in known:
      valid = ', '.join(sorted('/'.join(t) for t in known))
      what = 'expert' if need_expert else 'task'
      raise app.UsageError(f'No {what} for {"/".join(task)}: {what}s exist '
                           f'for {valid}')
  if need_expert:
    tasks, missing = available_tasks(requested)
  else:
    tasks, missing = tuple(requested or experts.registered()), {}
  if motions is not None:
    robot = f.pairs[0].partition(':')[0] if f.pairs else f.robots[0]
    tasks, no_motions = tasks_with_motions(tasks, motions, robot)
    missing.update(no_motions)
  return tasks, {task_key(*task, motions): reason
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
      rows = rewrite(f.out, json_out, notes)
    except ValueError as e:
      raise app.UsageError(str(e)) from e
    print(f'Wrote {f.out} ({len(rows)} rows) and {json_out} from '
          f'{json_out}')
    _print_below_bar(rows)
    return
  policies, pairs = _policies(f)
  if not f.shield:
    raise app.UsageError(f'--shield: expected some of {DEFAULT_SHIELD}, '
                         f'{", ".join(modes_lib.names())}')
  shields = [None if s == DEFAULT_SHIELD else s for s in f.shield]
  motions = None
  if f.motions is not None:
    folder = pathlib.Path(f.motions)
    if not folder.is_dir():
      raise app.UsageError(f'--motions {f.motions}: not a folder')
    motions = (f.motions_label or folder.resolve().name, f.motions)
  tasks, not_evaluated = _tasks(f, policies, motions)
  spaces = tuple(f.action_spaces) or (None,)
  job_list = jobs(tasks, f.robots, f.policies, f.episodes, spaces,
                  f.time_limit, pairs, motions, shields)
  if not job_list:
    raise app.UsageError('Nothing to run: ' + '; '.join(
        f'{key}: {reason}' for key, reason in not_evaluated.items()))
  try:
    previous, runs, old_missing, old_notes = (
        load_results(json_out) if f.update else ([], [], {}, None))
  except ValueError as e:
    raise app.UsageError(str(e)) from e
  partial = pathlib.Path(json_out + '.partial.jsonl')
  partial.parent.mkdir(parents=True, exist_ok=True)
  start = time.perf_counter()
  commit = _git_commit()   # The code this run loads.
  results = run(job_list, workers=f.workers, progress=f.progress,
                partial=partial)
  run_info = {
      'command': ' '.join(shlex.quote(a) for a in
                          ['python', '-m', 'hrc_suite.experts.evaluate']
                          + sys.argv[1:]),
      'date': datetime.datetime.now(datetime.timezone.utc).strftime(
          '%Y-%m-%d %H:%M UTC'),
      'machine': machine(), 'workers': f.workers,
      'wall_time': time.perf_counter() - start, 'commit': commit,
      'rows': list(dict.fromkeys(row_key(r) for r in results)),
  }
  not_evaluated = merge_not_evaluated(old_missing, not_evaluated, results)
  results = merge(previous, results)
  runs = merge_runs(runs, run_info)
  rows = write(results, f.out, json_out, runs, not_evaluated,
               old_notes if notes is None else notes)
  partial.unlink()
  print(f'Wrote {f.out} ({len(rows)} rows) and {json_out}')
  _print_below_bar(rows)


if __name__ == '__main__':
  define_flags()
  app.run(main)
