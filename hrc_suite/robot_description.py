"""Robot descriptions: the one source of truth for a robot's geometry.

A description file (`hrc_suite/assets/robots/<name>.json`) holds the kinematic
chain, limits, link capsules and link dynamics of one robot. The MuJoCo model
(`hrc_suite.entities.robot`), the pinocchio model (`hrc_suite.control`) and
the shield (`hrc_suite.safety`) are all built from it.

The robot registry is that folder: every `<name>.json` in it is a robot
(`ROBOT_NAMES`). A description file kept elsewhere joins with
`register(path)`, or wherever a robot name is taken, by giving its path
(`resolve`; docs/extending.md, "A robot in one description file").

Conventions (from the SaRA robot configurations; docs/shield_maths.md, 5.1):
* every joint is revolute about its local z axis;
* chain: T_i = T_{i-1} · A_i · Rz(q_i), starting from the robot base frame,
  where A_i = (fixed_rotation, fixed_translation) of link i;
* link i's capsule (p1, p2, radius), centre of mass and inertia are given in
  the frame after joint i's rotation;
* the flange (tool mounting frame) is a fixed transform after the last joint.

This module depends on NumPy only, so the safety code can use it without
MuJoCo.
"""

import dataclasses
import json
import os
import pathlib
from typing import Sequence, Union

import numpy as np

from hrc_suite import extensions
from hrc_suite import rotations

ROBOTS_DIR = pathlib.Path(__file__).resolve().parent / 'assets' / 'robots'

# Order of the paper's robots (docs/robots.md); other description files in
# ROBOTS_DIR follow them by name. Only an order: the folder is the registry.
_PAPER_ORDER = ('panda', 'sawyer', 'iiwa', 'jaco', 'kinova3', 'ur5e',
                'schunk')


def _shipped_names():
  stems = [path.stem for path in ROBOTS_DIR.glob('*.json')]
  rank = {name: i for i, name in enumerate(_PAPER_ORDER)}
  return tuple(sorted(stems, key=lambda n: (rank.get(n, len(rank)), n)))


# The robots of the benchmark: the description files in ROBOTS_DIR.
ROBOT_NAMES = _shipped_names()
_REGISTERED = {}   # name -> path of a description registered from elsewhere


class DescriptionError(ValueError):
  """A robot description file is missing, malformed or inconsistent."""


@dataclasses.dataclass(frozen=True)
class Capsule:
  """A capsule (p1 == p2 is a sphere) in some frame; metres."""
  p1: np.ndarray
  p2: np.ndarray
  radius: float


@dataclasses.dataclass(frozen=True)
class Link:
  """One moving link: the fixed transform to its joint, geometry, dynamics."""
  name: str
  fixed_rotation: np.ndarray     # (3, 3) A_i rotation.
  fixed_translation: np.ndarray  # (3,) A_i translation.
  capsule: Capsule               # In the frame after joint i's rotation.
  mass: float                    # kg
  inertia: np.ndarray            # (3, 3) kg m^2 about the CoM, link axes.
  center_of_mass: np.ndarray     # (3,) m, in the link frame.


@dataclasses.dataclass(frozen=True)
class JointLimits:
  """Per-joint limits; arrays of shape (dof,)."""
  q_min: np.ndarray       # rad
  q_max: np.ndarray       # rad
  v_max: np.ndarray       # rad/s
  a_max: np.ndarray       # rad/s^2
  j_max: np.ndarray       # rad/s^3
  a_max_ltt: np.ndarray   # rad/s^2, long-term planning
  j_max_ltt: np.ndarray   # rad/s^3, long-term planning
  torque: np.ndarray      # N m

  def __post_init__(self):
    # Read-only copies: a plan cache keys on the limits object
    # (safety/long_term_plan.py), so its values must not change.
    for field in dataclasses.fields(self):
      array = np.array(getattr(self, field.name), dtype=float)
      array.flags.writeable = False
      object.__setattr__(self, field.name, array)


@dataclasses.dataclass(frozen=True)
class ShieldParameters:
  """The shield's per-robot parameters (SaRA trajectory/robot config)."""
  secure_radius: float                 # m, covers tracking error.
  max_s_stop: float                    # s, braking-time bound.
  alpha_i_max: float                   # path-curvature bound per link.
  v_safe: float                        # m/s, PFL safe speed.
  reachability_interval_cycles: int    # cycles per reachable-set slice.
  unclampable_links: tuple             # pairs of link indices.


@dataclasses.dataclass(frozen=True)
class RobotDescription:
  """A validated robot description."""
  name: str
  display_name: str
  links: tuple
  limits: JointLimits
  flange_rotation: np.ndarray     # (3, 3) in the last link frame.
  flange_translation: np.ndarray  # (3,)
  shield: ShieldParameters
  q_home: np.ndarray              # (dof,) gripper down above the table.
  notes: tuple
  # Pairs of link indices never checked for self-collision (each with its
  # reason in `notes`): capsules that touch by construction.
  self_collision_exempt: tuple
  path: str

  @property
  def dof(self) -> int:
    return len(self.links)

  def fixed_transforms(self) -> np.ndarray:
    """(dof, 4, 4) homogeneous A_i."""
    out = np.tile(np.eye(4), (self.dof, 1, 1))
    for i, link in enumerate(self.links):
      out[i, :3, :3] = link.fixed_rotation
      out[i, :3, 3] = link.fixed_translation
    return out

  def flange_transform(self) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3] = self.flange_rotation
    out[:3, 3] = self.flange_translation
    return out

  def capsule_arrays(self):
    """(p1 (dof, 3), p2 (dof, 3), radius (dof,)) in the link frames."""
    p1 = np.array([l.capsule.p1 for l in self.links])
    p2 = np.array([l.capsule.p2 for l in self.links])
    radius = np.array([l.capsule.radius for l in self.links])
    return p1, p2, radius

  def forward_kinematics(self, q: np.ndarray,
                         base: Union[np.ndarray, None] = None) -> np.ndarray:
    """Link frames for joint vectors q (..., dof) -> (..., dof, 4, 4).

    Plain NumPy, batched over leading axes; `base` is the 4x4 base pose.
    """
    q = np.asarray(q, dtype=float)
    fixed = self.fixed_transforms()
    batch = q.shape[:-1]
    frame = np.broadcast_to(np.eye(4) if base is None else base,
                            batch + (4, 4)).copy()
    out = np.empty(batch + (self.dof, 4, 4))
    rz = np.zeros(batch + (self.dof, 4, 4))
    rz[..., :3, :3] = rotations.about_axis(rotations.Z, q)
    rz[..., 3, 3] = 1.0
    for i in range(self.dof):
      frame = frame @ fixed[i] @ rz[..., i, :, :]
      out[..., i, :, :] = frame
    return out


def _path_for(name_or_path: Union[str, os.PathLike]) -> pathlib.Path:
  text = os.fspath(name_or_path)
  if text in ROBOT_NAMES:
    return ROBOTS_DIR / f'{text}.json'
  if text not in _REGISTERED:
    extensions.load()
  if text in _REGISTERED:
    return _REGISTERED[text]
  path = pathlib.Path(text)
  if path.suffix == '.json':
    return path
  raise DescriptionError(
      f'Unknown robot {text!r}: expected one of {", ".join(names())} '
      'or the path of a .json description file.')


def names():
  """Every robot: the shipped ROBOT_NAMES, then those registered."""
  extensions.load()
  return ROBOT_NAMES + tuple(_REGISTERED)


def register(path: Union[str, os.PathLike]) -> str:
  """Registers the description file at `path` (validated) under its name,
  which must be the file's stem; returns the name. Registering the same
  file again is allowed; another file under a taken name is an error."""
  path = pathlib.Path(path).resolve()
  if path.suffix != '.json':
    raise DescriptionError(f'{path}: expected a .json description file')
  description = load(path)
  name = description.name
  if name != path.stem:
    raise DescriptionError(f'{path}: its name {name!r} must be the file '
                           f'name without .json ({path.stem!r})')
  taken = ROBOTS_DIR / f'{name}.json' if name in ROBOT_NAMES else (
      _REGISTERED.get(name))
  if taken is not None and taken != path:
    raise DescriptionError(f'{path}: robot {name!r} is already described '
                           f'by {taken}')
  _REGISTERED[name] = path
  return name


def unregister(name: str):
  """Forgets a description registered with `register`."""
  if name not in _REGISTERED:
    raise DescriptionError(f'Robot {name!r} was not registered: registered '
                           f'are {", ".join(_REGISTERED) or "none"}')
  del _REGISTERED[name]


def resolve(name_or_path: Union[str, os.PathLike]) -> str:
  """The robot name of a name or of a description file's path (which is
  registered); unknown names raise a DescriptionError listing `names()`."""
  if not isinstance(name_or_path, (str, os.PathLike)):
    raise DescriptionError(f'robot: expected a name ({", ".join(names())}) '
                           f'or a .json file path, got {name_or_path!r}')
  text = os.fspath(name_or_path)
  if text in ROBOT_NAMES or text in _REGISTERED:
    return text
  if text.endswith('.json'):
    return register(text)
  if text not in names():
    raise DescriptionError(
        f'Unknown robot {text!r}: expected one of {", ".join(names())} '
        'or the path of a .json description file.')
  return text


class _Reader:
  """Reads fields from the parsed JSON with errors naming file and field."""

  def __init__(self, path):
    self.path = path

  def fail(self, field, message):
    raise DescriptionError(f'{self.path}: field {field!r}: {message}')

  def get(self, data, key, field):
    if not isinstance(data, dict) or key not in data:
      self.fail(field, 'missing')
    return data[key]

  def array(self, data, key, field, shape):
    value = self.get(data, key, field)
    try:
      array = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
      self.fail(field, f'expected numbers of shape {shape}, got {value!r}')
    if array.shape != shape:
      self.fail(field, f'expected shape {shape}, got {array.shape}')
    if not np.all(np.isfinite(array)):
      self.fail(field, f'expected finite numbers, got {value!r}')
    return array

  def number(self, data, key, field, positive=True):
    value = self.array(data, key, field, ())
    if positive and not value > 0:
      self.fail(field, f'expected a positive number, got {float(value)}')
    return float(value)


def _inertia_matrix(reader, values, field):
  ixx, ixy, ixz, iyy, iyz, izz = values
  inertia = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
  eig = np.linalg.eigvalsh(inertia)
  if eig.min() <= 0:
    reader.fail(field, f'inertia is not positive definite (eigenvalues {eig})')
  return inertia


def _check_rotation(reader, rotation, field):
  """Validates a rotation and returns the nearest exact rotation matrix.

  Files give rotations to 4 digits (Sawyer's last joint), so they are
  orthonormalised here and MuJoCo, pinocchio and NumPy FK all use the
  same exact matrix.
  """
  if not np.allclose(rotation @ rotation.T, np.eye(3), atol=1e-3) or (
      np.linalg.det(rotation) < 0):
    reader.fail(field, 'expected a proper rotation matrix (orthonormal, '
                f'det +1), got {rotation.tolist()}')
  return rotations.nearest_rotation(rotation)


def _notes(reader, data):
  """The optional 'notes': a list of strings (free text, e.g. sources)."""
  notes = data.get('notes', [])
  if not (isinstance(notes, list)
          and all(isinstance(note, str) for note in notes)):
    reader.fail('notes', f'expected a list of strings, got {notes!r:.80}')
  return tuple(notes)


def load(name_or_path: Union[str, os.PathLike]) -> RobotDescription:
  """Loads and validates a robot description by robot name or file path."""
  path = _path_for(name_or_path)
  reader = _Reader(path)
  try:
    data = json.loads(path.read_text())
  except FileNotFoundError:
    raise DescriptionError(f'{path}: no such robot description file') from None
  except json.JSONDecodeError as e:
    raise DescriptionError(f'{path}: not valid JSON: {e}') from None

  raw_links = reader.get(data, 'links', 'links')
  if not isinstance(raw_links, list) or not raw_links:
    reader.fail('links', 'expected a non-empty list of links')
  links = []
  for i, raw in enumerate(raw_links):
    f = f'links[{i}]'
    rotation = reader.array(raw, 'fixed_rotation', f + '.fixed_rotation', (3, 3))
    rotation = _check_rotation(reader, rotation, f + '.fixed_rotation')
    raw_capsule = reader.get(raw, 'capsule', f + '.capsule')
    capsule = Capsule(
        p1=reader.array(raw_capsule, 'p1', f + '.capsule.p1', (3,)),
        p2=reader.array(raw_capsule, 'p2', f + '.capsule.p2', (3,)),
        radius=reader.number(raw_capsule, 'radius', f + '.capsule.radius'))
    inertia_values = reader.array(raw, 'inertia', f + '.inertia', (6,))
    links.append(Link(
        name=str(raw.get('name', f'link{i + 1}')),
        fixed_rotation=rotation,
        fixed_translation=reader.array(raw, 'fixed_translation',
                                       f + '.fixed_translation', (3,)),
        capsule=capsule,
        mass=reader.number(raw, 'mass', f + '.mass'),
        inertia=_inertia_matrix(reader, inertia_values, f + '.inertia'),
        center_of_mass=reader.array(raw, 'center_of_mass',
                                    f + '.center_of_mass', (3,)),
    ))
  dof = len(links)

  raw_limits = reader.get(data, 'limits', 'limits')
  limit_values = {}
  for key in ('q_min', 'q_max', 'v_max', 'a_max', 'j_max', 'a_max_ltt',
              'j_max_ltt', 'torque'):
    limit_values[key] = reader.array(raw_limits, key, f'limits.{key}', (dof,))
    if key != 'q_min' and key != 'q_max' and np.any(limit_values[key] <= 0):
      reader.fail(f'limits.{key}',
                  f'expected positive values, got {limit_values[key].tolist()}')
  limits = JointLimits(**limit_values)
  bad = np.nonzero(limits.q_min >= limits.q_max)[0]
  if bad.size:
    reader.fail('limits.q_min', f'must be below limits.q_max for joints '
                f'{bad.tolist()} ({limits.q_min[bad]} >= {limits.q_max[bad]})')
  for small, large in (('a_max_ltt', 'a_max'), ('j_max_ltt', 'j_max')):
    if np.any(limit_values[small] > limit_values[large]):
      reader.fail(f'limits.{small}', f'must not exceed limits.{large}')

  raw_flange = reader.get(data, 'flange', 'flange')
  flange_rotation = reader.array(raw_flange, 'rotation', 'flange.rotation',
                                 (3, 3))
  flange_rotation = _check_rotation(reader, flange_rotation,
                                    'flange.rotation')

  raw_shield = reader.get(data, 'shield', 'shield')
  unclampable = reader.get(raw_shield, 'unclampable_links',
                           'shield.unclampable_links')
  if not isinstance(unclampable, list):
    reader.fail('shield.unclampable_links', 'expected a list of pairs of '
                f'link indices, got {unclampable!r}')
  for pair in unclampable:
    if (not isinstance(pair, list) or len(pair) != 2 or
        not all(type(x) is int and 0 <= x < dof for x in pair)):
      reader.fail('shield.unclampable_links',
                  f'expected pairs of link indices in [0, {dof}), got '
                  f'{pair!r}')
  interval = reader.number(raw_shield, 'reachability_interval_cycles',
                           'shield.reachability_interval_cycles')
  if interval != int(interval):
    reader.fail('shield.reachability_interval_cycles',
                f'expected a whole number, got {interval}')
  shield = ShieldParameters(
      secure_radius=reader.number(raw_shield, 'secure_radius',
                                  'shield.secure_radius'),
      max_s_stop=reader.number(raw_shield, 'max_s_stop', 'shield.max_s_stop'),
      alpha_i_max=reader.number(raw_shield, 'alpha_i_max',
                                'shield.alpha_i_max'),
      v_safe=reader.number(raw_shield, 'v_safe', 'shield.v_safe'),
      reachability_interval_cycles=int(interval),
      unclampable_links=tuple(tuple(p) for p in unclampable))

  exempt = data.get('self_collision_exempt', [])
  if not isinstance(exempt, list):
    reader.fail('self_collision_exempt', f'expected a list of link index '
                f'pairs, got {exempt!r}')
  for pair in exempt:
    if (not isinstance(pair, list) or len(pair) != 2 or
        not all(isinstance(x, int) for x in pair) or
        not all(0 <= x < dof for x in pair) or pair[1] < pair[0] + 2):
      reader.fail('self_collision_exempt', f'expected pairs [i, j] of link '
                  f'indices in [0, {dof}) with j >= i + 2 (non-adjacent), '
                  f'got {pair!r}')

  if 'q_home' in data:
    q_home = reader.array(data, 'q_home', 'q_home', (dof,))
    if np.any(q_home < limits.q_min) or np.any(q_home > limits.q_max):
      reader.fail('q_home', f'{q_home.tolist()} is outside the joint limits')
  else:
    margin = 0.05 * (limits.q_max - limits.q_min)
    q_home = np.clip(np.zeros(dof), limits.q_min + margin, limits.q_max - margin)

  return RobotDescription(
      name=str(data.get('name', path.stem)),
      display_name=str(data.get('display_name', path.stem)),
      links=tuple(links),
      limits=limits,
      flange_rotation=flange_rotation,
      flange_translation=reader.array(raw_flange, 'translation',
                                      'flange.translation', (3,)),
      shield=shield,
      q_home=q_home,
      notes=_notes(reader, data),
      self_collision_exempt=tuple(tuple(p) for p in exempt),
      path=str(path),
  )


def load_all(names: Sequence[str] = ROBOT_NAMES):
  """All shipped descriptions, by name."""
  return {name: load(name) for name in names}
