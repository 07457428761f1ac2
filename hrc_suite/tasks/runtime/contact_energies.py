"""Robot-human contacts judged by energy, for the contact monitor.

At a robot-human contact of a task, the energy the arm's motion can put
into the person is min(E_j, E_n) of the touching link j at the robot's
joint state (contact_energy.ContactEnergyMeter), compared with the touched
body's limit: its clamped limit where the body is pressed between the link
and a static geom or a link that can close on it with the first
(contact_energy.clamped_geoms, from the simulation's own contacts), else
its transient one (docs/safety.md, "Energy limits of body regions"). A
ratio above 1 exceeds the limit.

The monitor (tasks/runtime/contacts.py) measures every robot-human contact this
way in every shield mode, for the episode metrics (largest energy and
ratio per body, tasks/runtime/metrics.py); in the mode 'pfl_energy' the ratio,
not the commanded speed, decides whether the contact is critical.

The person is kinematic and has no MuJoCo contacts with static geometry,
so a human geom counts as touching it where its capsule's bounding box
comes within its radius of one of the shield's static boxes
(clamping.box_gap, a lower bound of the distance: a conservative
decision, as the shield's own clamping check).

The human's bodies are its capsules (human_segments.SEGMENTS, one geom
each, in that order), named as the shield's body capsules whose limits
body_regions.json gives. The robot's geoms map to the shield's capsules
(link i's capsule is capsule i; the gripper's geoms the tool capsule,
carried by the last link), which the clamp geometry's `clampable` table
indexes.
"""

from typing import Sequence

import numpy as np

from hrc_suite.entities import human_segments
from hrc_suite.safety import clamping
from hrc_suite.safety import contact_energy

# The human's bodies, in the order of its geoms.
BODIES = tuple(name for name, _, _ in human_segments.SEGMENTS)


class ContactEnergies:
  """Energies of one physics' robot-human contacts and their maxima.

  Args:
    meter: the arm's contact_energy.ContactEnergyMeter.
    ngeom: the model's number of geoms.
    link_geoms: (dof,) geom ids of the links' capsules, base to flange.
    tool_geoms: geom ids of the gripper (the tool capsule).
    human_geoms: geom ids of the human's bodies, in BODIES' order.
    static_geoms: geom ids of static geometry (table, pedestal, floor).
    clampable: (L, L) bool, capsules that can close on a body part
      (clamping.ClampGeometry.clampable of the shield's capsules: the
      links', then the tool's).
    frame_index: (L,) each capsule's link (robot_reach.RobotReach).
    data, size: the physics' MjData and the model's geom_size (the human
      capsules' poses and radii and half lengths).
    box_min, box_max: (X, 3) m, the static boxes (clamping.ClampGeometry).
  """

  def __init__(self, meter: contact_energy.ContactEnergyMeter, ngeom: int,
               link_geoms: Sequence[int], tool_geoms: Sequence[int],
               human_geoms: Sequence[int], static_geoms: Sequence[int],
               clampable: np.ndarray, frame_index: np.ndarray, data,
               size: np.ndarray, box_min: np.ndarray, box_max: np.ndarray):
    link_geoms = np.asarray(link_geoms, dtype=int)
    human_geoms = np.asarray(human_geoms, dtype=int)
    frame_index = np.asarray(frame_index, dtype=int)
    clampable = np.asarray(clampable, dtype=bool)
    capsules = frame_index.shape[0]
    if human_geoms.shape != (len(BODIES),):
      raise ValueError(f'human_geoms: expected {len(BODIES)} geoms '
                       f'({", ".join(BODIES)}), got {human_geoms.size}')
    if link_geoms.size >= capsules or clampable.shape != (capsules,
                                                          capsules):
      raise ValueError(f'{link_geoms.size} link geoms and clampable '
                       f'{clampable.shape}: expected fewer links than the '
                       f'{capsules} capsules and ({capsules}, {capsules})')
    self.meter = meter
    # Each geom's capsule (-1: not the robot's), body (-1: not human).
    self._capsule = np.full(ngeom, -1, dtype=int)
    self._capsule[link_geoms] = np.arange(link_geoms.size)
    self._capsule[np.asarray(tool_geoms, dtype=int)] = capsules - 1
    self._body = np.full(ngeom, -1, dtype=int)
    self._body[human_geoms] = np.arange(len(BODIES))
    self._static = np.zeros(ngeom, dtype=bool)
    self._static[np.asarray(static_geoms, dtype=int)] = True
    self._human = self._body >= 0
    self._human_geoms = human_geoms
    self._some_static = int(np.asarray(static_geoms, dtype=int)[0])
    self._data, self._size = data, size
    self._box_min = np.asarray(box_min, dtype=float).reshape(-1, 3)
    self._box_max = np.asarray(box_max, dtype=float).reshape(-1, 3)
    self._clampable = clampable
    self._frame_index = frame_index
    self.max_energy = np.zeros(len(BODIES))   # J, per body
    self.max_ratio = np.zeros(len(BODIES))
    self._measured = False

  @property
  def measured(self) -> bool:
    """Whether a contact was measured since the last `reset` (if not, the
    maxima are zero)."""
    return self._measured

  def reset(self):
    """Starts a new interval for the maxima."""
    self.max_energy[:] = 0.0
    self.max_ratio[:] = 0.0
    self._measured = False

  def clamped(self, geom1, geom2) -> set:
    """The human geoms clamped in the contacts (geom1, geom2) (C,), those
    at a static box (module doc) counted as touching a static geom."""
    on_box = self._human_geoms[self._on_static_box()]
    geom1 = np.concatenate([np.asarray(geom1, dtype=int), on_box])
    geom2 = np.concatenate([np.asarray(geom2, dtype=int),
                            np.full(on_box.size, self._some_static)])
    return contact_energy.clamped_geoms(geom1, geom2, self._capsule,
                                        self._static, self._human,
                                        self._clampable)

  def _on_static_box(self) -> np.ndarray:
    """(bodies,) bool: the human capsules within their radius of a static
    box (bounding boxes)."""
    geoms = self._human_geoms
    centre = self._data.geom_xpos[geoms]
    axis = self._data.geom_xmat[geoms][:, 6:9]   # The capsules' z axes.
    radius, half = self._size[geoms, 0], self._size[geoms, 1]
    start = centre - half[:, None] * axis
    end = centre + half[:, None] * axis
    out = np.zeros(geoms.size, dtype=bool)
    for low, high in zip(self._box_min, self._box_max):
      out |= clamping.box_gap(start, end, low, high) < radius
    return out

  def measure(self, q, dq, robot_geom: int, human_geom: int,
              clamped: bool) -> contact_energy.ContactEnergy:
    """The ContactEnergy of a contact of `robot_geom` with `human_geom` at
    joint state (q, dq); the maxima are updated.

    Args:
      q, dq: (dof,) the robot's joint positions and velocities.
      robot_geom, human_geom: the contact's geom ids.
      clamped: whether the human geom is clamped (`clamped`).

    Returns:
      The contact's contact_energy.ContactEnergy.
    """
    capsule, body = self._capsule[robot_geom], self._body[human_geom]
    if capsule < 0 or body < 0:
      raise ValueError(f'geoms {robot_geom}, {human_geom}: expected a '
                       'robot geom and a human geom')
    result = self.meter.measure(q, dq, int(self._frame_index[capsule]),
                                BODIES[body], clamped)
    self.max_energy[body] = max(self.max_energy[body], result.energy)
    self.max_ratio[body] = max(self.max_ratio[body], result.ratio)
    self._measured = True
    return result
