"""Compiled verification of each shield mode: what a mode adds to the
compiled cycles (`cycle_kernels`).

A mode (safety/shield/modes.py) hands the compiled cycles one named group of
parameters (`ShieldMode.kernel_parameters`, a `typing.NamedTuple`) and,
per plan, one named group of tables (`ShieldMode.plan_tables`). The
group's class is the mode's id in the kernels: `register` binds it to
two compiled functions, and numba compiles the cycles once per class
(the overloads below choose them while typing, so no branch of another
mode is typed):

* `failsafe_target(parameters, plan, inverse, s)`: the failsafe's final
  path velocity when the intended step ends at plan time s on `plan` (a
  `Plan`; inverse = 1 / cycle time); 0 brakes to rest.
* `verdict(parameters, slices)`: (safe, first unsafe slice) of the exact
  check of a cycle's `Slices` (robot and human reach capsules, the
  monitored path), run when no broad phase settled the cycle.

Each is the compiled twin of the mode's readable method of the same name
(`modes.ShieldMode.failsafe_target`, `verdict`), in its operations and
order, so the compiled cycles give the readable shield's bits
(tests/safety/test_step_many.py). SSM (`SsmParameters`), the speed
limit of PFL and its variants (`SpeedLimitParameters`) and energy PFL
(`EnergyParameters`) are registered here; docs/extending.md, "A compiled verification", adds one.
"""

import math
from typing import NamedTuple

import numba
import numpy as np
from numba import extending

from hrc_suite.safety import kernels
from hrc_suite.safety.shield import energy_check_kernels as eck
from hrc_suite.safety.shield import path_kernels as pk

_jit = kernels._jit
_inline = kernels._inline


class Plan(NamedTuple):
  """A plan for the compiled cycles (LongTermPlan)."""
  samples: np.ndarray   # (N, 4, dof) q, dq, ddq, dddq; writeable.
  start: float          # Plan time (s) of sample 0.
  filled: int           # Samples [0, filled) are computed.
  tables: tuple         # The mode's tables of this plan (plan_tables).


class Slices(NamedTuple):
  """A cycle's check for a mode's `verdict`: K slices (the current step,
  then the failsafe's), their K + 1 edges and the monitored path."""
  robot_c1: np.ndarray    # (K, L, 3) robot reach capsules ...
  robot_c2: np.ndarray    # (K, L, 3)
  robot_r: np.ndarray     # (K, L)
  human_c1: np.ndarray    # (M, K, B, 3) human reach capsules ...
  human_c2: np.ndarray    # (M, K, B, 3)
  human_r: np.ndarray     # (M, K, B)
  s_edges: np.ndarray     # (K + 1,) plan times of the edges.
  t_edges: np.ndarray     # (K + 1,) s after the cycle's time.
  q_edges: np.ndarray     # (K + 1, dof) joint positions at the edges.
  current: np.ndarray     # Path array (path_kernels) at the cycle's start.
  failsafe: np.ndarray    # Path array of the failsafe.
  pieces: np.ndarray      # (MAX_PIECES, 5) its segments ...
  num_pieces: int         # ... of which this many are used.
  interval: float         # s, the failsafe's slices' length.
  plan: Plan
  inverse: float          # 1 / cycle time.


class SsmParameters(NamedTuple):
  """SSM: no contact while moving; no parameters."""


class SpeedLimitParameters(NamedTuple):
  """PFL (docs/shield_maths.md, 9.3): the surface speed limit where
  contact is possible."""
  allowed: float           # m/s (ShieldMode.speed_limit).
  s_dot_tolerance: float   # Relative (modes.S_DOT_TOLERANCE).


class EnergyParameters(NamedTuple):
  """Energy PFL (docs/shield_maths.md, 9.4; energy_verification): per
  human body the allowed energies and thickness, the energy allowed
  after the failsafe, what a body can be clamped against, and each robot
  capsule's link."""
  transient: np.ndarray     # (B,) J, margin x E_T.
  clamped: np.ndarray       # (B,) J, margin x E_QS.
  thickness: np.ndarray     # (B,) m.
  coasting: float           # J (EnergyLimits.coasting).
  box_min: np.ndarray       # (X, 3) m, static boxes ...
  box_max: np.ndarray       # (X, 3)
  clampable: np.ndarray     # (L, L) bool, capsule pairs that can clamp.
  frame_index: np.ndarray   # (L,) int64, each robot capsule's link.


class NoTables(NamedTuple):
  """No tables of a plan (SSM)."""


class SpeedTables(NamedTuple):
  """PFL tables of a plan (Shield.plan_speeds): the largest capsule
  surface speed at nominal path speed over the next samples, and from
  each sample to the end (both (N,), m/s)."""
  window: np.ndarray
  suffix: np.ndarray


class EnergyTables(NamedTuple):
  """Energy PFL tables of a plan (Shield.plan_energies): per link the
  largest contact energy bound at nominal path speed over the next
  samples (N, dof), and of any link from each sample to the end (N,),
  J."""
  window: np.ndarray
  suffix: np.ndarray


# Parameter group class -> (failsafe_target, verdict), compiled functions.
_VERIFICATIONS = {}


def register(parameters_class, failsafe_target_fn, verdict_fn):
  """Binds a mode's parameter group class (a typing.NamedTuple subclass)
  to its compiled `failsafe_target` and `verdict` (numba-jitted
  functions with the signatures of the module docstring)."""
  if not (isinstance(parameters_class, type)
          and issubclass(parameters_class, tuple)
          and hasattr(parameters_class, '_fields')):
    raise TypeError(f'mode_kernels.register: expected a NamedTuple class, '
                    f'got {parameters_class!r}')
  for name, fn in (('failsafe_target', failsafe_target_fn),
                   ('verdict', verdict_fn)):
    if not isinstance(fn, numba.core.dispatcher.Dispatcher):
      raise TypeError(f'mode_kernels.register: {name} of '
                      f'{parameters_class.__name__}: expected a numba-'
                      f'jitted function, got {fn!r}')
  if parameters_class in _VERIFICATIONS:
    raise ValueError(f'{parameters_class.__name__} already has a compiled '
                     'verification')
  _VERIFICATIONS[parameters_class] = (failsafe_target_fn, verdict_fn)


def _registered(parameters, which):
  kind = getattr(parameters, 'instance_class', None)
  if kind not in _VERIFICATIONS:
    raise numba.core.errors.TypingError(
        f'no compiled verification for mode parameters {parameters}; '
        f'expected one of {[c.__name__ for c in _VERIFICATIONS]} '
        '(mode_kernels.register)')
  return _VERIFICATIONS[kind][which]


def failsafe_target(parameters, plan, inverse, s):
  """The mode's failsafe target (compiled code only; see the module)."""
  raise NotImplementedError('compiled code only')


def verdict(parameters, slices):
  """The mode's exact verdict (compiled code only; see the module)."""
  raise NotImplementedError('compiled code only')


@extending.overload(failsafe_target)
def _failsafe_target(parameters, plan, inverse, s):
  target = _registered(parameters, 0)

  def impl(parameters, plan, inverse, s):
    return target(parameters, plan, inverse, s)
  return impl


@extending.overload(verdict)
def _verdict(parameters, slices):
  check = _registered(parameters, 1)

  def impl(parameters, slices):
    return check(parameters, slices)
  return impl


@_jit
def sample_index(s, start, inverse, last):
  """LongTermPlan.sample_index."""
  k = int(math.floor((s - start) * inverse))
  return 0 if k < 0 else (last if k > last else k)


@_inline
def slice_s_dot(slices, i):
  """The largest path velocity over slice i of a cycle: the current
  step's for slice 0, the failsafe's piecewise path over its slice for
  the others (the last ends where the failsafe does)."""
  if i == 0:
    return max(slices.current[1], slices.failsafe[1])
  count = slices.s_edges.shape[0] - 2
  before = i * slices.interval if i < count else slices.failsafe[6]
  return pk.max_s_dot(slices.pieces, slices.num_pieces,
                      (i - 1) * slices.interval, before)


@_inline
def edge_sample(slices, i):
  """The plan's sample index of slice edge i (sample_index)."""
  plan = slices.plan
  return sample_index(slices.s_edges[i], plan.start, slices.inverse,
                      plan.samples.shape[0] - 1)


@_jit
def ssm_first_unsafe(slices):
  """The first slice where every human model meets a robot capsule, or
  -1 (kernels.ssm_first_unsafe)."""
  return kernels.ssm_first_unsafe(slices.robot_c1, slices.robot_c2,
                                  slices.robot_r, slices.human_c1,
                                  slices.human_c2, slices.human_r)


# ------------------------------------------------------------------- SSM


@_jit
def _ssm_failsafe_target(parameters, plan, inverse, s):
  """SSM: brake to rest."""
  return 0.0


@_jit
def _ssm_verdict(parameters, slices):
  """SSM (docs/shield_maths.md, 9.2): safe iff no slice can meet the
  person."""
  first = ssm_first_unsafe(slices)
  return first < 0, first


register(SsmParameters, _ssm_failsafe_target, _ssm_verdict)


# ------------------------------------------------------------------- PFL


@_jit
def _speed_limit_failsafe_target(parameters, plan, inverse, s):
  """modes.ShieldMode.failsafe_target with a speed limit: the largest
  path velocity at which the rest of the plan stays under it (1 at
  most)."""
  remaining = plan.tables.suffix[sample_index(
      s, plan.start, inverse, plan.samples.shape[0] - 1)]
  allowed = parameters.allowed
  return 1.0 if remaining <= allowed else allowed / remaining


@_jit
def _speed_limit_verdict(parameters, slices):
  """modes.ShieldMode.verdict with a speed limit: SSM-safe, or from the
  first slice where contact is possible on (and after the failsafe) the
  robot's surface speed stays under the limit."""
  first = ssm_first_unsafe(slices)
  if first < 0:
    return True, first
  window, suffix = slices.plan.tables.window, slices.plan.tables.suffix
  count = slices.s_edges.shape[0] - 2
  allowed = parameters.allowed * (1.0 + parameters.s_dot_tolerance)
  for i in range(first, count + 1):
    if window[edge_sample(slices, i)] * slice_s_dot(slices, i) > allowed:
      return False, first
  return (suffix[edge_sample(slices, count + 1)]
          * pk.final_s_dot(slices.failsafe) <= allowed), first


register(SpeedLimitParameters, _speed_limit_failsafe_target,
         _speed_limit_verdict)


# ------------------------------------------------------------ energy PFL


@_jit
def _energy_failsafe_target(parameters, plan, inverse, s):
  """modes.PflEnergy.failsafe_target: the largest path velocity (1 at
  most) at which the rest of the plan stays within the coasting energy
  (energy_verification.coasting_speed)."""
  remaining = plan.tables.suffix[sample_index(
      s, plan.start, inverse, plan.samples.shape[0] - 1)]
  if remaining <= parameters.coasting:
    return 1.0
  return math.sqrt(parameters.coasting / remaining)


@_jit
def _energy_verdict(parameters, slices):
  """modes.PflEnergy.verdict: SSM-safe, or from the first slice where
  contact is possible on every possible contact within its body's
  energy limit (energy_check_kernels) and the coasting after the
  failsafe within the coasting energy."""
  first = ssm_first_unsafe(slices)
  if first < 0:
    return True, first
  window, suffix = slices.plan.tables.window, slices.plan.tables.suffix
  count = slices.s_edges.shape[0] - 2
  links = parameters.frame_index
  energies = np.zeros((count + 1, links.shape[0]))
  for i in range(first, count + 1):
    s_dot = slice_s_dot(slices, i)
    row = edge_sample(slices, i)
    squared = s_dot * s_dot
    for l in range(links.shape[0]):
      energies[i, l] = squared * window[row, links[l]]
  unsafe = eck.first_unsafe(
      eck.Capsules(slices.robot_c1, slices.robot_c2, slices.robot_r),
      eck.Capsules(slices.human_c1, slices.human_c2, slices.human_r),
      energies,
      eck.BodyLimits(parameters.transient, parameters.clamped,
                     parameters.thickness),
      eck.ClampBoxes(parameters.box_min, parameters.box_max,
                     parameters.clampable), first)
  if unsafe >= 0:
    return False, first
  final = pk.final_s_dot(slices.failsafe)
  remaining = suffix[edge_sample(slices, count + 1)]
  return (final * final * remaining
          <= parameters.coasting * (1.0 + eck._RATIO_TOLERANCE)), first


register(EnergyParameters, _energy_failsafe_target, _energy_verdict)
