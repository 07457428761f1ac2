"""Tests for the BVH parser, forward kinematics and import into clips."""

import numpy as np
import pytest

from hrc_suite.human import bvh
from hrc_suite.human import bvh_import
from hrc_suite.human import clip as clip_lib
from hrc_suite.human import keypoints
from hrc_suite.human import placement

I = keypoints.KEYPOINT_INDEX

CHAIN = """HIERARCHY
ROOT root
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT a
  {
    OFFSET 0 10 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    End Site
    {
      OFFSET 0 5 0
    }
  }
}
MOTION
Frames: 2
Frame Time: 0.5
1 2 3 0 0 0 0 0 0
0 0 0 90 0 0 0 90 0
"""


def two_rotation_file(order):
  first, second = order
  return f"""HIERARCHY
ROOT r
{{
  OFFSET 0 0 0
  CHANNELS 2 {first}rotation {second}rotation
  End Site
  {{
    OFFSET 1 0 0
  }}
}}
MOTION
Frames: 1
Frame Time: 0.01
90 90
"""


def test_chain_forward_kinematics():
  motion = bvh.parse(CHAIN)
  assert motion.skeleton.names == ('root', 'a', 'a_end')
  assert motion.skeleton.is_end_site.tolist() == [False, False, True]
  assert motion.num_frames == 2 and motion.fps == 2.0
  positions, rotations = bvh.forward_kinematics(motion)
  np.testing.assert_allclose(positions[0], [[1, 2, 3], [1, 12, 3], [1, 17, 3]],
                             atol=1e-12)
  # Root turned 90 deg about z, joint a 90 deg about x: the end site's bone
  # (0, 5, 0) turns into +z, the bone to a into -x.
  np.testing.assert_allclose(positions[1], [[0, 0, 0], [-10, 0, 0],
                                            [-10, 0, 5]], atol=1e-12)
  np.testing.assert_allclose(rotations[1, 1] @ rotations[1, 1].T, np.eye(3),
                             atol=1e-12)


# R is the product in channel order, applied to the end site's (1, 0, 0).
@pytest.mark.parametrize('order, expected', [
    ('XY', [0, 1, 0]),    # Rx(90) Ry(90): (1,0,0) -> (0,0,-1) -> (0,1,0)
    ('YX', [0, 0, -1]),   # Ry(90) Rx(90): (1,0,0) -> (1,0,0) -> (0,0,-1)
    ('ZX', [0, 1, 0]),    # Rz(90) Rx(90): (1,0,0) -> (1,0,0) -> (0,1,0)
    ('XZ', [0, 0, 1]),    # Rx(90) Rz(90): (1,0,0) -> (0,1,0) -> (0,0,1)
])
def test_rotation_channel_order(order, expected):
  positions, _ = bvh.forward_kinematics(bvh.parse(two_rotation_file(order)))
  np.testing.assert_allclose(positions[0, 1], expected, atol=1e-12)


def test_extrinsic_composition_reverses_the_product():
  for order in ('XY', 'ZX'):
    extrinsic, _ = bvh.forward_kinematics(
        bvh.parse(two_rotation_file(order)), composition='extrinsic')
    reversed_order, _ = bvh.forward_kinematics(
        bvh.parse(two_rotation_file(order[::-1])))
    np.testing.assert_allclose(extrinsic, reversed_order, atol=1e-12)
  with pytest.raises(ValueError, match='composition'):
    bvh.forward_kinematics(bvh.parse(CHAIN), composition='sideways')


def test_relabel_channels():
  motion = bvh.relabel_channels(bvh.parse(two_rotation_file('XY')),
                                {'r': ('Yrotation', 'Xrotation')})
  relabelled, _ = bvh.forward_kinematics(motion)
  np.testing.assert_allclose(relabelled[0, 1], [0, 0, -1], atol=1e-12)
  with pytest.raises(ValueError, match='has 2 channels'):
    bvh.relabel_channels(motion, {'r': ('Xrotation',)})
  with pytest.raises(ValueError, match='Bad channel names'):
    bvh.relabel_channels(motion, {'r': ('Xrotation', 'Xrotation')})
  with pytest.raises(KeyError, match='Unknown BVH joint'):
    bvh.relabel_channels(motion, {'q': ('Xrotation', 'Yrotation')})


def test_position_channels_in_any_order_and_six_channel_joint():
  text = """HIERARCHY
ROOT r
{
  OFFSET 0.5 0 0
  CHANNELS 3 Zposition Xposition Yposition
  JOINT free
  {
    OFFSET 0 1 0
    CHANNELS 6 Yrotation Zposition Xposition Yposition Xrotation Zrotation
    End Site
    {
      OFFSET 0 0 2
    }
  }
}
MOTION
Frames: 1
Frame Time: 0.04
3 1 2 90 0.1 0.2 0.3 0 0
"""
  motion = bvh.parse(text)
  assert motion.skeleton.channels[1][0] == 'Yrotation'
  positions, _ = bvh.forward_kinematics(motion)
  # Root: offset + (1, 2, 3); joint: offset + (0.2, 0.3, 0.1) translation.
  np.testing.assert_allclose(positions[0, 0], [1.5, 2, 3])
  np.testing.assert_allclose(positions[0, 1], [1.7, 3.3, 3.1])
  # Ry(90) turns the end site's (0, 0, 2) into (2, 0, 0).
  np.testing.assert_allclose(positions[0, 2], [3.7, 3.3, 3.1], atol=1e-12)


def stick_figure(unit_scale, frames=2, legs=False):
  """A standing T-pose person (1.75 m) in the given file unit per metre."""
  s = unit_scale

  def off(x, y, z):
    return f'{x * s:g} {y * s:g} {z * s:g}'

  def arm(side, sign):
    return f"""  JOINT {side}_collar
  {{
    OFFSET {off(0, 0.45, 0)}
    CHANNELS 3 Zrotation Xrotation Yrotation
    JOINT {side}_upper_arm
    {{
      OFFSET {off(sign * 0.18, 0, 0)}
      CHANNELS 3 Zrotation Xrotation Yrotation
      JOINT {side}_forearm
      {{
        OFFSET {off(sign * 0.3, 0, 0)}
        CHANNELS 3 Zrotation Xrotation Yrotation
        JOINT {side}_hand
        {{
          OFFSET {off(sign * 0.26, 0, 0)}
          CHANNELS 3 Zrotation Xrotation Yrotation
          End Site
          {{
            OFFSET 0 0 0
          }}
        }}
      }}
    }}
  }}
"""
  def leg(side, sign):
    return f"""  JOINT {side}_thigh
  {{
    OFFSET {off(sign * 0.09, -0.1, 0)}
    CHANNELS 3 Zrotation Xrotation Yrotation
    JOINT {side}_shin
    {{
      OFFSET {off(0, -0.43, 0)}
      CHANNELS 3 Zrotation Xrotation Yrotation
      JOINT {side}_foot
      {{
        OFFSET {off(0, -0.43, 0)}
        CHANNELS 3 Zrotation Xrotation Yrotation
        End Site
        {{
          OFFSET {off(0, -0.07, -0.1)}
        }}
      }}
    }}
  }}
"""

  # Facing -z (Y up, right-handed): the person's left is -x; walks forward.
  header = f"""HIERARCHY
ROOT hip
{{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation
  JOINT torso
  {{
    OFFSET 0 0 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    JOINT neck
    {{
      OFFSET {off(0, 0.45, 0)}
      CHANNELS 3 Zrotation Xrotation Yrotation
      JOINT head
      {{
        OFFSET {off(0, 0.2, -0.02)}
        CHANNELS 3 Zrotation Xrotation Yrotation
        End Site
        {{
          OFFSET 0 0 0
        }}
      }}
    }}
{arm('left', -1)}{arm('right', 1)}  }}
{(leg('left', -1) + leg('right', 1)) if legs else ''}}}
MOTION
Frames: {frames}
Frame Time: 0.01
"""
  rows = []
  for f in range(frames):
    values = np.zeros(57 if legs else 39)
    values[:3] = [0.3 * s, 1.0 * s, (0.5 - 0.001 * f) * s]
    values[36] = 10.0 * f / max(frames - 1, 1)   # right wrist bends.
    rows.append(' '.join(f'{v:g}' for v in values))
  return header + '\n'.join(rows) + '\n'


@pytest.mark.parametrize('units, per_metre', [('mm', 1000), ('cm', 100),
                                               ('m', 1)])
def test_units_given_and_detected(units, per_metre):
  motion = bvh.parse(stick_figure(per_metre))
  assert bvh.detect_scale(motion.skeleton) == bvh.UNITS[units]
  given, _ = bvh.forward_kinematics(motion, bvh.unit_scale(units,
                                                           motion.skeleton))
  reference, _ = bvh.forward_kinematics(bvh.parse(stick_figure(1)))
  np.testing.assert_allclose(given, reference, atol=1e-9)
  with pytest.raises(ValueError, match='furlong'):
    bvh.unit_scale('furlong', motion.skeleton)


def test_detection_refuses_unhuman_sizes():
  with pytest.raises(bvh.BvhError, match='units'):
    bvh.detect_scale(bvh.parse(stick_figure(1e5)).skeleton)


def test_y_up_becomes_z_up_right_handed():
  points = bvh.to_z_up(np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0],
                                 [0.0, 0.0, 1.0]]))
  np.testing.assert_allclose(points, [[0, 0, 1], [1, 0, 0], [0, -1, 0]])
  assert np.isclose(np.linalg.det(bvh.Y_UP_TO_Z_UP), 1.0)


def numbered(text):
  return {n: line for n, line in enumerate(text.splitlines(), 1)}


@pytest.mark.parametrize('old, new, line, words', [
    ('OFFSET 0 10 0', 'OFFSET 0 ten 0', 8, 'OFFSET value'),
    ('CHANNELS 3 Zrotation Xrotation Yrotation',
     'CHANNELS 3 Zrotation Wrotation Yrotation', 9, 'channel name'),
    ('CHANNELS 3 Zrotation Xrotation Yrotation',
     'CHANNELS 3 Zrotation Zrotation Yrotation', 9, 'repeated'),
    ('  JOINT a', '  JIONT a', 6, "JOINT, End Site or '}'"),
    ('1 2 3 0 0 0 0 0 0', '1 2 3 0 0 0 0 0', 19, 'expected 9 channel values'),
    ('0 0 0 90 0 0 0 90 0', '0 0 0 90 0 x 0 90 0', 20, 'expected numbers'),
    ('Frames: 2', 'Frames: 3', 20, 'expected 3 frames'),
    ('Frame Time: 0.5', 'Frame Time: -1', 18, 'positive Frame Time'),
    ('Frames: 2', 'Frames 2', 17, "'Frames:'"),
    ('MOTION', 'MOTIONS', 20, 'MOTION section'),
])
def test_malformed_files_name_the_line(old, new, line, words):
  assert old in CHAIN
  text = CHAIN.replace(old, new, 1)
  with pytest.raises(bvh.BvhError) as info:
    bvh.parse(text, source='bad.bvh')
  message = str(info.value)
  assert message.startswith(f'bad.bvh: line {line}:'), message
  assert words in message


def test_unclosed_hierarchy_and_missing_offset():
  text = CHAIN.replace('    }\n  }\n}\nMOTION', '    }\n  }\nMOTION')
  with pytest.raises(bvh.BvhError,
                     match='line 14: expected JOINT, End Site.*end of hier'):
    bvh.parse(text)
  with pytest.raises(bvh.BvhError, match=r"line 4: expected 'OFFSET'"):
    bvh.parse(CHAIN.replace('  OFFSET 0 0 0\n', '', 1))


def test_load_reports_missing_file(tmp_path):
  with pytest.raises(bvh.BvhError, match='cannot read'):
    bvh.load(tmp_path / 'none.bvh')


def test_mapping_errors_list_the_skeleton():
  motion = bvh.parse(CHAIN)
  with pytest.raises(bvh.BvhError, match="joint 'hip'.*has root, a, a_end"):
    bvh_import.import_motion(motion)
  mapping = bvh_import.SkeletonMapping('mine', {'pelvis': 'root'})
  with pytest.raises(bvh.BvhError, match="'mine' lacks keypoints.*'torso'"):
    bvh_import.import_motion(motion, mapping)
  points = {k: 'a' for k in keypoints.KEYPOINT_NAMES}
  points['head'] = 'nose'
  with pytest.raises(bvh.BvhError, match="needs joint 'nose' for 'head'"):
    bvh_import.import_motion(motion, bvh_import.SkeletonMapping('m', points))


def test_import_stick_figure_into_clip_frame():
  motion = bvh.parse(stick_figure(1000, frames=60))
  positions, facts = bvh_import.import_motion(motion)
  body = bvh_import.Anthropometrics()
  assert positions.shape == (60, keypoints.NUM_KEYPOINTS, 3)
  # Facing +z in the file becomes facing +x; left (-x in the file) is +y.
  assert positions[0, I['left_shoulder'], 1] > positions[0, I['right_shoulder'],
                                                         1]
  np.testing.assert_allclose(positions[0, I['left_shoulder'], 0],
                             positions[0, I['right_shoulder'], 0], atol=1e-9)
  assert abs(facts['facing_yaw_deg']) == pytest.approx(90.0)
  # Pelvis starts above the origin; straight legs reach the floor.
  window = round(bvh_import.FACING_WINDOW_S * motion.fps)
  np.testing.assert_allclose(positions[:window, I['pelvis'], :2].mean(0), 0,
                             atol=1e-9)
  assert positions[-1, I['pelvis'], 0] > positions[0, I['pelvis'], 0]
  standing = body.hip_drop + body.thigh_length + body.shin_length + (
      body.ankle_height)
  assert positions[:, I['pelvis'], 2].max() == pytest.approx(standing)
  np.testing.assert_allclose(positions[:, I['left_ankle'], 2],
                             body.ankle_height, atol=1e-9)
  # The hand keypoint extends the forearm by the hand length, whatever the
  # (meaningless) rotation of the wrist joint, which bends the right one.
  for side, sign in (('left', 1), ('right', -1)):
    hand = positions[:, I[f'{side}_hand']] - positions[:, I[f'{side}_wrist']]
    np.testing.assert_allclose(hand, [[0, sign * body.hand_length, 0]] * 60,
                               atol=1e-9)
  # Torso and chest sit a third and two thirds up the spine.
  np.testing.assert_allclose(
      positions[:, I['chest']] - positions[:, I['pelvis']],
      2 * (positions[:, I['torso']] - positions[:, I['pelvis']]), atol=1e-9)


def test_mapped_legs_set_the_floor():
  motion = bvh.parse(stick_figure(100, frames=60, legs=True))
  legs = {f'{side}_{part}': f'{side}_{joint}' for side in ('left', 'right')
          for part, joint in (('hip', 'thigh'), ('knee', 'shin'),
                              ('ankle', 'foot'))}
  mapping = bvh_import.SkeletonMapping(
      'full body', {**bvh_import.RECORDINGS_MAPPING.points, **legs})
  assert mapping.has_legs
  positions, facts = bvh_import.import_motion(motion, mapping)
  body = bvh_import.Anthropometrics()
  assert facts['legs'] == 'mapped'
  np.testing.assert_allclose(positions[:, I['left_ankle'], 2],
                             body.ankle_height, atol=1e-9)
  np.testing.assert_allclose(
      positions[:, I['pelvis'], 2] - positions[:, I['left_hip'], 2], 0.1,
      atol=1e-9)
  assert positions[0, I['left_hip'], 1] == pytest.approx(0.09)
  partial = bvh_import.SkeletonMapping(
      'half legs', {**bvh_import.RECORDINGS_MAPPING.points,
                    'left_hip': 'left_thigh'})
  with pytest.raises(bvh.BvhError, match="lacks keypoints.*'left_knee'"):
    bvh_import.import_motion(motion, partial)


def test_synthesised_knees_bend_forward_when_the_pelvis_drops():
  body = bvh_import.Anthropometrics()
  standing = body.hip_drop + body.thigh_length + body.shin_length + (
      body.ankle_height)
  pelvis = np.array([[0.0, 0.0, standing], [0.0, 0.0, standing - 0.2]])
  lateral = np.array([[0.0, 1.0, 0.0], [0.0, 1.0, 0.0]])
  legs = bvh_import.synthesise_legs(pelvis, lateral, body)
  knee, hip, ankle = legs['left_knee'], legs['left_hip'], legs['left_ankle']
  np.testing.assert_allclose(np.linalg.norm(knee - hip, axis=1),
                             body.thigh_length)
  np.testing.assert_allclose(np.linalg.norm(ankle - knee, axis=1),
                             body.shin_length)
  assert knee[0, 0] == pytest.approx(0.0, abs=1e-6)
  assert knee[1, 0] > 0.1   # forward, the way the person faces (+x).
  np.testing.assert_allclose(ankle[:, 2], body.ankle_height)
  np.testing.assert_allclose(hip[:, 1], body.hip_half_width)


def test_info_list_and_dict_become_idle_phases():
  info = {'keyframes': [350, 960], 'loop_amplitudes': {
      'present': [270, 0.7], 'wait': [10, 6.3, 2.4]},
          'loop_speeds': {'present': [1, 3.1], 'wait': [0.12, 0.07, 0.034]},
          'loop_amplitude_std_factor': 1.2, 'object_holding_hand': 'right'}
  fields = bvh_import.idle_phases_from_info(info, 100.0, 1500,
                                            'handover_human_to_robot')
  assert fields['keyframes'] == (350, 655, 960)
  present, wait = fields['idle_phases']
  assert (present.keyframe, present.event) == (1, 'object_taken')
  assert (wait.keyframe, wait.event) == (2, 'object_placed')
  np.testing.assert_allclose(present.amplitudes, [2.7, 0.007])
  np.testing.assert_allclose(wait.speeds, [0.12, 0.07, 0.034])
  assert present.amplitude_std_factor == 1.2 and present.speed_std_factor == 1.1
  assert fields['holding_hand'] == 'right'
  single = bvh_import.idle_phases_from_info(
      {'keyframes': [210, 1250], 'loop_amplitudes': [10, 4.1, 7.7],
       'loop_speeds': [0.15, 0.21, 0.0165]}, 100.0, 1500, 'inspection')
  (phase,) = single['idle_phases']
  assert single['keyframes'][phase.keyframe] == 210
  np.testing.assert_allclose(phase.amplitudes, [0.1, 0.041, 0.077])


@pytest.mark.parametrize('info, field', [
    ({'keyframes': [220, 400], 'loop_amplitudes': {'wait_for_second': [1, 2]},
      'loop_speeds': {'wait_for_second': [1, 2]}}, 'keyframes'),
    ({'keyframes': [100, 2000]}, 'keyframes'),
    ({'keyframes': [100, 200], 'loop_amplitudes': [1, 2],
      'loop_speeds': [1, 2, 3]}, 'loop_speeds'),
    ({'keyframes': [100, 200], 'loop_amplitudes': ['a', 2],
      'loop_speeds': [1, 2]}, 'loop_amplitudes'),
    ({'keyframes': [100, 200]}, 'loop_amplitudes'),
])
def test_bad_info_names_the_field(info, field):
  task = 'stacking' if 'wait_for_second' in str(info) else 'hammering'
  with pytest.raises(clip_lib.ClipError, match=f"x_info.json: field '{field}'"):
    bvh_import.idle_phases_from_info(info, 100.0, 1500, task, 'x_info.json')


def test_fast_phases_cover_fast_frames():
  positions = np.zeros((40, keypoints.NUM_KEYPOINTS, 3))
  positions[20:, 3, 0] = 0.1   # 10 m/s at 100 fps between frames 19 and 20.
  assert bvh_import.fast_phases(positions, 100.0) == ((17, 22),)


@pytest.mark.recordings
def test_real_recordings_import(recording_file):
  """One recording file (tests/conftest.py parametrizes recording_file)."""
  clip = bvh_import.import_clip(recording_file)
  p = clip.positions.astype(np.float64)
  for name, a, b in keypoints.SEGMENTS:
    length = np.linalg.norm(p[:, I[a]] - p[:, I[b]], axis=1)
    assert np.ptp(length) < 1e-5, (name, np.ptp(length))
  def length(a, b):
    return float(np.linalg.norm(p[0, I[a]] - p[0, I[b]]))
  for side in ('left', 'right'):
    assert 0.2 < length(f'{side}_shoulder', f'{side}_elbow') < 0.4
    assert 0.2 < length(f'{side}_elbow', f'{side}_wrist') < 0.35
  assert 0.2 < length('left_shoulder', 'right_shoulder') < 0.5
  assert 0.25 < length('pelvis', 'neck') < 0.7
  median = np.median(p[..., 2], axis=0)
  assert 1.45 < median[I['head']] < 1.95
  assert 0.85 < median[I['pelvis']] < 1.2
  assert median[I['neck']] > median[I['chest']] > median[I['pelvis']]
  body = bvh_import.Anthropometrics()
  assert p[..., 2].min() > 0.0   # nothing below the floor.
  assert p[:, I['left_ankle'], 2].min() >= body.ankle_height - 1e-5
  # The pelvis is at the station (the origin, human/placement.py) at the
  # anchor frame, or short of it, and never more than its lean allowance past
  # it; the person starts facing +x, within 45 degrees (the lab's axis
  # nearest to their first half second's facing): left shoulder to +y.
  pelvis = p[:, I['pelvis']]
  lean = placement.lean_allowance(clip.task)
  anchor = clip.metadata['import']['placement']['anchor_frame']
  if clip.task in bvh_import.REACH_TASKS:
    # The holding hand, not the pelvis, on the station's line.
    assert abs(p[anchor, I[f'{clip.holding_hand}_hand'], 1]) < 1e-5
  else:
    assert abs(pelvis[anchor, 1]) < 1e-5
  facts = clip.metadata['import']['placement']
  if 'task_frame' in facts:
    # Or moved until the task's point (bvh_import.task_point) lies in its
    # band, as far as the lean allows.
    low, high = (bvh_import.BOARD_REACH if clip.task == 'hammering_board'
                 else (bvh_import.HANDOVER_REACH, np.inf))
    x = p[facts['task_frame'], facts['task_keypoint'], 0]
    assert (abs(pelvis[anchor, 0]) < 1e-5 or abs(x - low) < 1e-5
            or abs(x - high) < 1e-5 or pelvis[:, 0].max() > lean - 1e-5)
    assert low - 1e-5 <= x <= high + 1e-5 or pelvis[:, 0].max() > lean - 1e-5
  else:
    assert pelvis[anchor, 0] < 1e-5
  assert pelvis[:, 0].max() <= lean + 1e-5
  assert (pelvis[anchor, 0] > -1e-5
          or pelvis[:, 0].max() > lean - 1e-5 or 'task_frame' in facts)
  window = slice(0, 50)
  lateral = (p[window, I['left_shoulder']] - p[window, I['right_shoulder']]
             ).mean(0)
  assert lateral[1] > 0.1 and abs(lateral[0]) < lateral[1]
  assert clip.task in clip_lib.MOTION_TASKS
  assert len(clip.idle_phases) == len(bvh_import.PHASE_RULES[clip.task])
  assert not len(clip_lib.speed_violations(clip))
