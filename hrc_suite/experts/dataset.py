"""Expert datasets: one .npz per episode plus dataset.json (docs/datasets.md).

  data = dataset.collect('/tmp/reach', 'reach', 'dense',
                         {'robot': 'schunk'}, policy='noisy_expert',
                         episodes=10, seed=0)
  data = dataset.load_dataset('/tmp/reach')
  episode = data.episodes[3]          # opened on access
  episode.actions, episode.observations['goal_difference']
  env = data.environment()            # same task and kwargs
  env.reset(); env.task.set_state(env.physics, data.snapshot(3, 17))

Episode i is played in an environment whose random_state is seeded
`seed + i` (and, for the noisy expert, with the noise of episode i of
`NoisyExpert(seed=seed)`), so it does not depend on the episodes before
it: an interrupted collection resumes at the first missing episode and
ends with the same files as an uninterrupted one. Files are written to a
temporary name and renamed, dataset.json last.
"""

import json
import math
import os
import pathlib
import zipfile
from typing import Any, Callable, Mapping, Optional, Sequence, Union

from dm_control import composer
from dm_control.composer.observation import observable as observable_lib
import dm_env
import numpy as np

from hrc_suite import experts
from hrc_suite import suite
from hrc_suite.experts import noise as noise_lib
from hrc_suite.tasks.runtime import snapshot_arrays

FORMAT = 'hrc_suite.expert_dataset'
FORMAT_VERSION = 1
METADATA_FILE = 'dataset.json'
EPISODE_FILE = 'episode_{:05d}.npz'
POLICIES = ('expert', 'noisy_expert')
# Keys of an episode file (docs/datasets.md); '<name>' parts vary.
OBSERVATION = 'observation/'                  # (T+1, ...) per observable
EXPERT_OBSERVATION = 'expert_observation/'    # (T+1, ...) noise-free, full
STEP_METRICS = 'step_metrics/'                # (T,) float64 per metric
EPISODE_METRICS = 'episode_metrics/'          # () float64 per metric
SNAPSHOT = 'snapshot/'                        # see _stack_snapshots
_PER_STEP = ('action', 'expert_action', 'reward', 'discount')
_REQUIRED = _PER_STEP + ('step_type', SNAPSHOT + 'specs',
                         SNAPSHOT + 'spec_index')
# Configuration entries a resumed collection must share with the stored one.
_CONFIG_KEYS = ('format', 'format_version', 'domain', 'task', 'task_kwargs',
                'robot', 'action_space', 'policy', 'noise', 'seed',
                'observations', 'expert_observations', 'action')


class DatasetError(ValueError):
  """A dataset file is missing, corrupt or does not match."""


def episode_seed(seed: int, index: int) -> int:
  """Seed of episode `index`'s environment random_state.

  Args:
    seed: the dataset's seed.
    index: the episode's index.

  Returns:
    seed + index.
  """
  return int(seed) + int(index)


def _json_value(value):
  """A JSON-able copy: non-finite floats become None, arrays lists."""
  if isinstance(value, dict):
    return {str(k): _json_value(v) for k, v in value.items()}
  if isinstance(value, (list, tuple)):
    return [_json_value(v) for v in value]
  if isinstance(value, np.ndarray):
    return _json_value(value.tolist())
  if isinstance(value, np.generic):
    value = value.item()
  if isinstance(value, float) and not math.isfinite(value):
    return None
  return value


def _write_atomically(path, write):
  """write(file) into path.tmp, flushed to disk, then renamed to path."""
  path = pathlib.Path(path)
  tmp = path.with_name(path.name + '.tmp')
  with open(tmp, 'wb') as f:
    write(f)
    f.flush()
    os.fsync(f.fileno())
  os.replace(tmp, path)


# ---------------------------------------------------------------- recording


def _spec_of(value):
  value = np.asarray(value)
  return {'shape': list(value.shape), 'dtype': value.dtype.name}


def expert_observation_names(task: composer.Task) -> tuple[str, ...]:
  """Every non-camera observable of the task (the 'full' preset).

  Args:
    task: the task.

  Returns:
    The observables' names, in the task's order.
  """
  return tuple(name for name, obs in task.task_observables.items()
               if not isinstance(obs, observable_lib.MJCFCamera))


class _SnapshotStack:
  """Per-step snapshots as a few arrays: the distinct specs (JSON strings),
  each step's spec index, and per dtype one flat buffer with per-step
  offsets (step t's numbers are buffer[offsets[t]:offsets[t + 1]])."""

  def __init__(self):
    self._specs, self._index, self._parts = {}, [], []

  def add(self, state):
    """Flattens `state` now (flat buffers are smaller than nested states)."""
    spec, buffers = snapshot_arrays.flatten(state)
    key = snapshot_arrays.spec_to_json(spec)
    self._index.append(self._specs.setdefault(key, len(self._specs)))
    self._parts.append(buffers)

  def arrays(self):
    parts = self._parts
    arrays = {SNAPSHOT + 'specs': np.array(list(self._specs), dtype=str),
              SNAPSHOT + 'spec_index': np.array(self._index, dtype=np.int32)}
    for name in sorted({name for buffers in parts for name in buffers}):
      sizes = [buffers[name].size if name in buffers else 0
               for buffers in parts]
      offsets = np.zeros(len(parts) + 1, dtype=np.int64)
      np.cumsum(sizes, out=offsets[1:])
      arrays[f'{SNAPSHOT}buffer/{name}'] = np.concatenate(
          [buffers[name] for buffers in parts if name in buffers])
      arrays[f'{SNAPSHOT}offsets/{name}'] = offsets
    return arrays


def record_episode(env: composer.Environment,
                   policy: Callable[[dm_env.TimeStep], np.ndarray],
                   progress: Optional[Any] = None
                   ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
  """Plays one episode (env.reset() first).

  Args:
    env: the environment.
    policy: action = policy(timestep); it may expose `last_expert_action`
      (a NoisyExpert), otherwise the executed action is the expert action.
    progress: a tqdm bar, updated per step, or None.

  Returns:
    (arrays, summary): the episode file's arrays (docs/datasets.md) and
    its summary: 'steps' and the episode metrics (JSON-able).
  """
  timestep = env.reset()
  task, physics = env.task, env.physics
  observables = task.task_observables
  expert_names = expert_observation_names(task)
  # The raw callables: no noise, no delay (as experts read them).
  expert_callables = [
      observables[name]._callable(physics)   # pylint: disable=protected-access
      for name in expert_names]
  observations = {name: [] for name in timestep.observation}
  expert_observations = {name: [] for name in expert_names}
  per_step = {name: [] for name in _PER_STEP}
  step_types, metrics = [], []
  states = _SnapshotStack()

  def observe(timestep):
    step_types.append(int(timestep.step_type))
    for name, value in timestep.observation.items():
      observations[name].append(np.array(value, copy=True))
    for name, fn in zip(expert_names, expert_callables):
      expert_observations[name].append(np.array(fn(), copy=True))
    states.add(task.get_state(physics))

  observe(timestep)
  while not timestep.last():
    action = np.asarray(policy(timestep), dtype=np.float64)
    expert_action = getattr(policy, 'last_expert_action', None)
    expert_action = action if expert_action is None else expert_action
    timestep = env.step(action)
    per_step['action'].append(action)
    per_step['expert_action'].append(np.asarray(expert_action, np.float64))
    per_step['reward'].append(timestep.reward)
    per_step['discount'].append(timestep.discount)
    metrics.append(dict(task.step_metrics))
    observe(timestep)
    if progress is not None:
      progress.update(1)

  arrays = {}
  for prefix, values in ((OBSERVATION, observations),
                         (EXPERT_OBSERVATION, expert_observations)):
    for name, sequence in values.items():
      arrays[prefix + name] = np.stack(sequence)
  for name, sequence in per_step.items():
    arrays[name] = np.asarray(sequence, dtype=np.float64)
  arrays['step_type'] = np.array(step_types, dtype=np.uint8)
  metric_names = sorted({name for step in metrics for name in step})
  for name in metric_names:
    arrays[STEP_METRICS + name] = np.array(
        [float(step.get(name, np.nan)) for step in metrics])
  episode_metrics = dict(task.episode_metrics)
  for name, value in episode_metrics.items():
    arrays[EPISODE_METRICS + name] = np.array(float(value))
  arrays.update(states.arrays())
  summary = {'steps': len(metrics), **_json_value(episode_metrics)}
  return arrays, summary


def _environment(domain, task, task_kwargs, seed=None):
  return suite.load(domain, task, task_kwargs=dict(task_kwargs),
                    environment_kwargs={'random_state': seed})


def _make_policy(env, policy, seed, noise_kwargs):
  """(policy object, JSON noise parameters or None)."""
  if policy == 'expert':
    if noise_kwargs:
      raise ValueError(f'noise_kwargs {noise_kwargs} given for the '
                       "noise-free policy 'expert'")
    return experts.make(env), None
  size = env.action_spec().shape[0]
  noise = noise_lib.OrnsteinUhlenbeckNoise.reference(
      size, env.task.action_space_name, **dict(noise_kwargs or {}))
  parameters = dict(noise.parameters, episode_seed=(
      'NoisyExpert seed = dataset seed; episode i: '
      'noise.episode_random_state(seed, i)'))
  return noise_lib.NoisyExpert(experts.make(env), noise, seed=seed), (
      parameters)


def _check_policy(policy, make_policy):
  if make_policy is None and policy not in POLICIES:
    raise ValueError(f'Unknown policy {policy!r}: expected one of '
                     f'{", ".join(map(repr, POLICIES))} (or pass '
                     'make_policy)')


class DatasetWriter:
  """Creates a dataset directory or reopens one with the same
  configuration; `add` writes the next episode.

  Args:
    directory: the dataset folder (created if needed).
    config: the collection's configuration (`collect`'s dataset.json
      entries but the episodes); a reopened folder keeps the episodes
      whose files exist, up to the first missing one.

  Raises:
    DatasetError: the folder holds another collection, or an unreadable
      description.
  """

  def __init__(self, directory: Union[str, os.PathLike],
               config: Mapping[str, Any]):
    self.directory = pathlib.Path(directory)
    self.directory.mkdir(parents=True, exist_ok=True)
    path = self.directory / METADATA_FILE
    config = _json_value(config)
    if path.exists():
      metadata = _read_metadata(path)
      different = [key for key in _CONFIG_KEYS
                   if metadata.get(key) != config.get(key)]
      if different:
        details = '; '.join(f'{key}: stored {metadata.get(key)!r}, '
                            f'requested {config.get(key)!r}'
                            for key in different)
        raise DatasetError(f'{path} describes another collection ({details})'
                           ': use another directory')
      episodes = metadata['episodes']
      # Keep the episodes whose files exist, up to the first missing one.
      kept = 0
      while kept < len(episodes) and (
          self.directory / episodes[kept]['file']).exists():
        kept += 1
      metadata['episodes'] = episodes[:kept]
      self.metadata = metadata
    else:
      self.metadata = dict(config, episodes=[])
      self._write_metadata()

  @property
  def num_episodes(self) -> int:
    """The number of episodes written."""
    return len(self.metadata['episodes'])

  def add(self, arrays: Mapping[str, np.ndarray],
          summary: Mapping[str, Any]) -> None:
    """Writes episode `num_episodes` and updates dataset.json.

    Args:
      arrays: the episode file's arrays (`record_episode`).
      summary: its summary (`record_episode`).
    """
    index = self.num_episodes
    name = EPISODE_FILE.format(index)
    _write_atomically(self.directory / name,
                      lambda f: np.savez_compressed(f, **arrays))
    self.metadata['episodes'].append(
        {'index': index, 'file': name,
         'seed': episode_seed(self.metadata['seed'], index), **summary})
    self._write_metadata()

  def _write_metadata(self):
    text = json.dumps(self.metadata, indent=1, allow_nan=False) + '\n'
    _write_atomically(self.directory / METADATA_FILE,
                      lambda f: f.write(text.encode()))


def collect(directory: Union[str, os.PathLike], domain: str, task: str,
            task_kwargs: Optional[Mapping[str, Any]] = None,
            policy: str = 'noisy_expert', episodes: int = 1, seed: int = 0,
            noise_kwargs: Optional[Mapping[str, Any]] = None,
            make_policy: Optional[Callable[[composer.Environment],
                                           Callable]] = None,
            progress: bool = False) -> 'Dataset':
  """Collects episodes 0..episodes-1 into `directory` (resuming after the
  ones already there) and returns the loaded Dataset.

  Args:
    directory: the dataset folder (created if needed).
    domain: a registered task's domain.
    task: the task.
    task_kwargs: its kwargs (JSON-able; robot, action_space, time_limit..).
    policy: 'expert' or 'noisy_expert', or a name for `make_policy`.
    episodes: total number of episodes the folder should hold.
    seed: episode i runs with environment seed `seed + i`.
    noise_kwargs: overrides of the reference OU parameters (alpha, sigma,
      dt, mu, weight, start) for 'noisy_expert'.
    make_policy: optional `make_policy(env) -> policy` replacing the
      expert (e.g. a scripted policy); `policy` is then only its name.
    progress: show tqdm progress bars.

  Returns:
    The loaded Dataset.

  Raises:
    ValueError: an unknown policy, bad episodes or seed, or noise_kwargs
      for the policy 'expert'.
    DatasetError: the folder holds another collection.
  """
  _check_policy(policy, make_policy)
  if not isinstance(episodes, int) or episodes < 0:
    raise ValueError(f'episodes must be an integer >= 0, got {episodes!r}')
  if not isinstance(seed, int) or seed < 0:
    raise ValueError(f'seed must be an integer >= 0, got {seed!r}')
  task_kwargs = dict(task_kwargs or {})
  env = _environment(domain, task, task_kwargs, seed)
  if make_policy is not None:
    agent, noise = make_policy(env), None
  else:
    agent, noise = _make_policy(env, policy, seed, noise_kwargs)
  first = env.reset().observation   # Compiles; observation shapes.
  physics = env.physics
  observables = env.task.task_observables
  config = {
      'format': FORMAT, 'format_version': FORMAT_VERSION,
      'domain': domain, 'task': task, 'task_kwargs': task_kwargs,
      'robot': env.task.robot.description.name,
      'action_space': env.task.action_space_name,
      'policy': policy, 'noise': noise, 'seed': seed,
      'episode_seeds': 'seed + episode index',
      'observations': {name: _spec_of(value) for name, value in
                       first.items()},
      'expert_observations': {
          name: _spec_of(observables[name]._callable(physics)())   # pylint: disable=protected-access
          for name in expert_observation_names(env.task)},
      'action': {'shape': list(env.action_spec().shape),
                 'names': env.action_spec().name.split('\t'),
                 'minimum': -1.0, 'maximum': 1.0},
      'control_timestep': env.task.control_timestep,
  }
  writer = DatasetWriter(directory, config)
  bar = steps = None
  if progress:
    import tqdm   # pylint: disable=g-import-not-at-top
    bar = tqdm.tqdm(total=episodes, initial=min(writer.num_episodes, episodes),
                    unit='episode', desc=f'{domain}/{task}')
    steps = tqdm.tqdm(total=env.task.horizon, unit='step', leave=False)
  try:
    for index in range(writer.num_episodes, episodes):
      env.random_state.seed(episode_seed(seed, index))
      if hasattr(agent, 'set_episode'):
        agent.set_episode(index)
      if steps is not None:
        steps.reset()
      arrays, summary = record_episode(env, agent, progress=steps)
      writer.add(arrays, summary)
      if bar is not None:
        bar.update(1)
        bar.set_postfix(success=summary['success'],
                        ret=f'{summary["return"]:.1f}')
  finally:
    for b in (steps, bar):
      if b is not None:
        b.close()
  return load_dataset(directory)


# ------------------------------------------------------------------ loading


def _read_metadata(path):
  try:
    metadata = json.loads(pathlib.Path(path).read_text())
  except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
    raise DatasetError(f'{path}: not a readable dataset description ({e})'
                       ) from e
  found = metadata.get('format') if isinstance(metadata, dict) else None
  if found != FORMAT:
    raise DatasetError(f'{path}: not an {FORMAT} description (format '
                       f'{found!r})')
  if metadata.get('format_version') != FORMAT_VERSION:
    raise DatasetError(f'{path}: format version '
                       f'{metadata.get("format_version")!r}, this code reads '
                       f'version {FORMAT_VERSION}')
  return metadata


class Episode:
  """One episode file, read on first use (every array at once).

  Args:
    path: the episode's .npz file.
  """

  def __init__(self, path: Union[str, os.PathLike]):
    self.path = pathlib.Path(path)
    self._arrays = None

  def _load(self):
    if self._arrays is None:
      try:
        with np.load(self.path, allow_pickle=False) as data:
          arrays = {name: data[name] for name in data.files}
      except (OSError, ValueError, EOFError, zipfile.BadZipFile,
              KeyError) as e:
        raise DatasetError(f'{self.path}: cannot read the episode file '
                           f'({type(e).__name__}: {e})') from e
      self._check(arrays)
      self._arrays = arrays
    return self._arrays

  def _check(self, arrays):
    missing = [key for key in _REQUIRED if key not in arrays]
    if missing:
      raise DatasetError(f'{self.path}: missing arrays {missing}')
    steps = arrays['action'].shape[0]
    for key, value in arrays.items():
      expected = None
      if key in _PER_STEP or key.startswith(STEP_METRICS):
        expected = steps
      elif key.startswith((OBSERVATION, EXPERT_OBSERVATION)) or key in (
          'step_type', SNAPSHOT + 'spec_index'):
        expected = steps + 1
      elif key.startswith(SNAPSHOT + 'offsets/'):
        expected = steps + 2
      if expected is not None and (value.ndim == 0 or
                                   value.shape[0] != expected):
        raise DatasetError(f'{self.path}: {key} has shape {value.shape}, '
                           f'expected {expected} entries along axis 0 '
                           f'({steps} steps)')

  def _group(self, prefix):
    return {key[len(prefix):]: value for key, value in self._load().items()
            if key.startswith(prefix)}

  # The properties raise DatasetError for an unreadable or inconsistent
  # file.

  @property
  def arrays(self) -> dict[str, np.ndarray]:
    """Every array of the file by key."""
    return dict(self._load())

  @property
  def num_steps(self) -> int:
    """T, the number of RL steps (actions)."""
    return self._load()['action'].shape[0]

  @property
  def observations(self) -> dict[str, np.ndarray]:
    """The agent's observations by name, (T+1, ...) each."""
    return self._group(OBSERVATION)

  @property
  def expert_observations(self) -> dict[str, np.ndarray]:
    """Every non-camera observable without noise or delay by name,
    (T+1, ...) each."""
    return self._group(EXPERT_OBSERVATION)

  @property
  def actions(self) -> np.ndarray:
    """The executed actions (T, action size)."""
    return self._load()['action']

  @property
  def expert_actions(self) -> np.ndarray:
    """The expert's actions before noise (T, action size)."""
    return self._load()['expert_action']

  @property
  def rewards(self) -> np.ndarray:
    """The rewards (T,) of the timesteps the actions led to."""
    return self._load()['reward']

  @property
  def discounts(self) -> np.ndarray:
    """The discounts (T,) of the timesteps the actions led to."""
    return self._load()['discount']

  @property
  def step_types(self) -> np.ndarray:
    """The step types (T+1,) uint8: 0 first, 1 mid, 2 last."""
    return self._load()['step_type']

  @property
  def step_metrics(self) -> dict[str, np.ndarray]:
    """The step metrics by name, (T,) float64 each (NaN where a step
    lacks the entry)."""
    return self._group(STEP_METRICS)

  @property
  def episode_metrics(self) -> dict[str, float]:
    """The episode metrics at the end by name."""
    return {k: float(v) for k, v in self._group(EPISODE_METRICS).items()}

  def snapshot(self, step: int) -> dict[str, Any]:
    """The task state at a timestep, for set_state.

    Args:
      step: the timestep, 0..num_steps.

    Returns:
      The snapshot (tasks/runtime/snapshots.py).

    Raises:
      IndexError: a step outside 0..num_steps.
      DatasetError: an unreadable file or snapshot.
    """
    arrays = self._load()
    count = arrays[SNAPSHOT + 'spec_index'].shape[0]
    if not isinstance(step, (int, np.integer)) or not 0 <= step < count:
      raise IndexError(f'{self.path}: step {step!r} outside 0..{count - 1}')
    specs = arrays[SNAPSHOT + 'specs']
    spec_index = int(arrays[SNAPSHOT + 'spec_index'][step])
    buffers = {}
    prefix = SNAPSHOT + 'buffer/'
    for key, data in arrays.items():
      if key.startswith(prefix):
        name = key[len(prefix):]
        offsets = arrays[f'{SNAPSHOT}offsets/{name}']
        buffers[name] = data[offsets[step]:offsets[step + 1]]
    try:
      return snapshot_arrays.unflatten(
          snapshot_arrays.spec_from_json(str(specs[spec_index])), buffers)
    except (ValueError, IndexError) as e:
      raise DatasetError(f'{self.path}: snapshot {step}: {e}') from e


class EpisodeSequence:
  """The episodes of a dataset, each loaded when first read
  (`Dataset.episodes`): len(), indexing (negative too) and iteration.

  Args:
    directory: the dataset folder.
    entries: dataset.json's episode entries (each with its 'file').
  """

  def __init__(self, directory: pathlib.Path,
               entries: Sequence[Mapping[str, Any]]):
    self._directory = directory
    self._entries = entries
    self._cache = {}

  def __len__(self):
    return len(self._entries)

  def __getitem__(self, index: int) -> 'Episode':
    if not -len(self) <= index < len(self):
      raise IndexError(f'episode {index} of a dataset with {len(self)}')
    index %= len(self)
    if index not in self._cache:
      path = self._directory / self._entries[index]['file']
      if not path.exists():
        raise DatasetError(f'{path}: episode file missing (listed in '
                           f'{self._directory / METADATA_FILE})')
      self._cache[index] = Episode(path)
    return self._cache[index]

  def __iter__(self):
    return (self[i] for i in range(len(self)))


class Dataset:
  """A loaded dataset: `metadata` (dataset.json), lazy `episodes`.

  Args:
    directory: the dataset folder.
    metadata: its dataset.json, parsed.
  """

  def __init__(self, directory: Union[str, os.PathLike],
               metadata: Mapping[str, Any]):
    self.directory = pathlib.Path(directory)
    self.metadata = metadata
    self.episodes = EpisodeSequence(self.directory, metadata['episodes'])

  def snapshot(self, episode: int, step: int) -> dict[str, Any]:
    """Nested task state of an episode at a timestep (set_state).

    Args:
      episode: the episode's index.
      step: the timestep, 0..its num_steps.

    Returns:
      The snapshot (`Episode.snapshot`).

    Raises:
      IndexError: an episode or step out of range.
      DatasetError: a missing or unreadable episode file.
    """
    return self.episodes[episode].snapshot(step)

  def environment(self, seed: Optional[int] = None) -> composer.Environment:
    """A new environment of the dataset's task and task kwargs.

    Args:
      seed: the environment's random_state seed (None: unseeded).

    Returns:
      The environment (hrc_suite.suite.load).
    """
    return _environment(self.metadata['domain'], self.metadata['task'],
                        self.metadata['task_kwargs'], seed)


def load_dataset(directory: Union[str, os.PathLike]) -> Dataset:
  """The dataset in a folder (dataset.json and its episode files).

  Args:
    directory: the dataset folder.

  Returns:
    The Dataset (episode files opened on access).

  Raises:
    DatasetError: no readable dataset.json of this format there.
  """
  path = pathlib.Path(directory) / METADATA_FILE
  if not path.exists():
    raise DatasetError(f'{path}: no dataset description (is {directory} a '
                       'dataset folder?)')
  return Dataset(directory, _read_metadata(path))
