"""Tests for hrc_suite.safety.shield.verification (docs/shield_maths.md, 9)."""

import numpy as np
import pytest

from hrc_suite import robot_description
from hrc_suite.safety import geometry
from hrc_suite.safety.shield import verification


def _robot(capsules):
  """[(p1, p2, r)] per interval, one link each -> (K, 1, 3) arrays."""
  c1 = np.array([[c[0]] for c in capsules], dtype=float)
  c2 = np.array([[c[1]] for c in capsules], dtype=float)
  r = np.array([[c[2]] for c in capsules], dtype=float)
  return c1, c2, r


def _human(models):
  """models[m][k] = (p1, p2, r), one body -> (M, K, 1, 3) arrays."""
  c1 = np.array([[[c[0]] for c in model] for model in models], dtype=float)
  c2 = np.array([[[c[1]] for c in model] for model in models], dtype=float)
  r = np.array([[[c[2]] for c in model] for model in models], dtype=float)
  return c1, c2, r


FAR = ((5, 5, 5), (5, 5, 6), 0.1)


@pytest.mark.parametrize('exact', [True, False])
def test_parallel_overlapping_capsules_are_unsafe_b3(exact):
  robot = _robot([((0, 0, 0), (2, 0, 0), 0.5)])
  human = _human([[((1, 1, 0), (3, 1, 0), 0.55)]])
  safe, first, distance = verification.ssm_verdict(robot, human, exact)
  assert not safe and first == 0
  assert distance < 0
  if exact:
    assert distance == pytest.approx(-0.05)


@pytest.mark.parametrize('exact', [True, False])
def test_an_interval_is_safe_if_some_model_is_free(exact):
  robot = _robot([((0, 0, 0), (1, 0, 0), 0.1)] * 3)
  hit = ((0.5, 0.1, 0), (0.5, 1, 0), 0.05)
  touch = ((0.5, 0.2, 0), (0.5, 1, 0), 0.1)   # Distance exactly 0: safe.
  models = [[hit, FAR, hit], [FAR, hit, hit], [touch, touch, hit]]
  safe, first, distance = verification.ssm_verdict(robot, _human(models),
                                                   exact)
  assert not safe and first == 2
  # Drop the last interval: every interval has a free model.
  robot2 = tuple(x[:2] for x in robot)
  human2 = tuple(x[:, :2] for x in _human(models))
  safe, first, distance = verification.ssm_verdict(robot2, human2, exact)
  assert safe and first == -1
  assert distance >= 0.0
  if exact:
    # Best model per interval: FAR then FAR -> clearances, min over k.
    expected = min(
        geometry.capsule_distance(np.array(robot[0][0, 0]),
                                  np.array(robot[1][0, 0]), 0.1,
                                  np.array(FAR[0]), np.array(FAR[1]), 0.1),
        np.inf)
    assert distance == pytest.approx(expected)


def _random_capsules(rs, k, l, m, b, spread):
  robot = (rs.uniform(-spread, spread, (k, l, 3)),
           rs.uniform(-spread, spread, (k, l, 3)),
           rs.uniform(0.01, 0.2, (k, l)))
  human = (rs.uniform(-spread, spread, (m, k, b, 3)) + [0.8, 0, 0],
           rs.uniform(-spread, spread, (m, k, b, 3)) + [0.8, 0, 0],
           rs.uniform(0.01, 0.3, (m, k, b)))
  return robot, human


def _brute_clearances(robot, human):
  rc1, rc2, rr = robot
  hc1, hc2, hr = human
  d = geometry.capsule_distance(rc1[None, :, :, None], rc2[None, :, :, None],
                                rr[None, :, :, None], hc1[:, :, None],
                                hc2[:, :, None], hr[:, :, None])
  return d.min(axis=(2, 3))


def test_clearances_and_verdicts_match_brute_force():
  rs = np.random.RandomState(0)
  outcomes = set()
  for trial in range(60):
    spread = rs.uniform(0.2, 1.0)
    robot, human = _random_capsules(rs, 4, 8, 3, 13, spread)
    expected = _brute_clearances(robot, human)
    np.testing.assert_allclose(verification.clearances(robot, human),
                               expected, atol=1e-12)
    per_interval = expected.max(axis=0)
    safe = bool(np.all(per_interval >= 0))
    first = -1 if safe else int(np.argmax(per_interval < 0))
    got = verification.ssm_verdict(robot, human)
    assert got[:2] == (safe, first)
    assert got[2] == pytest.approx(per_interval.min())
    fast = verification.ssm_verdict(robot, human, exact_distance=False)
    assert fast[:2] == (safe, first)
    if safe:
      assert 0.0 <= fast[2] <= got[2] + 1e-12
    else:
      assert fast[2] < 0
    outcomes.add(safe)
  assert outcomes == {True, False}


def test_bad_shapes_are_rejected():
  robot = _robot([((0, 0, 0), (1, 0, 0), 0.1)] * 2)
  human = _human([[FAR, FAR, FAR]])
  with pytest.raises(ValueError, match='human capsules'):
    verification.ssm_verdict(robot, human)
  with pytest.raises(ValueError, match='robot capsules'):
    verification.ssm_verdict((robot[0], robot[1], robot[2][0]), human)


def test_within_joint_limits():
  description = robot_description.load('panda')
  limits = description.limits
  assert verification.within_joint_limits(description.q_home, description)
  q = limits.q_max.copy()
  assert verification.within_joint_limits(q, description)
  q[3] += 0.005
  assert not verification.within_joint_limits(q, description)
  assert verification.within_joint_limits(q, description, tolerance=0.01)
  assert not verification.within_joint_limits(limits.q_max, description,
                                              tolerance=-0.01)
  batch = np.stack([description.q_home, limits.q_min - 0.1])
  assert not verification.within_joint_limits(batch, description)
  with pytest.raises(ValueError, match='q'):
    verification.within_joint_limits(np.zeros(6), description)
