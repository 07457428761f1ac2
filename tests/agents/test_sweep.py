"""agents.sweep: flags, resuming a killed sweep on a real local Ray, errors."""

import contextlib
import io
import os
import signal
import subprocess
import sys
import time

from absl import app
from absl import flags
import numpy as np
import pytest

from agents import grids
from agents import logging as logging_lib
from agents import report
from agents import sweep
from agents import sweep_layout as layout
from agents import sweep_work

_REPOSITORY = os.path.dirname(os.path.dirname(os.path.dirname(
    os.path.abspath(__file__))))
_TIMING = ('wall_time', 'eval_seconds')


def _flags(*args):
  flag_values = flags.FlagValues()
  sweep.define_flags(flag_values)
  flag_values(['sweep'] + list(args))
  return flag_values


def test_flags_replace_grid_fields():
  grid = sweep.grid_from_flags(_flags(
      '--grid=paper_reduced', '--tasks=reach/dense,pick_place/default',
      '--agents=sac,rsi+air', '--seeds=0-2,7', '--steps=2e5',
      '--eval_episodes=5', '--overrides={"batch_size": 64}'))
  assert grid.tasks == ('reach/dense', 'pick_place/default')
  assert grid.agents == ('sac', 'rsi+air')
  assert grid.seeds == (0, 1, 2, 7)
  assert grid.steps == 200_000 and grid.eval_episodes == 5
  assert grid.overrides == {'batch_size': 64}
  per_task = sweep.grid_from_flags(_flags(
      '--grid=paper', '--steps=reach/dense=10,lifting/default=20',
      '--tasks=reach/dense,lifting/default'))
  assert per_task.steps == {'reach/dense': 10, 'lifting/default': 20}
  # A task list alone keeps the paper's budgets of those tasks.
  assert sweep.grid_from_flags(_flags(
      '--grid=paper', '--tasks=lifting/default')).steps == {
          'lifting/default': 1_000_000}


@pytest.mark.parametrize('args, message', [
    (['--grid=papr'], "Unknown grid 'papr'"),
    ([], '--grid is required'),
    (['--grid=smoke', '--seeds=0-x'], "expected integers or ranges a-b, got "
     "'0-x'"),
    (['--grid=smoke', '--steps=1.5'], "'1.5' is not an integer"),
    (['--grid=smoke', '--task_kwargs=[1]'], 'expected a JSON object'),
    (['--grid=smoke', '--overrides={bad'], '--overrides: not valid JSON'),
    (['--grid=smoke', '--agents=sac,dqn'], 'agents='),
    (['--grid=smoke', '--tasks=reach/far'], "Unknown task 'far'"),
])
def test_bad_grids_and_overrides_are_usage_errors(args, message, tmp_path):
  with pytest.raises(app.UsageError, match=message):
    sweep.main(['sweep'], _flags(*args, f'--out={tmp_path}'))


def test_unreachable_cluster_addresses_are_named(tmp_path):
  # Port 1 on the loopback: nothing listens there.
  with pytest.raises(ConnectionError, match=r"--ray_address='127.0.0.1:1': "
                     'no answer from 127.0.0.1:1'):
    sweep.check_reachable('127.0.0.1:1', timeout=2)
  with pytest.raises(ValueError, match='expected auto, HOST:PORT'):
    sweep.check_reachable('cluster')
  # main turns it into a message and exit status 2, nothing started.
  stderr = io.StringIO()
  sys_stderr, sys.stderr = sys.stderr, stderr
  try:
    status = sweep.main(['sweep'], _flags(
        '--grid=smoke', f'--out={tmp_path}', '--ray_address=127.0.0.1:1'))
  finally:
    sys.stderr = sys_stderr
  assert status == 2
  assert 'Cannot reach a Ray cluster' in stderr.getvalue()



def test_ctrl_c_says_how_to_resume(tmp_path, monkeypatch, capsys):
  """Ctrl-C during the sweep ends it with the shells' status and the way
  to resume, not a traceback from inside Ray's wait."""
  def interrupted(*args, **kwargs):
    raise KeyboardInterrupt
  monkeypatch.setattr(sweep, 'run_sweep', interrupted)
  status = sweep.main(['sweep'], _flags('--grid=smoke', f'--out={tmp_path}'))
  assert status == sweep.INTERRUPTED_STATUS == 130
  assert 'resume from their last checkpoint when the same command starts '\
      'again' in capsys.readouterr().err

def test_sigterm_stops_the_sweep_as_ctrl_c_does(tmp_path, monkeypatch,
                                               capsys):
  """A scheduler's SIGTERM (or `kill`) ends the sweep with 128 + 15 and
  the way to resume; the process's own SIGTERM handling comes back."""
  def terminated(*args, **kwargs):
    os.kill(os.getpid(), signal.SIGTERM)
    time.sleep(30)   # The handler interrupts this.
    raise AssertionError('SIGTERM did not stop the sweep')
  monkeypatch.setattr(sweep, 'run_sweep', terminated)
  before = signal.getsignal(signal.SIGTERM)
  status = sweep.main(['sweep'], _flags('--grid=smoke', f'--out={tmp_path}'))
  assert status == sweep.TERMINATED_STATUS == 143
  assert '[sweep] terminated: finished runs are kept' in (
      capsys.readouterr().err)
  assert signal.getsignal(signal.SIGTERM) is before


def _raises_interrupt_inside_a_call():
  try:
    raise KeyboardInterrupt
  except KeyboardInterrupt:   # As a C extension reports Ctrl-C in a call.
    raise SystemError('returned a result with an exception set')


@pytest.mark.parametrize('raise_it, failure', [
    (lambda: (_ for _ in ()).throw(KeyboardInterrupt), False),
    (_raises_interrupt_inside_a_call, False),
    (lambda: (_ for _ in ()).throw(RuntimeError('diverged')), True),
])
def test_an_interrupted_run_is_not_recorded_as_failed(
    raise_it, failure, tmp_path, monkeypatch):
  from agents import train   # pylint: disable=g-import-not-at-top
  def stop(*args, **kwargs):
    raise_it()
  monkeypatch.setattr(train, 'make_run_config',
                      lambda dataset=None, **config: dict(config))
  monkeypatch.setattr(train, 'train', stop)
  monkeypatch.setattr(sweep_work, 'cpu_slot',   # Leave this process's
                      lambda cpus: contextlib.nullcontext())   # cores.
  root = str(tmp_path / 'sweep')
  with pytest.raises(BaseException):
    sweep_work.train_run(root, 'reach/sac/seed0', {'steps': 10}, cpus=1)
  directory = layout.run_directory(root, 'reach/sac/seed0')
  error_file = os.path.join(directory, layout.ERROR_FILE)
  assert os.path.exists(error_file) == failure
  if failure:
    assert 'RuntimeError: diverged' in open(error_file).read()
  else:
    assert 'interrupted' in open(os.path.join(directory,
                                              layout.LOG_FILE)).read()


def test_a_sweep_directory_keeps_its_grid(tmp_path):
  grid = grids.get('smoke')
  sweep.open_sweep(str(tmp_path), grid)
  record = sweep.open_sweep(str(tmp_path), grid.replace(steps=500))
  assert len(record['starts']) == 2   # steps may grow
  with pytest.raises(ValueError, match=r"another grid \(seeds: \[0\] -> "
                     r"\[0, 1\]\).*choose a new --out"):
    sweep.open_sweep(str(tmp_path), grid.replace(seeds=(0, 1)))


def test_progress_line_counts_runs_and_steps(tmp_path):
  grid = grids.get('smoke').replace(steps=1000)
  runs = grid.runs()
  reporter = sweep.ProgressReporter(str(tmp_path), runs, io.StringIO())
  first, second = (layout.run_directory(str(tmp_path), r.name) for r in runs)
  os.makedirs(first)
  os.makedirs(second)
  layout.write_json(os.path.join(first, layout.FINISHED_FILE),
                    {'steps': 1000})
  layout.ProgressWriter(second, 1000)(250, force=True)
  line = reporter.line(running=1)
  assert line.startswith('[sweep] runs: 1 done, 1 running, 0 waiting of 2 '
                         '| steps 1.25e+03 of 2e+03 (62.5 %)')
  assert 'left' in line   # a rate, hence an estimate


def test_thread_environment_confines_xla_to_one_core():
  one = sweep_work.thread_environment(1)
  assert '--xla_cpu_multi_thread_eigen=false' in one['XLA_FLAGS']
  assert one['NUMBA_NUM_THREADS'] == one['OMP_NUM_THREADS'] == '1'
  assert sweep_work.thread_environment(2)['OMP_NUM_THREADS'] == '2'


def test_cpu_slots_are_exclusive(tmp_path):
  cores = sorted(os.sched_getaffinity(0))
  with sweep_work.cpu_slot(1, str(tmp_path)) as first:
    assert first == cores[:1]
    assert sorted(os.sched_getaffinity(0)) == first
    child = subprocess.run(
        [sys.executable, '-c', 'import os\nfrom agents import sweep_work\n'
         f'os.sched_setaffinity(0, {cores})\n'   # not the parent's pinning
         f'with sweep_work.cpu_slot(1, {str(tmp_path)!r}) as c: print(c)'],
        capture_output=True, text=True, cwd=_REPOSITORY, check=True)
    expected = str(cores[1:2]) if len(cores) > 1 else 'None'
    assert child.stdout.strip() == expected
  os.sched_setaffinity(0, cores)


def _sweep_command(out, *extra):
  return [sys.executable, '-m', 'agents.sweep', '--grid=smoke', f'--out={out}',
          '--num_cpus=1', '--report_every=2', '--steps=600', *extra]


def _deterministic_rows(path):
  return [{k: v for k, v in row.items() if k not in _TIMING}
          for row in logging_lib.read_csv(path)]


def _arrays(directory):
  arrays = {}
  for name in sorted(os.listdir(directory)):
    if name.endswith('.npz'):
      with np.load(os.path.join(directory, name), allow_pickle=False) as data:
        arrays.update({f'{name}/{k}': data[k] for k in data.files})
  return arrays


def _final_agent(run_directory):
  pointer = os.path.join(run_directory, 'checkpoints', 'latest')
  name = open(pointer).read().strip()
  return _arrays(os.path.join(run_directory, 'checkpoints', name, 'agent'))


def _kill_session(session):
  """SIGKILL to every process of a session: the sweep, its Ray and Ray's
  workers (each in a process group of its own), as when a machine stops."""
  for name in os.listdir('/proc'):
    if name.isdigit():
      try:
        if os.getsid(int(name)) == session:
          os.kill(int(name), signal.SIGKILL)
      except (ProcessLookupError, PermissionError):
        pass


@pytest.mark.slow
def test_a_killed_sweep_resumes_to_the_same_results(tmp_path):
  """The smoke grid on a real local Ray (1 CPU), killed (SIGKILL to the
  sweep, its Ray and its workers) with one run finished and the other past
  a checkpoint, then started again: it re-runs nothing finished and ends
  with the results of an uninterrupted sweep."""
  whole, split = str(tmp_path / 'whole'), str(tmp_path / 'split')
  environment = dict(os.environ, PYTHONPATH=_REPOSITORY)
  # An announced cluster (RAY_ADDRESS, as `ray start` leaves on a machine)
  # is not joined by the embedded sweep: nothing answers at this one.
  subprocess.run(_sweep_command(whole), check=True, cwd=_REPOSITORY,
                 env=dict(environment, RAY_ADDRESS='127.0.0.1:1'),
                 capture_output=True, timeout=1800)
  runs = grids.get('smoke').replace(steps=600).runs()
  directories = [layout.run_directory(split, r.name) for r in runs]

  process = subprocess.Popen(_sweep_command(split), cwd=_REPOSITORY,
                             env=environment, start_new_session=True,
                             stdout=subprocess.DEVNULL,
                             stderr=subprocess.DEVNULL)
  killed_after = None
  deadline = time.time() + 1800
  while time.time() < deadline and process.poll() is None:
    finished = [d for d in directories if layout.is_finished(d, 600)]
    started = [d for d in directories if d not in finished and os.path.exists(
        os.path.join(d, 'checkpoints', 'latest'))]
    if finished and started:
      _kill_session(process.pid)
      killed_after = (finished[0], started[0])
      break
    time.sleep(0.05)
  process.wait(timeout=60)
  assert killed_after is not None, 'the sweep ended before it was killed'
  done, interrupted = killed_after
  assert not layout.is_finished(interrupted, 600)
  record = open(os.path.join(done, layout.FINISHED_FILE)).read()
  log = open(os.path.join(done, layout.LOG_FILE)).read()

  result = subprocess.run(_sweep_command(split), cwd=_REPOSITORY,
                          env=environment, capture_output=True, text=True,
                          timeout=1800)
  assert result.returncode == 0, result.stderr[-3000:]
  assert '2 runs, 1 finished before' in result.stdout
  # The finished run was not trained again.
  assert open(os.path.join(done, layout.FINISHED_FILE)).read() == record
  assert open(os.path.join(done, layout.LOG_FILE)).read() == log
  assert 'Resumed' in open(os.path.join(interrupted, layout.LOG_FILE)).read()
  for run, directory in zip(runs, directories):
    reference = layout.run_directory(whole, run.name)
    assert layout.is_finished(directory, 600)
    assert (_deterministic_rows(os.path.join(directory, 'eval.csv')) ==
            _deterministic_rows(os.path.join(reference, 'eval.csv')))
    expected, actual = _final_agent(reference), _final_agent(directory)
    assert expected.keys() == actual.keys() and expected
    for key, value in expected.items():
      np.testing.assert_array_equal(actual[key], value, err_msg=key)
  # Started once more, there is nothing left to do.
  again = subprocess.run(_sweep_command(split), cwd=_REPOSITORY,
                         env=environment, capture_output=True, text=True,
                         timeout=1800)
  assert again.returncode == 0 and '2 runs, 2 finished before' in again.stdout
  # The report reads the real sweep: 5 evaluations of each run, the
  # expert's return from the sweep's shared folder, no run missing.
  result = report.report(split, str(tmp_path / 'report'), resamples=100)
  assert result['missing'] == {}
  assert sorted((r['agent'], r['step']) for r in result['rows']) == [
      (agent, step) for agent in ('rsi', 'sac')
      for step in (0, 150, 300, 450, 600)]
  assert all(r['normalised_return'] is not None for r in result['rows'])
