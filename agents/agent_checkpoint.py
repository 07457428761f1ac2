"""An agent's checkpoint: writing, reading, and loading its policy alone.

A checkpoint is a directory (written atomically, agents/checkpoint_files.py)
holding

* agent.json: the algorithm ('agent'), its config, the seed, the
  observation keys and sizes, the action bounds, the update schedule's
  counters and the caller's metadata;
* learner.npz: the learner's whole state (parameters, optimiser states,
  key, and what else the algorithm learns, e.g. a Lagrange multiplier);
* replay.npz: the replay buffer;
* agent.npz: the actor's and the replay sampling's RandomStates, the
  policy the actor acts with (agents/agent.py: one learner call behind),
  the adder's episode in progress and the caller's arrays.

`restore` continues an agent exactly; `load_policy` rebuilds only the
policy, for evaluation and rendering.
"""

import collections
import os
import pathlib
from typing import Any, Dict, Mapping, Optional, Union

import dm_env
import numpy as np

from agents import action_scaler
from agents import adders
from agents import agent as agent_lib
from agents import builders
from agents import checkpoint_files
from agents import observations
from agents import variable_utils

CHECKPOINT_FORMAT = 1
_EXTRA_PREFIX = 'extra/'
_ACTING_PREFIX = 'acting_policy/'
_POLICY_PREFIX = 'policy_params/'
# Entries of agent.json that must match between a checkpoint and the agent
# restoring it.
_MATCHING = ('format', 'agent', 'config', 'images', 'observation_keys',
             'observation_size', 'action_size', 'action_minimum',
             'action_maximum')

CheckpointExtras = collections.namedtuple('CheckpointExtras',
                                          ['metadata', 'arrays'])


def _random_state_arrays(prefix, random_state):
  """{prefix/field: array} of a np.random.RandomState's state."""
  _, keys, position, has_gauss, cached = random_state.get_state()
  return {f'{prefix}/keys': keys,
          f'{prefix}/position': np.int64(position),
          f'{prefix}/has_gauss': np.int64(has_gauss),
          f'{prefix}/cached_gaussian': np.float64(cached)}


def _restore_random_state(arrays, prefix, random_state):
  """Sets a RandomState to the state `_random_state_arrays` saved."""
  random_state.set_state((
      'MT19937', arrays[f'{prefix}/keys'],
      int(arrays[f'{prefix}/position']),
      int(arrays[f'{prefix}/has_gauss']),
      float(arrays[f'{prefix}/cached_gaussian'])))


def describe(agent: agent_lib.Agent) -> Dict[str, Any]:
  """agent.json's entries that identify what the agent is.

  Args:
    agent: the agent.

  Returns:
    The algorithm, its config, the seed, the observation keys and sizes,
    and the action bounds.
  """
  scaler = agent.action_scaler
  return {
      'format': CHECKPOINT_FORMAT,
      'agent': agent.builder.name,
      'config': agent.config.to_dict(),
      'seed': agent.seed,
      'images': agent.images,
      'observation_keys': list(agent.flattener.keys),
      'observation_size': agent.flattener.size,
      'action_size': scaler.size,
      'action_minimum': scaler.minimum.tolist(),
      'action_maximum': scaler.maximum.tolist(),
  }


def _normalised(description):
  """A stored description in the current form: the algorithm named
  (checkpoints without the entry are SAC's) and its config rebuilt
  through its config class (which reads older field names)."""
  description = dict(description)
  description.setdefault('agent', 'sac')
  config_class = builders.config_class(description['agent'])
  description['config'] = config_class.from_dict(
      description['config']).to_dict()
  return description


def save(agent: agent_lib.Agent, directory: Union[str, os.PathLike],
         metadata: Optional[Mapping[str, Any]] = None,
         arrays: Optional[Mapping[str, np.ndarray]] = None) -> None:
  """Writes the whole agent to `directory` (replaced atomically).

  Args:
    agent: an `agents.agent.Agent`.
    directory: the checkpoint directory.
    metadata: JSON-able dict of the caller's (e.g. loop counters).
    arrays: {name: array} of the caller's (e.g. environment RNG state).
    Both come back from `restore`.
  """
  description = describe(agent)
  description['counters'] = agent.counters()
  description['metadata'] = metadata or {}
  agent_arrays = dict(
      _random_state_arrays('sample_random_state', agent.sample_random_state),
      **_random_state_arrays('actor_random_state', agent.actor.random_state))
  agent_arrays.update(agent.adder.state())
  for key, value in checkpoint_files.flatten_to_arrays(
      agent.acting_policy_params).items():
    agent_arrays[_ACTING_PREFIX + key] = value
  for key, value in (arrays or {}).items():
    agent_arrays[_EXTRA_PREFIX + key] = np.asarray(value)
  with checkpoint_files.atomic_directory(directory) as staging:
    checkpoint_files.save_json(staging / 'agent.json', description)
    checkpoint_files.save_arrays(staging / 'learner.npz', agent.learner.state())
    checkpoint_files.save_arrays(staging / 'replay.npz', agent.replay.state())
    checkpoint_files.save_arrays(staging / 'agent.npz', agent_arrays)


def restore(agent: agent_lib.Agent,
            directory: Union[str, os.PathLike]) -> CheckpointExtras:
  """Restores a `save`d agent into one built with the same spec, algorithm
  and config.

  Args:
    agent: the agent to restore into.
    directory: the checkpoint directory.

  Returns:
    CheckpointExtras(metadata, arrays) given to `save`.

  Raises:
    ValueError: a checkpoint of another agent (spec, algorithm or config),
      or state arrays that do not match.
  """
  directory = pathlib.Path(directory)
  description = _normalised(checkpoint_files.load_json(directory /
                                                    'agent.json'))
  expected = describe(agent)
  for key in _MATCHING:
    if description.get(key) != expected[key]:
      raise ValueError(f'Checkpoint {directory} has {key}='
                       f'{description.get(key)!r}, this agent has '
                       f'{expected[key]!r}')
  agent_arrays = checkpoint_files.load_arrays(directory / 'agent.npz')
  agent.learner.restore(checkpoint_files.load_arrays(directory / 'learner.npz'))
  agent.replay.restore(checkpoint_files.load_arrays(directory / 'replay.npz'))
  _restore_random_state(agent_arrays, 'sample_random_state',
                        agent.sample_random_state)
  if 'actor_random_state/keys' in agent_arrays:
    _restore_random_state(agent_arrays, 'actor_random_state',
                          agent.actor.random_state)
  else:   # Written when the actor sampled with a JAX key: seeded by it.
    agent.actor.random_state.seed(
        np.asarray(agent_arrays['actor_key']).astype(np.uint32))
  agent.adder.restore(agent_arrays)
  acting = {key[len(_ACTING_PREFIX):]: value
            for key, value in agent_arrays.items()
            if key.startswith(_ACTING_PREFIX)}
  learner_policy = agent.learner.get_variables([agent_lib.POLICY])[0]
  # Checkpoints written before the acting policy was saved act with the
  # learner's.
  agent.variable_client.restore(
      checkpoint_files.unflatten_from_arrays(learner_policy, acting) if acting
      else learner_policy)
  agent.restore_counters(description['counters'], description['seed'])
  extras = {key[len(_EXTRA_PREFIX):]: value
            for key, value in agent_arrays.items()
            if key.startswith(_EXTRA_PREFIX)}
  return CheckpointExtras(description['metadata'], extras)


def load_policy(directory: Union[str, os.PathLike],
                environment: dm_env.Environment, deterministic: bool = True,
                seed: int = 0) -> agent_lib.TimestepPolicy:
  """timestep -> action callable of a saved agent's policy on `environment`.

  Reads only agent.json and learner.npz's policy parameters; the
  environment must have the observations and actions the agent was trained
  on.

  Args:
    directory: the agent's checkpoint directory.
    environment: a dm_env environment with the agent's specs.
    deterministic: tanh(mean) actions, else samples seeded by `seed`.
    seed: the sampling seed.

  Returns:
    The policy: a timestep -> action callable.

  Raises:
    ValueError: another checkpoint format, or an environment whose
      observations or actions differ from the checkpoint's.
  """
  directory = pathlib.Path(directory)
  raw = checkpoint_files.load_json(directory / 'agent.json')
  if raw.get('format') != CHECKPOINT_FORMAT:
    raise ValueError(f'Checkpoint {directory} has format '
                     f'{raw.get("format")!r}, expected {CHECKPOINT_FORMAT}')
  description = _normalised(raw)
  flattener = observations.ObservationFlattener(
      environment.observation_spec(), images=description['images'],
      exclude=adders.COST_OBSERVATIONS)
  if list(flattener.keys) != description['observation_keys'] or (
      flattener.size != description['observation_size']):
    raise ValueError(
        f'The environment observes {list(flattener.keys)} ({flattener.size} '
        f'values), the checkpoint {directory} was trained on '
        f'{description["observation_keys"]} '
        f'({description["observation_size"]} values)')
  scaler = action_scaler.ActionScaler(environment.action_spec())
  if (scaler.size != description['action_size']
      or scaler.minimum.tolist() != description['action_minimum']
      or scaler.maximum.tolist() != description['action_maximum']):
    raise ValueError(f'The environment action spec {environment.action_spec()}'
                     f' differs from the checkpoint\'s ({directory})')
  builder = builders.make_builder(description['agent'],
                                  description['config'])
  networks = builder.make_networks(flattener.size, scaler.size)
  arrays = {key[len(_POLICY_PREFIX):]: value for key, value in
            checkpoint_files.load_arrays(directory / 'learner.npz').items()
            if key.startswith(_POLICY_PREFIX)}
  params = checkpoint_files.unflatten_from_arrays(
      networks.policy_init(np.random.RandomState(0)), arrays)
  actor = builder.make_actor(networks, variable_utils.FixedVariables(params),
                             seed, evaluation=deterministic)
  return agent_lib.TimestepPolicy(flattener, actor, scaler)
