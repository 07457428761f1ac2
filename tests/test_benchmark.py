"""The speed benchmark's throughput measurement runs (no timing is
asserted: speed targets live in the benchmark, docs/benchmarks.md)."""

from hrc_suite import benchmark


def test_rl_step_throughput_reports_rates_and_both_ratios():
  rate, per_step, bare, ratio = benchmark.rl_step_throughput(
      'reach', 'dense', 'schunk', rl_steps=24)
  assert rate == 1.0 / per_step
  assert per_step > 0.0 and bare > 0.0 and ratio > 0.0
