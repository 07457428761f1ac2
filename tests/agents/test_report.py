"""agents.report on sweep directories with known numbers."""

import json
import os

import numpy as np
import pytest

from agents import grids
from agents import logging as logging_lib
from agents import report
from agents import sweep_layout as layout

# Known numbers: the task's lowest return and the expert's mean return.
_MIN_RETURN, _EXPERT_RETURN = -200.0, -20.0


def _write_run(root, run, rows, finished=True):
  directory = layout.run_directory(root, run.name)
  os.makedirs(directory, exist_ok=True)
  layout.write_json(os.path.join(directory, 'config.json'),
                    dict(run.run_config, min_task_return=_MIN_RETURN))
  for name, table in rows.items():
    logger = logging_lib.CSVLogger(os.path.join(directory, name))
    for step, success, returned in table:
      logger.write({'success_rate': success, 'return_mean': returned,
                    'length_mean': 10.0, 'eval_seconds': 2.0}, step)
    logger.close()
  if finished:
    layout.write_json(os.path.join(directory, layout.FINISHED_FILE),
                      {'steps': run.run_config['steps']})


def _sweep(root, grid):
  layout.write_json(os.path.join(root, layout.SWEEP_FILE),
                    {'grid': grid.to_dict(), 'commit': 'abc'})
  os.makedirs(os.path.dirname(layout.expert_file(root, grid.tasks[0])))
  layout.write_json(layout.expert_file(root, grid.tasks[0]),
                    {'return_mean': _EXPERT_RETURN, 'success': 1.0,
                     'episodes': 2})


def _normalised(value):
  return (value - _MIN_RETURN) / (_EXPERT_RETURN - _MIN_RETURN)


def test_final_values_equal_a_hand_computation(tmp_path):
  grid = grids.get('smoke').replace(name='known', seeds=(0, 1, 2, 3, 4),
                                    steps=100, eval_every=50)
  _sweep(str(tmp_path), grid)
  # SAC: success 0, 0, 0, 0, 1 over the five seeds at the end; returns
  # -100 ... -20. SAC + RSI: seeds 0-2 only, seed 2 one evaluation short.
  sac_returns = [-100.0, -80.0, -60.0, -40.0, -20.0]
  for run in grid.runs():
    if run.agent == 'sac':
      success = 1.0 if run.seed == 4 else 0.0
      rows = [(0, 0.0, -200.0), (50, 0.0, -150.0),
              (100, success, sac_returns[run.seed])]
      _write_run(str(tmp_path), run, {'eval.csv': rows})
    elif run.seed < 3:
      rows = [(0, 0.0, -200.0), (50, 0.2 * (run.seed + 1), -110.0)]
      if run.seed < 2:
        rows.append((100, 0.5, -100.0))
      _write_run(str(tmp_path), run, {'eval.csv': rows},
                 finished=run.seed < 2)
  result = report.report(str(tmp_path), str(tmp_path / 'out'),
                         resamples=10_000,
                         minima={'reach/dense': _MIN_RETURN})
  final = {entry['agent']: entry for entry in result['final']}

  sac = final['sac']
  assert sac['step'] == 100 and sac['seeds'] == 5
  # Success: k of 5 resampled seeds succeed, k ~ Binomial(5, 0.2):
  # P(k = 0) = 0.33 > 2.5 %, so the CI's low end is 0; P(k <= 2) = 0.942
  # and P(k <= 3) = 0.993 bracket 97.5 %, so its high end is 3/5.
  assert sac['success']['mean'] == pytest.approx(0.2)
  assert sac['success']['low'] == 0.0
  assert sac['success']['high'] == pytest.approx(0.6)
  # Normalised return: (R + 200) / 180; the mean of -60 on average.
  assert sac['normalised_return']['mean'] == pytest.approx(_normalised(-60))
  samples = np.array([_normalised(r) for r in sac_returns])
  # The bootstrap distribution's 2.5 % and 97.5 % quantiles, by exact
  # enumeration of all 5^5 resamples.
  grid5 = np.stack(np.meshgrid(*[samples] * 5), -1).reshape(-1, 5)
  means = np.sort(grid5.mean(axis=1))
  low, high = np.quantile(means, [0.025, 0.975])
  assert sac['normalised_return']['low'] == pytest.approx(low, abs=0.01)
  assert sac['normalised_return']['high'] == pytest.approx(high, abs=0.01)

  # SAC + RSI: seeds 0-2 share the steps 0 and 50 only; 0.2, 0.4, 0.6.
  rsi = final['rsi']
  assert rsi['step'] == 50 and rsi['seeds'] == 3
  assert rsi['success']['mean'] == pytest.approx(0.4)
  # All three resampled seeds the same value: 1/27 = 3.7 % > 2.5 % each
  # way, so the CI is the sample's range.
  assert rsi['success']['low'] == pytest.approx(0.2)
  assert rsi['success']['high'] == pytest.approx(0.6)

  # Missing: seed 2 of rsi is unfinished, seeds 3 and 4 have no data.
  assert result['missing'] == {'reach-dense/rsi/seed2': 'no data',
                               'reach-dense/rsi/seed3': 'no data',
                               'reach-dense/rsi/seed4': 'no data'}
  text = open(tmp_path / 'out' / 'report.md').read()
  assert '* reach-dense/rsi/seed3: no data' in text
  assert '| reach/dense | SAC | 5 | 100 | 0.20 [0.00, 0.60]' in text

  rows = json.load(open(tmp_path / 'out' / 'evaluations.json'))['rows']
  assert len(rows) == 5 * 3 + 2 * 3 + 2
  row = next(r for r in rows if r['agent'] == 'sac' and r['seed'] == 1
             and r['step'] == 100)
  assert row['normalised_return'] == pytest.approx(_normalised(-80.0))
  assert row['success'] == 0.0 and row['eval_seconds'] == 2.0
  for name in ('success.png', 'return.png', 'final.csv'):
    assert os.path.getsize(tmp_path / 'out' / name) > 0
  assert result['cost']['reach/dense']['seconds'] == 2.0
  assert '| reach/dense | -200.00 | -20.00 |' in text


def test_the_minimum_is_the_tasks_lowest_possible_return():
  grid = grids.get('paper_reduced')
  # Lifting: failing (-10) ends the episode, and no other step pays less
  # than 0; reach/dense: -0.1 per m of the farthest distance every step.
  assert report.task_minimum(grid, 'lifting/default') == -10.0
  env_minimum = report.task_minimum(grid, 'reach/dense')
  assert -200.0 < env_minimum < -100.0


def test_seen_against_unseen_motions(tmp_path):
  grid = grids.get('overfitting').replace(
      name='splits', tasks=('reach/dense',), splits=(0, 1), steps=100,
      eval_every=100)
  _sweep(str(tmp_path), grid)
  for run in grid.runs():
    _write_run(str(tmp_path), run, {
        'eval.csv': [(0, 0.0, -200.0), (100, 1.0, -20.0)],
        'eval_unseen.csv': [(0, 0.0, -200.0), (100, 0.5, -110.0)]})
  result = report.report(str(tmp_path), str(tmp_path / 'out'),
                         resamples=1000,
                         minima={'reach/dense': _MIN_RETURN})
  seen, = result['overfitting']['seen']
  unseen, = result['overfitting']['unseen']
  assert seen['seeds'] == unseen['seeds'] == 2   # two splits of seed 0
  assert seen['success']['mean'] == 1.0
  assert unseen['success']['mean'] == 0.5
  assert unseen['normalised_return']['mean'] == pytest.approx(0.5)
  assert os.path.exists(tmp_path / 'out' / 'overfitting.png')
  text = open(tmp_path / 'out' / 'report.md').read()
  assert '| reach/dense | sac | unseen | 2 | 100 | 0.50 [0.50, 0.50]' in text


def test_a_folder_that_is_no_sweep(tmp_path):
  with pytest.raises(ValueError, match='is not a sweep directory'):
    report.report(str(tmp_path))


def test_safety_columns_and_variant_labels(tmp_path):
  """A safe-RL grid: the variants' labels name the lines, and the cost,
  critical contacts per 10^3 steps and shield interventions are averaged
  like the success."""
  grid = grids.get('safe_rl').replace(
      name='safe', tasks=('reach/dense',), seeds=(0, 1), steps=100,
      eval_every=100, agents=('sac_shield', 'sac_lag_off'))
  _sweep(str(tmp_path), grid)
  for run in grid.runs():
    directory = layout.run_directory(str(tmp_path), run.name)
    os.makedirs(directory)
    layout.write_json(os.path.join(directory, 'config.json'),
                      dict(run.run_config, min_task_return=_MIN_RETURN))
    logger = logging_lib.CSVLogger(os.path.join(directory, 'eval.csv'))
    shielded = run.agent == 'sac_shield'
    for step in (0, 100):
      logger.write({'success_rate': 0.5, 'return_mean': -50.0,
                    'length_mean': 40.0,
                    'cost_mean': 2.0 + run.seed if shielded else 6.0,
                    'contacts_human_critical_mean': 0.0 if shielded
                                                    else 0.4 * run.seed,
                    'shield_interventions_mean': 3.0 if shielded else 0.0},
                   step)
    logger.close()
  # A final.csv of other columns (an earlier report) is replaced.
  os.makedirs(tmp_path / 'out')
  (tmp_path / 'out' / 'final.csv').write_text('step,task,agent\n0,a,b\n')
  result = report.report(str(tmp_path), str(tmp_path / 'out'),
                         resamples=1000, minima={'reach/dense': _MIN_RETURN})
  assert 'cost_mean' in logging_lib.read_csv(
      str(tmp_path / 'out' / 'final.csv'))[0]
  final = {entry['agent']: entry for entry in result['final']}
  assert final['sac_shield']['cost']['mean'] == pytest.approx(2.5)
  assert final['sac_shield']['shield_interventions']['mean'] == 3.0
  # 0.4 critical contacts in 40 steps: 10 per 10^3 steps (seed 1).
  assert final['sac_lag_off']['critical_contacts_per_1000'][
      'mean'] == pytest.approx(5.0)
  text = open(tmp_path / 'out' / 'report.md').read()
  assert 'cost per episode | critical contacts per 10^3 steps' in text
  assert '| reach/dense | SAC, shield | 2 | 100 |' in text
  assert '| reach/dense | SAC-Lagrangian, no shield | 2 | 100 |' in text
  assert os.path.getsize(tmp_path / 'out' / 'cost.png') > 0
  # Keeping reach's limit of 1 per episode: the step-100 evaluations cost
  # 2 and 3 (shield) and 6 (no shield, seed 1 with a critical contact).
  assert ('| reach/dense | SAC, shield | 1 | 2 | 0 of 2 | 0 of 2 | 0 of 2 |'
          in text)
  assert ('| reach/dense | SAC-Lagrangian, no shield | 1 | 2 | 0 of 2 | '
          '0 of 2 | 1 of 2 |') in text
  assert {e['agent']: e['kept'] for e in result['limits']} == {
      'sac_shield': 0, 'sac_lag_off': 0}


def test_final_values_over_a_window_of_evaluations(tmp_path):
  """--final_window=2: each seed's mean over its last two common
  evaluations, then the bootstrap over seeds."""
  grid = grids.get('smoke').replace(name='window', seeds=(0, 1),
                                    agents=('sac',), steps=100,
                                    eval_every=50)
  _sweep(str(tmp_path), grid)
  for run in grid.runs():
    # Seed 0: success 0.2 at 50, 0.6 at 100 (mean 0.4); seed 1: 0.4, 1.0
    # (mean 0.7). Returns -150 then -50 (mean -100) for both.
    success = [(0.2, 0.6), (0.4, 1.0)][run.seed]
    _write_run(str(tmp_path), run, {'eval.csv': [
        (0, 0.0, -200.0), (50, success[0], -150.0),
        (100, success[1], -50.0)]})
  result = report.report(str(tmp_path), str(tmp_path / 'out'),
                         resamples=1000, minima={'reach/dense': _MIN_RETURN},
                         final_window=2)
  sac = result['final'][0]
  assert sac['step'] == 100
  assert sac['success']['mean'] == pytest.approx(0.55)
  # Two seeds: resamples of (0.4, 0.4), (0.4, 0.7), (0.7, 0.7).
  assert sac['success']['low'] == pytest.approx(0.4)
  assert sac['success']['high'] == pytest.approx(0.7)
  assert sac['return']['mean'] == pytest.approx(-100.0)
  text = open(tmp_path / 'out' / 'report.md').read()
  assert 'mean over its last 2 evaluations' in text
  # The last evaluation alone, as before: 0.6 and 1.0.
  last = report.report(str(tmp_path), str(tmp_path / 'out1'),
                       resamples=1000, minima={'reach/dense': _MIN_RETURN})
  assert last['final'][0]['success']['mean'] == pytest.approx(0.8)
  with pytest.raises(ValueError, match='window: expected a positive'):
    report.report(str(tmp_path), str(tmp_path / 'out0'), resamples=10,
                  minima={'reach/dense': _MIN_RETURN}, final_window=0)
