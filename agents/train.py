r"""Trains an agent on an hrc_suite task, with evaluation, logs and checkpoints.

  python -m agents.train --domain=reach --task=dense --robot=schunk \
      --action_space=cartesian --agent=sac --config=default --seed=0 \
      --steps=200000 --eval_every=10000 --eval_episodes=20 \
      --logdir=runs/reach_dense/seed0

Writes logdir/config.json, train.csv (one row per training episode),
eval.csv (one row per evaluation: deterministic episodes in a separate
environment, seeded from the run seed and the evaluation's index),
tensorboard/ and checkpoints/ (`agents.checkpoints`).

Resuming (--resume) continues exactly: the resumed run ends with the same
parameters, replay contents and logs as an uninterrupted run (the CSV and
TensorBoard rows after the checkpoint are dropped first, and the steps
after it are run again). Checkpoints are taken every --checkpoint_every
steps and at the end of the run. Plain SAC checkpoints inside an episode
too: the task's snapshot (HrcTask.get_state), the loop's last observation
and the environment's random state restore the episode exactly, provided
no observation is delayed (the delay buffers of composer's observation
updater are not part of a snapshot). With an imitation wrapper (whose
episode state is its own) or delayed observations, checkpoints wait for the
next episode boundary, and a run that ends inside an episode keeps its
previous checkpoint.

--plot writes the run's learning curve (`agents.plot`) as
logdir/curves.png; --video renders one deterministic episode of the final
policy (`hrc_suite.rendering.episode`, with the shield overlay) as logdir/episode.mp4.
The README's quickstart:

  python -m agents.train --config=quick --steps=25000 --eval_every=5000 \
      --logdir=runs/quickstart --plot --video
"""

import dataclasses
import json
import os
import time
from typing import (Any, Callable, Dict, Mapping, Optional, Sequence,
                    Tuple, Union)

from absl import app
from absl import flags
from absl import logging
import dm_env
import numpy as np
import tqdm

from agents import agent as agent_lib
from agents import agent_checkpoint
from agents import builders
from agents import checkpoint_policy
from agents import checkpoints
from agents import config as config_lib
from agents import imitation
from agents import logging as logging_lib
from agents import loop as loop_lib
from agents import plot as plot_lib
from agents import precompile
from agents import specs as specs_lib
from hrc_suite import registry_flags
from hrc_suite.rendering import episode as render
from hrc_suite import suite
from hrc_suite.experts import dataset as dataset_lib
from hrc_suite.tasks.runtime import metrics as metrics_lib

# The agents: SAC, its imitation variants (agents.imitation: SAC on a
# wrapped task) and SAC-Lagrangian (agents/sac_lag/).
AGENTS = imitation.AGENTS + ('sac_lag',)
_NEEDS_DATASET = imitation.NEEDS_DATASET
# Agents that train on the bare task, learning with the algorithm of
# agents/builders.py of the same name.
_BARE_TASK_AGENTS = ('sac', 'sac_lag')
# Keys of the run config a resumed run may change.
_RESUMABLE_CHANGES = ('steps',)
# Purposes of seeds derived from the run seed (np.random.SeedSequence);
# agents.evaluate uses 3.
_TRAIN_ENV, _AGENT, _EVAL_ENV, _IMITATION = 0, 1, 2, 4
# A run's description (config.json, `make_run_config`).
RunConfig = Dict[str, Any]


def derived_seed(seed: int, *purpose: int) -> int:
  """A 31-bit seed for one purpose of a run seed (independent streams).

  Args:
    seed: the run seed.
    *purpose: integers naming the purpose (the module's constants, an
      evaluation's index, ...).

  Returns:
    The seed.
  """
  sequence = np.random.SeedSequence([int(seed)] + [int(p) for p in purpose])
  return int(sequence.generate_state(1)[0] & 0x7FFFFFFF)


def parse_overrides(items: Sequence[str]) -> Dict[str, Any]:
  """Config overrides from the command line.

  Args:
    items: ['field=json value', ...].

  Returns:
    {'field': value}.

  Raises:
    ValueError: an item without '=' or a value that is not JSON.
  """
  overrides = {}
  for item in items:
    name, sep, value = item.partition('=')
    if not sep or not name:
      raise ValueError(f'Bad override {item!r}: expected field=value')
    try:
      overrides[name] = json.loads(value)
    except json.JSONDecodeError as e:
      raise ValueError(f'Bad override value in {item!r}: expected JSON '
                       f'(e.g. 100, 3e-4, [64, 64], null): {e}') from None
  return overrides


def make_run_config(domain: str, task: str, robot: str, action_space: str,
                    agent: str = 'sac', config: str = 'default',
                    overrides: Optional[Mapping[str, Any]] = None,
                    task_kwargs: Optional[Mapping[str, Any]] = None,
                    seed: int = 0, steps: int = 1000, eval_every: int = 0,
                    eval_episodes: int = 0, checkpoint_every: int = 0,
                    dataset: Optional[str] = None,
                    imitation_kwargs: Optional[Mapping[str, Any]] = None,
                    eval_sets: Optional[Mapping[str, Mapping[str, Any]]]
                    = None) -> RunConfig:
  """The JSON-ready description of a run (config.json).

  Args:
    domain: the task's domain.
    task: the task's name.
    robot: a robot name or description file.
    action_space: 'joint' or 'cartesian'.
    agent: one of AGENTS.
    config: a SAC preset (`agents.config.CONFIGS`).
    overrides: config fields (of the agent's algorithm's config).
    task_kwargs: further task kwargs (not robot, action_space or seed).
    seed: the run seed.
    steps: environment steps, an integer >= 0.
    eval_every: steps between evaluations (0: none).
    eval_episodes: episodes per evaluation (>= 1 with eval_every).
    checkpoint_every: steps between checkpoints (0: only at the end).
    dataset: an expert dataset directory (the imitation agents that need
      one only).
    imitation_kwargs: the imitation wrapper's kwargs.
    eval_sets: {name: task kwargs} of further evaluation environments,
      each the run's task with these kwargs replacing the run's (e.g. the
      unseen side of a motion split: {'unseen': {'motions': {'split':
      'test', ...}}}); each is evaluated with the run's main evaluation and
      logged to eval_<name>.csv.

  Returns:
    The run config.

  Raises:
    ValueError: an unknown agent or config field, a dataset missing or
      given where unused, bad counts, task kwargs setting a flag's value,
      or bad eval_sets.
  """
  if agent not in AGENTS:
    raise ValueError(f'Unknown agent {agent!r}: expected one of '
                     f'{", ".join(AGENTS)}')
  if agent in _NEEDS_DATASET and not dataset:
    raise ValueError(f'--agent={agent} needs --dataset (an expert dataset '
                     'of the task: python -m agents.collect_expert)')
  if agent not in _NEEDS_DATASET and dataset:
    raise ValueError(f'--dataset is only used by --agent='
                     f'{", ".join(_NEEDS_DATASET)}, not '
                     f'{agent}')
  if imitation_kwargs and agent in _BARE_TASK_AGENTS:
    raise ValueError(f'imitation_kwargs are for the imitation agents, not '
                     f'{agent}')
  for name, value, low in (('steps', steps, 0), ('eval_every', eval_every, 0),
                           ('eval_episodes', eval_episodes, 0),
                           ('checkpoint_every', checkpoint_every, 0)):
    if int(value) != value or value < low:
      raise ValueError(f'{name} must be an integer >= {low}, got {value!r}')
  if eval_every and not eval_episodes:
    raise ValueError('eval_every > 0 needs eval_episodes >= 1')
  task_kwargs = dict(task_kwargs or {})
  for name in ('robot', 'action_space', 'seed'):
    if name in task_kwargs:
      raise ValueError(f'task_kwargs must not set {name!r}: it is a flag '
                       'of its own (the seed is derived from --seed)')
  overrides = dict(overrides or {})
  sac_config = agent_config(agent, config, overrides)
  if builders.make_builder(algorithm(agent),
                           sac_config.to_dict()).needs_cost:
    # The cost reaches the agent as the 'safe_rl' preset's observable.
    task_kwargs.setdefault('observations', 'safe_rl')
  eval_sets = _check_eval_sets(eval_sets, eval_every)
  run_config = {
      'domain': domain, 'task': task, 'robot': robot,
      'action_space': action_space, 'task_kwargs': task_kwargs,
      'agent': agent, 'config': config, 'overrides': overrides,
      'sac_config': sac_config.to_dict(), 'seed': int(seed),
      'steps': int(steps), 'eval_every': int(eval_every),
      'eval_episodes': int(eval_episodes),
      'checkpoint_every': int(checkpoint_every),
      'dataset': os.path.abspath(dataset) if dataset else None,
      'imitation_kwargs': dict(imitation_kwargs or {}),
  }
  if eval_sets:   # Absent otherwise: configs written before it resume.
    run_config['eval_sets'] = eval_sets
  return run_config


def algorithm(agent: str) -> str:
  """The learning algorithm (agents/builders.py) of an agent name.

  Args:
    agent: one of AGENTS.

  Returns:
    'sac' or 'sac_lag'.
  """
  return agent if agent in _BARE_TASK_AGENTS else 'sac'


def agent_config(agent: str, preset: str,
                 overrides: Mapping[str, Any]) -> config_lib.SACConfig:
  """The config of an agent: the SAC preset's values, for sac_lag with the
  constraint's fields, and overrides of any of them.

  Args:
    agent: one of AGENTS.
    preset: a SAC preset (`agents.config.CONFIGS`).
    overrides: fields of the algorithm's config.

  Returns:
    The config (a SACConfig or a subclass).

  Raises:
    ValueError: an unknown preset or field, or a field's bad value.
  """
  if algorithm(agent) == 'sac':
    return config_lib.config_from_name(preset, **overrides)
  config_class = builders.config_class(algorithm(agent))
  fields = {field.name for field in dataclasses.fields(config_class)}
  unknown = sorted(set(overrides) - fields)
  if unknown:
    raise ValueError(f'Unknown {config_class.__name__} fields {unknown}: '
                     f'expected some of {", ".join(sorted(fields))}')
  sac_fields = {field.name for field in dataclasses.fields(
      config_lib.SACConfig)}
  base = config_lib.config_from_name(preset, **{
      k: v for k, v in overrides.items() if k in sac_fields})
  return config_class(**dict(dataclasses.asdict(base), **overrides))


def _check_eval_sets(eval_sets, eval_every):
  """{name: task kwargs dict} of valid names, or {}."""
  eval_sets = dict(eval_sets or {})
  for name, kwargs in eval_sets.items():
    if not (isinstance(name, str) and name.isidentifier()):
      raise ValueError(f'eval_sets name {name!r}: expected an identifier '
                       '(it names the file eval_<name>.csv)')
    if not isinstance(kwargs, dict):
      raise ValueError(f'eval_sets[{name!r}] = {kwargs!r}: expected a dict '
                       'of task kwargs')
    for key in ('robot', 'action_space', 'seed'):
      if key in kwargs:
        raise ValueError(f'eval_sets[{name!r}] must not set {key!r}: the run '
                         'sets it')
  if eval_sets and not eval_every:
    raise ValueError('eval_sets need eval_every > 0')
  return {name: dict(kwargs) for name, kwargs in eval_sets.items()}


def make_environment(run_config: Mapping[str, Any],
                     seed: int) -> suite.Environment:
  """The run's environment, compiled, with its RandomState seeded by seed.

  The throwaway first reset compiles the model, so that a fresh and a
  resumed run draw the same random numbers from then on.

  Args:
    run_config: of `make_run_config`.
    seed: the environment's seed.

  Returns:
    The environment (the bare task).
  """
  kwargs = dict(run_config['task_kwargs'], robot=run_config['robot'],
                action_space=run_config['action_space'])
  env = suite.load(run_config['domain'], run_config['task'],
                   task_kwargs=kwargs,
                   environment_kwargs={'random_state': int(seed)})
  env.reset()
  env.random_state.seed(int(seed))
  return env


def make_training_environment(run_config: Mapping[str, Any]
                              ) -> dm_env.Environment:
  """The training environment: the task, wrapped for imitation agents
  (agents.imitation; evaluation always runs the bare task).

  Args:
    run_config: of `make_run_config`.

  Returns:
    The environment.
  """
  env = make_environment(run_config, derived_seed(run_config['seed'],
                                                  _TRAIN_ENV))
  if run_config['agent'] in _BARE_TASK_AGENTS:
    return env
  dataset = None
  if run_config['dataset']:
    dataset = dataset_lib.load_dataset(run_config['dataset'])
  return imitation.wrap(env, run_config['agent'], dataset=dataset,
                        seed=derived_seed(run_config['seed'], _IMITATION),
                        **run_config['imitation_kwargs'])


def mid_episode_checkpoints(run_config: Mapping[str, Any]) -> bool:
  """Whether checkpoints of the run may be taken inside an episode: an
  agent on the bare task (no wrapper state) without delayed observations.

  Args:
    run_config: of `make_run_config`.

  Returns:
    Whether they may.
  """
  return (run_config['agent'] in _BARE_TASK_AGENTS and
          not run_config['task_kwargs'].get('observation_delay'))


def random_states(env: dm_env.Environment
                  ) -> Dict[str, np.random.RandomState]:
  """The random states of an environment and its wrappers.

  Args:
    env: the environment, perhaps wrapped.

  Returns:
    {name: np.random.RandomState}: 'environment' (the composer
    environment's) and '<depth>/<attribute>' for random states a wrapper
    keeps (e.g. RSI's draw of reference states).
  """
  found = {}
  depth = 0
  # A wrapper exposes the environment it wraps as an `environment` property.
  while isinstance(getattr(type(env), 'environment', None), property):
    for name, value in sorted(vars(env).items()):
      if isinstance(value, np.random.RandomState):
        found[f'{depth}/{name}'] = value
    env, depth = env.environment, depth + 1
  found['environment'] = env.random_state
  return found


def make_agent(run_config: Mapping[str, Any],
               env: dm_env.Environment) -> agent_lib.Agent:
  """The run's agent, seeded from the run seed.

  Args:
    run_config: of `make_run_config`.
    env: the training environment.

  Returns:
    The agent, with the builder of the run's algorithm.
  """
  builder = builders.make_builder(algorithm(run_config['agent']),
                                  run_config['sac_config'])
  return agent_lib.Agent(specs_lib.make_environment_spec(env), builder,
                         seed=derived_seed(run_config['seed'], _AGENT))


def task_facts(env: suite.Environment) -> Dict[str, Any]:
  """Reward range, horizon and minimal episode returns of env's task.

  Args:
    env: an environment of `suite.load`.

  Returns:
    {'reward_range', 'horizon', 'min_task_return' (without the collision
    penalty: HrcTask.min_task_return; the paper's runs had no penalty),
    'min_return' (with it at every step: the lowest possible)}.
  """
  low, high = env.task.reward_range
  horizon = int(env.task.horizon)
  penalty = min(float(getattr(env.task, 'collision_reward', 0.0)), 0.0)
  minimum = float(env.task.min_task_return)
  return {'reward_range': [float(low), float(high)], 'horizon': horizon,
          'min_return': minimum + penalty * horizon,
          'min_task_return': minimum}


def summarize(episodes: Sequence[Mapping[str, float]]) -> Dict[str, Any]:
  """One evaluation row from the episodes' metrics (means and rates).

  Args:
    episodes: per-episode metrics (`loop.evaluate`'s), at least one.

  Returns:
    The row.
  """
  row = {'episodes': len(episodes)}
  returns = np.array([e['episode_return'] for e in episodes])
  row['success_rate'] = float(np.mean([e.get('success', 0.0)
                                       for e in episodes]))
  row['return_mean'] = float(returns.mean())
  row['return_std'] = float(returns.std())
  row['length_mean'] = float(np.mean([e['episode_length'] for e in episodes]))
  skip = {'success', 'return', 'steps', 'episode_return', 'episode_length'}
  for name in episodes[0]:
    if name in skip:
      continue
    values = np.array([e[name] for e in episodes], dtype=float)
    if name == 'min_human_distance':
      row[name] = float(values.min())
    elif name == 'max_human_contact_speed':
      row[name] = float(values.max())
    else:
      row[f'{name}_mean'] = float(values.mean())
  return row


def evaluate_policy(run_config: Mapping[str, Any], env: suite.Environment,
                    agent: agent_lib.Agent, index: int,
                    eval_set: int = 0) -> Dict[str, Any]:
  """An evaluation: deterministic episodes, seeded by its number.

  Args:
    run_config: of `make_run_config`.
    env: the evaluation environment.
    agent: the agent, whose current policy is evaluated.
    index: the evaluation's number.
    eval_set: 0 for the run's task, k for the k-th of its eval_sets by
      name.

  Returns:
    The row of `summarize` with 'evaluation'.
  """
  purpose = (_EVAL_ENV, index) + ((eval_set,) if eval_set else ())
  env.random_state.seed(derived_seed(run_config['seed'], *purpose))
  episodes = loop_lib.evaluate(env, agent.policy(deterministic=True),
                               run_config['eval_episodes'])
  return dict(summarize(episodes), evaluation=index)


def make_eval_set_environments(run_config: Mapping[str, Any]
                               ) -> Dict[str, suite.Environment]:
  """The environments of the run's eval_sets.

  Args:
    run_config: of `make_run_config`.

  Returns:
    {name: environment}, sorted by name: the run's task with the set's
    task kwargs replacing the run's.
  """
  environments = {}
  for k, name in enumerate(sorted(run_config.get('eval_sets', {})), 1):
    kwargs = dict(run_config['task_kwargs'], **run_config['eval_sets'][name])
    environments[name] = make_environment(
        dict(run_config, task_kwargs=kwargs),
        derived_seed(run_config['seed'], _EVAL_ENV, k))
  return environments


def _check_resumable(stored, run_config):
  stored = dict(stored)
  if 'sac_config' in stored:   # Also one written before fused_steps.
    config_class = builders.config_class(algorithm(stored.get('agent',
                                                              'sac')))
    stored['sac_config'] = config_class.from_dict(
        stored['sac_config']).to_dict()
  changed = sorted(k for k in set(stored) | set(run_config)
                   if k not in _RESUMABLE_CHANGES and k in run_config
                   and stored.get(k) != run_config[k])
  if 'sac_config' not in changed:
    # Overrides that give the stored SAC config (e.g. fused_steps=1 for a
    # run begun with update_every=1) are no change.
    changed = [k for k in changed if k != 'overrides']
  if changed:
    details = '; '.join(f'{k}: {stored.get(k)!r} -> {run_config[k]!r}'
                        for k in changed)
    raise ValueError(f'Cannot resume with a different configuration '
                     f'({details}); only {list(_RESUMABLE_CHANGES)} may '
                     'change')


class _Progress:
  """A tqdm bar (or nothing)."""

  def __init__(self, enabled, total, initial):
    self._bar = None
    if enabled:
      self._bar = tqdm.tqdm(total=total, initial=initial, unit='step',
                            dynamic_ncols=True, smoothing=0.05)

  def update(self, steps=1, **postfix):
    if self._bar is not None:
      self._bar.update(steps)
      if postfix:
        self._bar.set_postfix(postfix, refresh=False)

  def close(self):
    if self._bar is not None:
      self._bar.close()


def train(run_config: Mapping[str, Any], logdir: Union[str, os.PathLike],
          resume: bool = False, progress: bool = False,
          on_step: Optional[Callable[[int], None]] = None
          ) -> Tuple[agent_lib.Agent, Dict[str, Any]]:
  """Runs (or resumes) a training run; returns the agent and loop state.

  Args:
    run_config: `make_run_config`'s dict.
    logdir: the run directory (`agents.checkpoints` layout).
    resume: continue from the latest checkpoint in logdir, if any.
    progress: show a progress bar.
    on_step: None or a function called with the steps done after every
      RL step (e.g. to report progress; keep it cheap).

  Returns:
    (the agent, the loop state: evaluations, schedules, wall time and
    counter).

  Raises:
    ValueError: a logdir holding a run without resume, a resumed run with
      another configuration, or a checkpoint that does not match.
  """
  logdir = os.fspath(logdir)
  os.makedirs(logdir, exist_ok=True)
  config_path = os.path.join(logdir, 'config.json')
  checkpoint = checkpoints.latest(logdir) if resume else None
  if not resume and (os.path.exists(config_path) or
                     checkpoints.latest(logdir) is not None):
    raise ValueError(f'{logdir} already holds a run: pass --resume to '
                     'continue it, or choose a new --logdir')
  if checkpoint is not None and os.path.exists(config_path):
    _check_resumable(checkpoints.read_json(config_path), run_config)

  env = make_training_environment(run_config)
  eval_env = None
  if run_config['eval_every']:
    eval_env = make_environment(run_config, derived_seed(run_config['seed'],
                                                         _EVAL_ENV))
  eval_set_envs = make_eval_set_environments(run_config)
  agent = make_agent(run_config, env)
  # The learner compiles while the first evaluation and the replay's
  # warm-up step the environment.
  agent.compile_update_in_background()
  observer = metrics_lib.EpisodeMetricsObserver()
  loop = loop_lib.EnvironmentLoop(env, agent, observers=[observer])
  state = {'evaluations': 0, 'next_eval': 0,
           'next_checkpoint': run_config['checkpoint_every'] or None,
           'wall_time': 0.0}
  if checkpoint is not None:
    stored, rng_states = checkpoints.load_loop_state(checkpoint)
    agent_checkpoint.restore(agent,
                             os.path.join(checkpoint, checkpoints.AGENT_DIR))
    loop.counter.restore(stored['counter'])
    current = random_states(env)
    if sorted(current) != sorted(rng_states):
      raise ValueError(f'Checkpoint {checkpoint} holds random states '
                       f'{sorted(rng_states)}, the environment has '
                       f'{sorted(current)}')
    for name, rng_state in rng_states.items():
      current[name].set_state(rng_state)
    episode = checkpoints.load_episode(checkpoint)
    if episode is not None:
      info, observation, snapshot = episode
      env.task.set_state(env.physics, snapshot)
      loop.restore_episode(info, observation)
    state.update({k: stored[k] for k in state})
    logging.info('Resumed %s at step %d', checkpoint, loop.counter.steps)
  elif resume:
    logging.info('No checkpoint in %s: starting afresh', logdir)
  run_config = dict(run_config, **task_facts(env))
  checkpoints.write_json(config_path, run_config)

  # Rows logged after the checkpoint (all rows if there is none) are
  # logged again by this run.
  resumed_at = loop.counter.steps if checkpoint is not None else -1
  train_csv = logging_lib.CSVLogger(os.path.join(logdir, 'train.csv'))
  eval_csv = logging_lib.CSVLogger(os.path.join(logdir, 'eval.csv'))
  eval_set_csvs = {name: logging_lib.CSVLogger(
      os.path.join(logdir, f'eval_{name}.csv')) for name in eval_set_envs}
  for logger in (train_csv, eval_csv, *eval_set_csvs.values()):
    logger.truncate(resumed_at)
  writer = logging_lib.summary_writer(
      os.path.join(logdir, 'tensorboard'),
      purge_step=resumed_at + 1 if resume else None)
  train_log = logging_lib.Dispatcher(
      [train_csv, logging_lib.TensorBoardLogger(writer, 'train')])
  learner_log = logging_lib.TensorBoardLogger(writer, 'learner')
  eval_log = logging_lib.TensorBoardLogger(writer, 'eval')
  bar = _Progress(progress, run_config['steps'], loop.counter.steps)
  start = time.perf_counter() - state['wall_time']
  last_saved = loop.counter.steps if checkpoint is not None else None

  def can_save():
    return mid_episode or not loop.in_episode

  def save():
    state['wall_time'] = time.perf_counter() - start
    loop_state = dict(state, counter=loop.counter.state(),
                      run_config=run_config)
    episode = loop.episode_state()
    if episode is not None:
      episode += (env.task.get_state(env.physics),)
    checkpoints.save(logdir, loop.counter.steps, agent, loop_state,
                     random_states(env), episode=episode)

  def timed_row(logger, env, eval_set=0):
    began = time.perf_counter()
    row = evaluate_policy(run_config, env, agent, state['evaluations'],
                          eval_set=eval_set)
    row['wall_time'] = time.perf_counter() - start
    # The evaluation's own seconds (files begun without the column keep
    # their columns).
    if logger.columns is None or 'eval_seconds' in logger.columns:
      row['eval_seconds'] = time.perf_counter() - began
    logger.write(row, loop.counter.steps)
    return row

  def evaluate():
    row = timed_row(eval_csv, eval_env)
    eval_log.write(row, loop.counter.steps)   # TensorBoard
    for k, name in enumerate(sorted(eval_set_envs), 1):
      timed_row(eval_set_csvs[name], eval_set_envs[name], eval_set=k)
    state['evaluations'] += 1
    state['next_eval'] += run_config['eval_every']
    bar.update(0, eval_success=f'{row["success_rate"]:.2f}')

  mid_episode = mid_episode_checkpoints(run_config)
  pending = False   # A checkpoint is due (when can_save()).
  try:
    while True:
      if eval_env is not None and loop.counter.steps >= state['next_eval']:
        evaluate()   # Before a checkpoint at the same step: it holds it.
      if pending and can_save():
        save()
        pending, last_saved = False, loop.counter.steps
      if loop.counter.steps >= run_config['steps']:
        break
      result = loop.step()
      bar.update(1)
      if on_step is not None:
        on_step(loop.counter.steps)
      if result is not None:
        result['wall_time'] = time.perf_counter() - start
        train_log.write(result, loop.counter.steps)
        if loop.update_metrics:
          learner_log.write(loop.update_metrics, loop.counter.steps)
        bar.update(0, ret=f'{result["episode_return"]:.2f}')
      due = state['next_checkpoint']
      if due is not None and loop.counter.steps >= due:
        pending = True
        state['next_checkpoint'] += run_config['checkpoint_every']
    if can_save() and last_saved != loop.counter.steps:
      save()
  finally:
    bar.close()
    train_log.close()
    eval_log.close()
    for logger in (eval_csv, *eval_set_csvs.values()):
      logger.close()
    writer.close()
  return agent, dict(state, counter=loop.counter.state())


def define_flags(flag_values: flags.FlagValues = flags.FLAGS) -> None:
  """Defines the binary's flags (only when run as a program, so that the
  module can be imported next to the other binaries).

  Args:
    flag_values: where to define them.
  """
  fv = flag_values
  flags.DEFINE_string('domain', 'reach', 'Task domain.', flag_values=fv)
  flags.DEFINE_string('task', 'dense', 'Task name within the domain.',
                      flag_values=fv)
  flags.DEFINE_string('robot', 'schunk', 'Robot name or description file.',
                      flag_values=fv)
  # Names are checked against the registries at parse time.
  registry_flags.check_task('domain', 'task', fv)
  registry_flags.check_robot('robot', fv)
  flags.DEFINE_enum('action_space', 'cartesian', ['joint', 'cartesian'],
                    'Action space.', flag_values=fv)
  flags.DEFINE_string('task_kwargs', '{}', 'JSON dict of further task '
                      'kwargs, e.g. \'{"time_limit": 5.0}\'.', flag_values=fv)
  flags.DEFINE_enum('agent', 'sac', AGENTS, 'Agent: plain SAC, an '
                    'imitation variant (agents.imitation) or SAC-Lagrangian '
                    '(sac_lag: its constraint fields are --override '
                    'fields, e.g. --override=cost_limit=2).', flag_values=fv)
  flags.DEFINE_string('dataset', None, 'Expert dataset directory (rsi, '
                      'sir, rsi+air): python -m agents.collect_expert.',
                      flag_values=fv)
  flags.DEFINE_string('imitation_kwargs', '{}', 'JSON dict of the imitation '
                      'wrapper\'s kwargs, e.g. \'{"probability": 0.5}\'.',
                      flag_values=fv)
  flags.DEFINE_enum('config', 'default', list(config_lib.CONFIGS),
                    'SAC preset.', flag_values=fv)
  flags.DEFINE_multi_string(
      'override', [], 'SACConfig field=value (value as JSON), repeatable, '
      'e.g. --override=min_replay_size=100.', flag_values=fv)
  flags.DEFINE_integer('seed', 0, 'Run seed.', flag_values=fv)
  flags.DEFINE_integer('steps', 200_000, 'Environment steps.', flag_values=fv)
  flags.DEFINE_integer('eval_every', 10_000,
                       'Steps between evaluations (0: none).', flag_values=fv)
  flags.DEFINE_integer('eval_episodes', 20, 'Episodes per evaluation.',
                       flag_values=fv)
  flags.DEFINE_integer(
      'checkpoint_every', 50_000, 'Steps between checkpoints (0: only at '
      'the end of the run); see the module docstring.', flag_values=fv)
  flags.DEFINE_string('logdir', None, 'Run directory.', required=True,
                      flag_values=fv)
  flags.DEFINE_bool('resume', False, 'Continue from the latest checkpoint in '
                    '--logdir (a fresh start if there is none).',
                    flag_values=fv)
  flags.DEFINE_bool('progress', True, 'Show a progress bar.', flag_values=fv)
  flags.DEFINE_bool('plot', False, 'At the end, write the learning curve as '
                    'logdir/curves.png (and .svg, .csv).', flag_values=fv)
  flags.DEFINE_bool('video', False, 'At the end, render an episode of the '
                    'final policy as logdir/episode.mp4.', flag_values=fv)
  flags.DEFINE_bool('precompile', True, 'First compile (or load) '
                    "hrc_suite's numba kernels on two cores "
                    '(agents.precompile).', flag_values=fv)


def main(argv: Sequence[str],
         flag_values: flags.FlagValues = flags.FLAGS) -> None:
  """Trains a run from the flags; plots and renders it if asked.

  Args:
    argv: the command line (unused).
    flag_values: the parsed flags.
  """
  del argv
  f = flag_values
  run_config = make_run_config(
      f.domain, f.task, f.robot, f.action_space, agent=f.agent,
      config=f.config, overrides=parse_overrides(f.override),
      task_kwargs=json.loads(f.task_kwargs), seed=f.seed, steps=f.steps,
      eval_every=f.eval_every, eval_episodes=f.eval_episodes,
      checkpoint_every=f.checkpoint_every, dataset=f.dataset,
      imitation_kwargs=json.loads(f.imitation_kwargs))
  if f.precompile:
    logging.info('Kernels compiled or loaded in %.1f s',
                 precompile.warm_up(f.robot))
  _, state = train(run_config, f.logdir, resume=f.resume,
                   progress=f.progress)
  logging.info('Done: %d steps, %d episodes, %d evaluations in %s',
               state['counter']['steps'], state['counter']['episodes'],
               state['evaluations'], f.logdir)
  if f.plot:
    for path in plot_lib.plot([f.logdir], os.path.join(f.logdir,
                                                       'curves.png')):
      print(f'Wrote {path}')
  if f.video:
    path, metrics = render_final_policy(f.logdir, f.seed)
    print(f'Wrote {path}: success {metrics["success"]:g}, return '
          f'{metrics["return"]:.3g}, {metrics["steps"]:g} steps')


def render_final_policy(logdir: str, seed: int = 0
                        ) -> Tuple[str, Dict[str, float]]:
  """Renders one deterministic episode of the run's latest checkpoint as
  logdir/episode.mp4 (hrc_suite.rendering.episode.run).

  Args:
    logdir: the run directory.
    seed: the episode's seed.

  Returns:
    (video path, episode metrics).
  """
  trained = checkpoint_policy.load(logdir)
  return render.run(trained.domain, trained.task, trained.robot,
                    policy=trained.factory,
                    out=os.path.join(logdir, 'episode.mp4'), seed=seed,
                    task_kwargs=trained.task_kwargs)


if __name__ == '__main__':
  define_flags()
  app.run(main)
