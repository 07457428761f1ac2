"""Compiled (numba) kernels of the contact monitor (tasks/runtime/contacts.py).

`classify` flags the contact types of the contacts' geom pairs from a
table of every pair's type, what contacts.ContactMonitor's NumPy path
(its `compiled=False` reference) computes from the geoms' categories;
`commanded_speed` is the speed of a contact point under the commanded
joint velocities, which both paths and the compiled physics loop
(tasks/runtime/physics_loop.py) use, summed in one fixed order. `ContactTables`
are what the compiled physics loop judges contacts with.
"""

import typing

import numba
import numpy as np

_jit = numba.njit(cache=True, nogil=True)

# contacts.ContactType.human_allowed (a robot-human pair before it is
# judged by speed).
HUMAN_ALLOWED = 1


class ContactTables(typing.NamedTuple):
  """What the compiled physics loop judges contacts with (built once per
  physics by the ContactMonitor)."""
  pair_types: np.ndarray       # (ngeom, ngeom) int8 contact type, -1: none
  categories: np.ndarray       # (ngeom,) int8 geom categories
  geom_body: np.ndarray        # (ngeom,) each geom's body
  dofs: np.ndarray             # (dof,) int64 the robot's dof addresses
  jacobian: np.ndarray         # (3, nv) float64 buffer for mj_jac
  critical_speed: float        # m/s
  human_in_python: bool        # robot-human contacts judged by the monitor


@_jit
def classify(geom, pair_types, flags):
  """flags[type] for each contact's geom pair (geom (ncon, 2)); returns
  whether one is a robot-human pair (flagged human_allowed)."""
  human = False
  for i in range(geom.shape[0]):
    kind = pair_types[geom[i, 0], geom[i, 1]]
    if kind >= 0:
      flags[kind] = True
      human |= kind == HUMAN_ALLOWED
  return human


@_jit
def commanded_speed(jacobian, dofs, dq_command):
  """|J[:, dofs] dq_command| (m/s), summed joint by joint in order (the
  same value in the Python loop and tasks/runtime/physics_loop.py)."""
  v0 = v1 = v2 = 0.0
  for k in range(dofs.shape[0]):
    column = dofs[k]
    v0 += jacobian[0, column] * dq_command[k]
    v1 += jacobian[1, column] * dq_command[k]
    v2 += jacobian[2, column] * dq_command[k]
  return np.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
