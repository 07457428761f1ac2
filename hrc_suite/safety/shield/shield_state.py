"""The shield's state: one record of everything a cycle reads and changes.

A cycle (docs/shield_maths.md, 4) reads a `ShieldState` and makes the
next one: `Shield.step` (the readable reference) and the compiled cycles
(`batch.step_many`, `cycle_kernels.ssm_cycles`) alike. `Shield.state`
returns the current record and takes one back, so a checkpoint is the
record itself: records are frozen and their arrays and paths are
replaced, never changed in place (the cycles copy before they change).

What is not in the record is derived from it and owned by the class
that computes it: the shield's lazy read-outs (reach capsules, speeds,
distances) and kernel constants (`Shield`), the human model's arm
lengths and velocity errors (`HumanReach`), a plan's samples and tables
(`LongTermPlan`).
"""

import dataclasses
from typing import Any, NamedTuple, Optional, Sequence, Type, TypeVar, Union

import numpy as np

from hrc_suite.safety import long_term_plan as ltp
from hrc_suite.safety.shield import human_reach as human_reach_lib
from hrc_suite.safety.shield import path as path_lib

# Floats of a path as an array (path_kernels): s, s_dot, s_ddot, jerk,
# three phase ends, three phase jerks.
PATH_SIZE = 10

_Record = TypeVar('_Record')   # record's dataclass.


class ReachEdges(NamedTuple):
  """The edges of a check's slices: they define its reach capsules."""
  plan: ltp.LongTermPlan
  s_edges: list     # (K + 1) plan times.
  t_edges: list     # (K + 1) s after the cycle's time.
  q_edges: np.ndarray   # (K + 1, dof) joint positions.


class PendingCheck(NamedTuple):
  """Mode 'off': the inputs of a cycle's check, run when a read-out needs
  it (path_check.PathCheck.verify's)."""
  plan: ltp.LongTermPlan
  current: path_lib.Path
  failsafe: path_lib.Path


@dataclasses.dataclass(frozen=True)
class Verification:
  """The last cycle's check (the read-outs of docs/safety.md, Modes)."""
  is_safe: Optional[bool]    # None: mode 'off', not run yet (`pending`).
  first_unsafe_interval: int   # -1: none.
  # m; None: not computed yet (computed when read); a broad phase's bound
  # when one settled the cycle; -inf when no path could be checked.
  reach_distance: Optional[float]
  edges: Optional[ReachEdges]    # None: no check (no monitored path).
  pending: Optional[PendingCheck] = None


@dataclasses.dataclass(frozen=True)
class ShieldState:
  """Everything a shield cycle reads and changes (see the module)."""
  command: np.ndarray        # (5, dof): q, dq, ddq, dddq, v_nominal.
  previous_q: np.ndarray     # (dof,) the command's q one cycle before.
  verified: path_lib.Path    # The verified path on `plan`.
  intended: Optional[path_lib.Path]   # The intended step kept (or None).
  plan: ltp.LongTermPlan     # The adopted plan.
  goal: Optional[np.ndarray]  # The clamped goal (None before new_goal).
  goal_pending: bool         # A goal's plan is not adopted yet.
  # The plan to the pending goal from the command, awaiting approval, and
  # its key: the verified path's (s, s_dot) it was planned from.
  candidate: Optional[ltp.LongTermPlan]
  candidate_key: Optional[tuple]
  time: float                # s, of the last cycle.
  intervened: bool           # The last cycle did not take the wanted step.
  verification: Verification
  human: human_reach_lib.HumanState

  def replace(self, **changes: Any) -> 'ShieldState':
    """A copy with changes: dataclasses.replace without __init__
    (`record`).

    Args:
      **changes: field name -> its new value.

    Returns:
      The copy.

    Raises:
      TypeError: a change names no field.
    """
    fields = self.__dataclass_fields__
    if not changes.keys() <= fields.keys():
      raise TypeError(f'ShieldState.replace: no fields '
                      f'{sorted(changes.keys() - fields.keys())}')
    made = object.__new__(ShieldState)   # As `record`: every field given.
    values = made.__dict__
    values.update(self.__dict__)
    values.update(changes)
    return made


def record(cls: Type[_Record], **values: Any) -> _Record:
  """`cls(**values)` for a frozen dataclass given every field, without its
  __init__'s one object.__setattr__ per field: the compiled cycles pack a
  record per call (safety/shield/batch.py).

  Args:
    cls: the dataclass (`ShieldState`, `Verification`,
      human_reach.HumanState).
    **values: field name -> value, for every field.

  Returns:
    The record.

  Raises:
    TypeError: values do not name exactly the fields of cls.
  """
  fields = cls.__dataclass_fields__
  if len(values) != len(fields) or not values.keys() <= fields.keys():
    raise TypeError(f'{cls.__name__}: expected the fields '
                    f'{sorted(fields)}, got {sorted(values)}')
  made = object.__new__(cls)
  made.__dict__.update(values)
  return made


def path_array(path: path_lib.Path) -> np.ndarray:
  """A path's floats, as the compiled cycles take it (path_kernels).

  Args:
    path: the path.

  Returns:
    (PATH_SIZE,): s, s_dot, s_ddot, jerk, phase ends and phase jerks.
  """
  ends, jerks = path.phase_ends, path.phase_jerks
  return np.array((path.s, path.s_dot, path.s_ddot, path.jerk, ends[0],
                   ends[1], ends[2], jerks[0], jerks[1], jerks[2]))


def path_from_array(values: Union[np.ndarray, Sequence[float]]
                    ) -> path_lib.Path:
  """The `path.Path` of `path_array`'s floats (attributes set as stored).

  Args:
    values: PATH_SIZE numbers, as `path_array` makes them.

  Returns:
    The path.

  Raises:
    ValueError: values are not PATH_SIZE numbers.
  """
  values = (values.tolist() if type(values) is np.ndarray
            and values.dtype == np.float64 and values.ndim == 1
            else np.asarray(values, dtype=float).ravel().tolist())
  if len(values) != PATH_SIZE:
    raise ValueError(f'path state: expected {PATH_SIZE} numbers, got '
                     f'{len(values)}')
  path = path_lib.Path.__new__(path_lib.Path)
  path.s, path.s_dot, path.s_ddot, path.jerk = values[:4]
  path.phase_ends = values[4:7]
  path.phase_jerks = values[7:]
  return path
