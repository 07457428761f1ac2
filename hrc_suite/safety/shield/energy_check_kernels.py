"""Compiled (numba) energy-based PFL check of a monitored path.

`energy_ratios` computes energy_verification.energy_ratios (its NumPy
reference, with clamping.contacts_and_clamps) with the same floating-point
operations in the same order, so the ratios are the same bits
(tests/safety/test_energy_verification.py); `energy_first_unsafe` gives
the verdict of those ratios, stopping at the first unsafe slice and at the
first contact that fails a model. Both skip work that cannot change their
result: `energy_ratios` a pair whose bounding balls are apart (kernels'
broad phase, with its slack) and the clamping tests of a contact whose
clamped ratio could not raise the model's largest ratio;
`energy_first_unsafe` every contact whose ratios are both within the
limit, before any geometry (`_model_exceeds`). Same compilation settings
as the shield's kernels.
"""

import math
from typing import NamedTuple

import numpy as np

from hrc_suite.safety import kernels

_jit = kernels._jit
_inline = kernels._inline

# Subtracted from the bounding balls' distance bound (m), as the SSM
# kernels' broad phase: a pair is skipped only where it surely does not
# intersect.
_BOUND_SLACK = 1e-9
# energy_verification.RATIO_TOLERANCE (a literal for the compiler).
_RATIO_TOLERANCE = 1e-9


@_inline
def _distance(rc1, rc2, k, l, hc1, hc2, m, b):
  """Segment distance of robot capsule (k, l) and body (m, k, b)."""
  return kernels.segment_distance(
      rc1[k, l, 0], rc1[k, l, 1], rc1[k, l, 2],
      hc1[m, k, b, 0], hc1[m, k, b, 1], hc1[m, k, b, 2],
      rc2[k, l, 0] - rc1[k, l, 0], rc2[k, l, 1] - rc1[k, l, 1],
      rc2[k, l, 2] - rc1[k, l, 2],
      hc2[m, k, b, 0] - hc1[m, k, b, 0], hc2[m, k, b, 1] - hc1[m, k, b, 1],
      hc2[m, k, b, 2] - hc1[m, k, b, 2])


@_inline
def _box_gap(hc1, hc2, m, k, b, box_min, box_max, x):
  """clamping.box_gap of body (m, k, b)'s segment and box x."""
  total = 0.0
  for i in range(3):
    low = min(hc1[m, k, b, i], hc2[m, k, b, i])
    high = max(hc1[m, k, b, i], hc2[m, k, b, i])
    gap = max(max(box_min[x, i] - high, low - box_max[x, i]), 0.0)
    total += gap * gap
  return math.sqrt(total)


class Capsules(NamedTuple):
  """Reach capsules: robot (K, L, 3), (K, L, 3), (K, L) or human
  (M, K, B, 3), (M, K, B, 3), (M, K, B)."""
  c1: np.ndarray
  c2: np.ndarray
  r: np.ndarray


class BodyLimits(NamedTuple):
  """Per human body (B,): allowed transient and clamped energies (J) and
  thickness (m) (energy_verification.EnergyLimits)."""
  transient: np.ndarray
  clamped: np.ndarray
  thickness: np.ndarray


class ClampBoxes(NamedTuple):
  """What a body can be clamped against (clamping.ClampGeometry): static
  boxes (X, 3) twice and clampable robot capsule pairs (L, L)."""
  box_min: np.ndarray
  box_max: np.ndarray
  clampable: np.ndarray


class Balls(NamedTuple):
  """The capsules' bounding balls (kernels._bounding_balls): robot
  centres (K L, 3) and radii (K L,), human (M K B, 3) and (M K B,)."""
  robot_mid: np.ndarray
  robot_reach: np.ndarray
  human_mid: np.ndarray
  human_reach: np.ndarray


@_inline
def _clamped(robot, human, limits, clamp, m, k, l, b):
  """Whether the contact of robot capsule l and body b (model m, slice k)
  may be clamped (clamping.contacts_and_clamps)."""
  rc1, rc2, rr = robot
  hc1, hc2, hr = human
  box_min, box_max = clamp.box_min, clamp.box_max
  grown = hr[m, k, b] + limits.thickness[b]
  for x in range(box_min.shape[0]):
    if _box_gap(hc1, hc2, m, k, b, box_min, box_max, x) - grown < 0.0:
      return True
  for other in range(rr.shape[1]):
    if clamp.clampable[l, other]:
      if (_distance(rc1, rc2, k, other, hc1, hc2, m, b) - rr[k, other]
          - grown < 0.0):
        return True
  return False


@_inline
def _model_ratio(robot, human, energies, limits, clamp, balls, m, k):
  """Model m's largest ratio in slice k."""
  rc1, rc2, rr = robot
  hc1, hc2, hr = human
  r_mid, r_reach = balls.robot_mid, balls.robot_reach
  h_mid, h_reach = balls.human_mid, balls.human_reach
  transient, clamped = limits.transient, limits.clamped
  count_l = rr.shape[1]
  count_k, count_b = hr.shape[1], hr.shape[2]
  best = 0.0
  for l in range(count_l):
    for b in range(count_b):
      # kernels' broad phase: the bounding balls' distance bound.
      i, j = k * count_l + l, (m * count_k + k) * count_b + b
      g0 = r_mid[i, 0] - h_mid[j, 0]
      g1 = r_mid[i, 1] - h_mid[j, 1]
      g2 = r_mid[i, 2] - h_mid[j, 2]
      if (math.sqrt(g0 * g0 + g1 * g1 + g2 * g2) - r_reach[i] - h_reach[j]
          - _BOUND_SLACK >= 0.0):
        continue
      if (_distance(rc1, rc2, k, l, hc1, hc2, m, b) - rr[k, l]
          - hr[m, k, b] >= 0.0):
        continue
      ratio = energies[k, l] / transient[b]
      if ratio > best:
        best = ratio
      if energies[k, l] / clamped[b] > best and _clamped(
          robot, human, limits, clamp, m, k, l, b):
        best = energies[k, l] / clamped[b]
  return best


@_inline
def _model_exceeds(robot, human, energies, limits, clamp, m, k, limit):
  """Whether model m's largest ratio in slice k exceeds `limit` (as
  `_model_ratio(...) > limit`): whether a possible contact's energy over
  its allowed energy does. A contact whose energy over its clamped limit,
  the larger of its two ratios, is within `limit` cannot, so only the
  others are tested; a robot capsule whose energy over the smallest
  clamped limit is within has none (a correctly rounded division by a
  larger positive number is not larger)."""
  rc1, rc2, rr = robot
  hc1, hc2, hr = human
  transient, clamped = limits.transient, limits.clamped
  count_b = hr.shape[2]
  if count_b == 0:
    return False
  smallest = clamped.min()
  for l in range(rr.shape[1]):
    energy = energies[k, l]
    if energy / smallest <= limit:
      continue
    for b in range(count_b):
      if energy / clamped[b] <= limit:
        continue
      if (_distance(rc1, rc2, k, l, hc1, hc2, m, b) - rr[k, l]
          - hr[m, k, b] >= 0.0):
        continue
      if energy / transient[b] > limit:
        return True
      if _clamped(robot, human, limits, clamp, m, k, l, b):
        return True
  return False


@_inline
def _balls(robot, human):
  """The `Balls` of robot and human `Capsules`."""
  r_mid, r_reach = kernels._bounding_balls(robot.c1, robot.c2, robot.r)
  h_mid, h_reach = kernels._bounding_balls(human.c1, human.c2, human.r)
  return Balls(r_mid, r_reach, h_mid, h_reach)


@_jit
def energy_ratios(rc1, rc2, rr, hc1, hc2, hr, energies, transient, clamped,
                  thickness, box_min, box_max, clampable):
  """(M, K): energy_verification.energy_ratios. Robot reach capsules rc1,
  rc2 (K, L, 3), rr (K, L); body capsules hc1, hc2 (M, K, B, 3), hr (M, K,
  B); energies (K, L), J; allowed transient and clamped energies (B,), J;
  body thickness (B,), m; static boxes (X, 3) twice; clampable (L, L)."""
  robot, human = Capsules(rc1, rc2, rr), Capsules(hc1, hc2, hr)
  limits = BodyLimits(transient, clamped, thickness)
  clamp = ClampBoxes(box_min, box_max, clampable)
  balls = _balls(robot, human)
  count_m, count_k = hr.shape[0], hr.shape[1]
  out = np.empty((count_m, count_k))
  for m in range(count_m):
    for k in range(count_k):
      out[m, k] = _model_ratio(robot, human, energies, limits, clamp, balls,
                               m, k)
  return out


@_jit
def first_unsafe(robot, human, energies, limits, clamp, start):
  """energy_verification.first_unsafe(energy_ratios(...)) from slice
  `start` on: the first slice k >= start in which every model's ratio
  exceeds 1 + the tolerance, or -1 (robot and human `Capsules`, energies
  (K, L), `BodyLimits`, `ClampBoxes`; rows of energies before start are
  not read)."""
  count_m, count_k = human.r.shape[0], human.r.shape[1]
  limit = 1.0 + _RATIO_TOLERANCE
  for k in range(start, count_k):
    passed = False
    for m in range(count_m):
      if not _model_exceeds(robot, human, energies, limits, clamp, m, k,
                            limit):
        passed = True
        break
    if not passed:
      return k
  return -1


@_jit
def energy_first_unsafe(rc1, rc2, rr, hc1, hc2, hr, energies, transient,
                        clamped, thickness, box_min, box_max, clampable,
                        start):
  """`first_unsafe` on the arrays of energy_ratios' arguments."""
  return first_unsafe(Capsules(rc1, rc2, rr), Capsules(hc1, hc2, hr),
                      energies, BodyLimits(transient, clamped, thickness),
                      ClampBoxes(box_min, box_max, clampable), start)


_warm = False


def warm_up():
  """Compiles (or loads from the cache) the kernels once per process."""
  global _warm
  if _warm:
    return
  count_k, count_l, count_b = 1, 2, 2
  robot = (np.zeros((count_k, count_l, 3)), np.zeros((count_k, count_l, 3)),
           np.ones((count_k, count_l)))
  human = (np.zeros((1, count_k, count_b, 3)),
           np.zeros((1, count_k, count_b, 3)),
           np.ones((1, count_k, count_b)))
  rest = (np.zeros((count_k, count_l)), np.ones(count_b), np.ones(count_b),
          np.ones(count_b), np.zeros((1, 3)), np.zeros((1, 3)),
          np.zeros((count_l, count_l), dtype=np.bool_))
  energy_ratios(*robot, *human, *rest)
  energy_first_unsafe(*robot, *human, *rest, 0)
  _warm = True
