"""Named grids: their size, their runs and clear errors for bad fields."""

import pytest

from agents import grids


def test_the_paper_grid_is_the_papers_figure():
  grid = grids.get('paper')
  # 6 tasks x 4 agents x 5 seeds; 2 tasks of 10^6 and 4 of 3 x 10^6 RL
  # steps per run (docs/reference_benchmark.md, Training and evaluation).
  assert grids.describe(grid) == {'runs': 120, 'steps': 20 * 14_000_000}
  assert grid.eval_every == 200_000 and grid.eval_episodes == 20
  assert grid.config == 'reference' and grid.robot == 'schunk'
  assert grid.task_kwargs == {'collision_reward': 0.0}


def test_named_grids_build_and_name_their_runs_uniquely():
  sizes = {'paper_reduced': (72, 72 * 100_000), 'overfitting': (5, 5_000_000),
           'smoke': (2, 600)}
  for name, (runs, steps) in sizes.items():
    grid = grids.get(name)
    assert grids.describe(grid) == {'runs': runs, 'steps': steps}, name
    names = [run.name for run in grid.runs()]
    assert len(set(names)) == len(names)


def test_runs_carry_the_tasks_defaults_and_the_splits_eval_sets():
  reach = grids.get('paper_reduced').runs()[0]
  assert reach.name == 'reach-dense/sac/seed0'
  assert reach.run_config['action_space'] == 'joint'   # The paper's reach.
  split_runs = grids.get('overfitting').runs()
  assert [r.name for r in split_runs] == [
      f'lifting-default/sac/split{k}-seed0' for k in range(5)]
  config = split_runs[3].run_config
  assert config['task_kwargs']['motions'] == {
      'split': 'train', 'test_clips': 2, 'split_seed': 3, 'source': None}
  assert config['eval_sets'] == {'unseen': {'motions': {
      'split': 'test', 'test_clips': 2, 'split_seed': 3, 'source': None}}}


def test_steps_per_task_and_replacement():
  grid = grids.get('smoke').replace(steps={'reach/dense': 500})
  assert grid.steps_of('reach/dense') == 500
  assert grids.Grid.from_dict(grid.to_dict()) == grid


@pytest.mark.parametrize('changes, message', [
    ({'tasks': ('reach/nope',)}, "Unknown task 'nope'"),
    ({'tasks': ('reach',)}, 'domain/task names'),
    ({'agents': ('sac', 'ppo')}, 'agents=.*expected a non-empty list'),
    ({'seeds': (0, 0)}, 'each seed once'),
    ({'seeds': (-1,)}, 'integers >= 0'),
    ({'steps': {'pick_place/default': 10}}, r"missing \['reach/dense'\]"),
    ({'steps': 0}, 'integers >= 1'),
    ({'eval_episodes': 0}, 'eval_episodes=0: expected an integer >= 1'),
    ({'config': 'fast'}, "config='fast'"),
    ({'overrides': {'learning_rat': 1.0}}, 'Unknown SACConfig fields'),
    ({'task_kwargs': {'robot': 'panda'}}, "no 'robot'"),
    ({'motions': '/no/such/folder'}, 'existing folder'),
])
def test_bad_fields_are_named(changes, message):
  with pytest.raises(ValueError, match=message):
    grids.get('smoke').replace(**changes)


def test_unknown_grid_and_field():
  with pytest.raises(ValueError, match="Unknown grid 'papr': expected one "
                     'of paper, paper_reduced, overfitting, safe_rl, smoke'):
    grids.get('papr')
  with pytest.raises(ValueError, match=r"Unknown grid fields \['seed'\]"):
    grids.get('smoke').replace(seed=1)


def test_variants_give_their_agent_task_kwargs_and_overrides():
  grid = grids.get('safe_rl')
  runs = {run.name: run for run in grid.runs()}
  assert len(runs) == 2 * 4 * 3
  off = runs['reach-dense/sac_lag_off/seed1'].run_config
  assert off['agent'] == 'sac_lag'
  assert off['task_kwargs'] == {'observations': 'safe_rl',
                                'collision_reward': 0.0, 'shield': 'off'}
  assert off['overrides'] == {
      'cost_limit': grids.SAFE_RL_LIMITS['reach/dense'],
      'multiplier_learning_rate': 0.01}
  shielded = runs['pick_place-default/sac_lag_shield/seed0'].run_config
  assert 'shield' not in shielded['task_kwargs']
  assert shielded['overrides']['cost_limit'] == grids.SAFE_RL_LIMITS[
      'pick_place/default']
  penalty = runs['reach-dense/sac_penalty/seed2'].run_config
  assert penalty['agent'] == 'sac' and penalty['overrides'] == {
      'cost_penalty': grids.SAFE_RL_PENALTY}
  assert grid.label_of('sac_lag_off') == 'SAC-Lagrangian, no shield'
  assert grid.label_of('rsi') == 'SAC + RSI'
  assert not grid.needs_dataset('sac_lag_off')
  assert grids.Grid.from_dict(grid.to_dict()) == grid


@pytest.mark.parametrize('variants, message', [
    ({'sac': {'agent': 'sac'}}, "'sac' is an agent"),
    ({'v': {'agent': 'ppo'}}, "not 'ppo'"),
    ({'v': {'agent': 'sac', 'colour': 'red'}}, 'agent, task_kwargs'),
    ({'v': {'agent': 'sac', 'task_kwargs': {'robot': 'panda'}}},
     "no \\['robot'\\]"),
    ({'v': {'agent': 'sac', 'overrides': {'cost_limit': 1.0}}},
     'Unknown SACConfig fields'),
    ({'v': {'agent': 'sac_lag', 'overrides': {'cost_limit': -1.0}}},
     'SACLagrangianConfig.cost_limit'),
])
def test_bad_variants_are_named(variants, message):
  with pytest.raises(ValueError, match=message):
    grids.get('smoke').replace(agents=('sac', 'v'), variants=variants)
