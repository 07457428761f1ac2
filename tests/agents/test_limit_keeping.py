"""agents.limit_keeping: evaluations within the cost limit, counted by
hand."""

from agents import grids
from agents import limit_keeping


def test_cost_limits_are_those_of_the_constrained_runs():
  grid = grids.get('safe_rl')
  assert limit_keeping.cost_limits(grid, 'reach/dense') == [
      grids.SAFE_RL_LIMITS['reach/dense']]
  assert limit_keeping.cost_limits(grid, 'pick_place/default') == [
      grids.SAFE_RL_LIMITS['pick_place/default']]
  # SAC with the shield alone: no limit.
  assert limit_keeping.cost_limits(grid.replace(agents=('sac_shield',)),
                                   'reach/dense') == []
  assert limit_keeping.cost_limits(grids.get('paper_reduced'),
                                   'reach/dense') == []


def _row(agent, seed, step, cost, critical=0.0, task='reach/dense'):
  return {'task': task, 'agent': agent, 'seed': seed, 'step': step,
          'cost': cost, 'critical_contacts_per_1000': critical}


def test_kept_limits_equal_a_hand_count():
  grid = grids.get('safe_rl').replace(
      name='limits', tasks=('reach/dense',), seeds=(0, 1), steps=400,
      agents=('sac_penalty', 'sac_lag_off'))
  limit = grids.SAFE_RL_LIMITS['reach/dense']
  rows = [
      # Step 0 (the untrained policy) is not counted.
      _row('sac_lag_off', 0, 0, 50.0, 10.0),
      _row('sac_lag_off', 0, 100, limit + 1.0, 5.0),   # Over, early.
      _row('sac_lag_off', 0, 200, limit),              # At the limit: kept.
      _row('sac_lag_off', 0, 300, 0.0),                # Late, kept.
      _row('sac_lag_off', 1, 300, limit + 0.5, 2.0),   # Late, over.
      _row('sac_lag_off', 1, 400, None),               # No cost: left out.
      _row('sac_penalty', 0, 400, 0.5 * limit),        # Late, kept.
  ]
  entries = {e['agent']: e for e in limit_keeping.kept_limits(rows, grid)}
  lag = entries['sac_lag_off']
  assert lag['limit'] == limit and lag['seeds'] == 2
  assert (lag['evaluations'], lag['kept']) == (4, 2)
  assert (lag['evaluations_late'], lag['kept_late']) == (2, 1)
  assert lag['with_critical'] == 2
  penalty = entries['sac_penalty']
  assert (penalty['evaluations'], penalty['kept'], penalty['kept_late'],
          penalty['seeds']) == (1, 1, 1, 1)
  lines = limit_keeping.markdown(
      list(entries.values()), {'sac_lag_off': 'SAC-Lagrangian, no shield'})
  assert (f'| reach/dense | SAC-Lagrangian, no shield | {limit:g} | 2 | '
          '2 of 4 | 1 of 2 | 2 of 4 |') in lines


def test_tasks_without_one_limit_are_left_out():
  grid = grids.get('safe_rl').replace(
      name='no_limit', tasks=('reach/dense',), seeds=(0,), steps=400,
      agents=('sac_shield', 'sac_penalty'))
  rows = [_row('sac_shield', 0, 100, 0.0), _row('sac_penalty', 0, 100, 3.0)]
  assert limit_keeping.kept_limits(rows, grid) == []
  assert limit_keeping.markdown([], {}) == []
