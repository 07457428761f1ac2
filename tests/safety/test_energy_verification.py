"""Energy-based PFL verification
(hrc_suite/safety/shield/energy_verification.py)
by hand and its compiled twin (energy_check_kernels.py) bit for bit."""

import numpy as np
import pytest

from hrc_suite import layout
from hrc_suite import robot_description
from hrc_suite.safety import body_regions
from hrc_suite.safety import clamping
from hrc_suite.safety import collision_prevention
from hrc_suite.safety.shield import energy_verification as ev
from hrc_suite.safety.shield import human_reach

TOP = layout.TABLE_TOP_Z
HAND = 4 * 140 ** 2 / (2 * 75e3)      # E_T of hand/fingers, J (0.523).
FACE_CLAMPED = 65 ** 2 / (2 * 75e3)   # E_QS of the face, J (0.0282).


@pytest.fixture(scope='module')
def limits():
  return ev.energy_limits(
      human_reach.HumanModelConfig.load(human_reach.DEFAULT_MODEL_PATH))


def _one_hand_scene(limits, hand_z):
  """A link's reach capsule above the left hand (all other bodies far
  away), one slice, one model; the geometry of the Panda's link 5."""
  count_b = len(limits.bodies)
  hc1 = np.tile([5.0, 5.0, 5.0], (1, 1, count_b, 1))
  hc1[..., 2] += np.arange(count_b)   # Far from the robot and each other.
  hc2 = hc1 + (0.0, 0.1, 0.0)
  hr = np.full((1, 1, count_b), 0.1)
  hand = limits.bodies.index('left_hand')
  hc1[0, 0, hand] = (0.5, 0.0, hand_z)
  hc2[0, 0, hand] = (0.6, 0.0, hand_z)
  hr[0, 0, hand] = 0.12
  robot = (np.array([[[0.55, 0.0, hand_z + 0.18]]]),
           np.array([[[0.55, 0.0, hand_z + 0.5]]]), np.array([[0.07]]))
  geometry = clamping.clamp_geometry(robot_description.load('panda'), [4],
                                     collision_prevention.workcell_boxes())
  return robot, (hc1, hc2, hr), geometry


def test_limits_are_the_regions_times_the_margin(limits):
  table = body_regions.load()
  hand = limits.bodies.index('left_hand')
  assert limits.transient[hand] == pytest.approx(0.81 * HAND, rel=1e-12)
  assert limits.clamped[hand] == pytest.approx(0.81 * HAND / 4, rel=1e-12)
  assert limits.coasting == pytest.approx(0.81 * FACE_CLAMPED, rel=1e-12)
  assert limits.coasting == pytest.approx(
      0.81 * min(r.energy_clamped for r in table.regions.values()),
      rel=1e-12)
  assert limits.thickness[hand] == 0.206
  with pytest.raises(ValueError, match='margin=1.5'):
    ev.energy_limits(human_reach.HumanModelConfig.load(
        human_reach.DEFAULT_MODEL_PATH), margin=1.5)


@pytest.mark.parametrize('compiled', [False, True])
def test_a_link_of_one_joule_against_a_hand(limits, compiled):
  """E^nom = 1 J: at s_dot 0.5, 0.25 J <= 0.81 x 0.523 J: safe; at s_dot
  1, 1 J: unsafe. On the table (clamped, 0.81 x 0.131 J) 0.25 J is
  unsafe too."""
  robot, human, geometry = _one_hand_scene(limits, TOP + 0.6)
  window = np.ones((1, 7))
  for s_dot, first in ((0.5, -1), (1.0, 0)):
    energies = ev.slice_energies([s_dot], window, [4])
    assert energies[0, 0] == s_dot ** 2
    ratios = ev.energy_ratios(robot, human, energies, limits, geometry,
                              compiled=compiled)
    assert ratios[0, 0] == pytest.approx(s_dot ** 2 / (0.81 * HAND),
                                         rel=1e-12)
    assert ev.first_unsafe_slice(robot, human, energies, limits, geometry,
                                 compiled=compiled) == first
  robot, human, geometry = _one_hand_scene(limits, TOP + 0.12)
  energies = ev.slice_energies([0.5], window, [4])
  ratios = ev.energy_ratios(robot, human, energies, limits, geometry,
                            compiled=compiled)
  assert ratios[0, 0] == pytest.approx(0.25 / (0.81 * HAND / 4), rel=1e-12)
  assert ev.first_unsafe_slice(robot, human, energies, limits, geometry,
                               compiled=compiled) == 0
  # Slow enough for the clamped limit: safe again.
  energies = ev.slice_energies([0.3], window, [4])
  assert ev.first_unsafe_slice(robot, human, energies, limits, geometry,
                               compiled=compiled) == -1


def test_one_passing_model_makes_a_slice_safe(limits):
  robot, (hc1, hc2, hr), geometry = _one_hand_scene(limits, TOP + 0.6)
  far = hc1.copy(), hc2.copy(), hr.copy()
  far[0][..., 2] += 3.0
  far[1][..., 2] += 3.0
  human = tuple(np.concatenate([a, b]) for a, b in zip((hc1, hc2, hr), far))
  energies = ev.slice_energies([1.0], np.ones((1, 7)), [4])
  for compiled in (False, True):
    ratios = ev.energy_ratios(robot, human, energies, limits, geometry,
                              compiled=compiled)
    assert ratios[0, 0] > 1.0 and ratios[1, 0] == 0.0
    assert ev.first_unsafe_slice(robot, human, energies, limits, geometry,
                                 compiled=compiled) == -1


def test_coasting_after_the_failsafe(limits):
  assert ev.coasting_speed(0.01, limits) == 1.0
  s_dot = ev.coasting_speed(2.0, limits)
  assert s_dot == pytest.approx((0.81 * FACE_CLAMPED / 2.0) ** 0.5,
                                rel=1e-12)
  assert ev.coasting_safe(s_dot, 2.0, limits)
  assert not ev.coasting_safe(1.01 * s_dot, 2.0, limits)
  robot, human, geometry = _one_hand_scene(limits, TOP + 0.6)
  energies = ev.slice_energies([0.5], np.ones((1, 7)), [4])
  assert ev.verify(robot, human, energies, limits, geometry, s_dot,
                   2.0) == -1
  assert ev.verify(robot, human, energies, limits, geometry, 1.0, 2.0) == 1
  energies = ev.slice_energies([1.0], np.ones((1, 7)), [4])
  assert ev.verify(robot, human, energies, limits, geometry, s_dot,
                   2.0, compiled=False) == 0


def _random_case(rng, limits):
  count_k, count_l = rng.randint(1, 8), rng.randint(1, 9)
  count_m, count_b = rng.choice([1, 3]), len(limits.bodies)
  spread = rng.choice([0.5, 1.0, 2.0])
  rc1 = rng.uniform(-spread, spread, (count_k, count_l, 3))
  rc2 = rc1 + rng.normal(0, 0.3, rc1.shape)
  rr = rng.uniform(0.02, 0.2, (count_k, count_l))
  hc1 = rng.uniform(-spread, spread, (count_m, count_k, count_b, 3))
  hc2 = hc1 + rng.normal(0, 0.3, hc1.shape)
  hr = rng.uniform(0.02, 0.2, (count_m, count_k, count_b))
  kind = rng.randint(4)
  if kind == 1:
    hc2 = hc1.copy()                    # Ball bodies.
  elif kind == 2:
    rc2 = rc1.copy()                    # Ball capsules.
  elif kind == 3:                       # Bodies parallel to a capsule.
    hc2 = hc1 + (rc2 - rc1)[None, :, :1] * rng.uniform(-2, 2)
  boxes = []
  for _ in range(rng.randint(0, 4)):
    low = rng.uniform(-spread, spread, 3)
    boxes.append((low, low + rng.uniform(0.05, 1.0, 3)))
  links = rng.randint(0, 7, count_l)
  geometry = clamping.clamp_geometry(
      robot_description.load(rng.choice(['panda', 'schunk'])
                             if links.max() < 6 else 'panda'), links, boxes)
  energies = rng.uniform(0.0, 1.0, (count_k, count_l)) ** 2 * rng.choice(
      [0.1, 1.0, 3.0])
  return (rc1, rc2, rr), (hc1, hc2, hr), energies, geometry


def test_compiled_check_equals_the_reference_bit_for_bit(limits):
  rng = np.random.RandomState(5)
  verdicts, clamps = set(), 0
  for _ in range(300):
    robot, human, energies, geometry = _random_case(rng, limits)
    expected = ev.energy_ratios(robot, human, energies, limits, geometry)
    got = ev.energy_ratios(robot, human, energies, limits, geometry,
                           compiled=True)
    np.testing.assert_array_equal(got, expected)
    first = ev.first_unsafe(expected)
    assert ev.first_unsafe_slice(robot, human, energies, limits,
                                 geometry) == first
    assert ev.first_unsafe_slice(robot, human, energies, limits, geometry,
                                 compiled=False) == first
    # From a start slice on: the rows before it are not read.
    start = rng.randint(0, energies.shape[0] + 1)
    later = energies.copy()
    later[:start] = np.nan
    tail = ev.first_unsafe(expected[:, start:])
    tail = tail if tail < 0 else tail + start
    for compiled in (True, False):
      assert ev.first_unsafe_slice(robot, human, later, limits, geometry,
                                   compiled=compiled, start=start) == tail
    verdicts.add(first < 0)
    clamps += int(clamping.contacts_and_clamps(robot, human,
                                               limits.thickness,
                                               geometry)[1].any())
  assert verdicts == {True, False}   # Both outcomes were exercised,
  assert 30 < clamps < 270           # and clamped and free contacts.


def test_compiled_verdict_at_the_limits_equals_the_reference(limits):
  # The compiled verdict skips contacts whose ratios are both within the
  # limit before any geometry: energies at the allowed energies, a rounding
  # step either side, give the reference's verdict.
  rng = np.random.RandomState(11)
  tolerance = 1.0 + ev.RATIO_TOLERANCE
  verdicts = set()
  for _ in range(200):
    robot, human, energies, geometry = _random_case(rng, limits)
    allowed = np.where(rng.uniform(size=energies.shape) < 0.5,
                       limits.clamped[rng.randint(len(limits.bodies),
                                                  size=energies.shape)],
                       limits.transient[rng.randint(len(limits.bodies),
                                                    size=energies.shape)])
    energies = allowed * tolerance
    nudge = rng.randint(-1, 2, energies.shape)
    energies = np.where(nudge > 0, np.nextafter(energies, np.inf),
                        np.where(nudge < 0, np.nextafter(energies, 0.0),
                                 energies))
    expected = ev.first_unsafe(ev.energy_ratios(robot, human, energies,
                                                limits, geometry))
    start = rng.randint(0, energies.shape[0] + 1)
    tail = ev.first_unsafe_slice(robot, human, energies, limits, geometry,
                                 compiled=False, start=start)
    assert ev.first_unsafe_slice(robot, human, energies, limits,
                                 geometry) == expected
    assert ev.first_unsafe_slice(robot, human, energies, limits, geometry,
                                 start=start) == tail
    verdicts.add(expected < 0)
  assert verdicts == {True, False}


def test_bad_arguments_are_named(limits):
  robot, human, geometry = _one_hand_scene(limits, TOP + 0.6)
  with pytest.raises(ValueError, match=r'energies: expected \(1, 1\)'):
    ev.energy_ratios(robot, human, np.ones((2, 1)), limits, geometry)
  with pytest.raises(ValueError, match='human capsules'):
    ev.energy_ratios(robot, tuple(x[:, :, :3] for x in human[:2])
                     + (human[2],), np.ones((1, 1)), limits, geometry)
  with pytest.raises(ValueError, match='s_dot_max'):
    ev.slice_energies([0.5, 0.5], np.ones((1, 7)), [4])
  with pytest.raises(ValueError, match=r'start=2: expected a slice index'):
    ev.first_unsafe_slice(robot, human, np.ones((1, 1)), limits, geometry,
                          start=2)
