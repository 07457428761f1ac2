"""The reachability shield (docs/safety.md).

`shield.Shield` is the shield; `from hrc_suite.safety import shield` and
`shield.Shield(...)` reach it here too. Modules: `shield` (the readable
cycle), `shield_state` (its state) and `state_io` (the state as a dict),
`cycle_terms` (the cycle's constants), `path_check` (the check of a
monitored path), `tracking` (how far the robot is from the command),
`energy_setup` (energy PFL's inputs), `modes` and `mode_kernels` (what a
mode checks, readable and compiled), `verification`, `energy_verification`
and `energy_check_kernels` (the SSM and energy verdicts), `human_reach`
(the human's reachable set), `path` and `path_kernels` (the monitored
path), `pfl_tables`, `speed_kernels` and `energy_table_kernels` (PFL's and
energy PFL's tables of a plan), `cycle_kernels` and `batch` (the compiled
cycles) and `benchmark` (their timing).
"""

from hrc_suite.safety.shield.shield import Shield

__all__ = ('Shield',)
