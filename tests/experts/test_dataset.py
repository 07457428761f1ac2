"""Expert datasets: round trip, snapshots, resume, corrupt files."""

import json
import shutil

import numpy as np
import pytest

from hrc_suite import suite
from hrc_suite.experts import dataset
from hrc_suite.experts import noise as noise_lib
from hrc_suite.tasks.runtime import snapshot_arrays

DOMAIN, TASK = 'reach', 'dense'
KWARGS = {'robot': 'schunk', 'time_limit': 1.5}   # 15 RL steps
SEED = 3


class Scripted:
  """A deterministic policy that also reports an 'expert' action."""

  def __init__(self, env):
    self._size = env.action_spec().shape[0]
    self._k = 0
    self.last_expert_action = None

  def __call__(self, timestep):
    if timestep.first():
      self._k = 0
    self._k += 1
    phase = 0.4 * self._k + np.arange(self._size)
    self.last_expert_action = np.sin(phase)
    return 0.9 * self.last_expert_action


def _collect(directory, episodes, **kwargs):
  return dataset.collect(directory, DOMAIN, TASK, KWARGS, policy='scripted',
                         episodes=episodes, seed=SEED, make_policy=Scripted,
                         **kwargs)


def test_round_trip_equals_a_fresh_recording(tmp_path):
  data = _collect(tmp_path / 'data', 2)
  assert len(data.episodes) == 2
  meta = data.metadata
  assert (meta['domain'], meta['task'], meta['robot'], meta['action_space'],
          meta['seed'], meta['policy']) == (DOMAIN, TASK, 'schunk', 'joint',
                                            SEED, 'scripted')
  assert list(meta['observations']) == ['goal_difference']
  for index in range(2):
    # Episode i is what a fresh environment seeded SEED + i plays.
    env = suite.load(DOMAIN, TASK, task_kwargs=KWARGS,
                     environment_kwargs={'random_state': SEED + index})
    expected, summary = dataset.record_episode(env, Scripted(env))
    episode = data.episodes[index]
    assert sorted(episode.arrays) == sorted(expected)
    for key, value in expected.items():
      np.testing.assert_array_equal(episode.arrays[key], value, err_msg=key)
      assert episode.arrays[key].dtype == value.dtype, key
    assert meta['episodes'][index] == {
        'index': index, 'file': f'episode_{index:05d}.npz',
        'seed': SEED + index, **summary}
  episode = data.episodes[1]
  steps = episode.num_steps
  assert steps == 15 and episode.step_types.tolist() == [0] + [1] * 14 + [2]
  assert episode.observations['goal_difference'].shape == (16, 6)
  assert episode.expert_observations['joint_positions'].shape == (16, 6)
  np.testing.assert_array_equal(episode.actions,
                                0.9 * episode.expert_actions)
  assert episode.episode_metrics['steps'] == 15.0
  np.testing.assert_array_equal(episode.rewards,
                                episode.step_metrics['reward'])


def test_snapshot_restores_the_next_observation(tmp_path):
  data = _collect(tmp_path / 'data', 2)
  episode = data.episodes[1]
  env = data.environment(seed=123)   # Another seed: the snapshot decides.
  env.reset()
  for step in (0, 6, 14):
    state = data.snapshot(1, step)
    env.task.set_state(env.physics, state)
    restored = env.task.get_state(env.physics)
    for part in ('physics', 'shield', 'player'):
      assert snapshot_arrays.equal(restored[part], state[part]), part
    timestep = env.step(episode.actions[step])
    assert timestep.reward == episode.rewards[step]
    np.testing.assert_array_equal(
        timestep.observation['goal_difference'],
        episode.observations['goal_difference'][step + 1])
    np.testing.assert_array_equal(
        env.task.robot.joint_positions(env.physics),
        episode.expert_observations['joint_positions'][step + 1])
  with pytest.raises(IndexError, match='step 16 outside 0..15'):
    episode.snapshot(16)


def _assert_same_dataset(first, second):
  assert first.metadata == second.metadata
  for a, b in zip(first.episodes, second.episodes):
    assert sorted(a.arrays) == sorted(b.arrays)
    for key, value in a.arrays.items():
      np.testing.assert_array_equal(value, b.arrays[key], err_msg=key)


def test_resume_after_an_interruption_equals_a_straight_run(tmp_path):
  straight = _collect(tmp_path / 'straight', 3)
  resumed_dir = tmp_path / 'resumed'
  _collect(resumed_dir, 1)
  # A crash while writing episode 1: its file renamed (or half-written as
  # .tmp) but dataset.json not yet updated. The resume rewrites it.
  (resumed_dir / 'episode_00001.npz').write_bytes(b'partial')
  (resumed_dir / 'episode_00001.npz.tmp').write_bytes(b'partial')
  assert len(dataset.load_dataset(resumed_dir).episodes) == 1
  resumed = _collect(resumed_dir, 3)
  assert len(resumed.episodes) == 3
  _assert_same_dataset(straight, resumed)
  # Asking for fewer episodes than there are keeps them all.
  assert len(_collect(resumed_dir, 2).episodes) == 3


def test_resume_with_another_configuration_is_refused(tmp_path):
  _collect(tmp_path / 'data', 1)
  with pytest.raises(dataset.DatasetError,
                     match=r"describes another collection \(seed: stored 3, "
                     'requested 4'):
    dataset.collect(tmp_path / 'data', DOMAIN, TASK, KWARGS,
                    policy='scripted', episodes=2, seed=4,
                    make_policy=Scripted)


def test_corrupt_or_missing_files_are_named(tmp_path):
  directory = tmp_path / 'data'
  _collect(directory, 2)
  path = directory / 'episode_00000.npz'
  path.write_bytes(path.read_bytes()[:200])
  data = dataset.load_dataset(directory)
  with pytest.raises(dataset.DatasetError,
                     match=r'episode_00000.npz: cannot read the episode file'):
    data.episodes[0].actions   # pylint: disable=expression-not-assigned
  (directory / 'episode_00001.npz').unlink()
  with pytest.raises(dataset.DatasetError,
                     match='episode_00001.npz: episode file missing'):
    data.episodes[1]   # pylint: disable=expression-not-assigned
  # An episode whose arrays disagree in length.
  other = tmp_path / 'other'
  _collect(other, 1)
  with np.load(other / 'episode_00000.npz') as saved:
    arrays = dict(saved)
  arrays['reward'] = arrays['reward'][:-1]
  np.savez(other / 'episode_00000.npz', **arrays)
  with pytest.raises(dataset.DatasetError,
                     match=r'reward has shape \(14,\), expected 15'):
    dataset.load_dataset(other).episodes[0].rewards   # pylint: disable=expression-not-assigned
  meta = other / 'dataset.json'
  meta.write_text(meta.read_text()[:50])
  with pytest.raises(dataset.DatasetError, match='dataset.json: not a '
                     'readable dataset description'):
    dataset.load_dataset(other)
  meta.write_text(json.dumps({'format': 'something else'}))
  with pytest.raises(dataset.DatasetError, match="not an hrc_suite.expert"):
    dataset.load_dataset(other)
  shutil.rmtree(other)
  with pytest.raises(dataset.DatasetError, match='no dataset description'):
    dataset.load_dataset(other)


def test_bad_arguments():
  with pytest.raises(ValueError, match="Unknown policy 'random'"):
    dataset.collect('/nonexistent', DOMAIN, TASK, KWARGS, policy='random')
  with pytest.raises(ValueError, match='episodes must be an integer >= 0'):
    dataset.collect('/nonexistent', DOMAIN, TASK, KWARGS, episodes=-1,
                    policy='scripted', make_policy=Scripted)


def test_noisy_expert_dataset(tmp_path):
  data = dataset.collect(tmp_path / 'data', DOMAIN, TASK, KWARGS,
                         policy='noisy_expert', episodes=1, seed=SEED)
  parameters = data.metadata['noise']
  assert parameters['weight'] == noise_lib.DEFAULT_WEIGHT
  size = data.metadata['action']['shape'][0]
  assert parameters['alpha'] == [10.0] * size   # Joint space (reference).
  episode = data.episodes[0]
  difference = episode.actions - episode.expert_actions
  assert np.mean(difference != 0.0) > 0.9   # (Equal only where clipped.)
  # (1 - w) a_e + w X with w = 0.02 and |a_e| <= 1: at most 0.02 (1 + |X|).
  assert np.abs(difference).max() < 0.2


class _Random:
  """Uniform actions from a seed reset at every first timestep."""

  def __init__(self, env):
    self._shape = env.action_spec().shape
    self._random = None

  def __call__(self, timestep):
    if timestep.first():
      self._random = np.random.RandomState(7)
    return self._random.uniform(-1.0, 1.0, self._shape)


@pytest.mark.parametrize('domain, task', suite.all_tasks())
def test_reseeded_environment_plays_what_a_fresh_one_plays(domain, task):
  # collect and evaluate reuse one environment, reseeding it per episode.
  kwargs = {'robot': 'schunk', 'time_limit': 1.0, 'observations': 'full'}
  used = suite.load(domain, task, task_kwargs=kwargs,
                    environment_kwargs={'random_state': 0})
  dataset.record_episode(used, _Random(used))
  used.random_state.seed(1)
  replayed, _ = dataset.record_episode(used, _Random(used))
  fresh = suite.load(domain, task, task_kwargs=kwargs,
                     environment_kwargs={'random_state': 1})
  expected, _ = dataset.record_episode(fresh, _Random(fresh))
  assert sorted(replayed) == sorted(expected)
  for key, value in expected.items():
    np.testing.assert_array_equal(replayed[key], value, err_msg=key)
