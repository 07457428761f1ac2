"""Tests for hrc_suite.safety.geometry (docs/shield_maths.md, 9.1, B3)."""

import numpy as np
import pytest

from hrc_suite.safety import geometry


def _brute_segment_distance(a0, a1, b0, b1, n=401):
  """Grid minimum over both parameters (an upper bound) and its bound."""
  s = np.linspace(0.0, 1.0, n)
  pa = a0 + s[:, None] * (a1 - a0)
  pb = b0 + s[:, None] * (b1 - b0)
  grid = np.linalg.norm(pa[:, None] - pb[None], axis=-1).min()
  slack = (np.linalg.norm(a1 - a0) + np.linalg.norm(b1 - b0)) / (n - 1)
  return grid, slack


def test_parallel_overlapping_segments_b3_case():
  a0, a1 = np.array([0.0, 0.0, 0.0]), np.array([2.0, 0.0, 0.0])
  b0, b1 = np.array([1.0, 1.0, 0.0]), np.array([3.0, 1.0, 0.0])
  assert geometry.segment_distance(a0, a1, b0, b1) == pytest.approx(1.0)
  # Reversed direction of one segment: still parallel and overlapping.
  assert geometry.segment_distance(a0, a1, b1, b0) == pytest.approx(1.0)
  assert geometry.capsule_distance(a0, a1, 0.5, b0, b1, 0.55) < 0.0
  assert geometry.capsule_distance(a0, a1, 0.5, b0, b1, 0.55) == (
      pytest.approx(-0.05))


@pytest.mark.parametrize('gap', [0.0, 0.3, 2.0])
def test_parallel_disjoint_and_collinear_segments(gap):
  a0, a1 = np.array([0.0, 0.0, 0.0]), np.array([1.0, 0.0, 0.0])
  b0, b1 = np.array([1.0 + gap, 0.5, 0.0]), np.array([4.0, 0.5, 0.0])
  assert geometry.segment_distance(a0, a1, b0, b1) == pytest.approx(
      np.hypot(gap, 0.5))
  # Collinear, overlapping and disjoint.
  c0, c1 = np.array([1.0 + gap, 0.0, 0.0]), np.array([5.0, 0.0, 0.0])
  assert geometry.segment_distance(a0, a1, c0, c1) == pytest.approx(gap)
  c0 = np.array([0.5 - gap, 0.0, 0.0])
  assert geometry.segment_distance(a0, a1, c1, c0) == pytest.approx(0.0)


def test_degenerate_segments():
  p = np.array([1.0, 2.0, 3.0])
  q = np.array([1.0, 2.0, 5.0])
  a0, a1 = np.array([0.0, 0.0, 0.0]), np.array([2.0, 0.0, 0.0])
  assert geometry.segment_distance(p, p, q, q) == pytest.approx(2.0)
  assert geometry.segment_distance(p, p, a0, a1) == pytest.approx(
      np.hypot(2.0, 3.0))
  assert geometry.segment_distance(a0, a1, p, p) == pytest.approx(
      np.hypot(2.0, 3.0))
  beyond = np.array([-3.0, 4.0, 0.0])
  assert geometry.segment_distance(a1, a0, beyond, beyond) == pytest.approx(
      5.0)
  # Two spheres touching are not intersecting (strict test).
  assert geometry.capsule_distance(p, p, 1.0, q, q, 1.0) == pytest.approx(0.0)
  assert not geometry.capsule_distance(p, p, 1.0, q, q, 1.0) < -1e-12


def test_random_segments_match_brute_force():
  rs = np.random.RandomState(1)
  cases = []
  for _ in range(150):
    a0, a1, b0, b1 = rs.uniform(-1, 1, (4, 3))
    cases.append((a0, a1, b0, b1))
  for _ in range(50):  # Exactly parallel, offset and shifted copies.
    a0, a1 = rs.uniform(-1, 1, (2, 3))
    shift = rs.uniform(-1, 1, 3)
    scale = rs.uniform(-2, 2)
    cases.append((a0, a1, a0 + shift, a0 + shift + scale * (a1 - a0)))
  for _ in range(30):  # Nearly parallel.
    a0, a1 = rs.uniform(-1, 1, (2, 3))
    shift = rs.uniform(-1, 1, 3)
    cases.append((a0, a1, a0 + shift, a1 + shift + 1e-9 * rs.randn(3)))
  stacked = [np.array(x) for x in zip(*cases)]
  got = geometry.segment_distance(*stacked)
  assert got.shape == (len(cases),)
  for k, case in enumerate(cases):
    grid, slack = _brute_segment_distance(*case)
    assert got[k] <= grid + 1e-9, (k, case)
    assert got[k] >= grid - slack - 1e-9, (k, case)
  # The closest points realise the distance.
  p, q = geometry.segment_closest_points(*stacked)
  np.testing.assert_allclose(np.linalg.norm(p - q, axis=-1), got, atol=1e-12)


def test_broadcasting_over_leading_axes():
  rs = np.random.RandomState(2)
  a0, a1 = rs.randn(2, 4, 1, 3)
  b0, b1 = rs.randn(2, 1, 5, 3)
  got = geometry.capsule_distance(a0, a1, 0.1, b0, b1, np.full((4, 5), 0.2))
  assert got.shape == (4, 5)
  for i in range(4):
    for j in range(5):
      assert got[i, j] == pytest.approx(geometry.segment_distance(
          a0[i, 0], a1[i, 0], b0[0, j], b1[0, j]) - 0.3)


def test_enclosing_ball_formula():
  centre, radius = geometry.enclosing_ball([0, 0, 0], 1.0, [3, 0, 0], 0.5)
  np.testing.assert_allclose(centre, [1.25, 0, 0])
  assert radius == pytest.approx(2.25)
  # Order does not matter.
  centre, radius = geometry.enclosing_ball([3, 0, 0], 0.5, [0, 0, 0], 1.0)
  np.testing.assert_allclose(centre, [1.25, 0, 0])
  assert radius == pytest.approx(2.25)
  # The larger ball already contains the smaller one.
  centre, radius = geometry.enclosing_ball([0, 0, 0], 1.0, [0.3, 0, 0], 0.5)
  np.testing.assert_allclose(centre, [0, 0, 0])
  assert radius == pytest.approx(1.0)
  # Equal balls at the same place.
  centre, radius = geometry.enclosing_ball([1, 1, 1], 0.2, [1, 1, 1], 0.2)
  np.testing.assert_allclose(centre, [1, 1, 1])
  assert radius == pytest.approx(0.2)


def test_enclosing_ball_contains_both_and_is_tight():
  rs = np.random.RandomState(3)
  c1, c2 = rs.randn(2, 200, 3)
  r1, r2 = rs.uniform(0, 1, (2, 200))
  centre, radius = geometry.enclosing_ball(c1, r1, c2, r2)
  far1 = np.linalg.norm(centre - c1, axis=-1) + r1
  far2 = np.linalg.norm(centre - c2, axis=-1) + r2
  assert np.all(far1 <= radius + 1e-12)
  assert np.all(far2 <= radius + 1e-12)
  # Tight: no ball smaller than half the hull's extent along the line.
  d = np.linalg.norm(c1 - c2, axis=-1)
  np.testing.assert_allclose(
      radius, np.maximum(np.maximum(r1, r2), 0.5 * (r1 + r2 + d)))


def test_segment_box_distance_matches_sampling():
  rs = np.random.RandomState(4)
  box_min = np.array([-0.5, -0.2, 0.0])
  box_max = np.array([0.5, 0.2, 0.1])
  a0, a1 = rs.uniform(-1.5, 1.5, (2, 300, 3))
  got = geometry.segment_box_distance(a0, a1, box_min, box_max)
  s = np.linspace(0, 1, 2001)
  pts = a0[:, None] + s[None, :, None] * (a1 - a0)[:, None]
  sampled = geometry.point_box_distance(pts, box_min, box_max).min(axis=1)
  slack = np.linalg.norm(a1 - a0, axis=-1) / 2000
  assert np.all(got <= sampled + 1e-9)
  assert np.all(got >= sampled - slack - 1e-9)
  # A segment through the box touches it.
  assert geometry.segment_box_distance(
      [-2, 0, 0.05], [2, 0, 0.05], box_min, box_max) == 0.0
  assert geometry.capsule_box_distance(
      [-2, 0, 0.3], [2, 0, 0.3], 0.25, box_min, box_max) == (
          pytest.approx(-0.05))


def test_segment_box_distance_special_cases():
  box_min, box_max = np.zeros(3), np.ones(3)
  # Axis-aligned segments (zero direction components), parallel to a face.
  assert geometry.segment_box_distance([-1, 2, 0.5], [2, 2, 0.5], box_min,
                                       box_max) == pytest.approx(1.0)
  assert geometry.segment_box_distance([2, 2, 2], [2, 2, 5], box_min,
                                       box_max) == pytest.approx(np.sqrt(3))
  # Passing a corner diagonally: closest approach inside the segment.
  assert geometry.segment_box_distance([3, 0, 1.5], [0, 3, 1.5], box_min,
                                       box_max) == pytest.approx(
                                           np.hypot(0.5, np.sqrt(0.5)))
  # Degenerate segment (a point), inside and outside.
  assert geometry.segment_box_distance([0.5] * 3, [0.5] * 3, box_min,
                                       box_max) == 0.0
  assert geometry.segment_box_distance([1, 1, 3], [1, 1, 3], box_min,
                                       box_max) == pytest.approx(2.0)
  # Broadcasting over boxes.
  got = geometry.segment_box_distance([-1, 0.5, 0.5], [-0.5, 0.5, 0.5],
                                      [[0, 0, 0], [1, 0, 0]],
                                      [[1, 1, 1], [2, 1, 1]])
  np.testing.assert_allclose(got, [0.5, 1.5])


def test_capsule_contains_capsule():
  assert geometry.capsule_contains_capsule(
      [0, 0, 0], [1, 0, 0], 0.5, [0.2, 0.1, 0], [0.8, -0.1, 0], 0.3)
  assert not geometry.capsule_contains_capsule(
      [0, 0, 0], [1, 0, 0], 0.5, [0.2, 0.1, 0], [1.8, -0.1, 0], 0.3)
