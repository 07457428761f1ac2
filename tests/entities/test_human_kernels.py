"""The compiled segment frames (human_kernels) against the NumPy reference
(human.segment_frames): bit for bit."""

import numpy as np

from hrc_suite.entities import human as human_lib
from hrc_suite.entities import human_kernels

SEGMENTS = 40
KEYPOINTS = 30


def _compiled(positions, proximal, distal, reference):
  middles = np.empty((len(proximal), 3))
  quaternions = np.empty((len(proximal), 4))
  human_kernels.segment_frames(positions, proximal, distal, reference,
                               middles, quaternions)
  return middles, quaternions


def test_kernel_matches_the_reference_bit_for_bit():
  rng = np.random.RandomState(0)
  for trial in range(200):
    positions = rng.normal(size=(KEYPOINTS, 3))
    proximal = rng.randint(0, KEYPOINTS, SEGMENTS)
    distal = rng.randint(0, KEYPOINTS, SEGMENTS)
    reference = rng.normal(size=(SEGMENTS, 3))
    reference *= rng.choice([1e-3, 1.0], (SEGMENTS, 1))
    # References along the segment (the fallback axis) and zero-length
    # segments along a vertical reference (the fallback's fallback).
    reference[:5] = positions[distal[:5]] - positions[proximal[:5]]
    distal[5:8] = proximal[5:8]
    reference[5:8] = (0.0, 0.0, 1.0)
    middles, _, quaternions = human_lib.segment_frames(
        positions, proximal, distal, reference)
    fast_middles, fast_quaternions = _compiled(positions, proximal, distal,
                                               reference)
    assert np.array_equal(fast_middles, middles), trial
    assert np.array_equal(fast_quaternions, quaternions), trial


def test_weak_and_degenerate_frames_are_covered():
  # The fallbacks of the test above are taken (the test can fail there).
  positions = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
  proximal, distal = np.array([0, 0]), np.array([1, 0])
  reference = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]])
  middles, _, quaternions = human_lib.segment_frames(
      positions, proximal, distal, reference)
  fast_middles, fast_quaternions = _compiled(positions, proximal, distal,
                                             reference)
  assert np.array_equal(fast_quaternions, quaternions)
  assert np.array_equal(fast_middles, middles)
  # Segment 0: x falls back to (-z_y, z_x, 0) = 0 -> (1, 0, 0): identity.
  np.testing.assert_allclose(quaternions[0], (1.0, 0.0, 0.0, 0.0))


def test_faster_than_decides_as_the_reference_at_its_threshold():
  rng = np.random.RandomState(1)
  dt = 0.004
  for _ in range(50):
    frames = rng.normal(size=(25, KEYPOINTS, 3)) * rng.uniform(0.001, 0.01)
    speeds = np.linalg.norm(np.diff(frames, axis=0), axis=-1) / dt
    v_max = speeds.max(axis=0)       # The reference: not faster.
    assert not np.any(speeds > v_max)
    assert not human_kernels.faster_than(frames, dt, v_max)
    # One ulp less for one keypoint: faster (the speeds agree to the bit).
    j = rng.randint(KEYPOINTS)
    v_max[j] = np.nextafter(v_max[j], 0.0)
    assert human_kernels.faster_than(frames, dt, v_max)
