"""Tests for hrc_suite.safety.shield.human_reach (docs/shield_maths.md, 8,
10)."""

import dataclasses
import json

import numpy as np
import pytest

from hrc_suite.human import keypoints as keypoint_set
from hrc_suite.safety import geometry
from hrc_suite.safety.shield import human_reach

N = keypoint_set.NUM_KEYPOINTS


def _ball(centre, radius):
  return np.asarray(centre, dtype=float), float(radius)


def test_combined_model_hand_computed_cases():
  p = np.zeros((1, 3))
  v = np.array([[1.0, 0.0, 0.0]])
  vmax, amax = np.array([2.0]), np.array([10.0])
  # Short horizon (t < (V - v0) / A = 0.1): the acceleration ball.
  centre, core = human_reach.combined_balls(p, v, vmax, amax, [0.05])
  np.testing.assert_allclose(centre[0, 0], [0.05, 0, 0])
  assert core[0, 0] == pytest.approx(0.5 * 10 * 0.05 ** 2)
  # Long horizon (t > (V + v0) / A = 0.3): shift V v0 / A, radius
  # V t - V^2 / (2 A).
  centre, core = human_reach.combined_balls(p, v, vmax, amax, [0.5])
  np.testing.assert_allclose(centre[0, 0], [2.0 * 1.0 / 10.0, 0, 0])
  assert core[0, 0] == pytest.approx(2.0 * 0.5 - 4.0 / 20.0)
  # In between (t = 0.15): t_up = 0.1, t_m = t_dn = 0.15, by hand
  # core = 10 sqrt(0.0053125^2 + 0.01125^2), shift = 0.14375.
  centre, core = human_reach.combined_balls(p, v, vmax, amax, [0.15])
  np.testing.assert_allclose(centre[0, 0], [0.14375, 0, 0])
  assert core[0, 0] == pytest.approx(10 * np.hypot(0.0053125, 0.01125))
  # Faster than v_max: a constant-speed ball about the measured position.
  centre, core = human_reach.combined_balls(p, 3 * v, vmax, amax, [0.2])
  np.testing.assert_allclose(centre[0, 0], [0, 0, 0])
  assert core[0, 0] == pytest.approx(0.6)
  # At rest: centred, radius A t^2 / 2 until v_max is reached.
  centre, core = human_reach.combined_balls(p, 0 * v, vmax, amax, [0.1, 1.0])
  np.testing.assert_allclose(centre[:, 0], 0.0)
  np.testing.assert_allclose(core[:, 0], [0.05, 2.0 - 0.2])


def test_combined_model_contains_every_admissible_motion():
  """Bang-bang and random accelerations within (V, A) from (p, v0)."""
  rs = np.random.RandomState(0)
  vmax, amax = 2.0, 30.0
  h = 2e-4
  times = np.arange(1, 1501) * h
  for _ in range(40):
    v = rs.randn(3)
    v *= rs.uniform(0, vmax) / np.linalg.norm(v)
    v0 = v.copy()
    p = np.zeros(3)
    acc = rs.randn(3)
    path = []
    for i in range(len(times)):
      if i % rs.randint(20, 400) == 0:
        acc = rs.randn(3)
        acc *= amax / np.linalg.norm(acc)
      new_v = v + acc * h
      speed = np.linalg.norm(new_v)
      if speed > vmax:
        new_v *= vmax / speed
      p = p + 0.5 * (v + new_v) * h
      v = new_v
      path.append(p)
    centre, core = human_reach.combined_balls(
        np.zeros((1, 3)), v0[None], np.array([vmax]), np.array([amax]), times)
    dist = np.linalg.norm(np.array(path) - centre[:, 0], axis=-1)
    assert np.all(dist <= core[:, 0] + 1e-9)


def _simulate(rs, vmax, amax, duration, h=1e-3, v_start=None,
              straight=False):
  """Independent keypoints within (vmax, amax): positions (T, N, 3).

  straight: the extreme motion, full acceleration along a fixed direction
  starting at full speed the other way (reverses, then saturates).
  """
  count = int(round(duration / h)) + 1
  p = rs.uniform(-0.5, 0.5, (N, 3)) + [1.0, 0.0, 1.2]
  direction = rs.randn(N, 3)
  direction /= np.linalg.norm(direction, axis=-1, keepdims=True)
  if straight:
    v_start = -direction * vmax[:, None]
  v = rs.randn(N, 3) if v_start is None else v_start.copy()
  speed = np.linalg.norm(v, axis=-1, keepdims=True)
  v = np.where(speed > vmax[:, None], v * vmax[:, None] / speed, v)
  acc = np.zeros((N, 3))
  out = [p.copy()]
  for i in range(count - 1):
    if straight:
      acc = direction * amax[:, None]
    elif i % 25 == 0:
      acc = rs.randn(N, 3)
      acc *= (amax * rs.uniform(0.5, 1.0, N))[:, None] / np.linalg.norm(
          acc, axis=-1, keepdims=True)
    new_v = v + acc * h
    speed = np.linalg.norm(new_v, axis=-1, keepdims=True)
    new_v = np.where(speed > vmax[:, None], new_v * vmax[:, None] / speed,
                     new_v)
    p = p + 0.5 * (v + new_v) * h
    v = new_v
    out.append(p.copy())
  return np.array(out)


@pytest.mark.parametrize('combined', [True, False])
def test_reach_capsules_contain_the_real_bodies(combined):
  """Property: for motions within the speed/acceleration limits, every
  model's capsule of every interval contains every real body capsule at all
  times of the interval (finite-difference velocities, 4 ms sampling)."""
  config = human_reach.HumanModelConfig.load()
  rs = np.random.RandomState(1)
  h = 1e-3
  sample = 4  # Measurement every 4 ms.
  t_edges = np.linspace(0.0, 0.2, 11)
  for trial in range(4):
    positions = _simulate(rs, config.v_max, config.a_max, 0.45, h,
                          straight=trial % 2 == 1)
    reach = human_reach.HumanReach(config, use_combined_model=combined)
    checked = 0
    for i in range(0, 201, sample):
      reach.measure(positions[i], i * h)
      if i % 40 or i == 0:
        continue
      lag = rs.uniform(0.0, 0.004)  # The cycle may lag the measurement.
      c1, c2, r = reach.reach_capsules(i * h + lag, t_edges)
      assert c1.shape == (reach.num_models, 10, reach.num_bodies, 3)
      for k in range(10):
        # Simulated samples inside [t_k, t_k+1] (times relative to i h).
        start = i + int(np.ceil((lag + t_edges[k]) / h - 1e-9))
        stop = i + int(np.floor((lag + t_edges[k + 1]) / h + 1e-9))
        for j in range(start, stop + 1):
          p1, p2, pr = reach.body_capsules(positions[j])
          inside = geometry.capsule_contains_capsule(
              c1[:, k], c2[:, k], r[:, k], p1, p2, pr, tolerance=1e-9)
          assert inside.all(), (trial, i, k, j, np.argwhere(~inside))
          checked += 1
    assert checked > 100


def test_first_measurement_does_not_assume_rest():
  """L2: with one sample the velocity models are the VEL ball, which also
  holds for a keypoint already moving at v_max."""
  config = human_reach.HumanModelConfig.load()
  rs = np.random.RandomState(2)
  v_start = rs.randn(N, 3)
  v_start *= 2.0 / np.linalg.norm(v_start, axis=-1, keepdims=True)
  positions = _simulate(rs, config.v_max, config.a_max, 0.2, 1e-3,
                        v_start=v_start)
  for combined in (True, False):
    reach = human_reach.HumanReach(config, use_combined_model=combined)
    reach.measure(positions[0], 0.0)
    assert not reach.has_velocity
    c1, c2, r = reach.reach_capsules(0.0, [0.0, 0.1, 0.2])
    # VEL radius at t = 0.2: v_max t + thickness / 2 for every body.
    vel = reach.num_models - 1
    np.testing.assert_allclose(r[vel, 1], 2.0 * 0.2 + np.array([
        b.thickness / 2 for b in config.bodies]))
    for j in range(0, 201, 10):
      k = 0 if j <= 100 else 1
      p1, p2, pr = reach.body_capsules(positions[j])
      assert geometry.capsule_contains_capsule(c1[:, k], c2[:, k], r[:, k],
                                               p1, p2, pr, 1e-9).all()


def test_finite_differences_use_the_previous_sample():
  reach = human_reach.HumanReach(use_kalman_filter=False)
  base = np.zeros((N, 3))
  reach.measure(base, 0.0)
  reach.measure(base + [0.01, 0, 0], 0.01)
  reach.measure(base + [0.03, 0, 0], 0.02)
  np.testing.assert_allclose(reach.velocities, np.tile([2.0, 0, 0], (N, 1)))
  assert reach.last_measurement_time == 0.02
  with pytest.raises(ValueError, match='before the previous'):
    reach.measure(base, 0.01)
  with pytest.raises(ValueError, match='keypoints'):
    reach.measure(np.zeros((3, 3)), 0.05)


def test_kalman_filter_tracks_constant_velocity_b2():
  """B2: 100 Hz samples of a keypoint at 1 m/s; dt from the previous sample
  keeps the estimate at 1 m/s (the original decayed to 0.01 m/s at 1 s)."""
  reach = human_reach.HumanReach(use_kalman_filter=True)
  for i in range(101):
    t = 0.01 * i
    reach.measure(np.tile([t, 0.0, 0.0], (N, 1)), t)
    if i == 10:
      assert reach.velocities[0, 0] == pytest.approx(1.0, abs=0.02)
  np.testing.assert_allclose(reach.velocities[:, 0], 1.0, atol=1e-3)
  np.testing.assert_allclose(reach.positions[:, 0], 1.0, atol=1e-4)
  reach.reset()
  assert reach.positions is None and not reach.has_velocity


def test_pos_model_extremity_balls():
  config = human_reach.HumanModelConfig.load()
  reach = human_reach.HumanReach(config, use_combined_model=False)
  assert reach.num_models == 3
  kp = np.random.RandomState(3).uniform(-0.3, 0.3, (N, 3))
  reach.measure(kp, 0.0)
  reach.measure(kp, 0.004)
  c1, c2, r = reach.reach_capsules(0.004, [0.0, 0.1])
  names = reach.body_names
  for arm in config.extremities:
    shoulder = kp[keypoint_set.KEYPOINT_INDEX[arm.base]]
    chain = sum(np.linalg.norm(
        kp[keypoint_set.KEYPOINT_INDEX[b.distal]] -
        kp[keypoint_set.KEYPOINT_INDEX[b.proximal]])
        for b in config.bodies if b.name in arm.covers)
    for body in arm.covers:
      i = names.index(body)
      np.testing.assert_allclose(c1[human_reach.POS, 0, i], shoulder)
      np.testing.assert_allclose(c2[human_reach.POS, 0, i], shoulder)
      assert r[human_reach.POS, 0, i] == pytest.approx(
          2.0 * 0.1 + max(arm.length, chain) + 0.103)
  # Bodies outside the arms use the VEL capsule in the POS model.
  torso = names.index('torso')
  np.testing.assert_allclose(r[human_reach.POS, 0, torso],
                             r[human_reach.VEL, 0, torso])


def test_ball_bodies_enclose_both_interval_ends_l5():
  """L5: a body with proximal == distal encloses the t_a and t_b balls."""
  config = human_reach.HumanModelConfig.load()
  head = human_reach.Body('head_ball', 'head', 'head', 0.2)
  config = dataclasses.replace(config, bodies=(head,), extremities=(),
                               measurement_error_vel=0.0)
  reach = human_reach.HumanReach(config, use_combined_model=False)
  kp = np.zeros((N, 3))
  reach.measure(kp, 0.0)
  reach.measure(kp + [0.004, 0, 0], 0.004)  # 1 m/s along x.
  c1, c2, r = reach.reach_capsules(0.004, [0.0, 0.02])
  accel = human_reach.ACCEL
  a = config.a_max[keypoint_set.KEYPOINT_INDEX['head']]
  ball_a = (np.array([0.004, 0, 0]), 0.0)
  ball_b = (np.array([0.024, 0, 0]), 0.5 * a * 0.02 ** 2 + a * 0.002 * 0.02)
  for centre, radius in (ball_a, ball_b):
    d = geometry.point_segment_distance(centre, c1[accel, 0, 0],
                                        c2[accel, 0, 0])
    assert d + radius + 0.1 <= r[accel, 0, 0] + 1e-12


def test_body_capsules_real_size():
  reach = human_reach.HumanReach()
  kp = np.random.RandomState(4).randn(N, 3)
  p1, p2, r = reach.body_capsules(kp)
  assert p1.shape == (reach.num_bodies, 3) == p2.shape
  i = reach.body_names.index('left_forearm')
  np.testing.assert_allclose(p1[i], kp[keypoint_set.KEYPOINT_INDEX[
      'left_elbow']])
  np.testing.assert_allclose(p2[i], kp[keypoint_set.KEYPOINT_INDEX[
      'left_wrist']])
  assert r[i] == pytest.approx(0.066)
  # Legs and pelvis are part of the model.
  assert {'left_thigh', 'right_shin', 'pelvis'} <= set(reach.body_names)


def test_model_file_errors_name_the_field(tmp_path):
  data = json.loads(human_reach.DEFAULT_MODEL_PATH.read_text())
  data['bodies'][0]['distal'] = 'nose'
  path = tmp_path / 'bad.json'
  path.write_text(json.dumps(data))
  with pytest.raises(ValueError, match=r"bodies\[0\].distal.*nose"):
    human_reach.HumanModelConfig.load(path)
  data = json.loads(human_reach.DEFAULT_MODEL_PATH.read_text())
  data['keypoints']['head']['v_max'] = -1
  path.write_text(json.dumps(data))
  with pytest.raises(ValueError, match='keypoints.head.v_max'):
    human_reach.HumanModelConfig.load(path)
  with pytest.raises(RuntimeError, match='no measurement'):
    human_reach.HumanReach().reach_capsules(0.0, [0.0, 0.1])
