"""The speed benchmarks run (no timing is asserted: speed targets live in
the benchmarks, docs/benchmarks.md)."""

import os
import pathlib
import re
import subprocess
import sys

import pytest

from hrc_suite import benchmark

_REPOSITORY = pathlib.Path(__file__).resolve().parent.parent


def test_rl_step_throughput_reports_rates_and_both_ratios():
  rate, per_step, bare, ratio = benchmark.rl_step_throughput(
      'reach', 'dense', 'schunk', rl_steps=24)
  assert rate == 1.0 / per_step
  assert per_step > 0.0 and bare > 0.0 and ratio > 0.0


def test_profile_parts_add_up_to_the_step_and_restore_the_code():
  """benchmark_profile.profile: every part is timed, the top-level parts
  and 'composer and the rest' add up to the total, nested parts are
  within their parent, and the timing wrappers are removed afterwards."""
  from hrc_suite import benchmark_profile
  from hrc_suite.safety.shield import batch
  step_many = batch.step_many
  out = benchmark_profile.profile('reach', 'dense', 'schunk', rl_steps=6,
                                  action_space='cartesian')
  assert batch.step_many is step_many
  labels = [label for label, *_ in benchmark_profile.PARTS]
  assert set(out) == set(labels) | {'composer and the rest', 'total'}
  top = {label for label, *_, is_top in benchmark_profile.PARTS if is_top}
  assert sum(out[label] for label in top) + out['composer and the rest'] == (
      pytest.approx(out['total']))
  assert out['total'] > 0.0
  shield = '  shield: 25 cycles (safety.shield.batch.step_many)'
  physics = 'task run_physics_steps: the RL step\'s physics steps'
  # Reach steps the shield every RL step inside its physics steps.
  assert 0.0 < out[shield] <= out[physics]


def _compare_speed_row(env, row_start, *args):
  """The row of `python scripts/compare_speed.py --base=HEAD ARGS --windows=2`
  starting with row_start (exactly one)."""
  result = subprocess.run(
      [sys.executable, 'scripts/compare_speed.py', '--base=HEAD', *args,
       '--windows=2'],
      cwd=_REPOSITORY, env=env, capture_output=True, text=True,
      timeout=1200)
  assert result.returncode == 0, result.stderr[-3000:]
  rows = [line for line in result.stdout.splitlines()
          if line.startswith(row_start)]
  assert len(rows) == 1, result.stdout
  return rows[0]


@pytest.mark.slow   # Compiles the commit's kernels in a new cache (~2 min).
def test_compare_speed_steps_a_commit_beside_the_working_tree(tmp_path):
  """scripts/compare_speed.py: the commit's package, its imports renamed,
  runs beside the working tree's; at HEAD both reach the same state, for
  a task and for the shield's cycles (--shield)."""
  if subprocess.run(['git', 'rev-parse', 'HEAD'], cwd=_REPOSITORY,
                    capture_output=True).returncode:
    pytest.skip('not a git checkout: compare_speed needs git archive')
  env = dict(os.environ, HOME=str(tmp_path), MUJOCO_GL='egl')
  row = _compare_speed_row(env, '| reach/dense | schunk |',
                           '--tasks=reach/dense', '--robots=schunk')
  assert row.endswith('| True |'), row
  package = next((tmp_path / '.cache' / 'hrc_suite_compare').glob(
      '*/hrc_suite_base'))
  imports = re.compile(r'^\s*(from|import) hrc_suite\b', re.MULTILINE)
  for source in package.rglob('*.py'):
    assert not imports.search(source.read_text()), source
  # Modules named in strings are renamed too; other names are kept.
  profile = (package / 'benchmark_profile.py').read_text()
  assert "'hrc_suite_base.tasks.base'" in profile
  assert "'hrc_suite.tasks." not in profile
  assert "FORMAT_NAME = 'hrc_suite.clip'" in (
      package / 'human' / 'clip.py').read_text()
  # The shield's RL-step cycles (--shield), from the same extracted commit.
  row = _compare_speed_row(env, '| jaco |', '--shield=pfl', '--robots=jaco')
  assert row.endswith('| True |'), row
