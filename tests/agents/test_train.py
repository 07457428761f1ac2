"""End-to-end tests of agents.train, agents.evaluate and agents.plot, and of
exact resumption from a checkpoint."""

import glob
import json
import os
import pathlib
import shutil

from absl import flags
import numpy as np
import pytest

from agents import agent_checkpoint
from agents import checkpoints
from agents import evaluate
from agents import logging as logging_lib
from agents import plot
from agents import train
from hrc_suite.human import clip as clip_lib
from hrc_suite.rendering import episode as render
from hrc_suite.experts import dataset as dataset_lib

# Ten-step episodes of reach/dense and a tiny SAC, so that runs take seconds.
_TASK_KWARGS = {'time_limit': 1.0}
_OVERRIDES = {'min_replay_size': 16, 'batch_size': 8, 'hidden_sizes': [16, 16]}
# Columns of train.csv that depend on timing, not on the run's computation.
_TIMING = ('steps_per_second', 'wall_time', 'eval_seconds')


def _run_config(seed=0, steps=60, eval_every=25, checkpoint_every=20):
  return train.make_run_config(
      'reach', 'dense', 'schunk', 'cartesian', overrides=_OVERRIDES,
      task_kwargs=_TASK_KWARGS, seed=seed, steps=steps,
      eval_every=eval_every, eval_episodes=2,
      checkpoint_every=checkpoint_every)


def _checkpoint_arrays(directory):
  """{relative path[/array name]: array or JSON value} of a checkpoint's
  agent files (parameters, optimiser states, replay, keys, counters)."""
  found = {}
  agent_dir = os.path.join(directory, checkpoints.AGENT_DIR)
  for path in sorted(glob.glob(os.path.join(agent_dir, '**', '*'),
                               recursive=True)):
    name = os.path.relpath(path, agent_dir)
    if path.endswith('.npz'):
      with np.load(path, allow_pickle=False) as data:
        for key in data.files:
          found[f'{name}/{key}'] = data[key]
    elif path.endswith('.json'):
      found[name] = checkpoints.read_json(path)
  return found


def _deterministic_rows(path):
  rows = logging_lib.read_csv(path)
  return [{k: v for k, v in row.items() if k not in _TIMING} for row in rows]


def _assert_same_runs(whole, split):
  """Asserts that two runs' latest checkpoints and logs are identical (but
  for timing); returns the checkpoint's arrays."""
  expected = _checkpoint_arrays(checkpoints.latest(whole))
  actual = _checkpoint_arrays(checkpoints.latest(split))
  assert expected.keys() == actual.keys() and expected
  for key, value in expected.items():
    if isinstance(value, np.ndarray):
      np.testing.assert_array_equal(actual[key], value, err_msg=key)
    else:
      assert actual[key] == value, key
  for name in ('train.csv', 'eval.csv'):
    assert (_deterministic_rows(os.path.join(split, name)) ==
            _deterministic_rows(os.path.join(whole, name))), name
  return expected


def _run_binary(module, args):
  """Runs a binary's main with its command-line flags (own FlagValues)."""
  flag_values = flags.FlagValues()
  module.define_flags(flag_values)
  flag_values([module.__name__] + list(args))
  module.main([], flag_values=flag_values)


@pytest.fixture(scope='module')
def two_runs(tmp_path_factory):
  """Seed 0 trained through the function, seed 1 through the command line
  (the same configuration)."""
  root = tmp_path_factory.mktemp('runs')
  logdirs = [str(root / 'seed0'), str(root / 'seed1')]
  train.train(_run_config(seed=0), logdirs[0])
  _run_binary(train, [
      '--domain=reach', '--task=dense', '--robot=schunk',
      '--action_space=cartesian', '--task_kwargs=' + json.dumps(_TASK_KWARGS),
      '--override=min_replay_size=16', '--override=batch_size=8',
      '--override=hidden_sizes=[16, 16]', '--seed=1', '--steps=60',
      '--eval_every=25', '--eval_episodes=2', '--checkpoint_every=20',
      f'--logdir={logdirs[1]}', '--noprogress'])
  return logdirs


def test_train_writes_logs_and_checkpoints(two_runs):
  logdir = two_runs[0]
  config = checkpoints.read_json(os.path.join(logdir, 'config.json'))
  assert config['horizon'] == 10 and config['min_return'] < 0
  assert config['sac_config']['min_replay_size'] == 16
  rows = logging_lib.read_csv(os.path.join(logdir, 'train.csv'))
  assert [int(r['step']) for r in rows] == [10, 20, 30, 40, 50, 60]
  for name in ('episode_return', 'success', 'shield_interventions',
               'contacts_human_critical'):
    assert name in rows[0]
  evaluations = logging_lib.read_csv(os.path.join(logdir, 'eval.csv'))
  assert [int(r['step']) for r in evaluations] == [0, 25, 50]
  assert all(0.0 <= float(r['success_rate']) <= 1.0 for r in evaluations)
  assert all(float(r['length_mean']) == 10.0 for r in evaluations)
  assert glob.glob(os.path.join(logdir, 'tensorboard', 'events.*'))
  latest = checkpoints.latest(logdir)
  assert os.path.basename(latest) == 'step_0000000060'
  kept = sorted(os.listdir(checkpoints.checkpoint_root(logdir)))
  assert kept == ['latest', 'step_0000000040', 'step_0000000060']
  # The learner ran: its parameters differ between the two checkpoints.
  before = _checkpoint_arrays(os.path.join(
      checkpoints.checkpoint_root(logdir), 'step_0000000040'))
  after = _checkpoint_arrays(latest)
  assert before.keys() == after.keys()
  assert any(isinstance(v, np.ndarray) and v.dtype.kind == 'f' and
             v.shape == after[k].shape and not np.array_equal(v, after[k])
             for k, v in before.items())
  # A second start into the same logdir without --resume is refused.
  with pytest.raises(ValueError, match='already holds a run'):
    train.train(_run_config(), logdir)


def test_evaluate_checkpoint(two_runs):
  results, summary = evaluate.run(two_runs[0], episodes=2, seed=7)
  assert len(results) == 2
  assert all(r['episode_length'] == 10 for r in results)
  assert summary['success']['low'] <= summary['success']['mean']
  assert summary['success']['mean'] <= summary['success']['high']
  assert summary['episode_length']['mean'] == 10.0
  again, _ = evaluate.run(two_runs[0], episodes=2, seed=7)
  assert again == results   # Deterministic policy, same seed.
  table = evaluate.format_table(summary, len(results))
  assert 'success rate' in table and 'shield interventions' in table
  output = os.path.join(os.path.dirname(two_runs[0]), 'evaluation.json')
  _run_binary(evaluate, [f'--checkpoint={two_runs[1]}', '--episodes=1',
                         f'--output={output}'])
  written = checkpoints.read_json(output)
  assert len(written['episodes']) == 1
  assert 0.0 <= written['summary']['success']['mean'] <= 1.0
  with pytest.raises(ValueError, match='No checkpoint'):
    evaluate.run(os.path.dirname(two_runs[0]), episodes=1)


def test_evaluate_on_other_motions(two_runs, tmp_path, monkeypatch):
  """--motions replaces the run's people (task_kwargs['motions'])."""
  library = pathlib.Path(clip_lib.__file__).parent.parent / 'assets' / (
      'motions/reach')
  stem = sorted(library.glob('*.json'))[0].stem
  for suffix in ('.json', '.npz'):
    shutil.copy(library / (stem + suffix), tmp_path / (stem + suffix))
  built = []
  make = train.make_environment
  def recording(run_config, seed):
    env = make(run_config, seed)
    built.append(env)
    return env
  monkeypatch.setattr(train, 'make_environment', recording)
  results, _ = evaluate.run(two_runs[0], episodes=1, seed=7,
                            motions=str(tmp_path))
  assert len(results) == 1
  assert [c.name for c in built[0].task.player.clips] == [stem]
  with pytest.raises(ValueError, match='expected a folder of motions'):
    evaluate.run(two_runs[0], episodes=1, motions=str(tmp_path / 'none'))


def test_plot_two_runs(two_runs, tmp_path):
  curves = plot.learning_curves(two_runs, np.random.RandomState(0),
                                expert=0.0, num_resamples=1000)
  assert len(curves) == 1 and curves[0].seeds == [0, 1]
  np.testing.assert_array_equal(curves[0].steps, [0, 25, 50])
  png, svg = plot.draw(curves, str(tmp_path / 'curves.png'), 'reach/dense')
  assert os.path.getsize(png) > 10_000 and os.path.getsize(svg) > 10_000
  out = str(tmp_path / 'cli' / 'curves.png')
  _run_binary(plot, ['--logdirs=' + ','.join(two_runs), f'--out={out}',
                     '--resamples=200', '--expert_return=0'])
  assert os.path.getsize(out) > 10_000
  assert os.path.getsize(out[:-4] + '.svg') > 10_000


def test_resume_matches_an_uninterrupted_run(two_runs, tmp_path):
  whole, split = two_runs[0], str(tmp_path / 'split')
  # Stopped after 35 steps, inside the fourth episode: the checkpoint
  # holds the episode (task snapshot, last observation) and the run
  # continues it.
  train.train(_run_config(steps=35), split)
  latest = checkpoints.latest(split)
  assert os.path.basename(latest) == 'step_0000000035'
  info, observation, _ = checkpoints.load_episode(latest)
  assert info['episode_steps'] == 5 and 'goal_difference' in observation
  assert len(logging_lib.read_csv(os.path.join(split, 'train.csv'))) == 3
  train.train(_run_config(steps=60), split, resume=True)
  _assert_same_runs(whole, split)
  # Only the step budget may change on resume.
  with pytest.raises(ValueError, match='different configuration'):
    train.train(_run_config(steps=80, eval_every=20), split, resume=True)


def test_bad_run_configs():
  for agent in ('rsi', 'sir', 'rsi+air'):
    with pytest.raises(ValueError, match='needs --dataset'):
      train.make_run_config('reach', 'dense', 'schunk', 'cartesian',
                            agent=agent)
  with pytest.raises(ValueError, match='only used by'):
    train.make_run_config('reach', 'dense', 'schunk', 'cartesian',
                          agent='air', dataset='/tmp/data')
  with pytest.raises(ValueError, match='Unknown agent'):
    train.make_run_config('reach', 'dense', 'schunk', 'cartesian',
                          agent='ppo')
  with pytest.raises(ValueError, match='Unknown SACConfig fields'):
    train.make_run_config('reach', 'dense', 'schunk', 'cartesian',
                          overrides={'learning_rat': 1e-3})
  with pytest.raises(ValueError, match='must not set'):
    train.make_run_config('reach', 'dense', 'schunk', 'cartesian',
                          task_kwargs={'seed': 3})
  assert train.parse_overrides(['batch_size=64', 'hidden_sizes=[8, 8]']) == {
      'batch_size': 64, 'hidden_sizes': [8, 8]}
  with pytest.raises(ValueError, match='field=value'):
    train.parse_overrides(['batch_size'])
  with pytest.raises(ValueError, match='expected JSON'):
    train.parse_overrides(['learning_rate=fast'])


def test_policy_of_a_run_for_rendering(two_runs):
  directory = checkpoints.agent_directory(two_runs[0])
  assert directory == os.path.join(checkpoints.latest(two_runs[0]), 'agent')
  assert checkpoints.agent_directory(directory) == directory
  env = train.make_environment(_run_config(), seed=3)
  policy = agent_checkpoint.load_policy(directory, env)
  timestep = env.reset()
  action = policy(timestep)
  assert action.shape == env.action_spec().shape
  assert np.all(np.abs(action) <= 1.0)
  np.testing.assert_array_equal(policy(timestep), action)   # Deterministic.


def test_render_renders_a_checkpoint_in_its_training_environment(
    two_runs, tmp_path):
  # hrc_suite.rendering.episode finds agents' loader through the installed entry point.
  out = tmp_path / 'trained.gif'
  path, metrics = render.run(policy=two_runs[0], out=str(out), max_steps=3,
                             width=64, height=48)
  assert path.stat().st_size > 1000 and metrics['steps'] == 3
  written = json.loads(path.with_suffix('.json').read_text())
  assert (written['domain'], written['task'], written['robot']) == (
      'reach', 'dense', 'schunk')
  assert written['task_kwargs'] == dict(_TASK_KWARGS,
                                        action_space='cartesian')
  with pytest.raises(ValueError, match='--robot=panda differs from the '
                     "checkpoint .* trained with robot 'schunk'"):
    render.run(robot='panda', policy=two_runs[0], out=str(out))
  with pytest.raises(ValueError, match='No checkpoint loader reads'):
    render.run(policy=str(tmp_path), out=str(out))


def test_train_writes_the_curve_and_a_video_of_the_final_policy(tmp_path):
  logdir = tmp_path / 'quick'
  _run_binary(train, [
      '--config=quick', '--task_kwargs=' + json.dumps(_TASK_KWARGS),
      '--override=min_replay_size=16', '--override=batch_size=8',
      '--steps=20', '--eval_every=10', '--eval_episodes=1',
      f'--logdir={logdir}', '--noprogress', '--plot', '--video'])
  config = checkpoints.read_json(logdir / 'config.json')
  assert config['sac_config']['reward_scale'] == 100.0
  assert (logdir / 'curves.png').stat().st_size > 10_000
  assert (logdir / 'episode.mp4').stat().st_size > 1000
  episode = json.loads((logdir / 'episode.json').read_text())
  assert episode['frames'] == 11 and episode['robot'] == 'schunk'


def _to_update_every(sac_config):
  """A SAC config dict as written before fused_steps replaced update_every
  (one update per step, as the presets had)."""
  old = dict(sac_config, update_every=1)
  del old['fused_steps']
  return old


def test_runs_begun_before_fused_steps_resume(tmp_path):
  logdir = str(tmp_path / 'run')
  old_overrides = dict(_OVERRIDES, fused_steps=1)
  train.train(train.make_run_config(
      'reach', 'dense', 'schunk', 'cartesian', overrides=old_overrides,
      task_kwargs=_TASK_KWARGS, steps=30, checkpoint_every=20), logdir)
  config_path = os.path.join(logdir, 'config.json')
  stored = checkpoints.read_json(config_path)
  stored['sac_config'] = _to_update_every(stored['sac_config'])
  stored['overrides'] = dict(_OVERRIDES)
  checkpoints.write_json(config_path, stored)
  agent_json = os.path.join(checkpoints.latest(logdir),
                            checkpoints.AGENT_DIR, 'agent.json')
  description = checkpoints.read_json(agent_json)
  description['config'] = _to_update_every(description['config'])
  checkpoints.write_json(agent_json, description)
  # The default fused_steps is a different schedule: refused.
  with pytest.raises(ValueError, match='different configuration.*fused'):
    train.train(train.make_run_config(
        'reach', 'dense', 'schunk', 'cartesian', overrides=_OVERRIDES,
        task_kwargs=_TASK_KWARGS, steps=40, checkpoint_every=20), logdir,
                resume=True)
  _, state = train.train(train.make_run_config(
      'reach', 'dense', 'schunk', 'cartesian', overrides=old_overrides,
      task_kwargs=_TASK_KWARGS, steps=40, checkpoint_every=20), logdir,
                         resume=True)
  assert state['counter']['steps'] == 40


def test_resume_without_a_checkpoint_starts_afresh(tmp_path):
  logdir = str(tmp_path / 'run')
  train.train(_run_config(steps=15, checkpoint_every=0), logdir)
  # A crash before the first checkpoint: logs but no checkpoint.
  shutil.rmtree(checkpoints.checkpoint_root(logdir))
  first = _deterministic_rows(os.path.join(logdir, 'train.csv'))
  train.train(_run_config(steps=15, checkpoint_every=0), logdir, resume=True)
  assert _deterministic_rows(os.path.join(logdir, 'train.csv')) == first
  evaluations = logging_lib.read_csv(os.path.join(logdir, 'eval.csv'))
  assert [int(r['step']) for r in evaluations] == [0]   # Not twice.


def test_imitation_agents_train_and_resume_exactly(tmp_path):
  data = str(tmp_path / 'dataset')
  dataset_lib.collect(data, 'reach', 'dense', task_kwargs=dict(
      _TASK_KWARGS, robot='schunk', action_space='cartesian'), episodes=2)

  def config(steps):
    return train.make_run_config(
        'reach', 'dense', 'schunk', 'cartesian', agent='rsi',
        overrides=_OVERRIDES, task_kwargs=_TASK_KWARGS, steps=steps,
        eval_every=0, checkpoint_every=15, dataset=data,
        imitation_kwargs={'probability': 0.5})

  whole, split = str(tmp_path / 'whole'), str(tmp_path / 'split')
  train.train(config(50), whole)
  train.train(config(30), split)
  train.train(config(50), split, resume=True)
  lengths = [int(r['episode_length']) for r in
             logging_lib.read_csv(os.path.join(whole, 'train.csv'))]
  assert min(lengths) < 10   # Some episodes started from dataset states.
  expected = _checkpoint_arrays(checkpoints.latest(whole))
  actual = _checkpoint_arrays(checkpoints.latest(split))
  assert expected.keys() == actual.keys()
  for key, value in expected.items():
    np.testing.assert_array_equal(actual[key], value, err_msg=key)
  assert (_deterministic_rows(os.path.join(split, 'train.csv')) ==
          _deterministic_rows(os.path.join(whole, 'train.csv')))
  latest = checkpoints.latest(whole)
  state, rng_states = checkpoints.load_loop_state(latest)
  assert sorted(rng_states) == ['0/_random', 'environment']
  assert state['run_config']['agent'] == 'rsi'
  # Wrapped environments are checkpointed at episode boundaries only.
  assert checkpoints.load_episode(latest) is None
  episode_ends = {int(r['step']) for r in logging_lib.read_csv(
      os.path.join(whole, 'train.csv'))}
  assert state['counter']['steps'] in episode_ends

  # AIR: the reward mixes the expert agreement into the task reward.
  air = str(tmp_path / 'air')
  train.train(train.make_run_config(
      'reach', 'dense', 'schunk', 'cartesian', agent='air',
      overrides=_OVERRIDES, task_kwargs=_TASK_KWARGS, steps=20), air)
  rows = logging_lib.read_csv(os.path.join(air, 'train.csv'))
  assert all(float(r['episode_return']) != float(r['return']) for r in rows)

  # RSI under AIR: RSI's draws are checkpointed one wrapper deeper.
  rsi_air = str(tmp_path / 'rsi_air')
  train.train(train.make_run_config(
      'reach', 'dense', 'schunk', 'cartesian', agent='rsi+air',
      overrides=_OVERRIDES, task_kwargs=_TASK_KWARGS, steps=40,
      checkpoint_every=10, dataset=data,
      imitation_kwargs={'probability': 1.0, 'scale': 0.5}), rsi_air)
  rows = logging_lib.read_csv(os.path.join(rsi_air, 'train.csv'))
  assert all(float(r['episode_return']) != float(r['return']) for r in rows)
  assert min(int(r['episode_length']) for r in rows) < 10
  _, rng_states = checkpoints.load_loop_state(checkpoints.latest(rsi_air))
  assert sorted(rng_states) == ['1/_random', 'environment']


def test_sac_lagrangian_trains_resumes_exactly_and_logs_the_cost(tmp_path):
  task_kwargs = dict(_TASK_KWARGS, shield='off')

  def config(steps):
    return train.make_run_config(
        'reach', 'dense', 'schunk', 'cartesian', agent='sac_lag',
        overrides=dict(_OVERRIDES, cost_limit=0.5,
                       multiplier_update='pid'),
        task_kwargs=task_kwargs, steps=steps, eval_every=25,
        eval_episodes=2, checkpoint_every=20)

  assert config(10)['task_kwargs']['observations'] == 'safe_rl'
  whole, split = str(tmp_path / 'whole'), str(tmp_path / 'split')
  train.train(config(60), whole)
  train.train(config(35), split)   # Inside an episode.
  assert checkpoints.load_episode(checkpoints.latest(split)) is not None
  train.train(config(60), split, resume=True)
  expected = _assert_same_runs(whole, split)
  assert 'learner.npz/multiplier_controller/value' in expected
  assert 'agent.npz/episode_cost' in expected
  # Training episodes' costs reached the replay and the multiplier.
  rows = logging_lib.read_csv(os.path.join(whole, 'train.csv'))
  replay_cost = expected['replay.npz/cost']
  assert replay_cost.shape == (60,)
  ends = np.cumsum([int(r['episode_length']) for r in rows])
  np.testing.assert_allclose(
      [replay_cost[start:end].sum() for start, end in
       zip(np.concatenate([[0], ends[:-1]]), ends)],
      [float(r['cost']) for r in rows])
  assert 'cost_mean' in logging_lib.read_csv(
      os.path.join(whole, 'eval.csv'))[0]
  # The checkpoint evaluates and plots like SAC's, with the cost panel.
  results, _ = evaluate.run(whole, episodes=1)
  assert 'cost' in results[0]
  paths = plot.plot([whole], str(tmp_path / 'curves.png'))
  assert 'cost_mean' in logging_lib.read_csv(paths[-1])[0]
