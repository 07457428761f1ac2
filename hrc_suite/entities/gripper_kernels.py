"""Compiled (numba) grasp test of the parallel gripper.

`grasped` decides what its NumPy reference (`grasping` in
tests/entities/entity_references.py; the gripper has no NumPy path)
decides, from the same contacts: a target body is grasped when every
finger touches it (or, for a root body, anything in its subtree) in some
contact. Only integer
comparisons: the two agree exactly (tests/entities/test_gripper.py).
Same compilation settings as the shield's kernels (safety/kernels.py).
"""

import numpy as np

from hrc_suite.safety import kernels

_jit = kernels._jit


@_jit
def grasped(geom1, geom2, geom_body, body_root, fingers, targets, out):
  """out[t] = whether every finger body touches target body targets[t]
  (its subtree if it is a root body) in one of the contacts between
  geoms geom1[c] and geom2[c] (c < len(geom1)); True for every target
  when there are no fingers."""
  for t in range(targets.shape[0]):
    target = targets[t]
    rooted = body_root[target] == target
    every = True
    for finger in fingers:
      touches = False
      for c in range(geom1.shape[0]):
        body1, body2 = geom_body[geom1[c]], geom_body[geom2[c]]
        in1 = (body_root[body1] if rooted else body1) == target
        in2 = (body_root[body2] if rooted else body2) == target
        if (body1 == finger and in2) or (body2 == finger and in1):
          touches = True
          break
      if not touches:
        every = False
        break
    out[t] = every


_warm = False


def warm_up():
  """Compiles (or loads from the cache) `grasped` for the types the
  gripper passes (MuJoCo's int32 ids, our intp ids), once per process."""
  global _warm
  if _warm:
    return
  ids32 = np.zeros(1, dtype=np.int32)
  ids = np.zeros(1, dtype=np.intp)
  ids.flags.writeable = False   # ElementIds' arrays are read-only.
  grasped(ids32, ids32, ids32, ids32, ids, ids, np.zeros(1, dtype=bool))
  _warm = True
