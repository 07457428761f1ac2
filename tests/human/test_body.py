"""Tests for the parametric human body."""

import numpy as np
import pytest

from hrc_suite.human import body
from hrc_suite.human import keypoints


def _pose(b, num_frames, rs):
  standing = b.hip_height - 0.02
  zeros = np.zeros(num_frames)
  return body.Pose(
      pelvis=np.column_stack([rs.uniform(-0.5, 0.5, num_frames),
                              rs.uniform(-0.5, 0.5, num_frames),
                              np.full(num_frames, standing)]),
      yaw=rs.uniform(-3, 3, num_frames), lean=rs.uniform(0, 0.6, num_frames),
      side=rs.uniform(-0.2, 0.2, num_frames),
      twist=rs.uniform(-0.3, 0.3, num_frames), head_pitch=zeros,
      head_yaw=zeros, hands=rs.uniform(-1, 1.5, (num_frames, 2, 3)),
      swivel=rs.uniform(-1, 1, (num_frames, 2)),
      wrist_bend=rs.uniform(0, 1, (num_frames, 2)),
      ankles=rs.uniform(-1, 1, (num_frames, 2, 3)))


def test_sampled_bodies_lie_in_din_ranges():
  rs = np.random.RandomState(0)
  for _ in range(300):
    b = body.sample_body(rs)
    assert body.STATURE_RANGE[0] <= b.stature <= body.STATURE_RANGE[1]
    for name, length in b.segment_lengths().items():
      low, high = body.SEGMENT_RANGES[name]
      assert low <= length <= high, (name, length)


def test_hand_length_matches_din_hand_range():
  for stature in body.STATURE_RANGE:
    b = body.proportional_body(stature)
    hand_length = b.hand / body.PALM_FRACTION_OF_HAND
    assert (body.HAND_LENGTH_RANGE[0] - 0.005 <= hand_length
            <= body.HAND_LENGTH_RANGE[1] + 0.005)


def test_sampler_is_deterministic_and_varies():
  a = body.sample_body(np.random.RandomState(3))
  b = body.sample_body(np.random.RandomState(3))
  c = body.sample_body(np.random.RandomState(4))
  assert a == b
  assert a != c


def test_stature_outside_range_is_rejected():
  with pytest.raises(ValueError, match='2.5'):
    body.proportional_body(2.5)
  with pytest.raises(ValueError, match='sex'):
    body.sample_body(np.random.RandomState(0), sex='x')


def test_forward_kinematics_keeps_segment_lengths_for_any_pose():
  rs = np.random.RandomState(1)
  b = body.sample_body(rs)
  positions = body.forward_kinematics(b, _pose(b, 500, rs))
  lengths = body.segment_lengths(positions)
  expected = np.array(list(b.segment_lengths().values()))
  np.testing.assert_allclose(lengths, np.broadcast_to(expected, lengths.shape),
                             atol=1e-9)


def test_reachable_hand_targets_are_met_exactly():
  rs = np.random.RandomState(2)
  b = body.proportional_body(1.75)
  pose = _pose(b, 50, rs)
  pose.yaw[:] = 0.0
  pose.lean[:] = 0.0
  pose.side[:] = 0.0
  pose.twist[:] = 0.0
  pose.pelvis[:] = (0.0, 0.0, b.hip_height - 0.02)
  shoulders = body.shoulder_positions(b, pose)
  direction = rs.normal(size=(50, 2, 3))
  direction /= np.linalg.norm(direction, axis=-1, keepdims=True)
  pose.hands = shoulders + direction * rs.uniform(
      0.3, 0.75 * b.arm_reach, (50, 2, 1))
  positions = body.forward_kinematics(b, pose)
  hands = positions[:, keypoints.index(['left_hand', 'right_hand'])]
  np.testing.assert_allclose(hands, pose.hands, atol=1e-9)


def test_standing_body_is_upright_with_feet_on_the_floor():
  b = body.proportional_body(1.75)
  pose = _pose(b, 1, np.random.RandomState(0))
  pose.pelvis[:] = (0, 0, b.hip_height - 0.01)
  pose.yaw[:] = pose.lean[:] = pose.side[:] = pose.twist[:] = 0.0
  pose.ankles[:] = [[0, 0.08, b.ankle_height], [0, -0.08, b.ankle_height]]
  pose.hands[:] = [[0.05, 0.25, 0.8], [0.05, -0.25, 0.8]]
  p = body.forward_kinematics(b, pose)[0]
  k = keypoints.KEYPOINT_INDEX
  assert p[k['head'], 2] == pytest.approx(body.EYE_HEIGHT_FRACTION * 1.75,
                                          abs=0.03)
  assert p[k['left_ankle'], 2] == pytest.approx(b.ankle_height, abs=1e-6)
  assert p[k['left_shoulder'], 1] > 0 > p[k['right_shoulder'], 1]


def test_elbow_speed_stays_bounded_through_full_extension():
  # The hand target sweeps out beyond reach at constant speed; the soft
  # extension limit keeps the elbow from whipping at the singularity.
  b = body.proportional_body(1.75)
  num_frames = 400
  pose = _pose(b, num_frames, np.random.RandomState(0))
  pose.pelvis[:] = (0.0, 0.0, b.hip_height - 0.02)
  pose.yaw[:] = pose.lean[:] = pose.side[:] = pose.twist[:] = 0.0
  pose.swivel[:] = 0.0
  pose.wrist_bend[:] = 0.0
  shoulder = body.shoulder_positions(b, pose)[0, 1]
  distance = np.linspace(0.4, 1.0, num_frames) * b.arm_reach * 1.1
  direction = np.array([0.8, -0.36, -0.48])
  pose.hands[:, 1] = shoulder + distance[:, None] * direction
  pose.hands[:, 0] = shoulder * [1, -1, 1] + [0.1, 0, -0.5]
  positions = body.forward_kinematics(b, pose)
  dt = 0.01
  hand_speed = np.linalg.norm(np.diff(positions[:, keypoints.KEYPOINT_INDEX[
      'right_hand']], axis=0), axis=-1) / dt
  elbow_speed = np.linalg.norm(np.diff(positions[:, keypoints.KEYPOINT_INDEX[
      'right_elbow']], axis=0), axis=-1) / dt
  assert elbow_speed.max() < 2.0 * hand_speed.max()
