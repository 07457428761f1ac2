"""The energy of a robot-human contact against its body region's limit.

For metrics of energy-based PFL (docs/safety.md, "Energy limits of body
regions"): at a contact of robot link j with a human body, the energy the
arm's motion can put into it is min(E_j, E_n) (robot_energy's module
docstring; arm_energy.ArmEnergyModel.contact_energy_bounds), compared with
the body's transient limit E_T, or its clamped limit E_QS when the body is
also pressed against something else (body_regions.py). The ratio has no
margin: above 1 the contact exceeds the limit of ISO/TS 15066 Annex A.

`clamped_geoms` decides clamping from the simulation's own contacts: a
human geom touching a robot link is clamped when it also touches a static
geom (table, pedestal, floor) or a link that can close on it with the
first (as clamping.py decides from reach capsules).
"""

import typing
from typing import Optional

import numpy as np

from hrc_suite import robot_description as robot_description_lib
from hrc_suite.safety import arm_energy
from hrc_suite.safety import body_regions
from hrc_suite.safety import robot_energy


class ContactEnergy(typing.NamedTuple):
  """One contact's energy and limit.

  Attributes:
    link: the robot link (0-based; the gripper counts as the last).
    body: the human body (shield body name, body_regions.json).
    energy: J, min(E_j, E_n) at the given joint state.
    limit: J, the body's clamped limit if clamped, else its transient one.
    clamped: whether the contact is clamped.
    ratio: energy / limit.
  """
  link: int
  body: str
  energy: float
  limit: float
  clamped: bool
  ratio: float


class ContactEnergyMeter:
  """Energies of robot-human contacts of one arm.

  Args:
    description: the robot's description.
    payload: what the last link carries (robot_energy.payload_from_physics
      of the gripper and a held object), or None.
    table: the body-region table (default: body_regions.load()).
  """

  def __init__(self, description: robot_description_lib.RobotDescription,
               payload: Optional[robot_energy.Payload] = None,
               table: Optional[body_regions.RegionTable] = None):
    self.description = description
    self.table = table or body_regions.load()
    self.model = arm_energy.ArmEnergyModel(description, payload)

  def set_payload(self, payload: Optional[robot_energy.Payload]):
    """Changes what the last link carries (an object grasped or let go)."""
    self.model = arm_energy.ArmEnergyModel(self.description, payload)

  def measure(self, q, dq, link: int, body: str,
              clamped: bool) -> ContactEnergy:
    """The ContactEnergy of a contact of `link` with `body` at joint state
    (q, dq) (dof,) (the commanded state, as tasks/runtime/contacts.py judges
    contacts, or the measured one)."""
    if isinstance(link, bool) or not 0 <= int(link) < self.model.dof:
      raise ValueError(f'link={link!r}: expected a link index in [0, '
                       f'{self.model.dof})')
    limits = self.table.limits(body)
    energy = float(self.model.contact_energy_bounds(q, dq)[int(link)])
    limit = limits.energy_clamped if clamped else limits.energy_transient
    return ContactEnergy(link=int(link), body=body, energy=energy,
                         limit=float(limit), clamped=bool(clamped),
                         ratio=energy / limit)


def clamped_geoms(geom1, geom2, link_of_geom, static_geom, human_geom,
                  clampable) -> set:
  """Human geoms pressed between a robot link and something else in the
  simulation's active contacts.

  Args:
    geom1, geom2: (C,) the active contacts' geom ids.
    link_of_geom: (G,) each geom's robot link, -1 for non-robot geoms.
    static_geom: (G,) bool, the static geoms.
    human_geom: (G,) bool, the human's geoms.
    clampable: (dof, dof) bool, link pairs that can close on a body part
      (clamping.ClampGeometry.clampable of the links' capsules).

  Returns:
    The set of human geom ids that touch a robot link and also a static
    geom or a link that can clamp with it.
  """
  geom1 = np.asarray(geom1, dtype=int)
  geom2 = np.asarray(geom2, dtype=int)
  links, static = {}, set()
  for a, b in zip(geom1.tolist() + geom2.tolist(),
                  geom2.tolist() + geom1.tolist()):
    if not human_geom[a]:
      continue
    if link_of_geom[b] >= 0:
      links.setdefault(a, set()).add(int(link_of_geom[b]))
    elif static_geom[b]:
      static.add(a)
  out = set()
  for geom, touching in links.items():
    if geom in static or any(clampable[i, j] for i in touching
                             for j in touching):
      out.add(geom)
  return out
