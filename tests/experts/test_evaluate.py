"""The expert evaluation command: bootstrap CI, table, JSON."""

import json

from absl import flags
import numpy as np
import pytest

from hrc_suite import experts
from hrc_suite.experts import evaluate


@pytest.fixture(autouse=True)
def _clear_cache():
  evaluate._ENV_CACHE.clear()   # pylint: disable=protected-access


def _flags(**values):
  """The command's flags (own FlagValues): defaults, then `values`."""
  flag_values = flags.FlagValues()
  evaluate.define_flags(flag_values)
  flag_values(['evaluate'])
  for name, value in values.items():
    setattr(flag_values, name, value)
  return flag_values

def test_success_ci_known_cases():
  assert evaluate.success_ci([1.0] * 20) == (1.0, 1.0, 1.0)
  assert evaluate.success_ci([0.0] * 7) == (0.0, 0.0, 0.0)
  # Half of 400 successes: the bootstrap CI is close to the normal
  # approximation 0.5 +- 1.96 sqrt(0.25 / 400) = 0.5 +- 0.049.
  rate, low, high = evaluate.success_ci([0.0, 1.0] * 200)
  assert rate == 0.5
  assert low == pytest.approx(0.451, abs=0.006)
  assert high == pytest.approx(0.549, abs=0.006)
  # Seeded: the same numbers again; 9 of 10 successes leave the CI below 1.
  assert evaluate.success_ci([1.0] * 9 + [0.0]) == evaluate.success_ci(
      [1.0] * 9 + [0.0])
  rate, low, high = evaluate.success_ci([1.0] * 9 + [0.0])
  assert rate == 0.9 and 0.6 <= low < 0.9 and high == 1.0


def _result(success, critical=0, seed=0, policy='expert'):
  metrics = {'success': success, 'return': 2.0 * seed, 'steps': 10.0 + seed,
             'shield_interventions': 1.0, 'contacts_static': 0.0,
             'self_collisions': 0.0, 'contacts_human_allowed': 3.0,
             'contacts_human_critical': float(critical)}
  return {'domain': 'reach', 'task': 'dense', 'robot': 'schunk',
          'action_space': 'joint', 'shield': 'ssm', 'policy': policy,
          'seed': seed, 'control_timestep': 0.1, 'wall_time': 1.5,
          'metrics': metrics}


def test_summary_and_bar():
  results = [_result(1.0, seed=0), _result(1.0, seed=1),
             _result(0.0, critical=2, seed=2),
             _result(1.0, seed=0, policy='noisy_expert')]
  rows = evaluate.summarise(results)
  assert [row['policy'] for row in rows] == ['expert', 'noisy_expert']
  row = rows[0]
  assert row['episodes'] == 3 and row['success'] == pytest.approx(2 / 3)
  assert row['steps'] == 11.0 and row['seconds'] == pytest.approx(1.1)
  assert row['contacts_human_critical'] == pytest.approx(2 / 3)
  assert row['critical_episodes'] == 1
  assert evaluate.below_bar(row) == [
      'success 0.67 < 0.80', 'critical human contacts in 1 of 3 episodes']
  assert evaluate.below_bar(rows[1]) == []


def _reach_expert_available():
  try:
    experts.expert_class('reach', 'dense')
  except (ImportError, ValueError):
    return False
  return True


def _table_rows(text):
  return [line for line in text.splitlines() if line.startswith('|')]


@pytest.mark.skipif(not _reach_expert_available(),
                    reason='the reach expert is not written yet')
def test_tiny_run_writes_a_well_formed_table(tmp_path):
  out, json_out = tmp_path / 'results' / 'experts.md', tmp_path / 'e.json'
  flag_values = _flags(
      episodes=1, tasks=['reach/dense'], robots=['schunk'],
      time_limit=0.5, out=str(out), json_out=str(json_out), progress=False)
  evaluate.main(['evaluate'], flag_values)
  text = out.read_text()
  table = _table_rows(text)
  header, separator, *rows = table
  columns = header.count('|') - 1
  assert separator == '|' + '---|' * columns
  assert len(rows) == 2   # expert and noisy expert
  for row, policy in zip(rows, ('expert', 'noisy_expert')):
    cells = [c.strip() for c in row.strip('|').split('|')]
    assert len(cells) == columns
    assert cells[:5] == ['reach/dense', 'schunk', policy, 'joint', '1']
    assert cells[7:9] == ['5.0', '0.5']   # 5 RL steps of 0.1 s
  assert '* Command: `python -m hrc_suite.experts.evaluate' in text
  assert f'{evaluate.machine()["cpus"]} CPUs' in text
  # One line per row below the bar (one episode of 0.5 s does not reach
  # the goal).
  below = [line for line in text.splitlines()
           if line.startswith('* BELOW THE BAR: reach/dense schunk')]
  assert len(below) == 2 and 'success 0.00 < 0.80' in below[0]
  payload = json.loads(json_out.read_text())
  assert [e['seed'] for e in payload['episodes']] == [0, 0]
  assert payload['episodes'][0]['metrics']['steps'] == 5.0
  assert len(payload['rows']) == 2
  run, = payload['runs']
  assert np.isfinite(run['wall_time'])
  assert run['rows'] == ['reach/dense schunk expert default',
                         'reach/dense schunk noisy_expert default']


def _row_cells(text):
  return [[c.strip() for c in row.strip('|').split('|')]
          for row in _table_rows(text)[2:]]


@pytest.mark.skipif(not _reach_expert_available(),
                    reason='the reach expert is not written yet')
def test_update_replaces_only_the_rows_it_reruns(tmp_path):
  out, json_out = tmp_path / 'experts.md', tmp_path / 'experts.json'

  def run(policy, episodes, update):
    evaluate.main(['evaluate'], _flags(
        episodes=episodes, tasks=['reach/dense'], robots=['schunk'],
        policies=[policy], time_limit=0.3, out=str(out),
        json_out=str(json_out), progress=False, update=update))
    return json.loads(json_out.read_text())

  run('expert', 1, update=False)
  payload = run('noisy_expert', 1, update=True)
  assert [r['policy'] for r in payload['rows']] == ['expert', 'noisy_expert']
  assert len(payload['runs']) == 2
  # Redo the expert row with 2 episodes: it stays first, the noisy row
  # keeps its episode, and the first run (only the expert row) is gone.
  payload = run('expert', 2, update=True)
  cells = _row_cells(out.read_text())
  assert [(c[2], c[4]) for c in cells] == [('expert', '2'),
                                          ('noisy_expert', '1')]
  assert [run['rows'] for run in payload['runs']] == [
      ['reach/dense schunk noisy_expert default'],
      ['reach/dense schunk expert default']]
  assert out.read_text().count('* Command: `python -m') == 2
  # Without --update the file is written afresh.
  payload = run('expert', 1, update=False)
  assert len(payload['rows']) == 1 and len(payload['runs']) == 1


def test_update_reads_a_file_of_one_run_and_rejects_other_files(tmp_path):
  old = tmp_path / 'old.json'
  episode = dict(_result(1.0), job=['reach', 'dense', 'schunk', None,
                                    'expert', None, 0])
  old.write_text(json.dumps({'info': {'command': 'c'}, 'episodes': [episode],
                             'rows': []}))
  episodes, runs = evaluate.load_previous(old)
  assert episodes == [episode]
  assert runs == [{'command': 'c',
                   'rows': ['reach/dense schunk expert default']}]
  assert evaluate.load_previous(tmp_path / 'missing.json') == ([], [])
  bad = tmp_path / 'bad.json'
  bad.write_text('{"rows": []}')
  with pytest.raises(ValueError, match='bad.json: not a results file'):
    evaluate.load_previous(bad)


def test_unknown_task_or_policy_is_a_usage_error():
  flag_values = _flags(tasks=['reach/far'], progress=False)
  with pytest.raises(Exception, match='No expert for reach/far'):
    evaluate.main(['evaluate'], flag_values)
  flag_values = _flags(policies=['random'], progress=False)
  with pytest.raises(Exception, match=r"Unknown policies \['random'\]"):
    evaluate.main(['evaluate'], flag_values)


def test_an_episode_that_raises_is_a_reported_failure(monkeypatch):
  def broken(env, noise=None):
    del env, noise

    def policy(timestep):
      raise RuntimeError('expert lost track')
    return policy

  monkeypatch.setattr(evaluate.experts, 'make', broken)
  job_list = evaluate.jobs([('reach', 'dense')], ['schunk'], ['expert'], 2,
                           time_limit=0.3)
  results = evaluate.run(job_list)
  assert [r['error'] for r in results] == [
      'RuntimeError: expert lost track'] * 2
  row, = evaluate.summarise(results)
  assert row['errors'] == 2 and row['success'] == 0.0
  assert evaluate.below_bar(row)[-1] == (
      '2 episodes raised (RuntimeError: expert lost track)')


def test_a_killed_run_resumes_from_its_partial_log(tmp_path, monkeypatch):
  partial = tmp_path / 'experts.json.partial.jsonl'
  job_list = evaluate.jobs([('reach', 'dense')], ['schunk'], ['expert'], 2,
                           time_limit=0.3)
  calls = []
  real = evaluate.run_job
  monkeypatch.setattr(evaluate, 'run_job',
                      lambda job: calls.append(job) or real(job))
  first = evaluate.run(job_list, partial=partial)
  assert len(calls) == 2 and len(partial.read_text().splitlines()) == 2
  # Kill after episode 0: its line stays, a torn line follows.
  line = json.loads(partial.read_text().splitlines()[0])
  partial.write_text(json.dumps(line) + '\n{"job": ["rea')
  resumed = evaluate.run(job_list, partial=partial)
  assert calls[2:] == [job_list[1]]   # Only the missing episode ran.
  assert resumed[0] == first[0]
  assert resumed[1]['metrics'] == first[1]['metrics']
  # Both episodes are logged now (after the torn line): nothing runs.
  assert evaluate.run(job_list, partial=partial)[1] == resumed[1]
  assert len(calls) == 3


@pytest.mark.slow   # Spawned processes import hrc_suite afresh (~15 s).
def test_spawned_workers_give_the_same_episodes():
  job_list = evaluate.jobs([('reach', 'dense')], ['schunk'],
                           ['expert', 'noisy_expert'], 2, time_limit=0.4)
  serial = evaluate.run(job_list)
  parallel = evaluate.run(job_list, workers=2)
  assert [r['job'] for r in parallel] == [list(job) for job in job_list]
  for one, other in zip(serial, parallel):
    assert one['metrics'] == other['metrics'] and other['error'] is None


def test_pairs_choose_robot_and_policy_combinations():
  job_list = evaluate.jobs([('reach', 'dense')], ['schunk', 'panda'],
                           ['expert', 'noisy_expert'], 2,
                           pairs=[('schunk', 'expert'), ('panda', 'expert'),
                                  ('schunk', 'noisy_expert')])
  assert [(job[2], job[4]) for job in job_list[::2]] == [
      ('schunk', 'expert'), ('panda', 'expert'), ('schunk', 'noisy_expert')]
  assert len(job_list) == 6
  with pytest.raises(Exception, match='robot:policy'):
    evaluate.main(['evaluate'], _flags(pairs=['schunk-expert'],
                                       progress=False))
