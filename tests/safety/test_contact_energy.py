"""Per-contact energies against body-region limits
(hrc_suite/safety/contact_energy.py)."""

import numpy as np
import pytest

from hrc_suite import robot_description
from hrc_suite.safety import contact_energy
from hrc_suite.safety import robot_energy

HAND = 4 * 140 ** 2 / (2 * 75e3)   # E_T of hand/fingers, J.


def test_a_contact_is_measured_against_its_bodys_limit():
  description = robot_description.load('panda')
  payload = robot_energy.Payload(0.9, np.array([0.0, 0.0, 0.06]),
                                 np.diag([2e-3, 2e-3, 1e-3]))
  meter = contact_energy.ContactEnergyMeter(description, payload)
  rng = np.random.RandomState(0)
  q = rng.uniform(description.limits.q_min, description.limits.q_max)
  dq = rng.uniform(-0.5, 0.5, description.dof)
  reference = robot_energy.ArmInertia(description, payload)
  bounds = reference.contact_energy_bounds(q, dq)
  free = meter.measure(q, dq, 3, 'left_hand', clamped=False)
  assert free.energy == pytest.approx(bounds[3], rel=1e-9)
  assert free.limit == pytest.approx(HAND, rel=1e-12)
  assert free.ratio == pytest.approx(bounds[3] / HAND, rel=1e-9)
  pressed = meter.measure(q, dq, 3, 'left_hand', clamped=True)
  assert pressed.ratio == pytest.approx(4 * free.ratio, rel=1e-12)
  # A held object makes the same motion more energetic at the last link.
  meter.set_payload(robot_energy.Payload(2.9, np.array([0.0, 0.0, 0.1]),
                                         np.diag([1e-2, 1e-2, 5e-3])))
  assert meter.measure(q, dq, 6, 'torso', False).energy > bounds[6]
  with pytest.raises(ValueError, match='link=7'):
    meter.measure(q, dq, 7, 'torso', False)
  with pytest.raises(ValueError, match="body 'tail'"):
    meter.measure(q, dq, 0, 'tail', False)


def test_clamped_geoms_from_the_simulations_contacts():
  # Geoms: 0 table (static), 1-3 robot links 0, 1, 5, 4-6 human.
  link_of_geom = np.array([-1, 0, 1, 5, -1, -1, -1])
  static = np.array([True] + [False] * 6)
  human = np.array([False] * 4 + [True] * 3)
  clampable = np.ones((7, 7), dtype=bool)
  np.fill_diagonal(clampable, False)
  clampable[0, 1] = clampable[1, 0] = False   # An unclampable pair.
  geom1 = [4, 0, 5, 2, 6, 6]
  geom2 = [3, 4, 1, 5, 1, 3]
  # 4: link 5 and the table; 5: links 0 and 1 (unclampable); 6: links 0, 5.
  assert contact_energy.clamped_geoms(geom1, geom2, link_of_geom, static,
                                      human, clampable) == {4, 6}
  clampable[0, 1] = clampable[1, 0] = True
  assert contact_energy.clamped_geoms(geom1, geom2, link_of_geom, static,
                                      human, clampable) == {4, 5, 6}
  # A human geom on the table, no link: no robot contact, not clamped.
  assert contact_energy.clamped_geoms([0], [4], link_of_geom, static, human,
                                      clampable) == set()
