"""agents.grid_cost: run times and the wall time of a grid by hand."""

import pytest

from agents import grid_cost
from agents import grids


def test_makespan_longest_first_onto_the_core_free_soonest():
  assert grid_cost.makespan([], 4) == 0.0
  # 5, 4, 3, 3, 3 on two cores, longest first onto the core free soonest:
  # 5 | 4, then 3 to the 4 (7), 3 to the 5 (8), 3 to the 7 -> 10 (the
  # optimum, {5, 4} and {3, 3, 3}, is 9).
  assert grid_cost.makespan([3, 5, 3, 4, 3], 2) == 10
  assert grid_cost.makespan([3, 5, 3, 4, 3], 100) == 5   # the longest run


def test_run_seconds_and_prediction_by_hand():
  grid = grids.get('smoke').replace(
      tasks=('reach/dense', 'pick_place/default'), agents=('sac', 'rsi'),
      seeds=(0, 1), steps=1000, eval_every=500, eval_episodes=2)
  rates = {('reach/dense', 'sac'): grid_cost.Rates(100.0, 50.0, 10.0, 1),
           ('reach/dense', 'rsi'): grid_cost.Rates(50.0, 50.0, 30.0, 1)}
  run = grid.runs()[0]
  # 1000 / 100 s of training; 3 evaluations x 2 episodes x 10 steps / 50.
  assert grid_cost.run_seconds(grid, run, rates) == pytest.approx(10 + 1.2)
  rsi = next(r for r in grid.runs() if r.agent == 'rsi')
  assert grid_cost.run_seconds(grid, rsi, rates) == pytest.approx(20 + 3.6)
  result = grid_cost.predict(grid, rates, cores=2, machines=(1, 2))
  assert result['unmeasured'] == ['pick_place/default']
  assert result['core_seconds'] == pytest.approx(2 * 11.2 + 2 * 23.6)
  assert result['wall'] == {1: pytest.approx(23.6 + 11.2),
                            2: pytest.approx(23.6)}
  # A task's agent not measured takes the task's mean over its agents.
  grid = grid.replace(agents=('sac', 'rsi', 'sir'))
  sir = next(r for r in grid.runs() if r.agent == 'sir')
  assert grid_cost.run_seconds(grid, sir, rates) == pytest.approx(
      1000 / 75 + 3 * 2 * 20 / 50)
