"""A recording's task facts derived from the motion: keyframes and targets.

The synthetic library writes each task's targets (where the hands grasp,
strike, place, present) into its clips as it makes them; a recording has
only the motion and, for the reference's recordings, an `_info.json` with
keyframes and idle phases (`bvh_import.idle_phases_from_info`). Each rule
below derives what its task needs (`clip.TASK_TARGETS`,
`clip.TASK_KEYFRAMES`) from the placed motion (`placement`), in the clip
frame (station at the origin, facing +x, table edge TABLE_EDGE_X ahead).
A rule that cannot derive a target raises ClipError naming the clip, the
target and the reason. docs/motion_library.md lists the rules.
"""

import dataclasses

import numpy as np

from hrc_suite import layout
from hrc_suite.human import clip as clip_lib
from hrc_suite.human import keypoints
from hrc_suite.human import placement

_K = keypoints.KEYPOINT_INDEX
TABLE_EDGE_X = placement.TABLE_EDGE_CLEARANCE   # clip frame, m
TABLE_Z = layout.TABLE_TOP_Z
# The synthetic library's values (task_motions): palm above a cube's centre
# when gripping it, cube edge, hammer palm-to-face reach and face drop.
GRIP_ABOVE_CENTRE = 0.035
CUBE_SIZE = 0.05
HAMMER_REACH = 0.26
HAMMER_FACE_BELOW_PALM = 0.04
# Where an object is held up for inspection, from the head of the waiting
# person: the synthetic library's mean over its 8 clips (0.63 m ahead,
# 0.33 m below; a reading distance).
INSPECTION_FROM_HEAD = np.array([0.63, 0.0, -0.33])
# How far onto the table (m) a point the robot brings an object to lies at
# least: the synthetic library's nearest inspection point is 0.33 m on.
OVER_TABLE = 0.3
# Stacking: a hand sets its cube down at its lowest point within this time
# of its farthest reach (the reference's recordings: 0.25-0.75 s); a pick is
# at least this far from the place (two cube sizes).
PLACE_SEARCH_S = 1.0
PICK_DISTANCE = 2 * CUBE_SIZE
# Blows of a hammering hand: its lowest points at least this far apart (s).
MIN_BLOW_PERIOD = 0.3
# A hammering hand moves down at least this fast in a blow (m/s): the
# synthetic strikes reach 2.5-3.7 m/s; the reference's recordings never
# strike (its robot hammers): their hands move down at most 0.27 m/s
# (docs/tasks.md, hammering/default). Slower clips are refused for
# hammering/default.
MIN_BLOW_SPEED = 1.0


def _fail(source, target, reason):
  raise clip_lib.ClipError(f'{source}: cannot derive {target!r}: {reason}')


def _hand(positions, side):
  return positions[:, _K[f'{side}_hand']]


def _window(fields, first, last, num_frames):
  keys = fields['keyframes']
  start = keys[first] if first is not None else 0
  end = keys[last] if last is not None else num_frames - 1
  return int(start), int(end)


def _holding_hand(fields, source, target):
  hand = fields.get('holding_hand')
  if hand not in clip_lib.HANDS:
    _fail(source, target, f'the clip names no holding hand (got {hand!r}; '
          f'the info file\'s object_holding_hand)')
  return hand


def _handover_robot_to_human(positions, fps, fields, source):
  del fps
  hand = _holding_hand(fields, source, 'handover_point')
  phase = fields['idle_phases'][0]
  frame = fields['keyframes'][phase.keyframe]
  return fields, {'handover_point': _hand(positions, hand)[frame]}


def _handover_human_to_robot(positions, fps, fields, source):
  """The person brings the object in hand: the pick keyframe is the first
  frame, where the holding hand is ('object_pick'); the presentation is
  the first idle phase's keyframe."""
  del fps
  hand = _holding_hand(fields, source, 'object_pick')
  keys = tuple(sorted(set(fields['keyframes']) | {0}))
  shift = len(keys) - len(fields['keyframes'])
  phases = tuple(dataclasses.replace(p, keyframe=p.keyframe + shift)
                 for p in fields['idle_phases'])
  present = keys[phases[0].keyframe]
  fields = dict(fields, keyframes=keys, idle_phases=phases)
  return fields, {'object_pick': _hand(positions, hand)[0],
                  'handover_point': _hand(positions, hand)[present]}


def _inspection(positions, fps, fields, source):
  """INSPECTION_FROM_HEAD from the head at the wait's keyframe, and at
  least OVER_TABLE onto the table: a person waiting further back (some
  recordings wait before their last step in) is shown the object where the
  robot can bring it."""
  del fps, source
  frame = fields['keyframes'][fields['idle_phases'][0].keyframe]
  point = positions[frame, _K['head']] + INSPECTION_FROM_HEAD
  point[0] = max(point[0], TABLE_EDGE_X + OVER_TABLE)
  return fields, {'inspection_point': point}


def _lifting(positions, fps, fields, source):
  """The reference's person holds the board for the whole recording: grasp
  at the first frame, put down at the last; grasps where the hands are at
  the first frame."""
  del fps
  if fields['keyframes']:
    first, last = fields['keyframes'][0], fields['keyframes'][-1]
  else:
    first, last = 0, len(positions) - 1
  if last <= first:
    _fail(source, 'keyframes', f'grasp and put-down frames {first}, {last} '
          f'are not in order')
  left, right = _hand(positions, 'left')[first], _hand(positions, 'right')[
      first]
  if left[1] <= right[1]:
    _fail(source, 'board_grasp_left', f'the left hand ({left.round(3)}) is '
          f'not left of the right hand ({right.round(3)}) at the grasp')
  fields = dict(fields, keyframes=(int(first), int(last)))
  return fields, {'board_grasp_left': left, 'board_grasp_right': right}


def _blow_points(z, fps):
  """Frames of a hand's lowest points, MIN_BLOW_PERIOD apart."""
  order = max(1, int(round(MIN_BLOW_PERIOD * fps / 2)))
  frames = [i for i in range(len(z))
            if z[i] <= z[max(0, i - order):i + order + 1].min()]
  return np.array(frames, dtype=int)


def _hammering(positions, fps, fields, source):
  """The striking hand's lowest points while the person hammers (between
  the first and last keyframe): 'strike_grip' their median, the nail
  HAMMER_REACH ahead of it along the facing and HAMMER_FACE_BELOW_PALM
  lower. The striking hand moves most up and down there. The reference's
  recordings hold no blows (its robot hammers): there the rule finds the
  hand resting on the board (docs/tasks.md, hammering/default)."""
  start, end = _window(fields, 0, -1, len(positions))
  sides = clip_lib.HANDS
  vertical = [np.std(_hand(positions, s)[start:end + 1, 2]) for s in sides]
  hand = fields.get('holding_hand') or sides[int(np.argmax(vertical))]
  z = _hand(positions, hand)[start:end + 1, 2]
  down = float(-np.min(np.diff(z), initial=0.0) * fps)
  if down < MIN_BLOW_SPEED:
    _fail(source, 'strike_grip', f'the person never strikes: the {hand} hand '
          f'moves down at most {down:.2f} m/s between frames {start} and '
          f'{end} (a blow: >= {MIN_BLOW_SPEED} m/s). The reference\'s '
          'hammering recordings have the robot hammer and the person bring '
          'the board: use hammering/robot_hammers')
  blows = _blow_points(z, fps)
  if len(blows) == 0:
    _fail(source, 'strike_grip', f'the {hand} hand has no lowest point '
          f'between frames {start} and {end}')
  grip = np.median(_hand(positions, hand)[start + blows], axis=0)
  nail = grip + [HAMMER_REACH, 0.0, -HAMMER_FACE_BELOW_PALM]
  fields = dict(fields, holding_hand=hand)
  return fields, {'strike_grip': grip, 'nail': nail}


def _hammering_board(positions, fps, fields, source):
  """hammering/robot_hammers: the person sets the board down at the first
  keyframe and takes it back at the last. Its handle lies under the hand
  farther over the table then (the other hand, at the hip in the
  reference's recordings, has let go): 'board_place' is that hand's point
  on the table top."""
  del fps
  keys = fields['keyframes']
  if len(keys) < 2:
    _fail(source, 'board_place', f'needs set-down and take-back keyframes, '
          f'the clip has {list(keys)}')
  frame = int(keys[0])
  hand = fields.get('holding_hand') or max(
      clip_lib.HANDS, key=lambda s: _hand(positions, s)[frame, 0])
  point = _hand(positions, hand)[frame]
  if point[0] <= TABLE_EDGE_X:
    _fail(source, 'board_place', f'the {hand} hand is at x = {point[0]:.2f} '
          f'm at the set-down frame {frame}, not over the table (edge at '
          f'{TABLE_EDGE_X:.2f} m)')
  fields = dict(fields, holding_hand=hand)
  return fields, {'board_place': np.array([point[0], point[1], TABLE_Z])}


def _placing_frame(positions, hand, start, end, search):
  """Frame where `hand` sets a cube down in [start, end]: its lowest point
  over the table within `search` frames of where it reaches farthest forward
  (the hand goes down onto the stack and back up; the farthest point may
  lie on the way back)."""
  path = _hand(positions, hand)
  farthest = start + int(np.argmax(path[start:end + 1, 0]))
  lo, hi = max(start, farthest - search), min(end, farthest + search)
  frames = lo + np.flatnonzero(path[lo:hi + 1, 0] > TABLE_EDGE_X + CUBE_SIZE)
  if len(frames) == 0:
    return farthest
  return int(frames[np.argmin(path[frames, 2])])


def _pick(positions, hand, start, place_frame, table_level):
  """Where `hand` picks its cube before `place_frame`: its lowest point
  over the table at least PICK_DISTANCE from the place and no higher than
  `table_level` + CUBE_SIZE / 2 (a cube lifted off the table). None when
  there is none: the person brought the cube in hand (the reference's
  recordings; its environment welds both cubes to the hands at reset)."""
  path = _hand(positions, hand)[start:place_frame + 1]
  place = _hand(positions, hand)[place_frame]
  candidates = np.flatnonzero(
      (path[:, 0] > TABLE_EDGE_X + CUBE_SIZE)
      & (np.linalg.norm(path[:, :2] - place[:2], axis=1) >= PICK_DISTANCE)
      & (path[:, 2] <= table_level + CUBE_SIZE / 2))
  if len(candidates) == 0:
    return None
  lowest = path[candidates[np.argmin(path[candidates, 2])]]
  return np.array([lowest[0], lowest[1], TABLE_Z + CUBE_SIZE / 2])


def _stacking(positions, fps, fields, source):
  """Cube 1 is set down by the first placing hand (keyframes 0 to 2), cube
  3 by the hand that reaches farthest between keyframes 2 and 4, each
  where that hand is lowest near its farthest reach (`_placing_frame`). A
  cube is picked where its hand goes down to the table before placing it
  (`_pick`), or, where it never does, is carried in: its pick is where the
  hand holds it at the first frame (the task then starts it in hand)."""
  first = fields.get('placing_hand')
  if first not in clip_lib.HANDS:
    _fail(source, 'cube_1_place', f'the clip names no first placing hand '
          f'(got {first!r}; the info file\'s first_placing_hand)')
  targets = {}
  windows = ((1, _window(fields, 0, 2, len(positions)), [first]),
             (3, _window(fields, 2, 4, len(positions)), clip_lib.HANDS))
  search = int(round(PLACE_SEARCH_S * fps))
  table_level, picks_from = None, 0
  for cube, (start, end), hands in windows:
    hand = max(hands, key=lambda h: _hand(positions, h)[start:end + 1, 0]
               .max())
    frame = _placing_frame(positions, hand, start, end, search)
    place = _hand(positions, hand)[frame] - [0, 0, GRIP_ABOVE_CENTRE]
    if place[0] <= TABLE_EDGE_X:
      _fail(source, f'cube_{cube}_place', f'the {hand} hand reaches at most '
            f'x = {place[0]:.2f} m between frames {start} and {end}, not '
            f'over the table (edge at {TABLE_EDGE_X:.2f} m)')
    if table_level is None:   # Cube 1 is set down on the table.
      table_level = _hand(positions, hand)[frame, 2]
    pick = _pick(positions, hand, picks_from, frame, table_level)
    picks_from = frame
    if pick is None:
      pick = _hand(positions, hand)[0] - [0, 0, GRIP_ABOVE_CENTRE]
    targets[f'cube_{cube}_pick'] = pick
    targets[f'cube_{cube}_place'] = place
  base = targets['cube_1_place']
  targets['stack_base'] = np.array([base[0], base[1], TABLE_Z])
  return fields, targets


def _no_targets(positions, fps, fields, source):
  del positions, fps, source
  return fields, {}


RULES = {
    'reach': _no_targets,
    'pick_place': _no_targets,
    'inspection': _inspection,
    'lifting': _lifting,
    'handover_robot_to_human': _handover_robot_to_human,
    'handover_human_to_robot': _handover_human_to_robot,
    'hammering': _hammering,
    'hammering_board': _hammering_board,
    'stacking': _stacking,
    'other': _no_targets,
}


def derive(task, positions, fps, fields, source='<recording>'):
  """(fields, targets): the clip fields (keyframes, idle_phases,
  holding_hand, placing_hand) as the task reads them and its targets."""
  fields, targets = RULES[task](np.asarray(positions, np.float64), fps,
                                dict(fields), source)
  return fields, {k: np.round(np.asarray(v, np.float64), 4)
                  for k, v in targets.items()}
