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


def test_warm_up_compiles_every_signature_the_player_uses():
  """A Player warms its kernels up when it is made: playing clips and an
  idle phase compiles nothing more (no RL step pays for a compilation)."""
  from hrc_suite.tasks.runtime import motions   # pylint: disable=g-import-not-at-top
  from hrc_suite.human import player as player_lib   # pylint: disable=g-import-not-at-top
  player = player_lib.Player(motions.load_motions(None, 'stacking'),
                             station=(1.0, 0.0, 0.0))
  dispatchers = {name: getattr(player_kernels, name)
                 for name in dir(player_kernels)
                 if hasattr(getattr(player_kernels, name), 'signatures')}
  before = {name: len(f.signatures) for name, f in dispatchers.items()}
  player.reset(np.random.RandomState(0))
  positions = np.empty((25, player.positions.shape[0], 3))
  times, clips = np.empty(25), [None] * 25
  waited = 0
  for _ in range(400):   # Into the first idle phase (a wait for an event).
    player.advance_many(0.004, positions, times, clips)
    waited += player.waiting_for is not None
  assert waited > 0
  player.trigger(player.waiting_for)
  player.advance_many(0.004, positions, times, clips)
  assert {name: len(f.signatures)
          for name, f in dispatchers.items()} == before
