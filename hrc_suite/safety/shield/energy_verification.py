"""Energy-based PFL verification of a monitored path (NumPy reference).

docs/shield_maths.md, 9.4. Per time slice k the robot's largest contact
energy at each of its capsules is s_dot_k^2 times the plan's energy table
at the capsule's link (arm_energy.ArmEnergyModel.plan_tables), s_dot_k the
slice's largest path velocity. For one human model, a slice is safe iff
every possible contact (a robot capsule l and a body capsule b whose reach
capsules intersect) has

  energy_kl  <=  margin * limit_b,

limit_b the body's clamped limit E_QS if the contact may be clamped
(clamping.py), else its transient limit E_T (body_regions.py). As in SSM
(9.2) every human model over-approximates the person, so the slice is safe
iff some model passes. `energy_ratios` gives each model's largest
energy / (margin limit) per slice (0 without contacts): safe iff at most
1 + RATIO_TOLERANCE.

After the failsafe the robot coasts at s_dot_lim along the rest of the
plan, unverified: the person may be anywhere and clamped against
anything, so s_dot_lim^2 times the plan's largest remaining energy stays
within margin times the smallest clamped limit of any body
(`coasting_speed`).

`energy_check_kernels` computes the same with the same floating-point
operations (tests/safety/test_energy_verification.py).
"""

import dataclasses
from typing import Optional

import numpy as np

from hrc_suite.safety import body_regions
from hrc_suite.safety import clamping
from hrc_suite.safety.shield import energy_check_kernels

# Energies are compared with this fraction of the regions' limits: PFL's
# speed margin (modes.PFL_SPEED_MARGIN, 0.9) squared, a design margin of
# this port for what the model leaves out (the controller's velocity
# tracking error, the gripper fingers' own motion); the plan's change
# between samples is bounded exactly instead (docs/shield_maths.md, 9.4).
ENERGY_MARGIN = 0.81
# Relative round-off allowed in the comparisons (the failsafe is planned to
# end exactly at s_dot_lim; the shield's _S_DOT_TOLERANCE).
RATIO_TOLERANCE = 1e-9


@dataclasses.dataclass(frozen=True)
class EnergyLimits:
  """What the check compares energies with, per human body capsule.

  Attributes:
    bodies: (B,) the body capsules' names (the human model's order).
    transient: (B,) J, margin times each body's transient limit E_T.
    clamped: (B,) J, margin times each body's clamped limit E_QS.
    thickness: (B,) m, each body's thickness (diameter).
    coasting: J, margin times the smallest clamped limit of any body: the
      energy allowed after the failsafe.
    margin: the fraction of the limits used.
  """
  bodies: tuple
  transient: np.ndarray
  clamped: np.ndarray
  thickness: np.ndarray
  coasting: float
  margin: float


def energy_limits(human_config, table: Optional[body_regions.RegionTable]
                  = None, margin: float = ENERGY_MARGIN) -> EnergyLimits:
  """The EnergyLimits of a human model.

  Args:
    human_config: human_reach.HumanModelConfig (its bodies, in order).
    table: the body-region table (default: body_regions.load()).
    margin: the fraction of the limits used, in (0, 1].

  Returns:
    The EnergyLimits.
  """
  if not 0.0 < margin <= 1.0:
    raise ValueError(f'margin={margin!r}: expected a fraction in (0, 1]')
  names = tuple(body.name for body in human_config.bodies)
  table = table or body_regions.load(body_names=names)
  limits = [table.limits(name) for name in names]
  clamped = margin * np.array([x.energy_clamped for x in limits])
  return EnergyLimits(
      bodies=names,
      transient=margin * np.array([x.energy_transient for x in limits]),
      clamped=clamped,
      thickness=np.array([body.thickness for body in human_config.bodies]),
      coasting=float(clamped.min()), margin=float(margin))


def slice_energies(s_dot_max, window_rows, frame_index) -> np.ndarray:
  """(K, L) J: each robot capsule's largest contact energy per slice,
  (s_dot_k * s_dot_k) * window_rows[k, frame_index[l]].

  Args:
    s_dot_max: (K,) each slice's largest path velocity.
    window_rows: (K, dof) the plan's energy window table at each slice's
      first sample (ArmEnergyModel.plan_tables).
    frame_index: (L,) each robot capsule's link.
  """
  s_dot_max = np.asarray(s_dot_max, dtype=float)
  window_rows = np.asarray(window_rows, dtype=float)
  if s_dot_max.ndim != 1 or window_rows.shape[0] != s_dot_max.shape[0]:
    raise ValueError(f's_dot_max (K,) and window_rows (K, dof): got '
                     f'{s_dot_max.shape} and {window_rows.shape}')
  squared = s_dot_max * s_dot_max
  return np.ascontiguousarray(
      squared[:, None] * window_rows[:, np.asarray(frame_index, dtype=int)])


def _arguments(robot, human, energies, limits, geometry):
  """The compiled kernels' arguments (C-contiguous float64, bool)."""
  rc1, rc2, rr = (np.ascontiguousarray(x, dtype=float) for x in robot)
  hc1, hc2, hr = (np.ascontiguousarray(x, dtype=float) for x in human)
  count_k, count_l = rr.shape
  if (rc1.shape != (count_k, count_l, 3) or rc2.shape != rc1.shape
      or hc1.ndim != 4 or hc1.shape[1] != count_k or hc2.shape != hc1.shape
      or hr.shape != hc1.shape[:3]):
    raise ValueError(f'robot capsules (K, L, 3), (K, L, 3), (K, L) and '
                     f'human capsules (M, K, B, 3), (M, K, B, 3), (M, K, B):'
                     f' got {rc1.shape}, {rc2.shape}, {rr.shape} and '
                     f'{hc1.shape}, {hc2.shape}, {hr.shape}')
  energies = np.ascontiguousarray(energies, dtype=float)
  if energies.shape != (count_k, count_l):
    raise ValueError(f'energies: expected ({count_k}, {count_l}) (slices, '
                     f'robot capsules), got {energies.shape}')
  count_b = hr.shape[2]
  if limits.transient.shape != (count_b,):
    raise ValueError(f'limits for {limits.transient.shape[0]} bodies, the '
                     f'human capsules have {count_b}')
  if geometry.clampable.shape != (count_l, count_l):
    raise ValueError(f'geometry.clampable: expected ({count_l}, {count_l})'
                     f' for {count_l} robot capsules, got '
                     f'{geometry.clampable.shape}')
  if not (limits.clamped <= limits.transient).all():
    # The compiled check skips clamping tests on this order.
    raise ValueError(f'limits: clamped {limits.clamped.tolist()} must not '
                     f'exceed transient {limits.transient.tolist()}')
  return (rc1, rc2, rr, hc1, hc2, hr, energies,
          np.ascontiguousarray(limits.transient, dtype=float),
          np.ascontiguousarray(limits.clamped, dtype=float),
          np.ascontiguousarray(limits.thickness, dtype=float),
          np.ascontiguousarray(geometry.box_min, dtype=float).reshape(-1, 3),
          np.ascontiguousarray(geometry.box_max, dtype=float).reshape(-1, 3),
          np.ascontiguousarray(geometry.clampable, dtype=np.bool_))


def energy_ratios(robot, human, energies, limits: EnergyLimits,
                  geometry: clamping.ClampGeometry,
                  compiled: bool = False) -> np.ndarray:
  """(M, K): per human model and slice the largest energy / allowed of any
  possible contact (0 where there is none).

  Args:
    robot: reach capsules (c1 (K, L, 3), c2, r (K, L)).
    human: body reach capsules (c1 (M, K, B, 3), c2, r (M, K, B)).
    energies: (K, L) J, `slice_energies`.
    limits: the EnergyLimits of the B bodies.
    geometry: the ClampGeometry of the L robot capsules.
    compiled: run energy_check_kernels.energy_ratios (the same bits).
  """
  arguments = _arguments(robot, human, energies, limits, geometry)
  if compiled:
    return energy_check_kernels.energy_ratios(*arguments)
  rc1, rc2, rr, hc1, hc2, hr, energies = arguments[:7]
  contact, clamped = clamping.contacts_and_clamps(
      (rc1, rc2, rr), (hc1, hc2, hr), limits.thickness, geometry)
  allowed = np.where(clamped, limits.clamped, limits.transient)
  ratios = np.where(contact, energies[None, :, :, None] / allowed, 0.0)
  if not ratios.size:
    return np.zeros(contact.shape[:2])
  return ratios.max(axis=(2, 3))


def first_unsafe(ratios) -> int:
  """The first slice in which every human model's ratio exceeds 1 (plus
  RATIO_TOLERANCE), or -1: the verdict of `energy_ratios`' (M, K)."""
  best = np.asarray(ratios, dtype=float).min(axis=0)
  unsafe = best > 1.0 + RATIO_TOLERANCE
  return int(np.argmax(unsafe)) if unsafe.any() else -1


def coasting_speed(remaining: float, limits: EnergyLimits) -> float:
  """s_dot_lim: the path velocity the failsafe ends at, 1 where the plan's
  largest remaining energy `remaining` (J, the suffix table) is within
  limits.coasting, else sqrt(limits.coasting / remaining)."""
  if remaining <= limits.coasting:
    return 1.0
  return float(np.sqrt(limits.coasting / remaining))


def coasting_safe(s_dot: float, remaining: float,
                  limits: EnergyLimits) -> bool:
  """Whether coasting at path velocity s_dot after the failsafe keeps the
  energy within limits.coasting (up to RATIO_TOLERANCE)."""
  return s_dot * s_dot * remaining <= limits.coasting * (1.0
                                                         + RATIO_TOLERANCE)


def first_unsafe_slice(robot, human, energies, limits: EnergyLimits,
                       geometry: clamping.ClampGeometry,
                       compiled: bool = True, start: int = 0) -> int:
  """first_unsafe(energy_ratios(...)) from slice `start` on (the first
  unsafe slice k >= start, or -1; rows of energies before start are not
  read); compiled: the kernel that stops at the first unsafe slice
  (energy_check_kernels.energy_first_unsafe)."""
  arguments = _arguments(robot, human, energies, limits, geometry)
  count_k = arguments[2].shape[0]
  if isinstance(start, bool) or not isinstance(start, (int, np.integer)) \
      or not 0 <= start <= count_k:
    raise ValueError(f'start={start!r}: expected a slice index in [0, '
                     f'{count_k}]')
  if compiled:
    return int(energy_check_kernels.energy_first_unsafe(*arguments,
                                                        int(start)))
  ratios = energy_ratios(robot, human, energies, limits, geometry)
  first = first_unsafe(ratios[:, start:])
  return first if first < 0 else first + int(start)


def verify(robot, human, energies, limits: EnergyLimits,
           geometry: clamping.ClampGeometry, final_s_dot: float,
           remaining: float, compiled: bool = True, start: int = 0) -> int:
  """The verdict of a monitored path: the first unsafe slice (from slice
  `start` on), K (the number of slices) if only the coasting after the
  failsafe is unsafe, or -1 (safe).

  Args:
    robot, human, energies, limits, geometry: as `energy_ratios`.
    final_s_dot: the failsafe's final path velocity.
    remaining: J, the plan's largest energy from the failsafe's end on
      (the suffix table).
    compiled: as first_unsafe_slice.
    start: the first slice checked (the shield: the first where contact
      is possible); rows of energies before it are not read.
  """
  first = first_unsafe_slice(robot, human, energies, limits, geometry,
                             compiled, start)
  if first >= 0:
    return first
  if not coasting_safe(final_s_dot, remaining, limits):
    return int(np.shape(robot[2])[0])
  return -1
