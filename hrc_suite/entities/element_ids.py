"""MJCF elements' ids, looked up once per Physics, and synchronised reads.

`physics.bind(element).xpos` costs a binding, a named-index lookup and a
copy on every call (about 3 us; docs/benchmarks.md, "Task code per RL
step"). Code
that runs every RL step reads rows of MjData by ids looked up once per
Physics instead. A binding's read of a derived quantity (positions,
frames) first runs mj_forward when a write through a binding has marked
the physics dirty (dm_control's mjcf.Physics); `synced_data` does the
same, so a raw read returns what the binding would.
"""

import numpy as np


class ElementIds:
  """Ids (int array) of MJCF elements in a Physics, cached per Physics.

  Element ids are those of the compiled model; a Physics recompiled from
  another model is another Physics object, and the ids are looked up
  again (identity, not equality: a weak proxy compares like its target).
  """

  def __init__(self, elements):
    self._elements = list(elements)
    self._cache = None

  def __call__(self, physics):
    if self._cache is None or self._cache[0] is not physics:
      ids = np.array(physics.bind(self._elements).element_id, dtype=np.intp)
      ids.flags.writeable = False
      self._cache = (physics, ids)
    return self._cache[1]


def synced_data(physics):
  """physics.data after the mj_forward a binding's read would run first
  (only when a write through a binding marked the physics dirty)."""
  if physics.is_dirty:
    physics.forward()
  return physics.data
