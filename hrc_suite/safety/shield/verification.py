"""Verification helpers: the SSM verdict and the joint-limit check.

SSM (docs/shield_maths.md, 9.2): interval k is safe iff SOME model m has no
intersection between any robot reach capsule and any of its body capsules
(every model over-approximates the human, so one collision-free model
suffices); the motion is safe iff every interval is safe. Intersection is
strict: capsules that touch (signed distance 0) do not intersect.

Broad phase: with midpoints m, half lengths h and radii r, the signed
distance of two capsules lies in [|m_a - m_b| - h_a - h_b - r_a - r_b,
|m_a - m_b| - r_a - r_b]. Per (model, interval) only pairs whose lower bound
does not exceed the best upper bound can hold the minimum; the exact
distance (geometry.capsule_distance) is computed for those alone.

The functions here are the readable NumPy reference; `compiled=True` and
`first_unsafe_interval` run the same maths as compiled kernels
(`kernels.ssm_clearances`, `kernels.ssm_first_unsafe`).
"""

import numpy as np

from hrc_suite.safety import geometry
from hrc_suite.safety import kernels


def _check(robot, human):
  rc1, rc2, rr = (np.asarray(x, dtype=float) for x in robot)
  hc1, hc2, hr = (np.asarray(x, dtype=float) for x in human)
  if rc1.ndim != 3 or rc2.shape != rc1.shape or rr.shape != rc1.shape[:2]:
    raise ValueError(f'robot capsules: expected c1, c2 (K, L, 3) and r (K, L),'
                     f' got {rc1.shape}, {rc2.shape}, {rr.shape}')
  if (hc1.ndim != 4 or hc2.shape != hc1.shape or
      hr.shape != hc1.shape[:3] or hc1.shape[1] != rc1.shape[0]):
    raise ValueError(f'human capsules: expected c1, c2 (M, K, B, 3) and r '
                     f'(M, K, B) with K = {rc1.shape[0]}, got {hc1.shape}, '
                     f'{hc2.shape}, {hr.shape}')
  return rc1, rc2, rr, hc1, hc2, hr


def _dot3(x, y):
  """Dot product over the leading (coordinate) axis."""
  return x[0] * y[0] + x[1] * y[1] + x[2] * y[2]


class _Capsules:
  """Robot and human capsules, coordinates first (structure of arrays: the
  pairwise arithmetic then runs over long contiguous rows)."""

  def __init__(self, rc1, rc2, rr, hc1, hc2, hr):
    self.shape = (hc1.shape[0], rc1.shape[0], rc1.shape[1], hc1.shape[2])
    self.r_start = np.ascontiguousarray(np.moveaxis(rc1, -1, 0))  # (3, K, L)
    self.r_dir = np.ascontiguousarray(np.moveaxis(rc2 - rc1, -1, 0))
    self.h_start = np.ascontiguousarray(np.moveaxis(hc1, -1, 0))  # (3,M,K,B)
    self.h_dir = np.ascontiguousarray(np.moveaxis(hc2 - hc1, -1, 0))
    self.r_radius, self.h_radius = rr, hr
    self.r_len_sq = _dot3(self.r_dir, self.r_dir)                   # (K, L)
    self.h_len_sq = _dot3(self.h_dir, self.h_dir)                   # (M, K, B)

  def bounds(self):
    """Upper and lower bounds (M, K, L, B) of the signed distances: the
    midpoint distance minus the radii, and that minus the half lengths."""
    r_mid = self.r_start + 0.5 * self.r_dir
    h_mid = self.h_start + 0.5 * self.h_dir
    gap = r_mid[:, None, :, :, None] - h_mid[:, :, :, None, :]
    gap *= gap
    upper = gap[0]
    upper += gap[1]
    upper += gap[2]
    np.sqrt(upper, out=upper)
    upper -= self.r_radius[None, :, :, None]
    upper -= self.h_radius[:, :, None, :]
    half = (0.5 * np.sqrt(self.r_len_sq)[None, :, :, None] +
            0.5 * np.sqrt(self.h_len_sq)[:, :, None, :])
    return upper, upper - half

  def exact(self, m, k, l, b):
    """Exact signed distances of the pairs (m, k, l, b) (index arrays)."""
    _, count_k, count_l, count_b = self.shape
    robot = k * count_l + l
    human = (m * count_k + k) * count_b + b
    d1 = self.r_dir.reshape(3, -1)[:, robot]
    d2 = self.h_dir.reshape(3, -1)[:, human]
    r = (self.r_start.reshape(3, -1)[:, robot] -
         self.h_start.reshape(3, -1)[:, human])
    s, t = geometry.closest_parameters(
        self.r_len_sq.ravel()[robot], _dot3(d1, d2), _dot3(d1, r),
        self.h_len_sq.ravel()[human], _dot3(d2, r))
    r += s * d1
    r -= t * d2
    return (np.sqrt(_dot3(r, r)) - self.r_radius.ravel()[robot]
            - self.h_radius.ravel()[human])


def clearances(robot, human):
  """Minimum signed distance (M, K) between the robot's capsules and the
  body capsules of each human model, per interval (exact).

  robot: (c1 (K, L, 3), c2 (K, L, 3), r (K, L)); human: (c1 (M, K, B, 3),
  c2 (M, K, B, 3), r (M, K, B)).
  """
  capsules = _Capsules(*_check(robot, human))
  upper, lower = capsules.bounds()
  best_upper = upper.min(axis=(2, 3))
  # Pairs that may hold the minimum; the pair of the best upper bound does.
  m, k, l, b = np.nonzero(lower <= best_upper[:, :, None, None])
  out = np.full(upper.shape, np.inf)
  out[m, k, l, b] = capsules.exact(m, k, l, b)
  return out.min(axis=(2, 3))


def first_unsafe_interval(robot, human):
  """The verdict alone, compiled: the first interval in which every human
  model meets a robot capsule, or -1 if the motion is safe (equals
  ssm_verdict(robot, human)[1]; stops at the first unsafe interval)."""
  return int(kernels.ssm_first_unsafe(*_contiguous(robot, human)))


def _contiguous(robot, human):
  return tuple(np.ascontiguousarray(x) for x in _check(robot, human))


def ssm_verdict(robot, human, exact_distance=True, compiled=False):
  """(safe, first_unsafe_interval or -1, min_distance).

  robot: (c1 (K, L, 3), c2, r (K, L)); human: (c1 (M, K, B, 3), c2,
  r (M, K, B)). min_distance is the clearance of the best human model in the
  worst interval (min over k of max over m of the minimum signed capsule
  distance); with the combined model it is the plain minimum distance. It is
  negative exactly when the verdict is unsafe.

  exact_distance=False gives the same verdict faster: only pairs whose
  bounds leave the verdict open get exact distances. min_distance is then
  only sign-exact: where a model's interval is clear its clearance is
  replaced by a lower bound (>= 0), where a midpoint upper bound already
  proves an intersection by that (negative) upper bound, and intervals
  decided by bounds alone keep their bounds.

  compiled=True computes the exact distances with the compiled kernel
  (exact_distance is then ignored: the distance is always exact).
  """
  checked = _check(robot, human)
  if compiled:
    per_interval = kernels.ssm_clearances(
        *(np.ascontiguousarray(x) for x in checked)).max(axis=0)
  elif exact_distance:
    per_interval = clearances(robot, human).max(axis=0)     # (K,)
  else:
    capsules = _Capsules(*checked)
    upper, lower = capsules.bounds()
    best_lower = lower.min(axis=(2, 3))
    if best_lower.min() >= 0.0:
      return True, -1, float(best_lower.max(axis=0).min())
    clearance = np.maximum(best_lower, 0.0)
    best_upper = upper.min(axis=(2, 3))
    sure_hit = best_upper < 0
    # Exact distances are needed only where the sign is open, in intervals
    # no model already proves free, before the first interval every model
    # proves unsafe.
    open_mk = ~sure_hit & ~np.any(best_lower >= 0, axis=0)[None]
    all_hit = np.all(sure_hit, axis=0)
    if all_hit.any():
      open_mk[:, int(np.argmax(all_hit)):] = False
    undecided = (lower < 0) & open_mk[:, :, None, None]
    if undecided.any():
      m, k, l, b = np.nonzero(undecided)
      exact = np.full(upper.shape, np.inf)
      exact[m, k, l, b] = capsules.exact(m, k, l, b)
      # Pairs with a non-negative lower bound cannot intersect, so a
      # negative minimum over the undecided pairs is the exact clearance.
      exact = exact.min(axis=(2, 3))
      clearance = np.where(exact < 0, exact, clearance)
    clearance = np.where(sure_hit, best_upper, clearance)
    per_interval = clearance.max(axis=0)
  unsafe = per_interval < 0.0
  first = int(np.argmax(unsafe)) if unsafe.any() else -1
  return first < 0, first, float(per_interval.min())


def within_joint_limits(q, description, tolerance=0.0):
  """True iff every q (..., dof) lies in [q_min - tolerance, q_max +
  tolerance] (a negative tolerance demands a margin inside the limits)."""
  q = np.asarray(q, dtype=float)
  limits = description.limits
  if q.ndim == 0 or q.shape[-1] != description.dof:
    raise ValueError(f'q: expected shape (..., {description.dof}) for '
                     f'{description.name}, got {q.shape}')
  return bool(np.all(q >= limits.q_min - tolerance) and
              np.all(q <= limits.q_max + tolerance))
