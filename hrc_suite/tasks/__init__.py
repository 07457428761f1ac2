"""Benchmark tasks: `base.HrcTask` and one module per task, on the runtime
every task shares (`tasks.runtime`). Load them by name through
`hrc_suite.suite.load`."""
