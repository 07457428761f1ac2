"""Motion clips: keypoint positions over time plus the task metadata.

A clip is authored in the CLIP FRAME: the person stands at the origin facing
+x, z up, floor at z = 0. Positions follow `keypoints.KEYPOINT_NAMES`. On disk a
clip is two files side by side: `<name>.npz` (the positions array, loaded
without pickle) and `<name>.json` (everything else).

Idle phases follow the reference benchmark: from keyframe time t_I until an
event, replay time is t_A = t_I + sum_i u_i sin((t - t_I) S_i / u_i), with the
amplitudes u_i in seconds of clip time and S_i the dimensionless slope at t_I.
"""

import dataclasses
import enum
import json
import math
import pathlib
import re
import zipfile
import zlib

import numpy as np

from hrc_suite.human import keypoints

MOTION_TASKS = ('reach', 'pick_place', 'inspection', 'lifting',
                'handover_robot_to_human', 'handover_human_to_robot',
                'hammering', 'stacking', 'hammering_board')
CLIP_TASKS = MOTION_TASKS + ('other',)

class Event(str, enum.Enum):
  """The events the shipped tasks trigger to end a clip's idle phase; each
  is its name as a string (clips store the string: Event('nail_hammered')
  is Event.nail_hammered, and the two compare and hash alike). Which task
  waits for which is the task's EVENTS (tasks/base.py); a task may name
  events of its own (any identifier-like string, `is_event_name`)."""
  # The robot holds the object in the inspection zone in front of the human.
  object_presented = 'object_presented'
  # The human has the object from the robot's gripper.
  object_received = 'object_received'
  # The robot has grasped the presented object; then has placed it.
  object_taken = 'object_taken'
  object_placed = 'object_placed'
  # The robot has driven the nail (the human holds the board, or brought it).
  nail_hammered = 'nail_hammered'
  # The robot has placed the second cube; then the fourth cube.
  second_cube_placed = 'second_cube_placed'
  fourth_cube_placed = 'fourth_cube_placed'

  def __str__(self):
    return self.value


HANDS = ('left', 'right')

# What each task reads from its clips besides the motion: target names
# (clip frame) and the least number of keyframes (lifting: grasp, put down;
# human-to-robot handover: pick, present), and whether the clip must name
# the hand holding the task's object. `check_for_task` enforces them when a
# task loads its motions; `task_targets` derives them for recordings.
TASK_TARGETS = {
    'reach': (),
    'pick_place': (),
    'inspection': ('inspection_point',),
    'lifting': ('board_grasp_left', 'board_grasp_right'),
    'handover_robot_to_human': (),
    'handover_human_to_robot': ('object_pick',),
    'hammering': ('nail', 'strike_grip'),
    'stacking': ('stack_base', 'cube_1_pick', 'cube_1_place', 'cube_3_pick',
                 'cube_3_place'),
    'hammering_board': ('board_place',),
}
TASK_KEYFRAMES = {'lifting': 2, 'handover_human_to_robot': 2,
                  'hammering_board': 2}

# The shield's human model bounds every keypoint speed by 2 m/s
# (docs/shield_maths.md, 8; ISO/TS 15066 walking speed 1.6 m/s plus margin).
MAX_KEYPOINT_SPEED = 2.0

# The reference randomises idle-phase amplitudes and speeds by
# factor ** clip(N(0, 1), -3, 3) with factor 1.1
# (docs/reference_benchmark.md, Human motions).
DEFAULT_STD_FACTOR = 1.1

FORMAT_NAME = 'hrc_suite.clip'
FORMAT_VERSION = 1

_NAME_PATTERN = re.compile(r'^[A-Za-z0-9_.\-]+$')
_EVENT_PATTERN = re.compile(r'^[A-Za-z_][A-Za-z0-9_]*$')
_ASSETS_DIR = pathlib.Path(__file__).resolve().parent.parent / 'assets'
_MOTIONS_DIR = _ASSETS_DIR / 'motions'


class ClipError(ValueError):
  """A clip or clip file is malformed."""


@dataclasses.dataclass(frozen=True, eq=False)
class IdlePhase:
  """A wait at a keyframe until an event; sine-warped replay meanwhile."""
  keyframe: int
  event: str
  amplitudes: np.ndarray
  speeds: np.ndarray
  amplitude_std_factor: float = DEFAULT_STD_FACTOR
  speed_std_factor: float = DEFAULT_STD_FACTOR

  def __post_init__(self):
    _coerce(self, 'keyframe', _as_int)
    _coerce(self, 'amplitudes', lambda v: np.asarray(v, dtype=np.float64))
    _coerce(self, 'speeds', lambda v: np.asarray(v, dtype=np.float64))

  def to_json(self):
    return {'keyframe': int(self.keyframe), 'event': self.event,
            'amplitudes': [float(a) for a in self.amplitudes],
            'speeds': [float(s) for s in self.speeds],
            'amplitude_std_factor': float(self.amplitude_std_factor),
            'speed_std_factor': float(self.speed_std_factor)}


@dataclasses.dataclass(frozen=True, eq=False)
class Clip:
  """Keypoint positions over time in the clip frame, with task metadata."""
  name: str
  task: str
  fps: float
  positions: np.ndarray
  keyframes: tuple = ()
  idle_phases: tuple = ()
  holding_hand: str | None = None
  placing_hand: str | None = None
  targets: dict = dataclasses.field(default_factory=dict)
  fast_phases: tuple = ()
  metadata: dict = dataclasses.field(default_factory=dict)

  def __post_init__(self):
    _coerce(self, 'positions', lambda v: np.asarray(v, dtype=np.float32))
    _coerce(self, 'keyframes', lambda v: tuple(_as_int(k) for k in v))
    _coerce(self, 'idle_phases', tuple)
    _coerce(self, 'fast_phases',
            lambda v: tuple((_as_int(s), _as_int(e)) for s, e in v))
    _coerce(self, 'targets', lambda v: {
        k: np.asarray(p, dtype=np.float64) for k, p in dict(v).items()})

  @property
  def num_frames(self):
    return int(self.positions.shape[0])

  @property
  def duration(self):
    """Seconds from the first to the last frame."""
    return (self.num_frames - 1) / float(self.fps)

  def keyframe_time(self, i):
    """Clip time in seconds of keyframe `i`."""
    return self.keyframes[i] / float(self.fps)

  def replace(self, **changes):
    return dataclasses.replace(self, **changes)


def _as_int(value):
  if isinstance(value, (bool, np.bool_)) or not float(value).is_integer():
    raise TypeError(f'{value!r} is not an integer')
  return int(value)


def _coerce(obj, field, convert):
  """Converts a field in place when possible; validate() reports otherwise."""
  try:
    object.__setattr__(obj, field, convert(getattr(obj, field)))
  except (TypeError, ValueError):
    pass


def _fail(source, field, message):
  raise ClipError(f'{source}: field {field!r}: {message}')


def _check_finite_vector(source, field, value, size=None):
  if not isinstance(value, np.ndarray) or value.ndim != 1:
    _fail(source, field, f'expected a 1-D array, got {value!r}')
  if size is not None and value.shape[0] not in size:
    _fail(source, field, f'expected length in {sorted(size)}, got '
          f'{value.shape[0]}')
  if not np.all(np.isfinite(value)):
    _fail(source, field, f'expected finite values, got {value.tolist()}')


def is_event_name(value):
  """Whether `value` can name an event: an identifier-like string (the
  task that plays a clip checks that it knows the event)."""
  return isinstance(value, str) and bool(_EVENT_PATTERN.match(value))


def _validate_idle_phase(phase, i, clip, source):
  field = f'idle_phases[{i}]'
  if not isinstance(phase, IdlePhase):
    _fail(source, field, f'expected an IdlePhase, got {type(phase).__name__}')
  if (not isinstance(phase.keyframe, (int, np.integer))
      or not 0 <= phase.keyframe < len(clip.keyframes)):
    _fail(source, field + '.keyframe', f'expected an index into the '
          f'{len(clip.keyframes)} keyframes, got {phase.keyframe!r}')
  if not is_event_name(phase.event):
    _fail(source, field + '.event',
          f'expected an identifier-like event name, got {phase.event!r}')
  _check_finite_vector(source, field + '.amplitudes', phase.amplitudes, {2, 3})
  _check_finite_vector(source, field + '.speeds', phase.speeds,
                       {phase.amplitudes.shape[0]})
  if np.any(phase.amplitudes <= 0):
    _fail(source, field + '.amplitudes', f'expected positive seconds, got '
          f'{phase.amplitudes.tolist()}')
  for name in ('amplitude_std_factor', 'speed_std_factor'):
    value = getattr(phase, name)
    if (not isinstance(value, (int, float, np.floating))
        or not math.isfinite(value) or value < 1.0):
      _fail(source, f'{field}.{name}', f'expected a finite factor >= 1, got '
            f'{value!r}')


def validate(clip, source='<clip>'):
  """Raises ClipError naming `source` and the field if `clip` is malformed."""
  if not isinstance(clip, Clip):
    raise ClipError(f'{source}: expected a Clip, got {type(clip).__name__}')
  if not isinstance(clip.name, str) or not _NAME_PATTERN.match(clip.name):
    _fail(source, 'name', f'expected letters, digits, "_", "-" or ".", got '
          f'{clip.name!r}')
  if clip.task not in CLIP_TASKS:
    _fail(source, 'task', f'expected one of {CLIP_TASKS}, got {clip.task!r}')
  if (not isinstance(clip.fps, (int, float, np.number))
      or not math.isfinite(clip.fps) or clip.fps <= 0):
    _fail(source, 'fps', f'expected a positive frame rate, got {clip.fps!r}')
  pos = clip.positions
  expected = f'(T >= 2, {keypoints.NUM_KEYPOINTS}, 3) float32'
  if not isinstance(pos, np.ndarray) or pos.dtype != np.float32:
    _fail(source, 'positions', f'expected a {expected} array, got '
          f'{type(pos).__name__} {getattr(pos, "dtype", "")}')
  if pos.ndim != 3 or pos.shape[0] < 2 or pos.shape[1:] != (
      keypoints.NUM_KEYPOINTS, 3):
    _fail(source, 'positions', f'expected shape {expected}, got {pos.shape}')
  if not np.all(np.isfinite(pos)):
    frame = int(np.argwhere(~np.isfinite(pos))[0, 0])
    _fail(source, 'positions', f'non-finite value at frame {frame}')
  num_frames = pos.shape[0]
  keys = clip.keyframes
  if (not isinstance(keys, tuple)
      or not all(isinstance(k, int) for k in keys)
      or any(k < 0 or k >= num_frames for k in keys)
      or any(b <= a for a, b in zip(keys, keys[1:]))):
    _fail(source, 'keyframes', f'expected increasing frame indices in '
          f'[0, {num_frames - 1}], got {keys!r}')
  if not isinstance(clip.idle_phases, tuple):
    _fail(source, 'idle_phases', 'expected a tuple of IdlePhase')
  for i, phase in enumerate(clip.idle_phases):
    _validate_idle_phase(phase, i, clip, source)
  anchors = [p.keyframe for p in clip.idle_phases]
  if any(b <= a for a, b in zip(anchors, anchors[1:])):
    _fail(source, 'idle_phases', f'expected phases in keyframe order, got '
          f'keyframe indices {anchors}')
  for field in ('holding_hand', 'placing_hand'):
    if getattr(clip, field) not in HANDS + (None,):
      _fail(source, field, f'expected "left", "right" or None, got '
            f'{getattr(clip, field)!r}')
  if not isinstance(clip.targets, dict):
    _fail(source, 'targets', 'expected a dict name -> (3,) position')
  for key, value in clip.targets.items():
    if not isinstance(key, str) or not key:
      _fail(source, 'targets', f'expected string names, got {key!r}')
    _check_finite_vector(source, f'targets[{key!r}]', value, {3})
  if not isinstance(clip.fast_phases, tuple):
    _fail(source, 'fast_phases', 'expected a tuple of (start, end) frames')
  for i, span in enumerate(clip.fast_phases):
    ok = (isinstance(span, tuple) and len(span) == 2
          and all(isinstance(f, int) for f in span)
          and 0 <= span[0] < span[1] <= num_frames - 1)
    if not ok:
      _fail(source, f'fast_phases[{i}]', f'expected (start, end) frames with '
            f'0 <= start < end <= {num_frames - 1}, got {span!r}')
  if not isinstance(clip.metadata, dict):
    _fail(source, 'metadata', 'expected a dict')
  try:
    json.dumps(clip.metadata, allow_nan=False)
  except (TypeError, ValueError) as e:
    _fail(source, 'metadata', f'not JSON-serialisable: {e}')
  return clip


def keypoint_speeds(clip):
  """(T - 1, NUM_KEYPOINTS) finite-difference speeds in m/s between frames."""
  steps = np.diff(clip.positions.astype(np.float64), axis=0)
  return np.linalg.norm(steps, axis=-1) * float(clip.fps)


def speed_violations(clip, limit=MAX_KEYPOINT_SPEED):
  """Frame intervals i (frame i -> i + 1) over `limit` outside fast phases."""
  over = keypoint_speeds(clip).max(axis=1) > limit
  for start, end in clip.fast_phases:
    over[start:end] = False
  return np.flatnonzero(over)


def _clip_to_json(clip):
  return {
      'format': FORMAT_NAME, 'version': FORMAT_VERSION,
      'name': clip.name, 'task': clip.task, 'fps': float(clip.fps),
      'num_frames': clip.num_frames,
      'keypoints': list(keypoints.KEYPOINT_NAMES),
      'keyframes': list(clip.keyframes),
      'idle_phases': [p.to_json() for p in clip.idle_phases],
      'holding_hand': clip.holding_hand, 'placing_hand': clip.placing_hand,
      'targets': {k: [float(x) for x in v] for k, v in clip.targets.items()},
      'fast_phases': [list(span) for span in clip.fast_phases],
      'metadata': clip.metadata,
  }


def save_clip(clip, directory):
  """Writes <name>.npz and <name>.json into `directory`; returns .json path."""
  validate(clip, source=f'clip {clip.name!r}')
  directory = pathlib.Path(directory)
  directory.mkdir(parents=True, exist_ok=True)
  json_path = directory / f'{clip.name}.json'
  np.savez_compressed(directory / f'{clip.name}.npz', positions=clip.positions)
  with open(json_path, 'w') as f:
    json.dump(_clip_to_json(clip), f, indent=1, allow_nan=False)
    f.write('\n')
  return json_path


def _clip_paths(path):
  path = pathlib.Path(path)
  if path.suffix in ('.json', '.npz'):
    path = path.with_suffix('')
  return path.with_name(path.name + '.json'), path.with_name(path.name + '.npz')


def _field(data, key, source):
  if key not in data:
    raise ClipError(f'{source}: field {key!r}: missing')
  return data[key]


def _idle_phase_from_json(entry, i, source):
  if not isinstance(entry, dict):
    raise ClipError(f'{source}: field idle_phases[{i}]: expected an object')
  sub = f'{source} idle_phases[{i}]'
  try:
    return IdlePhase(
        keyframe=_field(entry, 'keyframe', sub),
        event=_field(entry, 'event', sub),
        amplitudes=np.asarray(_field(entry, 'amplitudes', sub), np.float64),
        speeds=np.asarray(_field(entry, 'speeds', sub), np.float64),
        amplitude_std_factor=entry.get('amplitude_std_factor',
                                       DEFAULT_STD_FACTOR),
        speed_std_factor=entry.get('speed_std_factor', DEFAULT_STD_FACTOR))
  except (TypeError, ValueError) as e:
    raise ClipError(f'{source}: field idle_phases[{i}]: {e}') from e


def load_clip(path):
  """Loads and validates a clip from its .json, .npz or common stem."""
  json_path, npz_path = _clip_paths(path)
  for p in (json_path, npz_path):
    if not p.is_file():
      raise ClipError(f'{p}: clip file missing (a clip is <name>.json + '
                      f'<name>.npz)')
  source = str(json_path)
  try:
    with open(json_path) as f:
      data = json.load(f)
  except (OSError, ValueError) as e:
    raise ClipError(f'{source}: not valid JSON: {e}') from e
  if not isinstance(data, dict) or data.get('format') != FORMAT_NAME:
    raise ClipError(f'{source}: field \'format\': expected {FORMAT_NAME!r}')
  if data.get('version') != FORMAT_VERSION:
    raise ClipError(f'{source}: field \'version\': expected {FORMAT_VERSION}, '
                    f'got {data.get("version")!r}')
  if data.get('keypoints', list(keypoints.KEYPOINT_NAMES)) != list(
      keypoints.KEYPOINT_NAMES):
    raise ClipError(f'{source}: field \'keypoints\': expected '
                    f'{list(keypoints.KEYPOINT_NAMES)}')
  try:
    with np.load(npz_path, allow_pickle=False) as npz:
      positions = npz['positions']
  except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile,
          zlib.error) as e:
    # A truncated or empty file fails in numpy or zipfile (EOFError,
    # BadZipFile), a damaged one in zlib.
    raise ClipError(f'{npz_path}: field \'positions\': cannot read '
                    f'({type(e).__name__}: {e}); expected a .npz file with '
                    f'a (T, {keypoints.NUM_KEYPOINTS}, 3) array') from e
  phases = _field(data, 'idle_phases', source)
  if not isinstance(phases, list):
    raise ClipError(f'{source}: field \'idle_phases\': expected a list')
  try:
    clip = Clip(
        name=_field(data, 'name', source),
        task=_field(data, 'task', source),
        fps=_field(data, 'fps', source),
        positions=positions,
        keyframes=_field(data, 'keyframes', source),
        idle_phases=tuple(_idle_phase_from_json(p, i, source)
                          for i, p in enumerate(phases)),
        holding_hand=data.get('holding_hand'),
        placing_hand=data.get('placing_hand'),
        targets=data.get('targets', {}),
        fast_phases=data.get('fast_phases', []),
        metadata=data.get('metadata', {}))
  except TypeError as e:
    raise ClipError(f'{source}: {e}') from e
  validate(clip, source)
  if data.get('num_frames', clip.num_frames) != clip.num_frames:
    raise ClipError(f'{source}: field \'num_frames\': says '
                    f'{data["num_frames"]}, {npz_path.name} has '
                    f'{clip.num_frames}')
  return clip


def load_folder(directory):
  """All clips in `directory`, sorted by name; ClipError if none or broken."""
  directory = pathlib.Path(directory)
  if not directory.is_dir():
    raise ClipError(f'{directory}: not a folder of clips')
  stems = sorted({p.stem for p in directory.iterdir()
                  if p.suffix in ('.json', '.npz')})
  if not stems:
    raise ClipError(f'{directory}: no clips (<name>.json + <name>.npz) found')
  clips = [load_clip(directory / stem) for stem in stems]
  names = [c.name for c in clips]
  duplicates = sorted({n for n in names if names.count(n) > 1})
  if duplicates:
    raise ClipError(f'{directory}: duplicate clip names {duplicates}')
  return sorted(clips, key=lambda c: c.name)


def shipped_library(task):
  """The clips shipped in hrc_suite/assets/motions/<task>/."""
  if task not in MOTION_TASKS:
    raise ValueError(f'Unknown motion task {task!r}: expected one of '
                     f'{", ".join(MOTION_TASKS)}')
  return load_folder(_MOTIONS_DIR / task)
