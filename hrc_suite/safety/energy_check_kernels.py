"""Compiled (numba) energy-based PFL check of a monitored path.

`energy_ratios` computes energy_verification.energy_ratios (its NumPy
reference, with clamping.contacts_and_clamps) with the same floating-point
operations in the same order, so the ratios are the same bits
(tests/safety/test_energy_verification.py); `energy_first_unsafe` gives
the verdict, stopping at the first unsafe slice and at the first contact
that fails a model. Both skip work that cannot change the result: a pair
whose bounding balls are apart (kernels' broad phase, with its slack), and
the clamping tests of a contact whose clamped ratio could not raise the
model's largest ratio. Same compilation settings as the shield's kernels.
"""

import math

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


@_inline
def _clamped(rc1, rc2, rr, hc1, hc2, hr, thickness, box_min, box_max,
             clampable, m, k, l, b):
  """Whether the contact of robot capsule l and body b (model m, slice k)
  may be clamped (clamping.contacts_and_clamps)."""
  grown = hr[m, k, b] + thickness[b]
  for x in range(box_min.shape[0]):
    if _box_gap(hc1, hc2, m, k, b, box_min, box_max, x) - grown < 0.0:
      return True
  for other in range(rr.shape[1]):
    if clampable[l, other]:
      if (_distance(rc1, rc2, k, other, hc1, hc2, m, b) - rr[k, other]
          - grown < 0.0):
        return True
  return False


@_inline
def _model_ratio(rc1, rc2, rr, hc1, hc2, hr, energies, transient, clamped,
                 thickness, box_min, box_max, clampable, r_mid, r_reach,
                 h_mid, h_reach, m, k, stop):
  """Model m's largest ratio in slice k; returns as soon as it exceeds
  `stop` (np.inf: never)."""
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
          rc1, rc2, rr, hc1, hc2, hr, thickness, box_min, box_max,
          clampable, m, k, l, b):
        best = energies[k, l] / clamped[b]
      if best > stop:
        return best
  return best


@_jit
def energy_ratios(rc1, rc2, rr, hc1, hc2, hr, energies, transient, clamped,
                  thickness, box_min, box_max, clampable):
  """(M, K): energy_verification.energy_ratios. Robot reach capsules rc1,
  rc2 (K, L, 3), rr (K, L); body capsules hc1, hc2 (M, K, B, 3), hr (M, K,
  B); energies (K, L), J; allowed transient and clamped energies (B,), J;
  body thickness (B,), m; static boxes (X, 3) twice; clampable (L, L)."""
  count_m, count_k = hr.shape[0], hr.shape[1]
  r_mid, r_reach = kernels._bounding_balls(rc1, rc2, rr)
  h_mid, h_reach = kernels._bounding_balls(hc1, hc2, hr)
  out = np.empty((count_m, count_k))
  for m in range(count_m):
    for k in range(count_k):
      out[m, k] = _model_ratio(rc1, rc2, rr, hc1, hc2, hr, energies,
                               transient, clamped, thickness, box_min,
                               box_max, clampable, r_mid, r_reach, h_mid,
                               h_reach, m, k, np.inf)
  return out


@_jit
def energy_first_unsafe(rc1, rc2, rr, hc1, hc2, hr, energies, transient,
                        clamped, thickness, box_min, box_max, clampable):
  """energy_verification.first_unsafe(energy_ratios(...)): the first slice
  in which every model's ratio exceeds 1 + the tolerance, or -1."""
  count_m, count_k = hr.shape[0], hr.shape[1]
  r_mid, r_reach = kernels._bounding_balls(rc1, rc2, rr)
  h_mid, h_reach = kernels._bounding_balls(hc1, hc2, hr)
  limit = 1.0 + _RATIO_TOLERANCE
  for k in range(count_k):
    passed = False
    for m in range(count_m):
      if _model_ratio(rc1, rc2, rr, hc1, hc2, hr, energies, transient,
                      clamped, thickness, box_min, box_max, clampable,
                      r_mid, r_reach, h_mid, h_reach, m, k,
                      limit) <= limit:
        passed = True
        break
    if not passed:
      return k
  return -1


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
  energy_first_unsafe(*robot, *human, *rest)
  _warm = True
