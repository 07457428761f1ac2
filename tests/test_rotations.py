"""hrc_suite.rotations: round trips, known values, bad input, and the
compiled kernels that repeat its maths in scalar code."""

import mujoco
import numpy as np
import pytest

from hrc_suite import rotations
from hrc_suite.control import ik_kernels
from hrc_suite.entities import human_kernels
from hrc_suite.tasks.runtime import tool_hold_kernels

HALF = np.sqrt(0.5)


def _random_quats(n, seed=0):
  q = np.random.RandomState(seed).normal(size=(n, 4))
  return q / np.linalg.norm(q, axis=1, keepdims=True)


def _mju_mat(quat):
  out = np.empty(9)
  mujoco.mju_quat2Mat(out, quat)
  return out.reshape(3, 3)


def test_quat_to_mat_is_mujocos_rotation_and_batches():
  quats = _random_quats(50)
  matrices = rotations.quat_to_mat(quats)
  assert matrices.shape == (50, 3, 3)
  for q, m in zip(quats, matrices):
    np.testing.assert_allclose(m, _mju_mat(q), atol=1e-15)
    assert np.array_equal(rotations.quat_to_mat(q), m)
  # Normalised first: a scaled quaternion is the same rotation.
  np.testing.assert_allclose(rotations.quat_to_mat(3.0 * quats[0]),
                             matrices[0], atol=1e-15)
  assert rotations.quat_to_mat(quats.reshape(5, 10, 4)).shape == (5, 10, 3,
                                                                    3)


def test_mat_to_quat_is_mju_mat2quat_and_round_trips():
  quats = _random_quats(50, seed=1)
  matrices = rotations.quat_to_mat(quats)
  back = rotations.mat_to_quat(matrices)
  for q, m, b in zip(quats, matrices, back):
    expected = np.empty(4)
    mujoco.mju_mat2Quat(expected, m.ravel())
    assert np.array_equal(b, expected)
    np.testing.assert_allclose(b * np.sign(b @ q), q, atol=1e-14)
  # Half turns (w = 0) exactly.
  np.testing.assert_allclose(
      np.abs(rotations.mat_to_quat(np.diag([-1.0, -1.0, 1.0]))),
      [0.0, 0.0, 0.0, 1.0], atol=1e-15)


def test_axes_to_quat_matches_mat_to_quat_up_to_sign_with_w_non_negative():
  matrices = rotations.quat_to_mat(_random_quats(200, seed=2))
  quats = rotations.axes_to_quat(matrices[..., 0], matrices[..., 1],
                                 matrices[..., 2])
  assert (quats[:, 0] >= 0.0).all()
  exact = rotations.mat_to_quat(matrices)
  signs = np.sign(np.sum(quats * exact, axis=1))[:, None]
  np.testing.assert_allclose(quats * signs, exact, atol=1e-7)
  one = rotations.axes_to_quat(matrices[0, :, 0], matrices[0, :, 1],
                               matrices[0, :, 2])
  assert one.shape == (4,) and np.array_equal(one, quats[0])


def test_products_conjugates_and_rotation_vectors():
  a, b = _random_quats(2, seed=3)
  np.testing.assert_allclose(
      rotations.quat_to_mat(rotations.quat_mul(a, b)),
      rotations.quat_to_mat(a) @ rotations.quat_to_mat(b), atol=1e-14)
  np.testing.assert_allclose(rotations.quat_mul(a, rotations.quat_conj(a)),
                             rotations.IDENTITY_QUAT, atol=1e-15)
  np.testing.assert_allclose(
      rotations.quat_to_rotvec(rotations.yaw_to_quat(0.3)), [0, 0, 0.3],
      atol=1e-15)
  # The shorter way: a turn of 3pi/2 is -pi/2.
  np.testing.assert_allclose(
      rotations.quat_to_rotvec(rotations.yaw_to_quat(1.5 * np.pi)),
      [0, 0, -0.5 * np.pi], atol=1e-12)


def test_elementary_rotations_and_yaw():
  np.testing.assert_allclose(
      rotations.about_axis(rotations.Z, np.pi / 2) @ [1.0, 0.0, 0.0],
      [0.0, 1.0, 0.0], atol=1e-15)
  np.testing.assert_allclose(
      rotations.about_axis(rotations.X, np.pi / 2) @ [0.0, 1.0, 0.0],
      [0.0, 0.0, 1.0], atol=1e-15)
  np.testing.assert_allclose(
      rotations.about_axis(rotations.Y, np.pi / 2) @ [0.0, 0.0, 1.0],
      [1.0, 0.0, 0.0], atol=1e-15)
  angles = np.linspace(-3.0, 3.0, 7)
  for axis in (rotations.X, rotations.Y, rotations.Z):
    unit = np.eye(3)[axis]
    batch = rotations.about_axis(axis, angles)
    assert batch.shape == (7, 3, 3)
    for angle, matrix in zip(angles, batch):
      np.testing.assert_allclose(
          rotations.axis_angle_to_mat(unit, angle), matrix, atol=1e-15)
  np.testing.assert_allclose(rotations.quat_to_mat(rotations.yaw_to_quat(
      0.7)), rotations.yaw_to_mat(0.7), atol=1e-15)
  assert np.array_equal(rotations.axis_angle_to_mat(np.zeros(3), 1.0),
                        np.eye(3))


def test_yaw_of_quaternions_and_matrices():
  assert rotations.quat_yaw([1.0, 0, 0, 0]) == pytest.approx(0.0)
  assert rotations.quat_yaw([HALF, 0, 0, HALF]) == pytest.approx(np.pi / 2)
  # Gripper down (half turn about x), then yaw pi/2 about world z.
  both = rotations.quat_mul([HALF, 0, 0, HALF], [0.0, 1.0, 0.0, 0.0])
  assert rotations.quat_yaw(both) == pytest.approx(np.pi / 2)
  yaws = np.array([-3.0, -1.0, 0.0, 2.0])
  np.testing.assert_allclose(rotations.mat_yaw(rotations.yaw_to_mat(yaws)),
                             yaws, atol=1e-15)
  np.testing.assert_allclose(rotations.wrap_angle(np.array(
      [np.pi, 3 * np.pi / 2, -np.pi / 2])), [-np.pi, -np.pi / 2, -np.pi / 2])


def test_slerp_ends_and_middle():
  q0, q1 = rotations.yaw_to_quat(0.2), rotations.yaw_to_quat(1.0)
  np.testing.assert_allclose(rotations.slerp(q0, q1, 0.0), q0, atol=1e-15)
  np.testing.assert_allclose(rotations.slerp(q0, q1, 1.0), q1, atol=1e-15)
  np.testing.assert_allclose(rotations.slerp(q0, -q1, 0.5),
                             rotations.yaw_to_quat(0.6), atol=1e-15)


def test_nearest_rotation_and_xyaxes():
  rotation = rotations.yaw_to_mat(0.4)
  noisy = np.round(rotation, 4)
  nearest = rotations.nearest_rotation(noisy)
  np.testing.assert_allclose(nearest @ nearest.T, np.eye(3), atol=1e-15)
  np.testing.assert_allclose(nearest, rotation, atol=1e-4)
  flipped = rotations.nearest_rotation(np.diag([1.0, 1.0, -1.0]))
  assert np.linalg.det(flipped) == pytest.approx(1.0)
  assert np.array_equal(rotations.xyaxes_to_mat([1, 0, 0, 0, 1, 0]),
                        np.eye(3))
  np.testing.assert_allclose(rotations.xyaxes_to_mat([0, 2, 0, -1, 1, 0]),
                             rotations.yaw_to_mat(np.pi / 2), atol=1e-15)


@pytest.mark.parametrize('call, name', [
    (lambda: rotations.quat_to_mat('abc'), 'quat'),
    (lambda: rotations.quat_to_mat([1.0, 0.0, 0.0]), 'quat'),
    (lambda: rotations.quat_to_mat([0.0, 0.0, 0.0, 0.0]), 'quat'),
    (lambda: rotations.quat_to_mat([np.nan, 0.0, 0.0, 0.0]), 'quat'),
    (lambda: rotations.mat_to_quat(np.eye(4)), 'matrix'),
    (lambda: rotations.quat_mul([1.0, 0.0], [1.0, 0, 0, 0]), 'a'),
    (lambda: rotations.quat_mul([1.0, 0, 0, 0], None), 'b'),
    (lambda: rotations.quat_conj(np.ones((2, 4))), 'quat'),
    (lambda: rotations.about_axis(rotations.Z, 'north'), 'angle'),
    (lambda: rotations.about_axis(3, 0.1), 'axis'),
    (lambda: rotations.axis_angle_to_mat([1.0, 1.0, 0.0], 0.1), 'axis'),
    (lambda: rotations.nearest_rotation(np.eye(3)[None]), 'matrix'),
    (lambda: rotations.axes_to_quat([1, 0], [0, 1, 0], [0, 0, 1]), 'x'),
])
def test_bad_input_names_the_argument(call, name):
  with pytest.raises(ValueError, match=rf'^{name}: expected'):
    call()


def test_human_kernel_quaternion_is_axes_to_quat_bit_for_bit():
  matrices = rotations.quat_to_mat(_random_quats(200, seed=4))
  expected = rotations.axes_to_quat(matrices[..., 0], matrices[..., 1],
                                    matrices[..., 2])
  out = np.empty(4)
  for m, q in zip(matrices, expected):
    human_kernels._quaternion(m[:, 0].copy(), m[:, 1].copy(),
                              m[:, 2].copy(), out)
    assert np.array_equal(out, q)


def test_tool_hold_kernel_maths_is_the_modules():
  quats = _random_quats(100, seed=5)
  matrix, vector = np.empty((3, 3)), np.empty(3)
  for t, f in zip(quats[:50], quats[50:]):
    np.testing.assert_allclose(tool_hold_kernels._mul(*t, *f),
                               rotations.quat_mul(t, f), atol=1e-15)
    tool_hold_kernels._matrix(*t, matrix)
    np.testing.assert_allclose(matrix, rotations.quat_to_mat(t), atol=1e-15)
    tool_hold_kernels._rotation_vector(*t, *f, vector)
    np.testing.assert_allclose(vector, rotations.quat_to_rotvec(
        rotations.quat_mul(t, rotations.quat_conj(f))), atol=1e-13)


def test_ik_kernel_log3_is_the_rotation_vector_of_mat_to_quat():
  quats = list(_random_quats(50, seed=6)) + [
      rotations.IDENTITY_QUAT, rotations.yaw_to_quat(np.pi - 1e-5)]
  out = np.empty(3)
  for q in quats:
    matrix = rotations.quat_to_mat(q)
    ik_kernels.log3(matrix, out)
    np.testing.assert_allclose(
        out, rotations.quat_to_rotvec(rotations.mat_to_quat(matrix)),
        atol=1e-9)
  frames, pose = np.empty((1, 3, 4)), np.empty((3, 4))
  placement = np.hstack([np.eye(3), np.zeros((3, 1))])[None]
  ik_kernels.forward(np.array([0.8]), placement, placement[0], frames, pose)
  np.testing.assert_allclose(frames[0, :, :3],
                             rotations.about_axis(rotations.Z, 0.8),
                             atol=1e-15)


def test_ik_kernel_wrap_and_gripper_down_are_the_modules_bit_for_bit():
  """ik_kernels._wrap is rotations.wrap_angle and ik_kernels._gripper_down
  ik.gripper_down_rotation, bit for bit (the compiled IK picks its yaw and
  target rotation with them)."""
  from hrc_suite.control import ik   # pylint: disable=g-import-not-at-top
  rng = np.random.RandomState(7)
  angles = np.concatenate([rng.uniform(-20.0, 20.0, 2000),
                           [0.0, -0.0, np.pi, -np.pi, 2 * np.pi, 1e-300]])
  for angle in angles.tolist():
    assert (np.float64(ik_kernels._wrap(angle)).tobytes()
            == np.float64(rotations.wrap_angle(angle)).tobytes())
    assert (ik_kernels._gripper_down(angle).tobytes()
            == ik.gripper_down_rotation(angle).tobytes())
