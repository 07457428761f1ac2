"""Named experiment grids: which runs a sweep trains (`agents.sweep`).

A `Grid` is a typed, frozen description of a set of training runs: tasks x
agents x seeds (x motion splits), each task with its own budget, one robot,
one evaluation schedule, one SAC preset and the shared inputs the runs need
(expert datasets for RSI, SIR and AIR; expert returns for the normalised
return). `GRIDS` holds the named ones:

* `paper`: the original benchmark's main figure as the paper ran it
  (docs/reference_benchmark.md, Training and evaluation): six tasks x SAC,
  SAC + RSI, SIR, AIR x seeds 0-4 on the Schunk, 10^6 RL steps for reach and
  lifting and 3 x 10^6 for the others, 20 deterministic evaluation episodes
  every 2 x 10^5 steps, the paper's SAC hyperparameters and rewards (no
  collision penalty).
* `paper_reduced`: the same figure at what a 2-core machine runs in hours:
  seeds 0-2, 10^5 RL steps per task, 10 evaluation episodes every
  2.5 x 10^4 steps, 50-episode expert datasets.
* `overfitting`: the paper's ablation, SAC on collaborative lifting trained
  on 7 of the 9 motions and evaluated on the seen and the 2 unseen ones,
  over 5 splits (docs/reference_benchmark.md, Human motions).
* `safe_rl`: learning to be safe against being kept safe, on reach and
  pick and place: SAC with the shield, SAC without it (the safety cost as
  a reward penalty), SAC-Lagrangian without and with it (docs/safe_rl.md).
* `smoke`: two runs of a few hundred steps on reach, to check an
  installation or a cluster in about a minute.

A grid's agents are `agents.train` agents or named variants of them
(`variants`: an agent with its own task kwargs and config overrides, e.g.
SAC without the shield), each a line of the report.

Every field can be replaced (`Grid.replace`, the sweep's flags), and
`Grid.runs()` lists the runs with their `agents.train` run configs.
"""

import dataclasses
import os
import re
from typing import Any, Dict, List, Mapping, Optional, Tuple

from agents import imitation
from agents import train
from hrc_suite import suite

# The paper's agents (docs/reference_benchmark.md, Imitation): SAC, SAC
# with reference state initialisation, state imitation reward (which starts
# from the reference's states) and action imitation reward over RSI.
PAPER_AGENTS = ('sac', 'rsi', 'sir', 'rsi+air')
# The paper's figure: its six tasks with the paper's rewards (Table I).
PAPER_TASKS = ('reach/dense', 'pick_place/default', 'lifting/default',
               'handover/robot_to_human', 'handover/human_to_robot',
               'stacking/default')
# RL steps per task in the paper (docs/reference_benchmark.md, Training and
# evaluation): 10^6 for reach and lifting, 3 x 10^6 for the others.
PAPER_STEPS = {'reach/dense': 1_000_000, 'lifting/default': 1_000_000,
               'pick_place/default': 3_000_000,
               'handover/robot_to_human': 3_000_000,
               'handover/human_to_robot': 3_000_000,
               'stacking/default': 3_000_000}
# The paper's runs had no collision penalty
# (docs/reference_benchmark.md, Rewards and success).
PAPER_TASK_KWARGS = {'collision_reward': 0.0}

# Labels of the agents in reports, as the paper names them.
AGENT_LABELS = {'sac': 'SAC', 'rsi': 'SAC + RSI', 'sir': 'SIR',
                'air': 'AIR (no RSI)', 'rsi+air': 'AIR',
                'sac_lag': 'SAC-Lagrangian'}
# Task kwargs that are a grid's fields or a run's flags.
_RUN_KWARGS = ('robot', 'action_space', 'seed', 'motions')
_VARIANT_KEYS = ('agent', 'task_kwargs', 'overrides', 'task_overrides',
                 'label')


@dataclasses.dataclass(frozen=True)
class Run:
  """One training run of a grid.

  Attributes:
    name: the run's directory below the sweep's runs/ folder.
    task: 'domain/task'.
    agent: an `agents.train` agent.
    seed: the run seed.
    split: the motion split's seed, or None (the task's own motions).
    run_config: the `agents.train.make_run_config` arguments but the
      dataset (which the sweep makes and fills in).
  """
  name: str
  task: str
  agent: str
  seed: int
  split: Optional[int]
  run_config: Mapping


@dataclasses.dataclass(frozen=True)
class Grid:
  """A set of training runs with shared settings.

  Attributes:
    name: the grid's name (a key of GRIDS, or a user's).
    tasks: 'domain/task' names (registered tasks).
    agents: agents of `agents.train` (sac, rsi, sir, air, rsi+air,
      sac_lag) or names of `variants`.
    seeds: run seeds.
    steps: RL steps of every run, or {task: steps} per task.
    eval_every: RL steps between evaluations.
    eval_episodes: deterministic episodes per evaluation.
    robot: robot name or description file.
    config: SAC preset (agents.config.CONFIGS).
    overrides: SACConfig field overrides.
    task_kwargs: task kwargs of every run (and of its evaluation).
    motions: None (the shipped synthetic people) or a folder of recordings
      (`task_kwargs['motions']`; the reference's folder layout is taken
      as it is).
    splits: motion split seeds (hrc_suite.tasks.runtime.motions.MotionSplit):
    each
      run trains on the train side of its split and is evaluated on both
      sides; () trains on all of the task's motions.
    test_clips: clips on the test side of a split.
    dataset_episodes: noisy-expert episodes of the dataset of each task an
      RSI, SIR or AIR run needs.
    expert_episodes: deterministic expert episodes whose mean return is the
      normalised return's 1.
    checkpoint_every: RL steps between a run's checkpoints.
    imitation_kwargs: kwargs of the imitation wrappers (agents.imitation).
    variants: {name: {'agent': an agents.train agent, 'task_kwargs': {...},
      'overrides': {...}, 'task_overrides': {task: {...}}, 'label': '...'}}:
      agents run with task kwargs and config overrides of their own (over
      the grid's; task_overrides over those, for the runs of one task:
      entries of tasks not in the grid are unused), named in reports by
      their label.
    description: what the grid is for.
  """
  name: str
  tasks: Tuple[str, ...]
  agents: Tuple[str, ...]
  seeds: Tuple[int, ...]
  steps: object
  eval_every: int
  eval_episodes: int
  robot: str = 'schunk'
  config: str = 'reference'
  overrides: Mapping = dataclasses.field(default_factory=dict)
  task_kwargs: Mapping = dataclasses.field(default_factory=dict)
  motions: Optional[str] = None
  splits: Tuple[int, ...] = ()
  test_clips: int = 2
  dataset_episodes: int = 50
  expert_episodes: int = 20
  checkpoint_every: int = 10_000
  imitation_kwargs: Mapping = dataclasses.field(default_factory=dict)
  variants: Mapping = dataclasses.field(default_factory=dict)
  description: str = ''

  def __post_init__(self):
    for name in ('tasks', 'agents', 'seeds', 'splits'):
      object.__setattr__(self, name, tuple(getattr(self, name)))
    for name in ('overrides', 'task_kwargs', 'imitation_kwargs', 'variants'):
      object.__setattr__(self, name, dict(getattr(self, name)))
    if isinstance(self.steps, Mapping):
      object.__setattr__(self, 'steps', dict(self.steps))
    self.check()

  def _fail(self, field, expected):
    raise ValueError(f'Grid {self.name!r}: {field}={getattr(self, field)!r}: '
                     f'expected {expected}')

  def check(self) -> None:
    """Checks every field.

    Raises:
      ValueError: naming the first bad field.
    """
    if not self.tasks:
      self._fail('tasks', 'at least one domain/task')
    for name in self.tasks:
      domain, sep, task = str(name).partition('/')
      if not sep:
        self._fail('tasks', f'domain/task names, not {name!r}')
      try:
        suite.task_class(domain, task)
      except ValueError as e:
        raise ValueError(f'Grid {self.name!r}: tasks: {e}') from None
    if len(set(self.tasks)) != len(self.tasks):
      self._fail('tasks', 'each task once')
    self._check_variants()
    known = train.AGENTS + tuple(self.variants)
    if not self.agents or any(a not in known for a in self.agents):
      self._fail('agents', 'a non-empty list of ' + ', '.join(known))
    if len(set(self.agents)) != len(self.agents):
      self._fail('agents', 'each agent once')
    if not self.seeds or any(not _integer(s) or s < 0 for s in self.seeds):
      self._fail('seeds', 'a non-empty list of integers >= 0')
    if len(set(self.seeds)) != len(self.seeds):
      self._fail('seeds', 'each seed once')
    if isinstance(self.steps, dict):
      unknown = sorted(set(self.steps) - set(self.tasks))
      missing = sorted(set(self.tasks) - set(self.steps))
      if unknown or missing:
        self._fail('steps', f'one entry per task (missing {missing}, not '
                   f'in the grid {unknown})')
      values = list(self.steps.values())
    else:
      values = [self.steps]
    if any(not _integer(v) or v < 1 for v in values):
      self._fail('steps', 'integers >= 1 (one, or {task: steps})')
    for name, low in (('eval_every', 1), ('eval_episodes', 1),
                      ('dataset_episodes', 1), ('expert_episodes', 1),
                      ('checkpoint_every', 1), ('test_clips', 1)):
      if not _integer(getattr(self, name)) or getattr(self, name) < low:
        self._fail(name, f'an integer >= {low}')
    if self.config not in train.config_lib.CONFIGS:
      self._fail('config', 'one of ' + ', '.join(train.config_lib.CONFIGS))
    for entry in self.agents:
      for task in self.tasks:
        try:
          train.agent_config(self.agent_of(entry), self.config,
                             self.overrides_of(entry, task))
        except ValueError as e:
          raise ValueError(f'Grid {self.name!r}: agent {entry!r}: {e}'
                           ) from None
    for name in _RUN_KWARGS:
      if name in self.task_kwargs:
        self._fail('task_kwargs', f'no {name!r} (a field or flag of its own)')
    if any(not _integer(s) or s < 0 for s in self.splits):
      self._fail('splits', 'a list of integers >= 0')
    if len(set(self.splits)) != len(self.splits):
      self._fail('splits', 'each split once')
    if self.motions is not None and not os.path.isdir(self.motions):
      self._fail('motions', 'None or an existing folder of recordings')
    if not re.fullmatch(r'[A-Za-z0-9_.-]+', self.name):
      self._fail('name', 'letters, digits, _, . and -')

  def _check_variants(self):
    for name, variant in self.variants.items():
      if not re.fullmatch(r'[A-Za-z0-9_.+-]+', str(name)):
        self._fail('variants', f'names of letters, digits, _, ., + and -, '
                   f'not {name!r}')
      if name in train.AGENTS:
        self._fail('variants', f'names other than the agents\' ({name!r} is '
                   'an agent)')
      if not isinstance(variant, Mapping) or set(variant) - set(
          _VARIANT_KEYS) or 'agent' not in variant:
        self._fail('variants', f'{{name: {{agent, task_kwargs, overrides, '
                   f'label}}}}; {name!r} is {variant!r}')
      if variant['agent'] not in train.AGENTS:
        self._fail('variants', f'an agent of {", ".join(train.AGENTS)} for '
                   f'{name!r}, not {variant["agent"]!r}')
      for key in ('task_kwargs', 'overrides', 'task_overrides'):
        if not isinstance(variant.get(key, {}), Mapping):
          self._fail('variants', f'a dict as {name!r}\'s {key}')
      bad = sorted(set(variant.get('task_kwargs', {})) & set(_RUN_KWARGS))
      if bad:
        self._fail('variants', f'no {bad} in {name!r}\'s task_kwargs')

  def agent_of(self, entry: str) -> str:
    """The agents.train agent of an entry of `agents`.

    Args:
      entry: an agent or a variant's name.

    Returns:
      The agent.
    """
    return self.variants[entry]['agent'] if entry in self.variants else entry

  def overrides_of(self, entry: str, task: str) -> Dict[str, Any]:
    """The config overrides of the runs of an entry of `agents` on a task.

    Args:
      entry: an agent or a variant's name.
      task: 'domain/task'.

    Returns:
      The grid's overrides updated with the variant's and its task's.
    """
    variant = self.variants.get(entry, {})
    return dict(self.overrides, **variant.get('overrides', {}),
                **variant.get('task_overrides', {}).get(task, {}))

  def label_of(self, entry: str) -> str:
    """The report's name of an entry of `agents`.

    Args:
      entry: an agent or a variant's name.

    Returns:
      The variant's label, or the agent's (AGENT_LABELS).
    """
    if entry in self.variants:
      return self.variants[entry].get('label') or entry
    return AGENT_LABELS.get(entry, entry)

  def replace(self, **changes: Any) -> 'Grid':
    """A copy with fields changed.

    Args:
      **changes: new values of fields.

    Returns:
      The checked copy.

    Raises:
      ValueError: unknown fields, or a bad value.
    """
    fields = {f.name for f in dataclasses.fields(self)}
    unknown = sorted(set(changes) - fields)
    if unknown:
      raise ValueError(f'Unknown grid fields {unknown}: expected some of '
                       f'{", ".join(sorted(fields))}')
    return dataclasses.replace(self, **changes)

  def steps_of(self, task: str) -> int:
    """RL steps of the runs of a task.

    Args:
      task: 'domain/task' of the grid.

    Returns:
      The steps.
    """
    return int(self.steps[task] if isinstance(self.steps, dict)
               else self.steps)

  def to_dict(self) -> Dict[str, Any]:
    """JSON-ready dict (Grid(**d) rebuilds it)."""
    values = dataclasses.asdict(self)
    for name in ('tasks', 'agents', 'seeds', 'splits'):
      values[name] = list(values[name])
    return values

  @classmethod
  def from_dict(cls, values: Mapping[str, Any]) -> 'Grid':
    """The grid of a `to_dict` dict.

    Args:
      values: the fields.

    Returns:
      The checked grid.

    Raises:
      ValueError: a bad field.
    """
    return cls(**values)

  def needs_dataset(self, entry: str) -> bool:
    """Whether the runs of an entry of `agents` need an expert dataset.

    Args:
      entry: an agent or a variant's name.

    Returns:
      Whether they do (RSI, SIR, AIR).
    """
    return self.agent_of(entry) in imitation.NEEDS_DATASET

  def dataset_tasks(self) -> List[str]:
    """The tasks whose runs need an expert dataset."""
    if any(self.needs_dataset(agent) for agent in self.agents):
      return list(self.tasks)
    return []

  def task_kwargs_of(self, split: Optional[int] = None,
                     side: str = 'train') -> Dict[str, Any]:
    """The task kwargs of a run, its motions and split side included.

    Args:
      split: None, or the run's motion split seed.
      side: the split's side, 'train' or 'test'.

    Returns:
      The kwargs.
    """
    kwargs = dict(self.task_kwargs)
    if split is not None:
      kwargs['motions'] = {'split': side, 'test_clips': self.test_clips,
                           'split_seed': int(split), 'source': self.motions}
    elif self.motions is not None:
      kwargs['motions'] = self.motions
    return kwargs

  def runs(self) -> List[Run]:
    """Every run of the grid, task by task, then agent, split and seed."""
    runs = []
    for task in self.tasks:
      domain, name = task.split('/')
      action_space = default_action_space(domain, name)
      for agent in self.agents:
        for split in (self.splits or (None,)):
          for seed in self.seeds:
            run_name = f'{domain}-{name}/{agent}/'
            if split is not None:
              run_name += f'split{split}-'
            run_name += f'seed{seed}'
            task_kwargs = dict(
                self.task_kwargs_of(split),
                **self.variants.get(agent, {}).get('task_kwargs', {}))
            config = {
                'domain': domain, 'task': name, 'robot': self.robot,
                'action_space': action_space, 'agent': self.agent_of(agent),
                'config': self.config,
                'overrides': self.overrides_of(agent, task),
                'task_kwargs': task_kwargs,
                'seed': int(seed), 'steps': self.steps_of(task),
                'eval_every': self.eval_every,
                'eval_episodes': self.eval_episodes,
                'checkpoint_every': self.checkpoint_every,
                'imitation_kwargs': (dict(self.imitation_kwargs)
                                     if self.agent_of(agent)
                                     in imitation.NEEDS_DATASET + ('air',)
                                     else {}),
            }
            if split is not None:
              config['eval_sets'] = {
                  'unseen': {'motions': self.task_kwargs_of(
                      split, 'test')['motions']}}
            runs.append(Run(name=run_name, task=task, agent=agent,
                            seed=int(seed), split=split, run_config=config))
    return runs


def _integer(value):
  return isinstance(value, int) and not isinstance(value, bool)


def default_action_space(domain: str, task: str) -> str:
  """The task's default action space (the paper's: joint for reach,
  Cartesian for the others).

  Args:
    domain: a registered domain.
    task: a registered task of it.

  Returns:
    'joint' or 'cartesian'.
  """
  task_class = suite.task_class(domain, task)
  if task_class is None:
    return 'cartesian'
  return task_class.DEFAULT_ACTION_SPACE


def _paper():
  return Grid(
      name='paper', tasks=PAPER_TASKS, agents=PAPER_AGENTS,
      seeds=(0, 1, 2, 3, 4), steps=dict(PAPER_STEPS), eval_every=200_000,
      eval_episodes=20, config='reference', task_kwargs=PAPER_TASK_KWARGS,
      dataset_episodes=100, expert_episodes=50, checkpoint_every=50_000,
      description='The paper\'s main figure as the paper ran it.')


def _paper_reduced():
  return _paper().replace(
      name='paper_reduced', seeds=(0, 1, 2), steps=100_000,
      eval_every=25_000, eval_episodes=10, dataset_episodes=50,
      expert_episodes=20, checkpoint_every=10_000,
      description=('The paper\'s figure at a 2-core machine\'s budget: 3 '
                   'seeds, 10^5 RL steps per run.'))


def _overfitting():
  return Grid(
      name='overfitting', tasks=('lifting/default',), agents=('sac',),
      seeds=(0,), steps=1_000_000, eval_every=200_000, eval_episodes=20,
      config='reference', task_kwargs=PAPER_TASK_KWARGS,
      splits=(0, 1, 2, 3, 4), test_clips=2, checkpoint_every=50_000,
      description=('The paper\'s overfitting ablation: lifting, trained on '
                   'the train side of each motion split, evaluated on both '
                   'sides.'))


def _smoke():
  return Grid(
      name='smoke', tasks=('reach/dense',), agents=('sac', 'rsi'),
      seeds=(0,), steps=300, eval_every=150, eval_episodes=2,
      config='quick', overrides={'min_replay_size': 64, 'batch_size': 32},
      task_kwargs={'time_limit': 3.0}, dataset_episodes=2,
      expert_episodes=2, checkpoint_every=100,
      description=('Two short runs (SAC and SAC + RSI on reach) that check '
                   'an installation or a cluster.'))


# The safe-RL study (docs/safe_rl.md): the cost penalty per unsafe step
# (about 20 times reach's typical step reward of -0.1 x distance) and the
# per-episode cost limits, about a quarter of a random policy's cost on
# reach's 100-step episodes (0-9) and under a tenth of it on pick and
# place's 1000-step ones (24-388), measured with the shield off. The
# multiplier's step scales with an episode's excess cost, 10-40 times
# larger on pick and place's episodes: its learning rate is smaller there.
SAFE_RL_PENALTY = 1.0
SAFE_RL_LIMITS = {'reach/dense': 1.0, 'pick_place/default': 10.0}
SAFE_RL_MULTIPLIER_RATES = {'reach/dense': 0.01, 'pick_place/default': 0.001}


def _safe_rl():
  limits = {task: {'cost_limit': limit,
                   'multiplier_learning_rate': SAFE_RL_MULTIPLIER_RATES[task]}
            for task, limit in SAFE_RL_LIMITS.items()}
  off = {'shield': 'off'}
  return Grid(
      name='safe_rl', tasks=tuple(SAFE_RL_LIMITS),
      agents=('sac_shield', 'sac_penalty', 'sac_lag_off', 'sac_lag_shield'),
      variants={
          'sac_shield': {'agent': 'sac', 'label': 'SAC, shield'},
          'sac_penalty': {'agent': 'sac', 'task_kwargs': off,
                          'overrides': {'cost_penalty': SAFE_RL_PENALTY},
                          'label': 'SAC, no shield, cost penalty'},
          'sac_lag_off': {'agent': 'sac_lag', 'task_kwargs': off,
                      'task_overrides': limits,
                      'label': 'SAC-Lagrangian, no shield'},
          'sac_lag_shield': {'agent': 'sac_lag', 'task_overrides': limits,
                             'label': 'SAC-Lagrangian, shield'}},
      seeds=(0, 1, 2),
      steps={'reach/dense': 50_000, 'pick_place/default': 100_000},
      eval_every=10_000, eval_episodes=10, config='quick',
      task_kwargs={'observations': 'safe_rl', 'collision_reward': 0.0},
      checkpoint_every=10_000,
      description=('Learning to be safe against being kept safe: SAC and '
                   'SAC-Lagrangian with and without the shield, judged by '
                   'the safety cost.'))


GRIDS = {'paper': _paper, 'paper_reduced': _paper_reduced,
         'overfitting': _overfitting, 'safe_rl': _safe_rl, 'smoke': _smoke}


def get(name: str) -> Grid:
  """A grid by name.

  Args:
    name: a key of GRIDS.

  Returns:
    The grid.

  Raises:
    ValueError: an unknown name.
  """
  if name not in GRIDS:
    raise ValueError(f'Unknown grid {name!r}: expected one of '
                     f'{", ".join(GRIDS)}')
  return GRIDS[name]()


def describe(grid: Grid) -> Dict[str, int]:
  """A grid's size.

  Args:
    grid: the grid.

  Returns:
    {'runs': n, 'steps': total RL steps}.
  """
  runs = grid.runs()
  return {'runs': len(runs),
          'steps': sum(int(r.run_config['steps']) for r in runs)}
