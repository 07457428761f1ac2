"""The evaluation command: bootstrap CI, table, JSON, people, shields."""

import json

from absl import flags
from dm_env import specs
import numpy as np
import pytest

from hrc_suite.experts import evaluate
from hrc_suite.experts import evaluation_episodes as episodes_lib
from hrc_suite.experts import evaluation_report as report_lib
from hrc_suite.experts import evaluation_rows as rows_lib
from hrc_suite.human import recording_cache


@pytest.fixture(autouse=True)
def _clear_cache():
  episodes_lib._ENV_CACHE.clear()   # pylint: disable=protected-access


def _flags(**values):
  """The command's flags (own FlagValues): defaults, then `values`."""
  flag_values = flags.FlagValues()
  evaluate.define_flags(flag_values)
  flag_values(['evaluate'])
  for name, value in values.items():
    setattr(flag_values, name, value)
  return flag_values


def test_success_ci_known_cases():
  assert rows_lib.success_ci([1.0] * 20) == (1.0, 1.0, 1.0)
  assert rows_lib.success_ci([0.0] * 7) == (0.0, 0.0, 0.0)
  # Half of 400 successes: the bootstrap CI is close to the normal
  # approximation 0.5 +- 1.96 sqrt(0.25 / 400) = 0.5 +- 0.049.
  rate, low, high = rows_lib.success_ci([0.0, 1.0] * 200)
  assert rate == 0.5
  assert low == pytest.approx(0.451, abs=0.006)
  assert high == pytest.approx(0.549, abs=0.006)
  # Seeded: the same numbers again; 9 of 10 successes leave the CI below 1.
  assert rows_lib.success_ci([1.0] * 9 + [0.0]) == rows_lib.success_ci(
      [1.0] * 9 + [0.0])
  rate, low, high = rows_lib.success_ci([1.0] * 9 + [0.0])
  assert rate == 0.9 and 0.6 <= low < 0.9 and high == 1.0


def _result(success, critical=0, seed=0, policy='expert', shield='ssm',
            job=None):
  metrics = {'success': success, 'return': 2.0 * seed, 'steps': 10.0 + seed,
             'shield_interventions': 1.0, 'contacts_static': 0.0,
             'self_collisions': 0.0, 'contacts_human_allowed': 3.0,
             'contacts_human_critical': float(critical),
             'min_human_distance': 0.1 - 0.1 * critical}
  result = {'domain': 'reach', 'task': 'dense', 'robot': 'schunk',
            'action_space': 'joint', 'shield': shield, 'policy': policy,
            'seed': seed, 'control_timestep': 0.1, 'wall_time': 1.5,
            'metrics': metrics}
  if job is not None:
    result['job'] = job
  return result


def test_summary_and_bar():
  results = [_result(1.0, seed=0), _result(1.0, seed=1),
             _result(0.0, critical=2, seed=2),
             _result(1.0, seed=0, policy='noisy_expert')]
  rows = rows_lib.summarise(results)
  assert [row['policy'] for row in rows] == ['expert', 'noisy_expert']
  row = rows[0]
  assert row['episodes'] == 3 and row['success'] == pytest.approx(2 / 3)
  assert row['steps'] == 11.0 and row['seconds'] == pytest.approx(1.1)
  assert row['contacts_human_critical'] == pytest.approx(2 / 3)
  assert row['critical_episodes'] == 1
  assert rows_lib.below_bar(row) == [
      'success 0.67 < 0.80',
      'critical human contacts inside the human model in 1 of 3 episodes']
  assert rows_lib.below_bar(rows[1]) == []


def test_contacts_outside_the_human_model_do_not_fail_the_bar():
  """Critical contacts while the person moved faster than the shield's
  human model are outside its guarantee: counted, not held against the
  row; one contact inside the model fails it."""
  outside = _result(1.0, critical=3, seed=0)
  outside['metrics']['contacts_human_critical_outside_model'] = 3.0
  mixed = _result(1.0, critical=3, seed=1)
  mixed['metrics']['contacts_human_critical_outside_model'] = 2.0
  assert rows_lib.critical_inside_model(outside['metrics']) == 0
  assert rows_lib.critical_inside_model(mixed['metrics']) == 1
  row, = rows_lib.summarise([outside, _result(1.0, seed=2)])
  assert (row['critical_episodes'],
          row['critical_inside_model_episodes']) == (1, 0)
  assert row['contacts_human_critical_outside_model'] == 3.0
  assert rows_lib.below_bar(row) == []
  row, = rows_lib.summarise([outside, mixed])
  assert rows_lib.below_bar(row) == [
      'critical human contacts inside the human model in 1 of 2 episodes']


def _table_rows(text):
  return [line for line in text.splitlines() if line.startswith('|')]


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
    assert cells[:7] == ['reach/dense', 'schunk', policy, 'synthetic',
                         'ssm', 'joint', '1']
    assert cells[9:11] == ['5.0', '0.5']   # 5 RL steps of 0.1 s
  assert '* Command: `python -m hrc_suite.experts.evaluate' in text
  assert f'{report_lib.machine()["cpus"]} CPUs' in text
  # One line per row below the bar (one episode of 0.5 s does not reach
  # the goal).
  below = [line for line in text.splitlines()
           if line.startswith('* BELOW THE BAR: reach/dense schunk')]
  assert len(below) == 2 and 'success 0.00 < 0.80' in below[0]
  payload = json.loads(json_out.read_text())
  episodes = report_lib.load_results(json_out)[0]
  assert [e['seed'] for e in episodes] == [0, 0]
  assert episodes[0]['metrics']['steps'] == 5.0
  assert len(payload['episode_groups']) == len(payload['rows']) == 2
  run, = payload['runs']
  assert np.isfinite(run['wall_time'])
  assert run['rows'] == ['reach/dense schunk expert default',
                         'reach/dense schunk noisy_expert default']


def _row_cells(text):
  return [[c.strip() for c in row.strip('|').split('|')]
          for row in _table_rows(text)[2:]]


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
  assert [(c[2], c[6]) for c in cells] == [('expert', '2'),
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
  episodes, runs = report_lib.load_previous(old)
  assert episodes == [episode]
  assert runs == [{'command': 'c',
                   'rows': ['reach/dense schunk expert default']}]
  assert report_lib.load_previous(tmp_path / 'missing.json') == ([], [])
  bad = tmp_path / 'bad.json'
  bad.write_text('{"rows": []}')
  with pytest.raises(ValueError, match='bad.json: not a results file'):
    report_lib.load_previous(bad)


def test_unknown_task_or_policy_is_a_usage_error():
  flag_values = _flags(tasks=['reach/far'], progress=False)
  with pytest.raises(Exception, match='No expert for reach/far'):
    evaluate.main(['evaluate'], flag_values)
  flag_values = _flags(policies=['greedy'], progress=False)
  with pytest.raises(Exception, match=r"Unknown policies \['greedy'\]"):
    evaluate.main(['evaluate'], flag_values)
  # Shield modes are checked against the registry as flags are set.
  with pytest.raises(flags.IllegalFlagValueError,
                     match="unknown shield mode 'on': expected one of "
                     'default, ssm, pfl, off'):
    _flags(shield=['default', 'on'], progress=False)


def test_an_episode_that_raises_is_a_reported_failure(monkeypatch):
  def broken(env, noise=None):
    del env, noise

    def policy(timestep):
      raise RuntimeError('expert lost track')
    return policy

  monkeypatch.setattr(episodes_lib.experts, 'make', broken)
  job_list = episodes_lib.jobs([('reach', 'dense')], ['schunk'], ['expert'], 2,
                               time_limit=0.3)
  results = episodes_lib.run(job_list)
  assert [r['error'] for r in results] == [
      'RuntimeError: expert lost track'] * 2
  row, = rows_lib.summarise(results)
  assert row['errors'] == 2 and row['success'] == 0.0
  assert rows_lib.below_bar(row)[-1] == (
      '2 episodes raised (RuntimeError: expert lost track)')


def test_a_killed_run_resumes_from_its_partial_log(tmp_path, monkeypatch):
  partial = tmp_path / 'experts.json.partial.jsonl'
  job_list = episodes_lib.jobs([('reach', 'dense')], ['schunk'], ['expert'], 2,
                               time_limit=0.3)
  calls = []
  real = episodes_lib.run_job
  monkeypatch.setattr(episodes_lib, 'run_job',
                      lambda job: calls.append(job) or real(job))
  first = episodes_lib.run(job_list, partial=partial)
  assert len(calls) == 2 and len(partial.read_text().splitlines()) == 2
  # Kill after episode 0: its line stays, a torn line follows.
  line = json.loads(partial.read_text().splitlines()[0])
  partial.write_text(json.dumps(line) + '\n{"job": ["rea')
  resumed = episodes_lib.run(job_list, partial=partial)
  assert calls[2:] == [job_list[1]]   # Only the missing episode ran.
  assert resumed[0] == first[0]
  assert resumed[1]['metrics'] == first[1]['metrics']
  # Both episodes are logged now (after the torn line): nothing runs.
  assert episodes_lib.run(job_list, partial=partial)[1] == resumed[1]
  assert len(calls) == 3


@pytest.mark.slow   # Spawned processes import hrc_suite afresh (~15 s).
def test_spawned_workers_give_the_same_episodes():
  job_list = episodes_lib.jobs([('reach', 'dense')], ['schunk'],
                               ['expert', 'noisy_expert'], 2, time_limit=0.4)
  serial = episodes_lib.run(job_list)
  parallel = episodes_lib.run(job_list, workers=2)
  assert [r['job'] for r in parallel] == [list(job) for job in job_list]
  for one, other in zip(serial, parallel):
    assert one['metrics'] == other['metrics'] and other['error'] is None


def test_pairs_choose_robot_and_policy_combinations():
  job_list = episodes_lib.jobs([('reach', 'dense')], ['schunk', 'panda'],
                               ['expert', 'noisy_expert'], 2,
                               pairs=[('schunk', 'expert'),
                                      ('panda', 'expert'),
                                      ('schunk', 'noisy_expert')])
  assert [(job[2], job[4]) for job in job_list[::2]] == [
      ('schunk', 'expert'), ('panda', 'expert'), ('schunk', 'noisy_expert')]
  assert len(job_list) == 6
  with pytest.raises(Exception, match='robot:policy'):
    evaluate.main(['evaluate'], _flags(pairs=['schunk-expert'],
                                       progress=False))


def test_random_policy_is_uniform_and_seeded_per_episode():
  spec = specs.BoundedArray((3,), np.float32, minimum=[-1.0, 0.0, -2.0],
                            maximum=[1.0, 0.5, 2.0])
  policy = episodes_lib.RandomPolicy(spec)

  def episode(seed, steps=200):
    policy.set_episode(seed)
    return np.array([policy(None) for _ in range(steps)])

  actions = episode(3)
  assert actions.dtype == np.float32
  assert np.all(actions >= spec.minimum) and np.all(actions <= spec.maximum)
  # Uniform: the means are near the middle (std of a mean of 200 uniform
  # draws on [a, b]: (b - a) / sqrt(12 * 200) = 0.02 (b - a); 5 std).
  width = spec.maximum - spec.minimum
  assert np.all(np.abs(actions.mean(axis=0) - [0.0, 0.25, 0.0])
                < 0.1 * width)
  # The episode's seed alone decides: numpy's global state does not.
  np.random.seed(0)
  again = episode(3)
  np.random.seed(1)
  np.testing.assert_array_equal(episode(3), again)
  np.testing.assert_array_equal(actions, again)
  assert not np.array_equal(episode(4), actions)
  with pytest.raises(ValueError, match='finite bounds'):
    episodes_lib.RandomPolicy(specs.BoundedArray((2,), float, -np.inf, 1.0))


def test_jobs_and_row_keys_name_people_and_shield():
  real = ('real', '/data/motions')
  job_list = episodes_lib.jobs([('lifting', 'default')], ['panda'], ['random'],
                               2, motions=real, shields=(None, 'off'))
  assert [job[-1] for job in job_list] == [None, None, 'off', 'off']
  assert job_list[0][7] == list(real)   # As it reads back from JSON.
  keys = [rows_lib.row_key({'job': job}) for job in job_list]
  assert keys[0] == 'lifting/default panda random default people=real'
  assert keys[2] == keys[0] + ' shield=off'
  # A job of a file written before people and shields: synthetic people
  # and the task's shield, its row key unchanged.
  old = ['reach', 'dense', 'schunk', None, 'expert', None, 0]
  assert episodes_lib.job_fields(old)[7:] == (None, None)
  assert rows_lib.row_key({'job': old}) == 'reach/dense schunk expert default'
  assert episodes_lib.people({'job': old}) == 'synthetic'
  assert episodes_lib.people({'job': job_list[0]}) == 'real'


def _run(rows):
  return {'command': 'python -m hrc_suite.experts.evaluate', 'date': 'd',
          'commit': 'abc', 'workers': 1, 'wall_time': 1.0,
          'machine': report_lib.machine(),
          'rows': [rows_lib.row_key(r) for r in rows]}


def test_random_rows_have_the_safety_bar_and_shield_off_has_none():
  real = ['real', '/data']

  def random(seed, shield, critical):
    job = ['reach', 'dense', 'schunk', None, 'random', None, seed, real,
           None if shield == 'ssm' else shield]
    return dict(_result(0.0, critical, seed, 'random', shield, job),
                people='real')

  results = ([random(s, 'ssm', 0) for s in range(3)]
             + [random(s, 'off', 2 * (s > 0)) for s in range(3)])
  on, off = rows_lib.summarise(results)
  assert (on['people'], on['shield'], on['shield_choice']) == (
      'real', 'ssm', 'default')
  assert (off['shield'], off['critical_episodes']) == ('off', 2)
  assert off['min_human_distance'] == pytest.approx(-0.1)
  # No success bar for a random policy; no safety bar with the shield off.
  assert rows_lib.below_bar(on) == [] and rows_lib.below_bar(off) == []
  with_contact = rows_lib.summarise([random(0, 'ssm', 1)])[0]
  assert rows_lib.below_bar(with_contact) == [
      'critical human contacts inside the human model in 1 of 1 episodes']
  text = report_lib.markdown([on, off], [_run(results)], results=results)
  assert text.startswith('# Test-policy safety check (people: real)\n')
  assert ('## Rows below the bar (random policy: zero critical human '
          'contacts inside the human model with the shield on)') in text
  assert ('* reach/dense schunk random (real people, shield off): critical '
          'human contacts in 2 of 3 episodes (1.3 physics steps per '
          'episode); closest approach -0.100 m') in text
  assert "real: the task's motions in `/data`" in text
  # A shield-off row without critical contacts says so.
  quiet = [random(0, 'off', 0)]
  assert 'NO critical human contact in 1 episodes' in report_lib.markdown(
      rows_lib.summarise(quiet), [_run(quiet)])


def test_metrics_older_episodes_lack_show_as_missing():
  row, = rows_lib.summarise([_result(1.0)])   # No pushed contacts etc.
  text = report_lib.markdown([row], [_run([])])
  cells = _row_cells(text)[0]
  header = [c.strip() for c in _table_rows(text)[0].strip('|').split('|')]
  assert len(cells) == len(header)
  values = dict(zip(header, cells))
  assert values['contacts human critical'] == '0.00'
  for name in ('contacts human pushed', 'steps outside human model',
               'shield resyncs', 'physics errors'):
    assert values[name] == report_lib.MISSING


def _old_file(path):
  """A results file as the command wrote it before people and shields."""
  episode = dict(_result(1.0), job=['reach', 'dense', 'schunk', None,
                                    'expert', None, 0])
  path.write_text(json.dumps({
      'runs': [dict(_run([episode]), command='old command')],
      'rows': [], 'episodes': [episode], 'not_evaluated': {}}))
  return episode


def test_rewrite_only_writes_the_table_without_running(tmp_path,
                                                       monkeypatch):
  out, json_out = tmp_path / 't.md', tmp_path / 't.json'
  episode = _old_file(json_out)
  monkeypatch.setattr(episodes_lib, 'run_job', lambda job: pytest.fail('ran'))
  notes = tmp_path / 'notes.md'
  notes.write_text('Hand-written note.\n')
  evaluate.main(['evaluate'], _flags(rewrite_only=True, out=str(out),
                                     json_out=str(json_out),
                                     notes=str(notes)))
  text = out.read_text()
  cells, = _row_cells(text)
  assert cells[:7] == ['reach/dense', 'schunk', 'expert', 'synthetic', 'ssm',
                       'joint', '1']
  assert '* Command: `old command`' in text
  assert '## Notes\n\nHand-written note.\n' in text
  payload = json.loads(json_out.read_text())
  assert report_lib.load_results(json_out)[0] == [episode] and payload['notes']
  # Again without --notes: the notes stay, the table is the same.
  evaluate.main(['evaluate'], _flags(rewrite_only=True, out=str(out),
                                     json_out=str(json_out)))
  assert out.read_text() == text
  with pytest.raises(Exception, match='no results to rewrite'):
    evaluate.main(['evaluate'], _flags(rewrite_only=True,
                                       out=str(tmp_path / 'none.md')))


@pytest.fixture
def real_motions(tmp_path_factory, monkeypatch, recordings_dir):
  """The reference recordings, converted into a cache shared by this
  session's tests."""
  monkeypatch.setenv(recording_cache.CACHE_ENV,
                     str(tmp_path_factory.getbasetemp() / 'recordings'))
  return recordings_dir


@pytest.mark.recordings
def test_random_policy_on_real_recordings_with_and_without_shield(
    tmp_path, real_motions):
  out, json_out = tmp_path / 'safety.md', tmp_path / 'safety.json'
  old = _old_file(json_out)
  evaluate.main(['evaluate'], _flags(
      episodes=1, tasks=['reach/dense', 'pick_place/close'],
      robots=['panda'], policies=['random'], shield=['default', 'off'],
      motions=str(real_motions), motions_label='real', time_limit=0.3,
      out=str(out), json_out=str(json_out), progress=False, update=True))
  text = out.read_text()
  cells = _row_cells(text)
  # The old synthetic row stays; reach has no recordings: not evaluated.
  assert [c[:7] for c in cells] == [
      ['reach/dense', 'schunk', 'expert', 'synthetic', 'ssm', 'joint', '1'],
      ['pick_place/close', 'panda', 'random', 'real', 'ssm', 'cartesian',
       '1'],
      ['pick_place/close', 'panda', 'random', 'real', 'off', 'cartesian',
       '1']]
  assert cells[1][10] == '0.3'   # s
  assert text.startswith('# Expert baseline and test-policy safety check')
  assert '## Shield off: the check can fail' in text
  assert ("* reach/dense (real people): skipped: ClipError: "
          in text) and "no sub-folder for task 'reach'" in text
  payload = json.loads(json_out.read_text())
  episodes = report_lib.load_results(json_out)[0]
  assert episodes[0] == old
  assert [r['people'] for r in payload['rows']] == [
      'synthetic', 'real', 'real']
  assert list(payload['not_evaluated']) == ['reach/dense people=real']
  assert payload['runs'][-1]['rows'] == [
      'pick_place/close panda random default people=real',
      'pick_place/close panda random default people=real shield=off']
  metrics = episodes[1]['metrics']
  for name in ('steps_outside_human_model', 'contacts_human_pushed',
               'shield_resyncs', 'physics_errors'):
    assert metrics[name] is not None
  # Every task without recordings: nothing to run.
  with pytest.raises(Exception, match='Nothing to run: reach/dense'):
    evaluate.main(['evaluate'], _flags(
        episodes=1, tasks=['reach/dense'], policies=['random'],
        motions=str(real_motions), out=str(tmp_path / 'x.md'),
        progress=False))
