"""Energy limits of contacts per body region (ISO/TS 15066 Annex A).

The standard models a body region as a spring of stiffness k: a contact
may transfer the energy E = F^2 / (2 k) with F the permissible force.
Transient contacts (the body part can move away) allow twice the
quasi-static (clamped) force, so

  E_transient = (2 F_QS)^2 / (2 k),   E_clamped = F_QS^2 / (2 k).

In a two-body collision the energy is E = mu v_rel^2 / 2 with the reduced
mass mu = (1/m_H + 1/m_R)^-1 of the body region's effective mass m_H and
the robot's m_R, so the largest permissible relative speed is
v_max = F_T / sqrt(mu k).

The numbers (force, pressure, stiffness and effective mass per region) and
their provenance are in hrc_suite/assets/human/body_regions.json (read
from public tables quoting the standard; the standard itself was not
consulted: docs/safety.md, "Energy limits of body regions"). Each body
capsule of the shield's human model lists the regions it covers; its
limits are the smallest of theirs.
"""

import dataclasses
import json
import math
import pathlib
from typing import Dict, Mapping, Optional, Tuple

DEFAULT_PATH = (pathlib.Path(__file__).resolve().parents[1] / 'assets' /
                'human' / 'body_regions.json')
# Transient contacts allow this multiple of the quasi-static force
# (ISO/TS 15066:2016 Annex A; body_regions.json, sources).
TRANSIENT_FORCE_FACTOR = 2.0
_N_PER_MM = 1000.0   # N/m per N/mm.
_FIELDS = ('force_quasi_static', 'pressure_quasi_static', 'stiffness',
           'effective_mass')


@dataclasses.dataclass(frozen=True)
class BodyRegion:
  """One body region of ISO/TS 15066 Annex A.

  Attributes:
    name: the region (e.g. 'hand_fingers').
    force_quasi_static: F_QS, N: the permissible clamped force.
    pressure_quasi_static: p_QS, N/cm^2: the permissible clamped pressure.
    stiffness: k, N/m: the body model's spring stiffness.
    effective_mass: m_H, kg: the region's effective mass.
  """
  name: str
  force_quasi_static: float
  pressure_quasi_static: float
  stiffness: float
  effective_mass: float

  @property
  def force_transient(self) -> float:
    """F_T = 2 F_QS, N."""
    return TRANSIENT_FORCE_FACTOR * self.force_quasi_static

  @property
  def energy_transient(self) -> float:
    """E_T = F_T^2 / (2 k), J: the energy a transient contact may
    transfer."""
    return self.force_transient ** 2 / (2.0 * self.stiffness)

  @property
  def energy_clamped(self) -> float:
    """E_QS = F_QS^2 / (2 k), J: the energy a clamped contact may
    transfer."""
    return self.force_quasi_static ** 2 / (2.0 * self.stiffness)

  def max_relative_speed(self, robot_mass: float,
                         clamped: bool = False) -> float:
    """v_max = F / sqrt(mu k), m/s, with mu the reduced mass of the region
    and a robot of effective mass `robot_mass` (kg) and F the transient
    force (or the quasi-static one for a clamped contact)."""
    if not robot_mass > 0:
      raise ValueError(f'robot_mass={robot_mass!r}: expected a mass > 0 kg')
    reduced = 1.0 / (1.0 / self.effective_mass + 1.0 / robot_mass)
    force = self.force_quasi_static if clamped else self.force_transient
    return force / math.sqrt(reduced * self.stiffness)


@dataclasses.dataclass(frozen=True)
class BodyLimits:
  """The energy limits of one body capsule of the shield's human model.

  Attributes:
    body: the capsule's name (shield_human_model.json's bodies).
    regions: the regions it covers.
    energy_transient: J, the smallest E_T of the regions.
    energy_clamped: J, the smallest E_QS of the regions.
    transient_region: the region giving energy_transient.
    clamped_region: the region giving energy_clamped.
  """
  body: str
  regions: Tuple[str, ...]
  energy_transient: float
  energy_clamped: float
  transient_region: str
  clamped_region: str


@dataclasses.dataclass(frozen=True)
class RegionTable:
  """Body regions and the limits of the shield's body capsules.

  Attributes:
    regions: {name: BodyRegion}.
    bodies: {shield body name: BodyLimits}.
    sources: {topic: where the numbers come from}.
  """
  regions: Mapping[str, BodyRegion]
  bodies: Mapping[str, BodyLimits]
  sources: Mapping[str, str]

  def limits(self, body: str) -> BodyLimits:
    """The limits of a shield body capsule, by name."""
    if body not in self.bodies:
      raise ValueError(f'No energy limits for body {body!r}: the table has '
                       f'{", ".join(self.bodies)}')
    return self.bodies[body]


def _positive(value, where):
  if isinstance(value, bool) or not isinstance(value, (int, float)) or (
      not math.isfinite(value) or value <= 0):
    raise ValueError(f'{where}={value!r}: expected a finite number > 0')
  return float(value)


def _region(name, values, path):
  if not isinstance(values, Mapping):
    raise ValueError(f'{path}: regions.{name} must be an object with '
                     f'{", ".join(_FIELDS)}, got {values!r}')
  missing = [field for field in _FIELDS if field not in values]
  extra = sorted(set(values) - set(_FIELDS))
  if missing or extra:
    raise ValueError(f'{path}: regions.{name} lacks {missing} / has '
                     f'unknown {extra}: expected {", ".join(_FIELDS)}')
  numbers = {field: _positive(values[field], f'{path}: regions.{name}.'
                              f'{field}') for field in _FIELDS}
  numbers['stiffness'] *= _N_PER_MM
  return BodyRegion(name=name, **numbers)


def _body(name, region_names, regions, path):
  if (not isinstance(region_names, list) or not region_names
      or any(r not in regions for r in region_names)):
    raise ValueError(f'{path}: shield_bodies.{name}={region_names!r}: '
                     f'expected a non-empty list of regions of '
                     f'{", ".join(regions)}')
  covered = [regions[r] for r in region_names]
  transient = min(covered, key=lambda r: r.energy_transient)
  clamped = min(covered, key=lambda r: r.energy_clamped)
  return BodyLimits(body=name, regions=tuple(region_names),
                    energy_transient=transient.energy_transient,
                    energy_clamped=clamped.energy_clamped,
                    transient_region=transient.name,
                    clamped_region=clamped.name)


def load(path: Optional[str] = None,
         body_names: Optional[Tuple[str, ...]] = None) -> RegionTable:
  """Reads a body-region table (default: DEFAULT_PATH).

  Args:
    path: the JSON file.
    body_names: the shield's body capsules; each must have limits (None:
      no check).

  Returns:
    The RegionTable.
  """
  path = pathlib.Path(path or DEFAULT_PATH)
  with open(path) as handle:
    raw = json.load(handle)
  for key in ('regions', 'shield_bodies', 'sources'):
    if not isinstance(raw.get(key), Mapping):
      raise ValueError(f'{path}: expected an object {key!r}')
  regions = {name: _region(name, values, path)
             for name, values in raw['regions'].items()}
  bodies: Dict[str, BodyLimits] = {
      name: _body(name, names, regions, path)
      for name, names in raw['shield_bodies'].items()}
  if body_names is not None:
    missing = [name for name in body_names if name not in bodies]
    if missing:
      raise ValueError(f'{path}: no energy limits for the shield bodies '
                       f'{missing}')
  return RegionTable(regions=regions, bodies=bodies,
                     sources=dict(raw['sources']))
