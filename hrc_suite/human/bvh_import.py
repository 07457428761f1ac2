"""BVH files to motion clips: keypoint mapping, legs, placement, idle phases.

Steps: forward kinematics of the BVH skeleton (`bvh.py`), conversion to metres
and Z-up, keypoints through a `SkeletonMapping`, legs synthesised under the
pelvis when the skeleton has none, then the clip frame: the person's initial
pelvis at the origin, facing +x (estimated from the shoulders, and hips when
mapped, over the first frames), floor at z = 0. The reference recordings'
`<n>_info.json` becomes keyframes and idle phases (`idle_phases_from_info`).
"""

import dataclasses
import json
import math
import pathlib
import re

import numpy as np

from hrc_suite import rotations
from hrc_suite.human import bvh
from hrc_suite.human import clip as clip_lib
from hrc_suite.human import keypoints
from hrc_suite.human import placement
from hrc_suite.human import synthesis
from hrc_suite.human import task_targets

LEG_KEYPOINTS = tuple(f'{side}_{part}' for side in ('left', 'right')
                      for part in ('hip', 'knee', 'ankle'))
FACING_WINDOW_S = 0.5   # seconds of the clip start used to estimate facing.
_UP = np.array([0.0, 0.0, 1.0])


# Body proportions of stature H (D. A. Winter, "Biomechanics and Motor Control
# of Human Movement", 4th ed. 2009, Fig. 4.1, after Drillis and Contini) for
# H = 1.75 m, the 50th-percentile German man of DIN 33402-2.
_STATURE_M = 1.75
_HAND_FRACTION = 0.108        # wrist to fingertip.
_PALM_CENTRE_OF_HAND = 0.45   # modelling choice: hand keypoint at the palm.
_HIP_BREADTH_FRACTION = 0.191
_THIGH_FRACTION = 0.245
_SHIN_FRACTION = 0.246
_ANKLE_HEIGHT_FRACTION = 0.039


@dataclasses.dataclass(frozen=True)
class Anthropometrics:
  """Body dimensions (metres) for the parts a skeleton lacks.

  Defaults: Winter's proportions at H = 1.75 m (constants above); hip joint
  centres a quarter of the hip breadth either side of the midline.
  """
  hand_length: float = round(_PALM_CENTRE_OF_HAND * _HAND_FRACTION *
                             _STATURE_M, 4)   # wrist to hand keypoint.
  hip_half_width: float = round(0.25 * _HIP_BREADTH_FRACTION * _STATURE_M, 4)
  # Pelvis keypoint to the hip joint centres, downwards. Modelling choice for
  # the recordings: their root sits at the lower back, 0.32 m below the
  # shoulder joints; 0.1 m puts a standing subject's shoulders at about
  # 1.35 m and head joint at about 1.7 m.
  hip_drop: float = 0.10
  thigh_length: float = round(_THIGH_FRACTION * _STATURE_M, 4)
  shin_length: float = round(_SHIN_FRACTION * _STATURE_M, 4)
  ankle_height: float = round(_ANKLE_HEIGHT_FRACTION * _STATURE_M, 4)


@dataclasses.dataclass(frozen=True)
class SkeletonMapping:
  """How a BVH skeleton's joints give our keypoints.

  `points` maps a keypoint name to one of:
    'joint'                   the joint (or end site '<joint>_end') position;
    ('lerp', a, b, f)         the point a fraction f from joint a to joint b;
    ('extend', joint, metres) a point `metres` beyond `joint`, continuing the
                              bone from its parent joint.
  Leg keypoints may be left out all together: legs are then synthesised.
  `channels` relabels mislabelled channels (`bvh.relabel_channels`) and
  `composition` is the files' Euler habit (`bvh.forward_kinematics`).
  """
  name: str
  points: dict
  channels: dict = dataclasses.field(default_factory=dict)
  composition: str = 'intrinsic'

  def check(self, skeleton, source='<bvh>'):
    names = set(skeleton.names)
    # Legs are all mapped or all synthesised.
    legs_mapped = any(k in self.points for k in LEG_KEYPOINTS)
    missing = [k for k in keypoints.KEYPOINT_NAMES if k not in self.points
               and (legs_mapped or k not in LEG_KEYPOINTS)]
    if missing:
      raise bvh.BvhError(f'{source}: mapping {self.name!r} lacks keypoints '
                         f'{missing}')
    for joint in self.channels:
      if joint not in names:
        raise bvh.BvhError(
            f'{source}: mapping {self.name!r} relabels joint {joint!r}; the '
            f'skeleton has {", ".join(skeleton.names)}')
    for key, spec in self.points.items():
      if key not in keypoints.KEYPOINT_INDEX:
        raise bvh.BvhError(f'{source}: mapping {self.name!r} has unknown '
                           f'keypoint {key!r}')
      joints = _spec_joints(spec, key, self.name)
      for joint in joints:
        if joint not in names:
          raise bvh.BvhError(
              f'{source}: mapping {self.name!r} needs joint {joint!r} for '
              f'{key!r}; the skeleton has {", ".join(skeleton.names)}')

  @property
  def has_legs(self):
    return all(k in self.points for k in LEG_KEYPOINTS)


def _spec_joints(spec, key, mapping_name):
  if isinstance(spec, str):
    return (spec,)
  if isinstance(spec, tuple) and len(spec) == 4 and spec[0] == 'lerp':
    return spec[1:3]
  if isinstance(spec, tuple) and len(spec) == 3 and spec[0] == 'extend':
    return spec[1:2]
  raise ValueError(f'Mapping {mapping_name!r}: bad spec for {key!r}: {spec!r}; '
                   f'expected a joint name, ("lerp", a, b, f) or ("extend", '
                   f'joint, metres)')


def _side_points(side, hand_length):
  return {
      f'{side}_shoulder': f'{side}_upper_arm',
      f'{side}_elbow': f'{side}_forearm',
      f'{side}_wrist': f'{side}_hand',
      f'{side}_hand': ('extend', f'{side}_hand', hand_length),
  }


# The skeleton of the reference recordings (shared/motions, README): hip (root)
# -> torso -> neck -> head, and per side collar -> upper_arm -> forearm -> hand.
# Each joint sits at the proximal end of the named bone, so the upper_arm
# joint is the shoulder and the hand joint the wrist; torso sits on the hip.
# Their exporter (Vicon CSV -> BVH in the recordings' own pipeline) decomposes
# every rotation into extrinsic z-x-y angles (R = Ry Rx Rz) and writes the
# root's angles in z, x, y order under a "Zrotation Yrotation Xrotation"
# header. Read as standard BVH the people lean up to 70 degrees and the head
# drops below the pelvis; read this way the head stays above the pelvis
# (median cosine to vertical of pelvis->head >= 0.91 in every file).
RECORDINGS_MAPPING = SkeletonMapping(
    name='human-robot-animations',
    points={
        'pelvis': 'hip',
        'torso': ('lerp', 'torso', 'neck', 1.0 / 3.0),
        'chest': ('lerp', 'torso', 'neck', 2.0 / 3.0),
        'neck': 'neck',
        'head': 'head',
        **_side_points('left', Anthropometrics.hand_length),
        **_side_points('right', Anthropometrics.hand_length),
    },
    channels={'hip': ('Xposition', 'Yposition', 'Zposition', 'Zrotation',
                      'Xrotation', 'Yrotation')},
    composition='extrinsic')

# Reference recording folders -> our task names.
REFERENCE_FOLDER_TASKS = {
    'RobotHumanHandover': 'handover_robot_to_human',
    'HumanRobotHandover': 'handover_human_to_robot',
    'CollaborativeLifting': 'lifting',
    'CollaborativeStacking': 'stacking',
    # The reference's robot hammers, its person brings the board:
    # hammering/robot_hammers (docs/tasks.md; hammering/default refuses them,
    # recording_cache.SHARED_FOLDERS).
    'CollaborativeHammering': 'hammering_board',
    'ObjectInspection': 'inspection',
    'PickPlaceCloseHuman': 'pick_place',
}

# Where each task's idle phases start, as in the reference environments:
# (info phase key or None for a plain list, anchor, event). Anchor ('key', i)
# is keyframes[i]; ('mid', i, j) the frame halfway between keyframes i and j
# (the handovers and hammering loop back and forth between the two).
PHASE_RULES = {
    'handover_robot_to_human': ((None, ('mid', 0, 1), 'object_received'),),
    'handover_human_to_robot': (('present', ('mid', 0, 1), 'object_taken'),
                                ('wait', ('key', 1), 'object_placed')),
    'inspection': ((None, ('key', 0), 'object_presented'),),
    'hammering': ((None, ('mid', 0, 1), 'nail_hammered'),),
    'hammering_board': ((None, ('mid', 0, 1), 'nail_hammered'),),
    'stacking': (('wait_for_second', ('key', 2), 'second_cube_placed'),
                 ('wait_for_fourth', ('key', 4), 'fourth_cube_placed')),
    'lifting': (),
    'pick_place': (),
    'reach': (),
}

# Tasks whose person holds the holding hand out to the robot at the first
# wait (the handovers): placed with that hand at least HANDOVER_REACH ahead
# of the station (placement.TaskPoint), the median of the shipped synthetic
# clips' handover points (0.50-0.67 m ahead, median 0.57 robot-to-human
# and 0.61 human-to-robot).
REACH_TASKS = ('handover_robot_to_human', 'handover_human_to_robot')
HANDOVER_REACH = 0.58   # m
# hammering/robot_hammers: the hand on the plank's handle at the set-down
# (the first keyframe) lands this far ahead of the station (m): the
# reference's recordings, placed by the pelvis at the wait, set the plank
# down 0.556-0.75 m ahead; the nail then lies 0.235 m further, 0.455-0.665
# m from the robot's base, inside the Schunk's and the Panda's gripper-
# down reach (tasks/hammering_robot.py, PLANK_*). A person who sets it
# down closer to the body, or reaches farther, is placed so that the
# set-down lies in this band.
BOARD_REACH = (0.55, 0.76)


def task_point(task, fields):
  """The `placement.TaskPoint` of a recording of `task` with its clip
  `fields` (keyframes, idle_phases, holding_hand), or None."""
  hand = fields.get('holding_hand')
  keys, phases = fields['keyframes'], fields['idle_phases']
  hands = ((hand,) if hand in clip_lib.HANDS else clip_lib.HANDS)
  indices = tuple(keypoints.KEYPOINT_INDEX[f'{h}_hand'] for h in hands)
  if task in REACH_TASKS and phases and hand in clip_lib.HANDS:
    return placement.TaskPoint(indices, (HANDOVER_REACH, math.inf))
  if task == 'hammering_board' and keys:
    return placement.TaskPoint(indices, BOARD_REACH, frame=keys[0],
                               on_line=False)
  return None


def _points(spec, fk_pos, skeleton):
  """(F, 3) positions of one mapping spec, file axes, metres."""
  if isinstance(spec, str):
    return fk_pos[:, skeleton.index(spec)]
  if spec[0] == 'lerp':
    _, a, b, fraction = spec
    pa, pb = fk_pos[:, skeleton.index(a)], fk_pos[:, skeleton.index(b)]
    return pa + fraction * (pb - pa)
  _, joint, metres = spec
  j = skeleton.index(joint)
  parent = skeleton.parents[j]
  if parent < 0 or np.linalg.norm(skeleton.offsets[j]) == 0:
    raise bvh.BvhError(f'cannot extend beyond {joint!r}: no bone ends there')
  bone = fk_pos[:, j] - fk_pos[:, parent]
  return fk_pos[:, j] + metres * bone / np.linalg.norm(bone, axis=1,
                                                       keepdims=True)


def _horizontal_unit(vectors, fallback, min_norm=1e-6):
  """Normalised horizontal parts of (F, 3) vectors; fallback where short."""
  flat = vectors * np.array([1.0, 1.0, 0.0])
  norm = np.linalg.norm(flat, axis=-1, keepdims=True)
  return np.where(norm > min_norm, flat / np.maximum(norm, 1e-12), fallback)


def synthesise_legs(pelvis, lateral, body):
  """Hip, knee and ankle keypoints (F, 3) each under the pelvis.

  Hips sit sideways of the pelvis along the (F, 3) horizontal unit `lateral`
  (pointing left) and `body.hip_drop` below it. Ankles stand straight under
  the hips, `body.ankle_height` above the floor z = 0; when the hip is lower
  than a straight leg the knee bends forward (two-link IK), when higher the
  foot leaves the floor. Segment lengths stay constant.
  """
  forward = np.cross(lateral, _UP)
  leg = body.thigh_length + body.shin_length
  out = {}
  for side, sign in (('left', 1.0), ('right', -1.0)):
    hip = pelvis + sign * body.hip_half_width * lateral
    hip[:, 2] -= body.hip_drop
    drop = np.clip(hip[:, 2] - body.ankle_height, 1e-3, leg)
    ankle = hip.copy()
    ankle[:, 2] -= drop
    # Angle at the hip between straight down and the thigh (law of cosines).
    cos_a = (body.thigh_length**2 + drop**2 - body.shin_length**2) / (
        2.0 * body.thigh_length * drop)
    angle = np.arccos(np.clip(cos_a, -1.0, 1.0))[:, None]
    knee = hip + body.thigh_length * (
        -np.cos(angle) * _UP + np.sin(angle) * forward)
    out[f'{side}_hip'], out[f'{side}_knee'], out[f'{side}_ankle'] = (
        hip, knee, ankle)
  return out


def import_motion(motion, mapping=RECORDINGS_MAPPING, units=None,
                  up_axis='y', body=Anthropometrics()):
  """Keypoints (F, NUM_KEYPOINTS, 3) in the clip frame, and import facts."""
  mapping.check(motion.skeleton, motion.source)
  if mapping.channels:
    motion = bvh.relabel_channels(motion, mapping.channels)
  skeleton = motion.skeleton
  scale = bvh.unit_scale(units, skeleton)
  fk_pos, fk_rot = bvh.forward_kinematics(motion, scale, mapping.composition)
  num_frames = motion.num_frames
  points = {key: bvh.to_z_up(_points(spec, fk_pos, skeleton),
                             up_axis)
            for key, spec in mapping.points.items()}
  window = max(1, min(num_frames, round(FACING_WINDOW_S * motion.fps)))
  lateral = points['left_shoulder'] - points['right_shoulder']
  if mapping.has_legs:
    lateral = lateral + points['left_hip'] - points['right_hip']
  lateral0 = lateral[:window].mean(axis=0) * np.array([1.0, 1.0, 0.0])
  if np.linalg.norm(lateral0) < 1e-6:
    raise bvh.BvhError(f'{motion.source}: cannot tell the facing direction: '
                       f'left and right keypoints coincide')
  forward0 = np.cross(lateral0, _UP)
  yaw = math.atan2(forward0[1], forward0[0])
  origin = points['pelvis'][:window].mean(axis=0) * np.array([1.0, 1.0, 0.0])
  turn = rotations.yaw_to_mat(-yaw)
  points = {k: (p - origin) @ turn.T for k, p in points.items()}
  if mapping.has_legs:
    floor = min(points[f'{s}_ankle'][:, 2].min() for s in ('left', 'right'))
    floor -= body.ankle_height
  else:
    # A straight leg under the highest pelvis of the clip reaches the floor.
    floor = points['pelvis'][:, 2].max() - body.hip_drop - (
        body.thigh_length + body.shin_length + body.ankle_height)
  points = {k: p - floor * _UP for k, p in points.items()}
  if not mapping.has_legs:
    lateral = _pelvis_lateral(motion, mapping, points, turn, scale, up_axis,
                              fk_rot)
    points.update(synthesise_legs(points['pelvis'], lateral, body))
  positions = np.stack([points[k] for k in keypoints.KEYPOINT_NAMES], axis=1)
  facts = {'scale_m_per_unit': scale, 'facing_yaw_deg': math.degrees(yaw),
           'origin_m': origin[:2].tolist(), 'floor_m': float(floor),
           'legs': 'mapped' if mapping.has_legs else 'synthesised'}
  return positions, facts


def _pelvis_lateral(motion, mapping, points, turn, scale, up_axis, fk_rot):
  """(F, 3) horizontal left-pointing unit vectors turned with the root.

  The shoulders' left-right line in the rest pose, carried by the root joint's
  rotation alone, so the synthesised hips follow the pelvis, not the torso
  twist; the current shoulder line where the root is tilted too far to tell.
  """
  skeleton = motion.skeleton
  rest = bvh.Motion(skeleton, motion.frame_time,
                    np.zeros((1, skeleton.num_channels)))
  rest_pos, _ = bvh.forward_kinematics(rest, scale, mapping.composition)
  rest_lateral = (
      _points(mapping.points['left_shoulder'], rest_pos, skeleton) -
      _points(mapping.points['right_shoulder'], rest_pos, skeleton))[0]
  rest_lateral /= np.linalg.norm(rest_lateral)
  root = int(np.flatnonzero(skeleton.parents < 0)[0])
  root_lateral = bvh.to_z_up(fk_rot[:, root] @ rest_lateral, up_axis) @ turn.T
  shoulder_lateral = _horizontal_unit(
      points['left_shoulder'] - points['right_shoulder'],
      np.array([0.0, 1.0, 0.0]))
  # Below 0.3 the root's left axis is tilted over 70 degrees from horizontal.
  return _horizontal_unit(root_lateral, shoulder_lateral, min_norm=0.3)


def _info_error(source, field, message):
  return clip_lib.ClipError(f'{source}: field {field!r}: {message}')


def _anchor_frame(anchor, keyframes, source):
  needed = max(anchor[1:]) + 1
  if len(keyframes) < needed:
    raise _info_error(source, 'keyframes', f'expected at least {needed} '
                      f'keyframes for this task, got {keyframes}')
  if anchor[0] == 'key':
    return keyframes[anchor[1]]
  return (keyframes[anchor[1]] + keyframes[anchor[2]]) // 2


def _loop_values(info, key, phase_key, source):
  values = info.get(key)
  if isinstance(values, dict):
    if phase_key is None or phase_key not in values:
      raise _info_error(source, key, f'expected a list or an entry '
                        f'{phase_key!r}, got keys {sorted(values)}')
    values = values[phase_key]
  if not isinstance(values, list) or not values:
    raise _info_error(source, key, f'expected a list of numbers, got '
                      f'{values!r}')
  try:
    return np.array([float(v) for v in values])
  except (TypeError, ValueError):
    raise _info_error(source, key,
                      f'expected numbers, got {values!r}') from None


def _generic_rules(info):
  """Idle phases of an unknown task: phase i at keyframes[i]."""
  loops = info.get('loop_amplitudes')
  if loops is None:
    return ()
  if isinstance(loops, dict):
    return tuple((key, ('key', i), key) for i, key in enumerate(loops))
  return ((None, ('key', 0), 'idle'),)


def idle_phases_from_info(info, fps, num_frames, task, source='<info>'):
  """Keyframes and idle phases from a reference `<n>_info.json` dict.

  Amplitudes are frames in the reference; here seconds (divided by fps).
  Returns dict(keyframes, idle_phases, holding_hand, placing_hand).
  """
  if not isinstance(info, dict):
    raise clip_lib.ClipError(f'{source}: expected a JSON object')
  keyframes = info.get('keyframes', [])
  if (not isinstance(keyframes, list)
      or not all(isinstance(k, int) and 0 <= k < num_frames
                 for k in keyframes)):
    raise _info_error(source, 'keyframes', f'expected frame indices in '
                      f'[0, {num_frames - 1}], got {keyframes!r}')
  rules = PHASE_RULES.get(task)
  if rules is None:
    rules = _generic_rules(info)
  elif rules and 'loop_amplitudes' not in info:
    raise _info_error(source, 'loop_amplitudes', f'missing; task {task!r} '
                      f'has idle phases')
  anchors = [_anchor_frame(anchor, keyframes, source)
             for _, anchor, _ in rules]
  all_keys = tuple(sorted(set(keyframes) | set(anchors)))
  phases = []
  for (phase_key, _, event), frame in zip(rules, anchors):
    amplitudes = _loop_values(info, 'loop_amplitudes', phase_key, source)
    speeds = _loop_values(info, 'loop_speeds', phase_key, source)
    if amplitudes.shape != speeds.shape:
      raise _info_error(source, 'loop_speeds', f'expected {len(amplitudes)} '
                        f'values like loop_amplitudes, got {len(speeds)}')
    phases.append(clip_lib.IdlePhase(
        keyframe=all_keys.index(frame), event=event,
        amplitudes=amplitudes / fps, speeds=speeds,
        amplitude_std_factor=float(info.get(
            'loop_amplitude_std_factor', clip_lib.DEFAULT_STD_FACTOR)),
        speed_std_factor=float(info.get(
            'loop_speed_std_factor', clip_lib.DEFAULT_STD_FACTOR))))
  return dict(keyframes=all_keys, idle_phases=tuple(phases),
              holding_hand=info.get('object_holding_hand'),
              placing_hand=info.get('first_placing_hand'))


def fast_phases(positions, fps, limit=clip_lib.MAX_KEYPOINT_SPEED, pad=2):
  """(start, end) frame spans where a keypoint exceeds `limit` m/s."""
  speed = np.linalg.norm(np.diff(positions, axis=0), axis=-1).max(axis=1)
  over = speed * fps > limit
  spans = []
  for i in np.flatnonzero(over):
    start, end = max(0, i - pad), min(len(positions) - 1, i + 1 + pad)
    if spans and start <= spans[-1][1]:
      spans[-1] = (spans[-1][0], end)
    else:
      spans.append((int(start), int(end)))
  return tuple(spans)


def info_path_for(bvh_path):
  """The reference's `<n>_info.json` beside `<n>.bvh`."""
  bvh_path = pathlib.Path(bvh_path)
  return bvh_path.with_name(f'{bvh_path.stem}_info.json')


def import_clip(bvh_path, task=None, name=None, info_path=None,
                mapping=RECORDINGS_MAPPING, units=None, up_axis='y',
                body=Anthropometrics()):
  """A validated Clip from a BVH file and its info JSON (if present).

  `task` defaults to the reference folder's task ('other' if unknown);
  `name` to '<folder>_<stem>'.
  """
  bvh_path = pathlib.Path(bvh_path)
  folder = bvh_path.resolve().parent.name
  if task is None:
    task = REFERENCE_FOLDER_TASKS.get(folder, 'other')
  if task not in clip_lib.CLIP_TASKS:
    raise ValueError(f'Unknown task {task!r}: expected one of '
                     f'{", ".join(clip_lib.CLIP_TASKS)}')
  motion = bvh.load(bvh_path)
  positions, facts = import_motion(motion, mapping, units, up_axis, body)
  info_path = info_path_for(bvh_path) if info_path is None else pathlib.Path(
      info_path)
  info = {}
  if info_path.is_file():
    try:
      info = json.loads(info_path.read_text())
    except ValueError as e:
      raise clip_lib.ClipError(f'{info_path}: not valid JSON: {e}') from e
  fields = idle_phases_from_info(info, motion.fps, motion.num_frames, task,
                                 str(info_path))
  # Recordings of the reference share its lab's axes (they carry
  # orientation_quat).
  turn = (placement.snapped_turn(facts['facing_yaw_deg'])
          if 'orientation_quat' in info else 0.0)
  name = name or re.sub(r'[^A-Za-z0-9_.\-]', '_',
                        f'{folder}_{bvh_path.stem}')
  metadata = {
      'source': 'bvh', 'file': f'{folder}/{bvh_path.name}',
      'skeleton_mapping': mapping.name, 'units_m': facts['scale_m_per_unit'],
      'import': facts, 'anthropometrics': dataclasses.asdict(body),
      'reference_info': info,
  }
  return clip_from_motion(positions, motion.fps, fields, task, name, turn,
                          metadata, str(bvh_path))


def clip_from_motion(positions, fps, fields, task, name, turn=0.0,
                     metadata=None, source='<recording>'):
  """A validated Clip of a person's motion for `task`: placed at the
  station (placement.py, with the task's point `task_point`), idle phases
  calmed, targets and keyframes derived (task_targets.py), idle phases
  fitted to the shield's human model where they can be.

  Args:
    positions: (F, NUM_KEYPOINTS, 3) keypoints in a clip frame facing +x,
      floor at z = 0, anywhere on the floor (`import_motion`).
    fps: frames per second.
    fields: dict(keyframes, idle_phases, holding_hand, placing_hand), as
      `idle_phases_from_info` gives them.
    task: a clip task (clip.CLIP_TASKS).
    name: the clip's name.
    turn: rad, the facing correction (`placement.snapped_turn`).
    metadata: the clip's metadata; its 'import' dict (added if missing)
      receives the placement's facts.
    source: names the recording in errors.

  Returns:
    The Clip. Raises clip.ClipError where a target cannot be derived.
  """
  fields = dict(fields)
  metadata = dict(metadata or {})
  metadata['import'] = dict(metadata.get('import', {}))
  phases = fields['idle_phases']
  anchor = fields['keyframes'][phases[0].keyframe] if phases else None
  positions, metadata['import']['placement'] = placement.place_at_station(
      positions, turn, anchor, task_point(task, fields),
      placement.lean_allowance(task))
  fields['idle_phases'] = tuple(_calm_idle_phase(p)
                                for p in fields['idle_phases'])
  fields, targets = task_targets.derive(task, positions, fps, fields, source)
  result = clip_lib.Clip(
      name=name, task=task, fps=fps,
      positions=positions.astype(np.float32),
      targets=targets, fast_phases=fast_phases(positions, fps),
      metadata=metadata, **fields)
  result = clip_lib.validate(result, source=source)
  try:
    # Idle phases slowed where their worst case passes the shield's model,
    # as for the synthetic library.
    return synthesis.fit_idle_phases(result)
  except ValueError as e:
    # Left as recorded: loading then refuses the clip or plays it outside
    # the guarantee (tasks/runtime/motions.check_motions).
    metadata = dict(result.metadata, idle_fit=str(e))
    return result.replace(metadata=metadata)


def _calm_idle_phase(phase):
  """The phase with sines above synthesis.MAX_IDLE_HZ slowed to it.

  The reference's idle phases add a sine of 0.6-0.7 frames at 70-125 Hz
  (docs/motion_library.md): it moves the person by under a millimetre but
  multiplies keypoint speeds by up to 4. Slowing it to MAX_IDLE_HZ (slope
  S = u * omega) keeps its amplitude and removes the jitter.
  """
  factor = (phase.speed_std_factor * phase.amplitude_std_factor) ** 3
  omega_max = 2 * math.pi * synthesis.MAX_IDLE_HZ / factor
  omegas = np.abs(phase.speeds) / phase.amplitudes
  speeds = np.where(omegas > omega_max,
                    np.sign(phase.speeds) * phase.amplitudes * omega_max,
                    phase.speeds)
  return dataclasses.replace(phase, speeds=np.floor(
      speeds / synthesis.IDLE_SPEED_QUANTUM) * synthesis.IDLE_SPEED_QUANTUM)
