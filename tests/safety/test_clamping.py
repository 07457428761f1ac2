"""Clamping decisions (hrc_suite/safety/clamping.py) on hand-built
geometry: a hand on the table under a descending link, a hand in free air,
two links closing on a forearm."""

import numpy as np
import pytest

from hrc_suite import layout
from hrc_suite import robot_description
from hrc_suite.safety import clamping
from hrc_suite.safety import collision_prevention
from hrc_suite.safety import geometry

HAND_THICKNESS = 0.206      # shield_human_model.json, left_hand.
FOREARM_THICKNESS = 0.132   # left_forearm.
TOP = layout.TABLE_TOP_Z


def _robot(capsules):
  """One slice of robot reach capsules from [(p1, p2, r)]."""
  c1 = np.array([[c[0] for c in capsules]], dtype=float)
  c2 = np.array([[c[1] for c in capsules]], dtype=float)
  r = np.array([[c[2] for c in capsules]], dtype=float)
  return c1, c2, r


def _human(bodies):
  """One model, one slice of body capsules from [(p1, p2, r)]."""
  c1, c2, r = _robot(bodies)
  return c1[None], c2[None], r[None]


def _geometry(name, links, boxes=None):
  description = robot_description.load(name)
  if boxes is None:
    boxes = collision_prevention.workcell_boxes()
  return clamping.clamp_geometry(description, links, boxes)


def test_a_hand_on_the_table_under_a_descending_link_is_clamped():
  # The hand lies on the table (its capsule's radius, half its thickness
  # plus reach, reaches the top); the link's reach capsule comes down on it.
  hand = ((0.5, 0.0, TOP + 0.12), (0.6, 0.0, TOP + 0.12), 0.12)
  link = ((0.55, 0.0, TOP + 0.30), (0.55, 0.0, TOP + 0.60), 0.07)
  geometry_ = _geometry('panda', [5])
  contact, clamped = clamping.contacts_and_clamps(
      _robot([link]), _human([hand]), [HAND_THICKNESS], geometry_)
  assert contact[0, 0, 0, 0] and clamped[0, 0, 0, 0]
  # Without static boxes it is a transient contact.
  free = _geometry('panda', [5], boxes=())
  contact, clamped = clamping.contacts_and_clamps(
      _robot([link]), _human([hand]), [HAND_THICKNESS], free)
  assert contact[0, 0, 0, 0] and not clamped[0, 0, 0, 0]


def test_a_hand_in_free_air_is_not_clamped():
  # 0.6 m above the table: more than the hand's radius plus thickness.
  hand = ((0.5, 0.0, TOP + 0.6), (0.6, 0.0, TOP + 0.6), 0.12)
  link = ((0.55, 0.0, TOP + 0.75), (0.55, 0.0, TOP + 1.0), 0.07)
  gripper = ((0.55, 0.0, TOP + 0.75), (0.55, 0.1, TOP + 0.75), 0.05)
  # The gripper is on the link's frame: it moves with it, no clamp.
  geometry_ = _geometry('panda', [6, 6])
  contact, clamped = clamping.contacts_and_clamps(
      _robot([link, gripper]), _human([hand]), [HAND_THICKNESS], geometry_)
  assert contact[0, 0, 0, 0] and contact[0, 0, 1, 0]
  assert not clamped.any()
  # Lowered to within one thickness plus its radius of the table top, the
  # table counts (the link may push it there).
  low = ((0.5, 0.0, TOP + 0.3), (0.6, 0.0, TOP + 0.3), 0.12)
  assert geometry.point_box_distance(
      np.array(low[0]), *collision_prevention.workcell_boxes()['table']) < (
          0.12 + HAND_THICKNESS)
  _, clamped = clamping.contacts_and_clamps(
      _robot([((0.55, 0.0, TOP + 0.45), (0.55, 0.0, TOP + 0.8), 0.07)]),
      _human([low]), [HAND_THICKNESS], _geometry('panda', [6]))
  assert clamped[0, 0, 0, 0]


@pytest.mark.parametrize('name, clampable', [('panda', True),
                                             ('schunk', False)])
def test_two_links_closing_on_a_forearm_clamp_it(name, clampable):
  """Links 1 and 2 above and below a forearm in free air: clamped for a
  robot whose description lets them clamp (Panda), not for one that lists
  the pair unclampable (Schunk: [1, 2])."""
  forearm = ((0.4, -0.15, TOP + 0.7), (0.4, 0.15, TOP + 0.7), 0.09)
  above = ((0.3, 0.0, TOP + 0.85), (0.5, 0.0, TOP + 0.85), 0.07)
  below = ((0.3, 0.0, TOP + 0.55), (0.5, 0.0, TOP + 0.55), 0.07)
  geometry_ = _geometry(name, [1, 2])
  assert geometry_.clampable[0, 1] == clampable
  contact, clamped = clamping.contacts_and_clamps(
      _robot([above, below]), _human([forearm]), [FOREARM_THICKNESS],
      geometry_)
  assert contact[0, 0, :, 0].all()
  assert (clamped[0, 0, :, 0] == clampable).all()
  # Only one link near the forearm: nothing to clamp against.
  far = ((0.3, 0.0, TOP + 1.5), (0.5, 0.0, TOP + 1.5), 0.07)
  contact, clamped = clamping.contacts_and_clamps(
      _robot([above, far]), _human([forearm]), [FOREARM_THICKNESS],
      geometry_)
  assert contact[0, 0, 0, 0] and not contact[0, 0, 1, 0]
  assert not clamped.any()


def test_box_gap_is_a_lower_bound_of_the_exact_distance():
  rng = np.random.RandomState(0)
  start = rng.uniform(-2, 2, (500, 3))
  end = start + rng.normal(0, 0.5, (500, 3))
  low = np.array([-0.3, -0.5, -0.1])
  high = np.array([0.4, 0.2, 0.3])
  bound = clamping.box_gap(start, end, low, high)
  exact = geometry.segment_box_distance(start, end, low, high)
  assert (bound <= exact + 1e-12).all()
  # Exact for segments beside the box along one axis.
  above = np.array([[0.0, 0.0, 1.0], [0.1, -0.2, 0.8]])
  np.testing.assert_allclose(clamping.box_gap(above[:1], above[1:], low,
                                              high), 0.5, rtol=1e-14)


def test_segment_distance_equals_the_kernels_bits():
  from hrc_suite.safety import kernels  # pylint: disable=g-import-not-at-top
  rng = np.random.RandomState(1)
  points = rng.uniform(-1, 1, (300, 4, 3))
  points[::7, 1] = 0.0                  # Point segments.
  points[::5, 3] = points[::5, 1]       # Parallel segments.
  got = clamping.segment_distance(*(tuple(points[:, i, c] for c in range(3))
                                    for i in range(4)))
  expected = [kernels.segment_distance(*p[0], *p[2], *p[1], *p[3])
              for p in points]
  np.testing.assert_array_equal(got, expected)


def test_bad_geometry_is_named():
  description = robot_description.load('panda')
  with pytest.raises(ValueError, match=r'frame_index=\[7\]'):
    clamping.clamp_geometry(description, [7])
  with pytest.raises(ValueError, match=r'boxes\[0\]'):
    clamping.clamp_geometry(description, [0], [((1, 1, 1), (0, 0, 0))])
  geometry_ = clamping.clamp_geometry(description, [0, 1])
  with pytest.raises(ValueError, match='thickness'):
    clamping.contacts_and_clamps(_robot([((0, 0, 0), (1, 0, 0), 0.1)] * 2),
                                 _human([((0, 0, 0), (1, 0, 0), 0.1)]),
                                 [0.1, 0.2], geometry_)
