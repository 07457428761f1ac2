"""The results file's layout: episodes row by row, rounded, read back."""

import json

import pytest

from hrc_suite.experts import evaluation_report
from hrc_suite.experts import results_file


def _episode(seed, policy='expert', metrics=None, **extra):
  job = ['reach', 'dense', 'schunk', None, policy, None, seed, None, None]
  result = {'job': job, 'domain': 'reach', 'task': 'dense',
            'robot': 'schunk', 'action_space': 'joint', 'shield': 'ssm',
            'policy': policy, 'seed': seed, 'control_timestep': 0.1,
            'wall_time': 0.25 + seed, 'error': None, 'people': 'synthetic',
            'metrics': metrics if metrics is not None else {
                'success': 1.0, 'return': -7.381066600462631 - seed,
                'steps': 37.0 + seed, 'min_human_distance': None}}
  result.update(extra)
  return result


def test_rounding_keeps_six_significant_digits():
  assert results_file.round_metric(-7.381066600462631) == -7.38107
  assert results_file.round_metric(3.234602905755051e-05) == 3.2346e-05
  assert results_file.round_metric(-2369.5512) == -2369.55
  assert results_file.round_metric(37.0) == 37
  assert isinstance(results_file.round_metric(37.0), int)
  assert results_file.round_metric(None) is None
  assert results_file.round_metric(float('nan')) is None
  row = results_file.round_row({'success': 1.0, 'return': -10.580503198,
                                'min_human_distance': float('nan'),
                                'episodes': 50, 'first_error': None})
  assert row == {'success': 1.0, 'return': -10.5805,
                 'min_human_distance': None, 'episodes': 50,
                 'first_error': None}
  assert isinstance(row['success'], float)


def test_groups_are_rows_with_shared_fields_and_per_episode_columns():
  episodes = [_episode(0), _episode(1), _episode(0, 'noisy_expert')]
  groups = results_file.pack(episodes)
  assert [g['job'] for g in groups] == [
      ['reach', 'dense', 'schunk', None, 'expert', None, None, None],
      ['reach', 'dense', 'schunk', None, 'noisy_expert', None, None, None]]
  first = groups[0]
  assert first['fields']['robot'] == 'schunk'
  assert first['fields']['control_timestep'] == 0.1
  assert first['columns'] == {'seed': [0, 1], 'wall_time': [0.25, 1.25]}
  assert first['metrics'] == {'success': [1, 1],
                              'return': [-7.38107, -8.38107],
                              'steps': [37, 38],
                              'min_human_distance': [None, None]}


def test_unpack_gives_the_episodes_back_rounded():
  episodes = [_episode(0, wall_time=0.12345), _episode(1, clip='a'),
              _episode(2, clip='b')]
  back = results_file.unpack(results_file.pack(episodes))
  assert back[1] == dict(episodes[1], metrics={
      'success': 1.0, 'return': -8.38107, 'steps': 38.0,
      'min_human_distance': None})
  assert back[0]['wall_time'] == 0.123
  assert back[0]['job'] == episodes[0]['job']
  assert back[0]['clip'] is None and back[2]['clip'] == 'b'
  assert all(isinstance(v, float) for v in back[2]['metrics'].values()
             if v is not None)


def test_an_episode_that_raised_keeps_no_metrics():
  failed = _episode(1, error='RuntimeError: lost', traceback='tb')
  failed['metrics'] = None
  back = results_file.unpack(results_file.pack([_episode(0), failed]))
  assert back[1]['metrics'] is None
  assert back[1]['error'] == 'RuntimeError: lost'
  assert back[0]['error'] is None and back[0]['traceback'] is None
  assert back[0]['metrics']['success'] == 1.0


def test_a_job_without_its_seed_is_refused():
  episode = _episode(3)
  episode['job'][6] = 4
  with pytest.raises(ValueError, match='episode 0: job .* seed 3'):
    results_file.pack([episode])


def test_columns_of_different_lengths_are_refused():
  group, = results_file.pack([_episode(0), _episode(1)])
  group['metrics']['steps'].append(40)
  with pytest.raises(ValueError, match=r'different lengths \[2, 3\]'):
    results_file.unpack([group])


def test_dumps_puts_containers_of_containers_one_item_a_line():
  payload = {'rows': [{'a': 1.5, 'b': None}, {'a': 2}],
             'groups': [{'job': ['x', None, ['real', '/d']],
                         'metrics': {'m': [1, 2.5]}}],
             'notes': 'n'}
  text = results_file.dumps(payload)
  assert json.loads(text) == payload
  assert text.splitlines() == [
      '{', ' "rows": [', '  {"a":1.5,"b":null},', '  {"a":2}', ' ],',
      ' "groups": [', '  {', '   "job": ["x",null,["real","/d"]],',
      '   "metrics": {', '    "m": [1,2.5]', '   }', '  }', ' ],',
      ' "notes": "n"', '}']
  with pytest.raises(ValueError):
    results_file.dumps({'x': [float('nan')]})


def test_files_of_one_dict_per_episode_read_as_well(tmp_path):
  episodes = [_episode(0), _episode(1)]
  old = tmp_path / 'old.json'
  old.write_text(json.dumps({'runs': [], 'rows': [], 'episodes': episodes}))
  assert evaluation_report.load_results(old)[0] == episodes
  new = tmp_path / 'new.json'
  new.write_text(json.dumps({'runs': [], 'rows': [], 'episode_groups':
                             results_file.pack(episodes)}))
  assert evaluation_report.load_results(new)[0] == results_file.unpack(
      results_file.pack(episodes))
