"""The task's self-collision check of the robot's final configuration.

A configuration self-collides when two capsules of collision prevention's
checked pairs overlap (`CollisionPrevention.pairs`, the robot capsule
model; metrics.COUNTERS, self_collisions). compiled=True (the task's fast
path) runs collision prevention's compiled capsule test
(`collision_kernels.colliding`, pairs only, no boxes, no margins), else the
NumPy reference below. The kernel's forward kinematics and segment distances
agree with the reference to round-off, so the two decide alike except
for capsules within ~1e-15 m of touching (tests/tasks/
test_self_collision.py; tests/tasks/test_fast_path.py compares the
counter on every task).
"""

import numpy as np

from hrc_suite.safety import geometry
from hrc_suite.safety.collision_prevention import kernels as collision_kernels


class SelfCollision:
  """Whether a configuration of `checker`'s robot self-collides."""

  def __init__(self, checker, compiled=True):
    self._checker = checker
    self._compiled = bool(compiled)
    num_capsules = checker.num_capsules
    # collision_kernels.colliding's arguments for "pairs only": no boxes,
    # zero margins, no masks.
    self._margins = (np.zeros((1, num_capsules)),
                     np.zeros((1, len(checker.pairs))))
    self._no_boxes = (np.zeros((0, 3)), np.zeros((0, 3)),
                      np.zeros((0, num_capsules), dtype=bool),
                      np.zeros((0, num_capsules)))
    self._no_masks = (np.zeros((0, 0, 0), dtype=bool),
                      np.zeros((0, 0), dtype=bool))
    self._q = np.zeros((1, checker.dof))
    self._pairs = np.ascontiguousarray(checker.pairs, dtype=np.int64)

  def __call__(self, q):
    """True if configuration q (dof,) self-collides."""
    checker = self._checker
    if not len(checker.pairs):
      return False
    if not self._compiled:
      return self.reference(q)
    self._q[0] = q
    reach = checker.reach
    return bool(collision_kernels.colliding(
        self._q, *reach.kernel_model, reach.kernel_frames,
        reach.kernel_radii, *self._margins, *self._no_boxes,
        self._pairs, *self._no_masks)[0])

  def reference(self, q):
    """The NumPy reference: signed capsule distances of the pairs."""
    checker = self._checker
    p1, p2, r = checker.reach.capsules(np.asarray(q, dtype=float)[None])
    i, j = checker.pairs[:, 0], checker.pairs[:, 1]
    distance = geometry.capsule_distance(p1[0, i], p2[0, i], r[i],
                                         p1[0, j], p2[0, j], r[j])
    return bool(np.any(distance < 0.0))
