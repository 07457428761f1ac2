"""The arm's energy model for energy-based PFL, in the compiled kernels' form.

`ArmEnergyModel` holds what `energy_kernels` needs of one robot arm: the
links' fixed transforms, masses, centres of mass and inertias (from the
robot description; the payload, the gripper and a held object, merged into
the last link), the joints' armature, and the constants of the bound
between plan samples (docs/shield_maths.md, 9.4). Its link energies equal
robot_energy.ArmInertia.link_energies (pinocchio's composite-rigid-body
algorithm on the same description and payload, the reference;
tests/safety/test_arm_energy.py) to round-off.

Per plan it makes the energy tables of the `pfl_energy` mode: per link j
the largest contact energy bound at nominal path speed over the next
`width` samples (a slice of the monitored path), and the largest of any
link from each sample to the plan's end (after the failsafe), in J; the
energy at path velocity s_dot is s_dot^2 times these (docs/shield_maths.md,
9.4).
"""

from typing import Optional, Tuple

import numpy as np

from hrc_suite import robot_description as robot_description_lib
from hrc_suite.safety import energy_kernels
from hrc_suite.safety import robot_energy


def merge_inertia(mass_a, centre_a, inertia_a, mass_b, centre_b, inertia_b):
  """The rigid union of two bodies in one frame: (mass, centre of mass (3,),
  inertia about it (3, 3)); each body's inertia about its own centre."""
  mass = mass_a + mass_b
  centre = (mass_a * np.asarray(centre_a, float)
            + mass_b * np.asarray(centre_b, float)) / mass
  inertia = np.asarray(inertia_a, float) + np.asarray(inertia_b, float)
  for part_mass, part_centre in ((mass_a, centre_a), (mass_b, centre_b)):
    d = np.asarray(part_centre, float) - centre
    inertia = inertia + part_mass * (d @ d * np.eye(3) - np.outer(d, d))
  return mass, centre, inertia


class ArmEnergyModel:
  """Link energies and plan energy tables of one arm (see the module);
  `kernel_arrays` (energy_kernels.ArmArrays) hands the model to compiled
  code (the shield's energy_table_kernels).

  Args:
    description: the robot's description.
    payload: what the last link carries rigidly (robot_energy.Payload:
      gripper, held object), or None.
  """

  def __init__(self, description: robot_description_lib.RobotDescription,
               payload: Optional[robot_energy.Payload] = None):
    self.description = description
    self.payload = payload
    dof = description.dof
    self.dof = dof
    fixed = description.fixed_transforms()
    # Relative to the robot's base: the energies do not depend on its pose.
    self.fixed = np.ascontiguousarray(fixed[:, :3])
    masses = np.array([link.mass for link in description.links], float)
    centres = np.array([link.center_of_mass for link in description.links],
                       float)
    inertias = np.array([link.inertia for link in description.links], float)
    if payload is not None:
      if not payload.mass >= 0:
        raise ValueError(f'payload.mass={payload.mass!r}: expected >= 0 kg')
      if payload.mass > 0:
        masses[-1], centres[-1], inertias[-1] = merge_inertia(
            masses[-1], centres[-1], inertias[-1], payload.mass,
            payload.center_of_mass, payload.inertia)
    self.masses = np.ascontiguousarray(masses)
    self.centres = np.ascontiguousarray(centres)
    self.inertias = np.ascontiguousarray(inertias)
    self.armature = np.ascontiguousarray(robot_energy.armature(description))
    # Bounds of the change between samples (docs/shield_maths.md, 9.4).
    hop = np.linalg.norm(fixed[:, :3, 3], axis=-1)
    reach = np.linalg.norm(centres, axis=-1)
    levers = np.zeros((dof, dof))
    for link in range(dof):
      for joint in range(link + 1):
        levers[joint, link] = hop[joint + 1:link + 1].sum() + reach[link]
    self.levers = levers
    self.inertia_bound = np.ascontiguousarray(
        np.linalg.eigvalsh(inertias)[:, -1])
    diagonal = np.array([
        self.armature[i] + sum(masses[l] * levers[i, l] ** 2
                               + self.inertia_bound[l]
                               for l in range(i, dof))
        for i in range(dof)])
    self.trace_bound = np.sqrt(np.cumsum(diagonal))
    self.kernel_arrays = energy_kernels.ArmArrays(
        self.fixed, self.masses, self.centres, self.inertias, self.armature,
        np.ascontiguousarray(levers), np.ascontiguousarray(self.trace_bound),
        np.ascontiguousarray(self.inertia_bound))
    self._reference = None
    energy_kernels.warm_up()

  def _check(self, value, name):
    value = np.asarray(value, dtype=float)
    if value.ndim == 0 or value.shape[-1] != self.dof:
      raise ValueError(f'{name}: expected shape (..., {self.dof}) for '
                       f'{self.description.name}, got {value.shape}')
    return value

  def link_energies(self, q, dq, compiled: bool = True) -> np.ndarray:
    """E_j (..., dof), J, at configurations q and joint velocities dq
    (..., dof) (robot_energy's module docstring). compiled=False runs the
    pinocchio reference (robot_energy.ArmInertia)."""
    q, dq = np.broadcast_arrays(self._check(q, 'q'), self._check(dq, 'dq'))
    batch = q.shape[:-1]
    # Writeable copies: one kernel signature (broadcast views are
    # read-only).
    q = np.array(q.reshape(-1, self.dof), dtype=float, order='C')
    dq = np.array(dq.reshape(-1, self.dof), dtype=float, order='C')
    if compiled:
      out = energy_kernels.link_energies(q, dq, self.fixed, self.masses,
                                         self.centres, self.inertias,
                                         self.armature)
    else:
      if self._reference is None:
        self._reference = robot_energy.ArmInertia(self.description,
                                                  self.payload)
      out = np.array([self._reference.link_energies(a, b)
                      for a, b in zip(q, dq)]).reshape(-1, self.dof)
    return out.reshape(batch + (self.dof,))

  def contact_energy_bounds(self, q, dq, compiled: bool = True
                            ) -> np.ndarray:
    """min(E_j, E_n) (..., dof), J: what a contact at link j can take from
    the arm's motion at most (robot_energy's module docstring)."""
    energies = self.link_energies(q, dq, compiled)
    return np.minimum(energies, energies[..., -1:])

  def energy_bounds(self, samples, cycle_time: float) -> np.ndarray:
    """(N, dof), J: per plan sample (N, 4, dof) (q, dq, ddq, dddq every
    cycle_time seconds at nominal path speed) a bound of the contact
    energy bound min(E_j, E_n) on the plan's piece from the sample to the
    next (its Taylor polynomial, as the shield evaluates it;
    docs/shield_maths.md, 9.4)."""
    samples = np.ascontiguousarray(samples, dtype=float)
    if samples.ndim != 3 or samples.shape[1:] != (4, self.dof) or (
        samples.shape[0] < 1):
      raise ValueError(f'samples: expected shape (N >= 1, 4, {self.dof}), '
                       f'got {samples.shape}')
    if not cycle_time > 0:
      raise ValueError(f'cycle_time={cycle_time!r}: expected > 0 s')
    return energy_kernels.energy_bounds(
        samples, self.fixed, self.masses, self.centres, self.inertias,
        self.armature, self.levers, self.trace_bound, self.inertia_bound,
        float(cycle_time))

  def plan_tables(self, samples, cycle_time: float, width: int
                  ) -> Tuple[np.ndarray, np.ndarray]:
    """Energy tables of a plan (docs/shield_maths.md, 9.4): window (N, dof),
    J, the largest bound of each link over samples i..i+width, and suffix
    (N,), J, the largest of any link from sample i to the end."""
    if isinstance(width, bool) or not isinstance(width, (int, np.integer)) \
        or width < 0:
      raise ValueError(f'width={width!r}: expected an int >= 0')
    return energy_kernels.energy_tables(
        self.energy_bounds(samples, cycle_time), int(width))
