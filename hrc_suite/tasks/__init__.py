"""Benchmark tasks: the shared shielded step loop (`base.HrcTask`) and one
module per task. Load them by name through `hrc_suite.suite.load`."""
