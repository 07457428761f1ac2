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
                     'of paper, paper_reduced, overfitting, smoke'):
    grids.get('papr')
  with pytest.raises(ValueError, match=r"Unknown grid fields \['seed'\]"):
    grids.get('smoke').replace(seed=1)
