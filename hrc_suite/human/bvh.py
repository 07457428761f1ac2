"""BVH motion files: parser and vectorised forward kinematics.

A BVH file has a HIERARCHY (ROOT/JOINT blocks with OFFSET, CHANNELS and
End Site leaves) and a MOTION section (Frames, Frame Time and one line of
channel values per frame). Conventions used here, as in the Biovision format:

* A joint's local transform is a translation by OFFSET plus its position
  channels, followed by its rotation channels applied in the listed order:
  "Zrotation Xrotation Yrotation" gives R = Rz(a) Rx(b) Ry(c) (intrinsic).
  Angles in degrees. Files written with the opposite habit (extrinsic angles,
  R = Ry(c) Rx(b) Rz(a)) are read with composition='extrinsic', and wrongly
  labelled channels fixed with `relabel_channels`.
* World position of a joint = parent world position + parent world rotation
  @ local translation; world rotation = parent world rotation @ local R.
* End sites become points named `<parent>_end` with no channels.

Positions come out in the file's axes and units; `to_z_up` and a unit scale
convert them (see `bvh_import` for keypoints and the clip frame).
"""

import dataclasses
import pathlib

import numpy as np

from hrc_suite import rotations

_POSITION_CHANNELS = {'xposition': 0, 'yposition': 1, 'zposition': 2}
_ROTATION_CHANNELS = {'xrotation': rotations.X, 'yrotation': rotations.Y,
                      'zrotation': rotations.Z}

# Metres per file unit.
UNITS = {'mm': 1e-3, 'cm': 1e-2, 'm': 1.0}
# Auto-detection: the rest pose of a human skeleton spans about this many
# metres (bounding-box diagonal of a standing adult in T- or A-pose, upper body
# alone about 1.2-1.6 m, whole body 1.8-2.5 m; DIN 33402-2 stature and span).
_NOMINAL_SKELETON_SPAN_M = 1.6
_PLAUSIBLE_SPAN_M = (0.3, 6.0)


class BvhError(ValueError):
  """A BVH file is malformed; the message names the source and line."""


@dataclasses.dataclass(frozen=True, eq=False)
class Skeleton:
  """Joint tree of a BVH file, parents before children."""
  names: tuple            # joint names; end sites are '<parent>_end'
  parents: np.ndarray     # (J,) int, -1 for a root
  offsets: np.ndarray     # (J, 3) float64, file units and axes
  channels: tuple         # per joint, tuple of channel names as in the file
  is_end_site: np.ndarray  # (J,) bool

  @property
  def num_joints(self):
    return len(self.names)

  @property
  def num_channels(self):
    return sum(len(c) for c in self.channels)

  def index(self, name):
    try:
      return self.names.index(name)
    except ValueError:
      raise KeyError(f'Unknown BVH joint {name!r}: the skeleton has '
                     f'{", ".join(self.names)}') from None

  def rest_positions(self):
    """(J, 3) joint positions with all channels zero, file units and axes."""
    out = np.zeros((self.num_joints, 3))
    for j, parent in enumerate(self.parents):
      out[j] = self.offsets[j] + (out[parent] if parent >= 0 else 0.0)
    return out


@dataclasses.dataclass(frozen=True, eq=False)
class Motion:
  """A parsed BVH file: skeleton plus per-frame channel values."""
  skeleton: Skeleton
  frame_time: float       # seconds
  values: np.ndarray      # (F, C) float64 channel values, file order
  source: str = '<bvh>'

  @property
  def num_frames(self):
    return int(self.values.shape[0])

  @property
  def fps(self):
    return 1.0 / self.frame_time


class _Tokens:
  """Whitespace tokens of the hierarchy with their line numbers."""

  def __init__(self, lines, source):
    self.items = []
    self.source = source
    for number, line in lines:
      self.items.extend((tok, number) for tok in line.split())
    self.pos = 0
    self.last_line = lines[-1][0] if lines else 1

  def error(self, message, line=None):
    if line is None:
      line = self.items[self.pos][1] if self.pos < len(self.items) else (
          self.last_line)
    return BvhError(f'{self.source}: line {line}: {message}')

  def peek(self):
    return self.items[self.pos][0] if self.pos < len(self.items) else None

  def next(self, expected):
    if self.pos >= len(self.items):
      raise self.error(f'expected {expected}, found end of hierarchy')
    item = self.items[self.pos]
    self.pos += 1
    return item

  def expect(self, word):
    tok, line = self.next(repr(word))
    if tok != word:
      raise self.error(f'expected {word!r}, found {tok!r}', line)
    return line

  def number(self, what):
    tok, line = self.next(what)
    try:
      return float(tok)
    except ValueError:
      raise self.error(f'expected {what}, found {tok!r}', line) from None


def _parse_hierarchy(tokens):
  names, parents, offsets, channels, end_sites = [], [], [], [], []

  def parse_joint(name, parent, line):
    if name in names:
      raise tokens.error(f'duplicate joint name {name!r}', line)
    index = len(names)
    names.append(name)
    parents.append(parent)
    end_sites.append(False)
    tokens.expect('{')
    tokens.expect('OFFSET')
    offsets.append([tokens.number(f'OFFSET value of {name!r}')
                    for _ in range(3)])
    tok, line = tokens.next('CHANNELS')
    if tok != 'CHANNELS':
      raise tokens.error(f'expected CHANNELS for joint {name!r}, found '
                         f'{tok!r}', line)
    count = tokens.number('channel count')
    if count not in (0, 1, 2, 3, 4, 5, 6):
      raise tokens.error(f'expected a channel count 0..6, found {count:g}',
                         line)
    joint_channels = []
    for _ in range(int(count)):
      tok, line = tokens.next('a channel name')
      if tok.lower() not in _POSITION_CHANNELS and (
          tok.lower() not in _ROTATION_CHANNELS):
        raise tokens.error(
            f'expected a channel name (X/Y/Z position or rotation), found '
            f'{tok!r}', line)
      if tok.lower() in (c.lower() for c in joint_channels):
        raise tokens.error(f'channel {tok!r} repeated for joint {name!r}',
                           line)
      joint_channels.append(tok)
    channels.append(tuple(joint_channels))
    children = 0
    while True:
      tok, line = tokens.next(f"JOINT, End Site or '}}' in {name!r}")
      if tok == '}':
        break
      if tok == 'JOINT':
        child, child_line = tokens.next('a joint name')
        parse_joint(child, index, child_line)
      elif tok == 'End':
        tok, line = tokens.next("'Site'")
        if tok.lower() != 'site':
          raise tokens.error(f"expected 'Site' after 'End', found {tok!r}",
                             line)
        site = f'{name}_end' if children == 0 else f'{name}_end{children}'
        names.append(site)
        parents.append(index)
        end_sites.append(True)
        channels.append(())
        tokens.expect('{')
        tokens.expect('OFFSET')
        offsets.append([tokens.number(f'OFFSET value of the end site of '
                                      f'{name!r}') for _ in range(3)])
        tokens.expect('}')
      else:
        raise tokens.error(f"expected JOINT, End Site or '}}' in joint "
                           f'{name!r}, found {tok!r}', line)
      children += 1

  tokens.expect('HIERARCHY')
  while tokens.peek() is not None:
    tok, line = tokens.next('ROOT')
    if tok != 'ROOT':
      raise tokens.error(f'expected ROOT, found {tok!r}', line)
    root, line = tokens.next('a root joint name')
    parse_joint(root, -1, line)
  if not names:
    raise tokens.error('expected ROOT, found an empty hierarchy')
  return Skeleton(names=tuple(names), parents=np.array(parents, dtype=int),
                  offsets=np.array(offsets, dtype=np.float64),
                  channels=tuple(channels),
                  is_end_site=np.array(end_sites, dtype=bool))


def _header_value(lines, i, key, source, convert):
  """Parses 'Frames: N' / 'Frame Time: t' at lines[i]; returns value."""
  if i >= len(lines):
    raise BvhError(f'{source}: line {lines[-1][0] if lines else 1}: expected '
                   f'{key!r}, found end of file')
  number, text = lines[i]
  if not text.startswith(key):
    raise BvhError(f'{source}: line {number}: expected {key!r}, found '
                   f'{text[:40]!r}')
  rest = text[len(key):].strip()
  try:
    value = convert(rest)
  except ValueError:
    raise BvhError(f'{source}: line {number}: expected a number after '
                   f'{key!r}, found {rest!r}') from None
  return value


def parse(text, source='<bvh>'):
  """Parses BVH text into a Motion; BvhError names the line on bad input."""
  lines = [(n, line.strip()) for n, line in enumerate(text.splitlines(), 1)]
  lines = [(n, line) for n, line in lines if line]
  motion_at = next((i for i, (_, line) in enumerate(lines)
                    if line.split()[0] == 'MOTION'), None)
  if motion_at is None:
    last = lines[-1][0] if lines else 1
    raise BvhError(f'{source}: line {last}: expected a MOTION section, found '
                   f'end of file')
  skeleton = _parse_hierarchy(_Tokens(lines[:motion_at], source))
  if lines[motion_at][1] != 'MOTION':
    raise BvhError(f'{source}: line {lines[motion_at][0]}: expected MOTION '
                   f'alone on its line')
  num_frames = _header_value(lines, motion_at + 1, 'Frames:', source, int)
  frame_time = _header_value(lines, motion_at + 2, 'Frame Time:', source,
                             float)
  if num_frames < 1:
    raise BvhError(f'{source}: line {lines[motion_at + 1][0]}: expected at '
                   f'least 1 frame, found {num_frames}')
  if not frame_time > 0:
    raise BvhError(f'{source}: line {lines[motion_at + 2][0]}: expected a '
                   f'positive Frame Time, found {frame_time}')
  data = lines[motion_at + 3:]
  if len(data) != num_frames:
    line = data[-1][0] if data else lines[motion_at + 2][0]
    raise BvhError(f'{source}: line {line}: expected {num_frames} frames '
                   f'(Frames: line {lines[motion_at + 1][0]}), found '
                   f'{len(data)} lines of values')
  count = skeleton.num_channels
  for number, line in data:
    if len(line.split()) != count:
      raise BvhError(f'{source}: line {number}: expected {count} channel '
                     f'values, found {len(line.split())}')
  try:
    values = np.array(' '.join(line for _, line in data).split(),
                      dtype=np.float64).reshape(num_frames, count)
  except ValueError:
    for number, line in data:
      try:
        [float(v) for v in line.split()]
      except ValueError as e:
        raise BvhError(f'{source}: line {number}: expected numbers, {e}') from (
            None)
    raise
  if not np.all(np.isfinite(values)):
    row = int(np.argwhere(~np.isfinite(values))[0, 0])
    raise BvhError(f'{source}: line {data[row][0]}: non-finite channel value')
  return Motion(skeleton=skeleton, frame_time=frame_time, values=values,
                source=source)


def load(path):
  """Parses the BVH file at `path`."""
  path = pathlib.Path(path)
  try:
    text = path.read_text()
  except (OSError, UnicodeDecodeError) as e:
    raise BvhError(f'{path}: cannot read: {e}') from e
  return parse(text, source=str(path))


def relabel_channels(motion, channels):
  """The motion with the channel names of some joints replaced.

  `channels` maps a joint name to its true channel names, in file order (the
  values stay where they are). For files whose header mislabels channels.
  """
  skeleton = motion.skeleton
  new = list(skeleton.channels)
  for joint, names in channels.items():
    j = skeleton.index(joint)
    names = tuple(names)
    if len(names) != len(new[j]):
      raise ValueError(f'Joint {joint!r} has {len(new[j])} channels, the '
                       f'relabelling gives {len(names)}: {names}')
    keys = [n.lower() for n in names]
    if (len(set(keys)) != len(keys) or
        any(k not in _POSITION_CHANNELS and k not in _ROTATION_CHANNELS
            for k in keys)):
      raise ValueError(f'Bad channel names for {joint!r}: {names}')
    new[j] = names
  return dataclasses.replace(
      motion, skeleton=dataclasses.replace(skeleton, channels=tuple(new)))


def forward_kinematics(motion, scale=1.0, composition='intrinsic'):
  """World positions (F, J, 3) and rotations (F, J, 3, 3) of every joint.

  Positions are in the file's axes, multiplied by `scale` (metres per unit).
  Each joint's rotation matrices are computed for all frames at once.
  composition: 'intrinsic' (BVH standard, R = product in channel order) or
  'extrinsic' (R = product in reverse channel order).
  """
  if composition not in ('intrinsic', 'extrinsic'):
    raise ValueError(f'Unknown composition {composition!r}: expected '
                     f'"intrinsic" or "extrinsic"')
  extrinsic = composition == 'extrinsic'
  skeleton = motion.skeleton
  num_frames = motion.num_frames
  positions = np.zeros((num_frames, skeleton.num_joints, 3))
  frames = np.zeros((num_frames, skeleton.num_joints, 3, 3))
  column = 0
  for j, parent in enumerate(skeleton.parents):
    translation = np.broadcast_to(skeleton.offsets[j], (num_frames, 3)).copy()
    local = None
    for name in skeleton.channels[j]:
      values = motion.values[:, column]
      column += 1
      key = name.lower()
      if key in _POSITION_CHANNELS:
        translation[:, _POSITION_CHANNELS[key]] += values
      else:
        r = rotations.about_axis(_ROTATION_CHANNELS[key],
                                 np.radians(values))
        if local is None:
          local = r
        else:
          local = r @ local if extrinsic else local @ r
    if local is None:
      local = np.broadcast_to(np.eye(3), (num_frames, 3, 3))
    translation *= scale
    if parent < 0:
      positions[:, j] = translation
      frames[:, j] = local
    else:
      positions[:, j] = positions[:, parent] + np.einsum(
          'fij,fj->fi', frames[:, parent], translation)
      frames[:, j] = frames[:, parent] @ local
  return positions, frames


def detect_scale(skeleton):
  """Metres per file unit, guessed from the rest pose's span (mm, cm or m)."""
  rest = skeleton.rest_positions()
  span = float(np.linalg.norm(rest.max(axis=0) - rest.min(axis=0)))
  if span <= 0:
    raise BvhError('cannot detect units: the rest pose has zero size; pass '
                   'units= "mm", "cm" or "m"')
  unit = min(UNITS, key=lambda u: abs(np.log(span * UNITS[u] /
                                             _NOMINAL_SKELETON_SPAN_M)))
  metres = span * UNITS[unit]
  if not _PLAUSIBLE_SPAN_M[0] <= metres <= _PLAUSIBLE_SPAN_M[1]:
    raise BvhError(f'cannot detect units: rest pose spans {span:g} file units, '
                   f'not a human size in mm, cm or m; pass units=')
  return UNITS[unit]


def unit_scale(units, skeleton):
  """Metres per file unit for units in UNITS, or None to auto-detect."""
  if units is None:
    return detect_scale(skeleton)
  if units not in UNITS:
    raise ValueError(f'Unknown units {units!r}: expected one of '
                     f'{", ".join(UNITS)} or None (auto-detect)')
  return UNITS[units]


# Y-up right-handed (x, y, z) -> Z-up right-handed: a +90 degree rotation
# about x, (x, y, z) -> (x, -z, y).
Y_UP_TO_Z_UP = np.array([[1.0, 0.0, 0.0],
                         [0.0, 0.0, -1.0],
                         [0.0, 1.0, 0.0]])


def to_z_up(points, up_axis='y'):
  """Rotates (..., 3) points from a Y-up (or already Z-up) frame to Z-up."""
  if up_axis == 'z':
    return np.asarray(points, dtype=np.float64)
  if up_axis != 'y':
    raise ValueError(f'Unknown up axis {up_axis!r}: expected "y" or "z"')
  return np.asarray(points, dtype=np.float64) @ Y_UP_TO_Z_UP.T
