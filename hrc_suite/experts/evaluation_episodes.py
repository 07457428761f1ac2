"""The episodes of an expert evaluation (`python -m
hrc_suite.experts.evaluate`): jobs, the policies they play and running
them.

A job is one episode: (domain, task, robot, action_space, policy,
time_limit, seed, motions, shield) (`job_fields`). `run_job` plays it in
an environment kept per process (`_environment`: one per job key, the
last) and returns its result, a JSON-able dict; `run` runs jobs in this
process or in spawned ones and logs finished episodes to a partial file,
from which a killed run resumes.

Episode `seed` runs in an environment whose random_state is seeded `seed`;
the noisy expert uses the noise of episode `seed` of NoisyExpert(seed=0);
the random policy draws from np.random.default_rng(seed); the chaser is
deterministic.
"""

import json
import multiprocessing
import os
import pathlib
import time
import traceback
from typing import Any, Iterable, Mapping, Optional, Sequence, Union

import dm_env
from dm_env import specs
import numpy as np

from hrc_suite import experts
from hrc_suite import suite
from hrc_suite.experts import adversary
from hrc_suite.experts import noise as noise_lib
from hrc_suite.experts import pace
from hrc_suite.human import clip as clip_lib
from hrc_suite.tasks.runtime import metrics as metrics_lib
from hrc_suite.tasks.runtime import motions as task_motions

EXPERT_POLICIES = ('expert', 'noisy_expert')
TEST_POLICIES = ('random', 'chase')   # Safety checks, no success bar.
POLICIES = EXPERT_POLICIES + TEST_POLICIES
# The people of rows run without --motions: the shipped library.
SYNTHETIC = 'synthetic'
# Innermost frames of an episode's exception kept in its result.
TRACEBACK_FRAMES = 8
# An episode to run: (domain, task, robot, action_space, policy, time_limit,
# seed, motions, shield) (`job_fields`), a list once stored in JSON.
Job = Sequence[Any]
# An episode's result (`run_job`), JSON-able.
Result = dict[str, Any]
# People: (label, folder) of recorded motions, None for the shipped library.
Motions = Optional[Sequence[str]]


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
