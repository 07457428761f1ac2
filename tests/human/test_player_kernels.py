"""The player's placement kernel (human/player_kernels.py): the documented
rounding (two fused multiply-adds), whatever BLAS the machine has."""

import fractions

import numpy as np

from hrc_suite.human import player_kernels


def _exact_fma(a, b, c):
  """a * b + c rounded once, in exact rational arithmetic."""
  return float(fractions.Fraction(a) * fractions.Fraction(b)
               + fractions.Fraction(c))


def test_fma_rounds_once():
  # 0.1 * 10 rounds to 1.0 when rounded twice; once, the error remains.
  assert 0.1 * 10.0 - 1.0 == 0.0
  assert player_kernels.fma(0.1, 10.0, -1.0) == _exact_fma(0.1, 10.0, -1.0)
  assert player_kernels.fma(0.1, 10.0, -1.0) != 0.0


def test_place_is_two_fused_multiply_adds_in_order():
  rng = np.random.RandomState(0)
  local = rng.randn(200, 3)
  rot_t = np.linalg.qr(rng.randn(3, 3))[0]
  trans = rng.randn(3)
  out = np.empty_like(local)
  player_kernels.place(local, rot_t, trans, out)
  for row in range(len(local)):
    for c in range(3):
      product = _exact_fma(local[row, 2], rot_t[2, c], _exact_fma(
          local[row, 1], rot_t[1, c], local[row, 0] * rot_t[0, c]))
      assert out[row, c] == product + trans[c]
  # The product np.matmul computes (bit for bit where BLAS rounds so).
  np.testing.assert_allclose(out, local @ rot_t + trans, rtol=0, atol=1e-14)
  rotated = np.empty_like(local)
  player_kernels.rotate(local, rot_t, rotated)
  np.testing.assert_allclose(rotated, local @ rot_t, rtol=0, atol=1e-14)
  np.testing.assert_array_equal(rotated + trans, out)
