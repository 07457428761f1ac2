"""PFL's look-ahead tables of a plan: how many samples a slice spans
(`PFL_WINDOW`) and the speed tables from capsule surface speeds
(`pfl_speed_tables`; docs/shield_maths.md, 9.3).

A shield keeps a plan's tables on the plan (`Shield.plan_speeds`,
computed from the plan in one kernel: speed_kernels.plan_speed_tables;
energy PFL's: `energy_setup.EnergySetup.plan_energies`).
"""

from typing import Tuple

import numpy as np

from hrc_suite.safety import kernels

# PFL: samples over which a reachable-set slice can extend (one slice is
# reachability_interval_cycles = 5 cycles of plan time at s_dot <= 1; one
# more for the Taylor step past the last sample).
PFL_WINDOW = 6


def pfl_speed_tables(speeds: np.ndarray, compiled: bool = True
                     ) -> Tuple[np.ndarray, np.ndarray]:
  """PFL tables from a plan's capsule surface speeds at nominal path speed
  (`Shield.plan_speeds` computes them from the plan in one kernel).

  Args:
    speeds: (N, L) the surface speed of each capsule at each plan sample,
      m/s.
    compiled: False runs the NumPy reference.

  Returns:
    (window, suffix), both (N,): the largest speed over the next
    PFL_WINDOW samples (the last held past the end), and from each sample
    to the end.
  """
  if compiled:
    return kernels.speed_tables(np.ascontiguousarray(speeds, dtype=float),
                                PFL_WINDOW)
  speeds = speeds.max(axis=1)
  padded = np.concatenate([speeds, np.full(PFL_WINDOW, speeds[-1])])
  window = np.lib.stride_tricks.sliding_window_view(
      padded, PFL_WINDOW + 1).max(axis=1)[:len(speeds)]
  suffix = np.maximum.accumulate(speeds[::-1])[::-1]
  return window, suffix
