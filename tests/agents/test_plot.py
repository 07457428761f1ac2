"""Tests of the learning-curve plot on synthetic runs."""

import json
import os

import numpy as np
import pytest

from agents import logging as logging_lib
from agents import plot


def _write_run(logdir, seed, success, returns, agent='sac', steps=None):
  os.makedirs(logdir)
  config = {'domain': 'reach', 'task': 'dense', 'robot': 'schunk',
            'action_space': 'cartesian', 'task_kwargs': {}, 'agent': agent,
            'config': 'default', 'overrides': {}, 'seed': seed,
            'steps': 1000, 'eval_every': 100, 'eval_episodes': 4,
            'checkpoint_every': 0, 'min_return': -100.0,
            'min_task_return': -60.0,
            'reward_range': [-1.0, 0.0], 'horizon': 100}
  with open(os.path.join(logdir, 'config.json'), 'w') as f:
    json.dump(config, f)
  logger = logging_lib.CSVLogger(os.path.join(logdir, 'eval.csv'))
  steps = steps if steps is not None else 100 * np.arange(len(success))
  for step, s, r in zip(steps, success, returns):
    logger.write({'success_rate': s, 'return_mean': r, 'evaluation': 0},
                 int(step))
  logger.close()


def _two_seeds(tmp_path):
  """Two seeds of one configuration; the second has one more evaluation."""
  a, b = str(tmp_path / 'a'), str(tmp_path / 'b')
  _write_run(a, 0, [0.0, 0.5, 1.0], [-100.0, -60.0, -20.0])
  _write_run(b, 1, [0.0, 1.0, 1.0, 1.0], [-100.0, -40.0, -20.0, -20.0])
  return a, b


def test_curves_over_seeds_normalised_by_the_expert(tmp_path):
  a, b = _two_seeds(tmp_path)
  curves = plot.learning_curves([a, b], np.random.RandomState(0),
                                expert=-20.0, num_resamples=2000,
                                minimum='total')
  assert len(curves) == 1
  curve = curves[0]
  assert curve.seeds == [0, 1] and curve.normalised
  np.testing.assert_array_equal(curve.steps, [0, 100, 200])  # Shared only.
  mean, low, high = curve.success
  np.testing.assert_allclose(mean, [0.0, 0.75, 1.0])
  # Two seeds: the resampled means are the two values and their mean.
  np.testing.assert_allclose(low, [0.0, 0.5, 1.0])
  np.testing.assert_allclose(high, [0.0, 1.0, 1.0])
  # (return - min) / (expert - min) with min -100, expert -20.
  np.testing.assert_allclose(curve.returns[0], [0.0, 0.625, 1.0])

  paths = plot.draw(curves, str(tmp_path / 'out' / 'curves.png'), 'reach')
  png, svg = paths
  with open(png, 'rb') as f:
    assert f.read(8) == b'\x89PNG\r\n\x1a\n'
  assert os.path.getsize(png) > 10_000
  with open(svg) as f:
    text = f.read()
  assert '<svg' in text and 'path' in text and len(text) > 10_000
  rows = logging_lib.read_csv(plot.write_table(
      curves, str(tmp_path / 'out' / 'curves.csv')))
  assert [int(r['step']) for r in rows] == [0, 100, 200]
  assert [float(r['success_mean']) for r in rows] == [0.0, 0.75, 1.0]
  assert float(rows[1]['return_mean']) == pytest.approx(0.625)


def test_groups_by_configuration_and_experts_file(tmp_path):
  _write_run(str(tmp_path / 's0'), 0, [0.0, 1.0], [-80.0, -50.0])
  _write_run(str(tmp_path / 'air0'), 0, [0.5, 1.0], [-60.0, -30.0],
             agent='air')
  experts = tmp_path / 'experts.json'
  experts.write_text(json.dumps(
      {'reach/dense': {'schunk': {'return_mean': -50.0}}}))
  curves = plot.learning_curves(
      [str(tmp_path / 's0'), str(tmp_path / 'air0')],
      np.random.RandomState(0), experts_json=str(experts),
      num_resamples=100, minimum='total')
  assert [c.label for c in curves] == ['sac (default)', 'air (default)']
  np.testing.assert_allclose(curves[0].returns[0], [0.4, 1.0])
  # The rows of hrc_suite.experts.evaluate: the deterministic expert of the
  # same robot and action space, on the synthetic people behind the
  # task's default shield (as training runs meet them).
  rows = [{'domain': 'reach', 'task': 'dense', 'robot': robot,
           'action_space': space, 'policy': policy, 'return': value,
           'people': people, 'shield_choice': shield}
          for robot, space, policy, value, people, shield in (
              ('panda', 'cartesian', 'expert', -10.0, 'synthetic',
               'default'),
              ('schunk', 'joint', 'expert', -10.0, 'synthetic', 'default'),
              ('schunk', 'cartesian', 'noisy_expert', -10.0, 'synthetic',
               'default'),
              ('schunk', 'cartesian', 'expert', -50.0, 'synthetic',
               'default'),
              ('schunk', 'cartesian', 'expert', -10.0, 'real', 'default'),
              ('schunk', 'cartesian', 'expert', -10.0, 'synthetic', 'off'))]
  experts.write_text(json.dumps({'info': {}, 'rows': rows}))
  from_rows = plot.learning_curves([str(tmp_path / 's0')],
                                   np.random.RandomState(0),
                                   experts_json=str(experts),
                                   num_resamples=100, minimum='total')
  np.testing.assert_allclose(from_rows[0].returns[0], [0.4, 1.0])
  # Without an expert return the raw return is kept.
  raw = plot.learning_curves([str(tmp_path / 's0')],
                             np.random.RandomState(0), num_resamples=100,
                             minimum='total')
  assert not raw[0].normalised
  # The task-only minimum (-60): (-50 + 60) / (-50 + 60) at the end.
  task = plot.learning_curves([str(tmp_path / 's0')],
                              np.random.RandomState(0), expert=-50.0,
                              num_resamples=100, minimum='task')
  np.testing.assert_allclose(task[0].returns[0], [-2.0, 1.0])
  with pytest.raises(ValueError, match='Unknown minimum'):
    plot.learning_curves([str(tmp_path / 's0')], np.random.RandomState(0),
                         minimum='lowest')
  np.testing.assert_allclose(raw[0].returns[0], [-80.0, -50.0])


def test_per_seed_curves_keep_each_run(tmp_path):
  a, b = _two_seeds(tmp_path)
  curves = plot.learning_curves([a, b], np.random.RandomState(0),
                                expert=-20.0, num_resamples=100,
                                per_seed=True)
  assert [c.seeds for c in curves] == [[0], [1]]
  # Each run keeps all its evaluations, and its band is its own values.
  np.testing.assert_array_equal(curves[1].steps, [0, 100, 200, 300])
  for curve, success in zip(curves, ([0.0, 0.5, 1.0], [0.0, 1.0, 1.0, 1.0])):
    for array in curve.success:
      np.testing.assert_allclose(array, success)
  out = str(tmp_path / 'per_seed.png')
  paths = plot.plot([a, b], out, expert=-20.0, num_resamples=100,
                    per_seed=True)
  rows = logging_lib.read_csv(paths[-1])
  assert [r['seed_ids'] for r in rows] == ['0'] * 3 + ['1'] * 4


def test_title_says_what_one_seed_shows(tmp_path):
  a, b = _two_seeds(tmp_path)
  config, _ = plot.load_run(a)

  def curves(logdirs):
    return plot.learning_curves(logdirs, np.random.RandomState(0),
                                expert=-20.0, num_resamples=10)

  one, both = curves([a]), curves([a, b])
  assert plot.title(config, one).endswith(': one seed (no confidence '
                                          'interval)')
  assert plot.title(config, both).endswith(
      ': mean and 95 % bootstrap CI over seeds')
  assert 'none for the curves of one seed' in plot.title(config, one + both)
  assert 'one curve per seed' in plot.title(config, one, per_seed=True)


def test_bad_runs_raise(tmp_path):
  with pytest.raises(ValueError, match='not a training run'):
    plot.learning_curves([str(tmp_path)], np.random.RandomState(0),
                         minimum='total')
  _write_run(str(tmp_path / 'a'), 0, [0.0], [-1.0])
  _write_run(str(tmp_path / 'b'), 0, [0.0], [-1.0])
  with pytest.raises(ValueError, match='repeat seeds'):
    plot.learning_curves([str(tmp_path / 'a'), str(tmp_path / 'b')],
                         np.random.RandomState(0), minimum='total')
  with pytest.raises(ValueError, match='must exceed the minimal'):
    plot.learning_curves([str(tmp_path / 'a')], np.random.RandomState(0),
                         expert=-200.0, minimum='total')
