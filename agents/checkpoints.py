"""Training-run checkpoints: layout, atomic writes, lookup and loading.

A run's log directory holds

  config.json                run configuration (task, agent, seeds, ...)
  train.csv, eval.csv        one row per training episode / evaluation
  tensorboard/               the same scalars as TensorBoard events
  checkpoints/latest         name of the newest complete checkpoint
  checkpoints/step_<steps>/  agent/ (SACAgent.save: parameters, optimiser
                             states, replay, RNG keys, counters), loop.json
                             (loop counters, schedules, the training
                             environment's and its wrappers' RandomState
                             scalars, the run config) and
                             random_states.npz (their Mersenne-Twister
                             keys); episode.npz if the checkpoint was
                             taken inside an episode (the task's snapshot
                             and the last observation)

A checkpoint is written into a temporary directory that is renamed into
place, then `latest` is replaced atomically, so an interrupted write never
leaves a half checkpoint behind `latest`. The newest KEEP checkpoints are
kept.
"""

import json
import os
import shutil
from typing import Any, Dict, Mapping, Optional, Tuple, Union

import numpy as np

from agents import agent as agent_lib
from agents import agent_checkpoint
from hrc_suite.tasks.runtime import snapshot_arrays

KEEP = 2                     # checkpoints kept per run
_LATEST = 'latest'
_PREFIX = 'step_'
_LOOP_FILE = 'loop.json'
_RNG_FILE = 'random_states.npz'
_EPISODE_FILE = 'episode.npz'
_TASK_PREFIX = 'task/'
_OBSERVATION_PREFIX = 'observation/'
AGENT_DIR = 'agent'
# A file or folder's path.
Path = Union[str, os.PathLike]
# The state tuple of np.random.RandomState.get_state.
RandomStateTuple = Tuple[str, np.ndarray, int, int, float]


def checkpoint_root(logdir: Path) -> str:
  """A run's checkpoints/ folder.

  Args:
    logdir: the run's log directory.

  Returns:
    The folder's path.
  """
  return os.path.join(os.fspath(logdir), 'checkpoints')


def write_json(path: Path, value: Any) -> None:
  """Writes JSON atomically (a temporary file of this process, renamed).

  Args:
    path: the file.
    value: JSON-able.
  """
  temporary = f'{path}.{os.getpid()}.tmp'
  with open(temporary, 'w') as f:
    json.dump(value, f, indent=2, sort_keys=True)
    f.write('\n')
  os.replace(temporary, path)


def read_json(path: Path) -> Any:
  """Reads a JSON file.

  Args:
    path: the file.

  Returns:
    Its value.
  """
  with open(path) as f:
    return json.load(f)


def random_state_to_arrays(random_state: np.random.RandomState
                           ) -> Tuple[np.ndarray, Dict[str, Any]]:
  """A RandomState's state as an array and JSON-ready scalars.

  Args:
    random_state: the RandomState.

  Returns:
    (key array, {'name', 'position', 'has_gauss', 'cached_gaussian'}).
  """
  name, key, position, has_gauss, cached = random_state.get_state()
  return np.asarray(key), {'name': name, 'position': int(position),
                           'has_gauss': int(has_gauss),
                           'cached_gaussian': float(cached)}


def random_state_from_arrays(key: np.ndarray,
                             scalars: Mapping[str, Any]) -> RandomStateTuple:
  """The state tuple for RandomState.set_state.

  Args:
    key: the key array of `random_state_to_arrays`.
    scalars: its scalars.

  Returns:
    The state tuple.
  """
  return (scalars['name'], np.asarray(key, dtype=np.uint32),
          int(scalars['position']), int(scalars['has_gauss']),
          float(scalars['cached_gaussian']))


def save(logdir: Path, steps: int, agent: agent_lib.Agent,
         loop_state: Mapping[str, Any],
         random_states: Mapping[str, np.random.RandomState],
         episode: Optional[Tuple[Mapping[str, Any], Mapping[str, Any],
                                 Mapping[str, Any]]] = None) -> str:
  """Writes checkpoint step_<steps> of a run and points `latest` to it.

  Args:
    logdir: the run's log directory.
    steps: environment steps done (names the checkpoint).
    agent: the agent (`agent_checkpoint.save`).
    loop_state: JSON-ready dict (counters, schedules, run config).
    random_states: {name: np.random.RandomState} of the training
      environment (and its wrappers).
    episode: None at an episode boundary, else (info, observation, task
      snapshot) of the episode in progress: the loop's JSON-ready info and
      observation dict (`EnvironmentLoop.episode_state`) and the task's
      `get_state` snapshot.

  Returns:
    The checkpoint's directory.
  """
  root = checkpoint_root(logdir)
  os.makedirs(root, exist_ok=True)
  name = f'{_PREFIX}{steps:010d}'
  final = os.path.join(root, name)
  temporary = final + '.tmp'
  if os.path.exists(temporary):
    shutil.rmtree(temporary)
  os.makedirs(temporary)
  agent_checkpoint.save(agent, os.path.join(temporary, AGENT_DIR))
  keys, scalars = {}, {}
  for label, random_state in random_states.items():
    keys[label], scalars[label] = random_state_to_arrays(random_state)
  np.savez(os.path.join(temporary, _RNG_FILE), **keys)
  episode_info = None
  if episode is not None:
    episode_info, observation, snapshot = episode
    arrays = snapshot_arrays.to_arrays(snapshot, prefix=_TASK_PREFIX)
    for key, value in observation.items():
      arrays[_OBSERVATION_PREFIX + key] = np.asarray(value)
    np.savez(os.path.join(temporary, _EPISODE_FILE), **arrays)
  write_json(os.path.join(temporary, _LOOP_FILE),
             dict(loop_state, random_states=scalars, episode=episode_info))
  if os.path.exists(final):   # Same step saved before (e.g. a rerun).
    shutil.rmtree(final)
  os.replace(temporary, final)
  pointer = os.path.join(root, _LATEST)
  with open(pointer + '.tmp', 'w') as f:
    f.write(name + '\n')
  os.replace(pointer + '.tmp', pointer)
  for old in sorted(n for n in os.listdir(root)
                    if n.startswith(_PREFIX) and not n.endswith('.tmp'))[
                        :-KEEP]:
    shutil.rmtree(os.path.join(root, old))
  return final


def latest(logdir: Path) -> Optional[str]:
  """The newest complete checkpoint directory of a run, or None.

  Args:
    logdir: the run's log directory.

  Returns:
    The directory, or None if the run has no checkpoint.

  Raises:
    ValueError: a `latest` pointer naming no directory.
  """
  pointer = os.path.join(checkpoint_root(logdir), _LATEST)
  if not os.path.exists(pointer):
    return None
  with open(pointer) as f:
    name = f.read().strip()
  directory = os.path.join(checkpoint_root(logdir), name)
  if not os.path.isdir(directory):
    raise ValueError(f'{pointer} names {name!r}, which does not exist')
  return directory


def resolve(path: Path) -> str:
  """A checkpoint directory from a path.

  Args:
    path: a run's logdir, its checkpoints/ folder or a checkpoint
      directory itself.

  Returns:
    The checkpoint directory (the newest of a run).

  Raises:
    ValueError: a path that holds no checkpoint.
  """
  path = os.fspath(path)
  if os.path.exists(os.path.join(path, _LOOP_FILE)):
    return path
  for root in (path, os.path.dirname(path.rstrip(os.sep))):
    if os.path.basename(root.rstrip(os.sep)) == 'checkpoints':
      found = latest(os.path.dirname(root.rstrip(os.sep)))
      if found:
        return found
  found = latest(path) if os.path.isdir(path) else None
  if found is None:
    raise ValueError(f'No checkpoint at {path!r}: expected a run logdir '
                     '(with checkpoints/latest), its checkpoints/ folder or '
                     f'a checkpoint directory holding {_LOOP_FILE}')
  return found


def load_episode(directory: Path
                 ) -> Optional[Tuple[Dict[str, Any], Dict[str, np.ndarray],
                                     Dict[str, Any]]]:
  """The episode a checkpoint was taken in.

  Args:
    directory: the checkpoint directory.

  Returns:
    (info, observation dict, task snapshot), or None if it was taken at an
    episode boundary.
  """
  state = read_json(os.path.join(directory, _LOOP_FILE))
  if state.get('episode') is None:
    return None
  with np.load(os.path.join(directory, _EPISODE_FILE),
               allow_pickle=False) as data:
    arrays = {name: data[name] for name in data.files}
  observation = {name[len(_OBSERVATION_PREFIX):]: value
                 for name, value in arrays.items()
                 if name.startswith(_OBSERVATION_PREFIX)}
  return (state['episode'], observation,
          snapshot_arrays.from_arrays(arrays, prefix=_TASK_PREFIX))


def agent_directory(path: Path) -> str:
  """The agent directory (for `agents.agent_checkpoint.load_policy`).

  Args:
    path: a run logdir, its checkpoints/ folder, a checkpoint or an agent
      directory.

  Returns:
    The agent directory.

  Raises:
    ValueError: a path that holds no checkpoint.
  """
  path = os.fspath(path)
  if os.path.exists(os.path.join(path, 'agent.json')):
    return path
  return os.path.join(resolve(path), AGENT_DIR)


def load_loop_state(directory: Path
                    ) -> Tuple[Dict[str, Any], Dict[str, RandomStateTuple]]:
  """A checkpoint's loop state and random states.

  Args:
    directory: the checkpoint directory.

  Returns:
    (loop state dict, {name: RandomState state tuple}).

  Raises:
    ValueError: random state files that disagree.
  """
  state = read_json(os.path.join(directory, _LOOP_FILE))
  with np.load(os.path.join(directory, _RNG_FILE),
               allow_pickle=False) as data:
    keys = {name: data[name] for name in data.files}
  scalars = state['random_states']
  if sorted(keys) != sorted(scalars):
    raise ValueError(f'{directory}: {_RNG_FILE} holds {sorted(keys)}, '
                     f'{_LOOP_FILE} describes {sorted(scalars)}')
  return state, {name: random_state_from_arrays(keys[name], scalars[name])
                 for name in keys}
