"""Behaviour cloning: the fit reproduces the dataset's actions, the binary
fits and evaluates end to end."""

import json

from absl import flags
import numpy as np
import pytest

from agents import behaviour_cloning as bc
from agents import observations as observations_lib
from hrc_suite.experts import dataset as dataset_lib

TASK_KWARGS = {'robot': 'panda', 'action_space': 'cartesian',
               'time_limit': 1.0}


@pytest.fixture(scope='module')
def reach_dataset(tmp_path_factory):
  directory = tmp_path_factory.mktemp('bc_reach_dataset')
  return dataset_lib.collect(directory, 'reach', 'dense', TASK_KWARGS,
                             policy='noisy_expert', episodes=2, seed=7)


def test_fit_reproduces_the_recorded_actions(reach_dataset):
  env = bc.environment(reach_dataset, seed=0)
  flattener = observations_lib.ObservationFlattener(env.observation_spec())
  inputs, targets = bc.training_pairs(reach_dataset, flattener)
  steps = sum(len(e.actions) for e in reach_dataset.episodes)
  assert inputs.shape == (steps, flattener.size)
  assert targets.shape == (steps, 3)
  episode = reach_dataset.episodes[1]
  np.testing.assert_array_equal(
      inputs[-1], flattener({k: v[len(episode.actions) - 1]
                             for k, v in episode.observations.items()}))
  config = bc.BehaviourCloningConfig(hidden_sizes=(32, 32), steps=1500)
  policy, loss = bc.fit(inputs, targets, flattener, config, seed=0)
  # Far below the spread of the actions (a constant policy's error).
  assert loss < 0.05 * np.sum(targets.var(axis=0))

  class Step:   # A timestep-like carrier of one recorded observation.
    observation = {k: v[3] for k, v in episode.observations.items()}
  np.testing.assert_allclose(policy(Step), episode.actions[3], atol=0.1)
  with pytest.raises(ValueError, match=r'\[-1, 1\]'):
    bc.fit(inputs, 2 * targets + 2, flattener, config)
  with pytest.raises(ValueError, match='hidden_sizes'):
    bc.BehaviourCloningConfig(hidden_sizes=())


def test_binary_fits_and_evaluates(reach_dataset, tmp_path):
  flag_values = flags.FlagValues()
  bc.define_flags(flag_values)
  output = tmp_path / 'bc.json'
  flag_values(['bc', f'--dataset={reach_dataset.directory}', '--episodes=2',
               '--steps=200', '--hidden_sizes=16,16', f'--output={output}'])
  bc.main([], flag_values=flag_values)
  result = json.loads(output.read_text())
  assert len(result['episodes']) == 2
  assert 0.0 <= result['summary']['success']['mean'] <= 1.0
  assert result['config']['hidden_sizes'] == [16, 16]
