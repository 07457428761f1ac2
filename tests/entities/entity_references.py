"""Readable NumPy references of the entities' kernels that have no NumPy
path in the package (docs/architecture.md, "Kernels and their
references"): the tests compare the kernels with them."""

import numpy as np


def _in_subtree(model, bodies, target):
  """Whether each of `bodies` is `target` (its subtree for a root body)."""
  if model.body_rootid[target] == target:
    return model.body_rootid[bodies] == target
  return bodies == target


def grasping(gripper, physics, bodies):
  """ParallelGripper.grasping (gripper_kernels.grasped) in NumPy: for each
  of `bodies`, whether every finger touches it (its subtree for a root
  body) in some contact; (n,) bools."""
  data, model = physics.data, physics.model
  grasped = np.zeros(len(bodies), dtype=bool)
  ncon = data.ncon
  if ncon == 0:
    return grasped
  contact = data.contact
  body1 = model.geom_bodyid[contact.geom1[:ncon]]
  body2 = model.geom_bodyid[contact.geom2[:ncon]]
  fingers = gripper._finger_ids(physics)   # pylint: disable=protected-access
  if len(fingers) and not ((body1[:, None] == fingers).any()
                           or (body2[:, None] == fingers).any()):
    return grasped   # No finger touches anything.
  # pylint: disable-next=protected-access
  for i, target in enumerate(gripper._target_ids(physics, bodies)):
    in_target1 = _in_subtree(model, body1, target)
    in_target2 = _in_subtree(model, body2, target)
    grasped[i] = all(
        (((body1 == finger) & in_target2)
         | ((body2 == finger) & in_target1)).any() for finger in fingers)
  return grasped
