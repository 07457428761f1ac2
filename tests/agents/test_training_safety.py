"""agents.training_safety: what training cost, against a hand computation."""

import os

import numpy as np
import pytest

from agents import grids
from agents import logging as logging_lib
from agents import sweep_layout as layout
from agents import training_safety


def _train_csv(root, run, episodes):
  directory = layout.run_directory(root, run.name)
  os.makedirs(directory, exist_ok=True)
  logger = logging_lib.CSVLogger(os.path.join(directory, 'train.csv'))
  step = 0
  for episode in episodes:
    step += int(episode['episode_length'])
    logger.write(episode, step)
  logger.close()


def _grid():
  return grids.get('safe_rl').replace(
      name='train', tasks=('reach/dense',), seeds=(0, 1, 2), steps=400,
      agents=('sac_shield', 'sac_lag_off'))


def test_training_totals_and_rates_equal_a_hand_computation(tmp_path):
  root = str(tmp_path)
  grid = _grid()
  for run in grid.runs():
    if run.seed == 2:
      continue   # Not started: no train.csv.
    shielded = run.agent == 'sac_shield'
    # Two episodes of 100 and 300 steps; costs 3 + 1 (seed 0), 5 + 3
    # (seed 1); critical contacts only without the shield.
    _train_csv(root, run, [
        {'episode_length': 100, 'cost': 3.0 + 2 * run.seed,
         'contacts_human_critical': 0.0 if shielded else 2.0,
         'shield_interventions': 4.0 if shielded else 0.0},
        {'episode_length': 300, 'cost': 1.0 + 2 * run.seed,
         'contacts_human_critical': 0.0 if shielded else 1.0 + run.seed,
         'shield_interventions': 8.0 if shielded else 0.0}])
  rows, left_out = training_safety.training_rows(root, grid)
  assert sorted(left_out) == ['reach-dense/sac_lag_off/seed2',
                              'reach-dense/sac_shield/seed2']
  seed1 = next(r for r in rows if r['agent'] == 'sac_lag_off'
               and r['seed'] == 1)
  assert seed1['steps'] == 400 and seed1['episodes'] == 2
  assert seed1['cost'] == 8.0 and seed1['critical_contacts'] == 4.0
  summary = training_safety.summary(rows, np.random.RandomState(0), 1000)
  entries = {e['agent']: e for e in summary if e['quarter'] == 'all'}
  lag = entries['sac_lag_off']
  # Per 10^3 steps: cost 4/400 -> 10, 8/400 -> 20; critical 3/400 -> 7.5,
  # 4/400 -> 10.
  assert lag['seeds'] == 2 and lag['steps'] == 400
  assert lag['cost']['mean'] == pytest.approx(15.0)
  assert lag['cost']['low'] == pytest.approx(10.0)
  assert lag['cost']['high'] == pytest.approx(20.0)
  assert lag['critical_contacts']['mean'] == pytest.approx(8.75)
  assert entries['sac_shield']['critical_contacts']['mean'] == 0.0
  assert entries['sac_shield']['shield_interventions'][
      'mean'] == pytest.approx(30.0)
  lines = '\n'.join(training_safety.markdown(
      summary, {'sac_lag_off': 'SAC-Lagrangian, no shield'}, left_out))
  assert ('| reach/dense | SAC-Lagrangian, no shield | 2 | 400 | '
          '15.00 [10.00, 20.00] | 8.75 [7.50, 10.00] |') in lines
  # By quarter of the 400-step budget: the 100-step episode ends in the
  # first quarter, the 300-step one (steps 101-400) in the last; the
  # second and third have none. Cost per 10^3 steps: quarter 1 3/100 and
  # 5/100 -> 30, 50; quarter 4 1/300 and 3/300 -> 3.33, 10.
  quarters = {e['quarter']: e for e in summary
              if e['agent'] == 'sac_lag_off'}
  assert sorted(quarters, key=str) == [1, 4, 'all']
  assert quarters[1]['steps'] == 100 and quarters[4]['steps'] == 300
  assert quarters[1]['cost']['mean'] == pytest.approx(40.0)
  assert quarters[4]['cost']['low'] == pytest.approx(10 / 3)
  assert quarters[4]['cost']['high'] == pytest.approx(10.0)
  assert ('| reach/dense | SAC-Lagrangian, no shield | 40.00 [30.00, 50.00] '
          '| - | - | 6.67 [3.33, 10.00] |') in lines


def test_runs_without_a_cost_are_left_out(tmp_path):
  root = str(tmp_path)
  grid = _grid().replace(seeds=(0,), agents=('sac_shield',))
  _train_csv(root, grid.runs()[0], [{'episode_length': 100, 'return': 1.0}])
  rows, left_out = training_safety.training_rows(root, grid)
  assert rows == [] and left_out == ['reach-dense/sac_shield/seed0']
  assert training_safety.markdown([], {}, left_out) == []


def test_a_row_without_its_length_is_named(tmp_path):
  root = str(tmp_path)
  grid = _grid().replace(seeds=(0,), agents=('sac_shield',))
  _train_csv(root, grid.runs()[0], [{'episode_length': 100, 'cost': 1.0}])
  path = os.path.join(layout.run_directory(root, grid.runs()[0].name),
                      'train.csv')
  with open(path, 'a') as f:
    f.write('200,,2.0\n')
  with pytest.raises(ValueError, match='a row without episode_length'):
    training_safety.training_rows(root, grid)
