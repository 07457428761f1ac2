"""hrc_suite: human-robot collaboration benchmarks on dm_control composer."""
