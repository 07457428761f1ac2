"""Compiled (numba) playback of the player (human/player.py).

`place` is the player's one placement of clip-local points in the world,
`local @ rot_t + trans`, for both of its paths. np.matmul leaves that
product to BLAS, whose rounding depends on the BLAS kernel the CPU gets;
`place` fixes it: each entry is fma(l2, r2, fma(l1, r1, l0 * r0)), the
order of OpenBLAS's Haswell/Zen kernel (on such CPUs it equals np.matmul
bit for bit, and it is the same on every CPU). `play_within_clip` is
`Player._advance_within_clip` (an RL step's frames inside one clip) and
the outputs after it, the same operations in the same order. Same
compilation settings as the shield's kernels (safety/kernels.py: cache,
IEEE arithmetic: no contraction but the explicit fma).
"""

import math

import numpy as np
from numba import types
from numba.extending import intrinsic

from hrc_suite.safety import kernels

_jit = kernels._jit


@intrinsic
def _fma(typingctx, a, b, c):
  """a * b + c with one rounding (LLVM's llvm.fma.f64)."""
  del typingctx
  if not all(isinstance(x, types.Float) for x in (a, b, c)):
    return None
  signature = types.float64(types.float64, types.float64, types.float64)

  def codegen(context, builder, sig, args):
    del context, sig
    return builder.fma(*args)
  return signature, codegen


@_jit
def fma(a, b, c):
  """a * b + c rounded once (for tests and callers outside kernels)."""
  return _fma(a, b, c)


@_jit
def _rotated(local, row, rot_t, c):
  """Entry c of local[row] @ rot_t, see the module doc."""
  return _fma(local[row, 2], rot_t[2, c],
              _fma(local[row, 1], rot_t[1, c], local[row, 0] * rot_t[0, c]))


@_jit
def place(local, rot_t, trans, out):
  """out (n, 3) = local (n, 3) @ rot_t (3, 3) + trans (3,)."""
  for row in range(local.shape[0]):
    for c in range(3):
      out[row, c] = _rotated(local, row, rot_t, c) + trans[c]


@_jit
def rotate(local, rot_t, out):
  """out (n, 3) = local (n, 3) @ rot_t (3, 3), as `place`."""
  for row in range(local.shape[0]):
    for c in range(3):
      out[row, c] = _rotated(local, row, rot_t, c)


@_jit
def _pose(t, fps, last, clip_positions, clip_steps, rot_t, trans, local,
          out):
  """The keypoints at clip time t (0 before the clip) into out (K, 3): the
  frames' linear interpolation, placed; returns the frame index."""
  frame = (0.0 if t <= 0.0 else t) * fps
  index = min(int(frame), last)
  fraction = frame - index
  for j in range(local.shape[0]):
    for c in range(3):
      local[j, c] = (clip_steps[index, j, c] * fraction
                     + clip_positions[index, j, c])
  place(local, rot_t, trans, out)
  return index


@_jit
def _velocities(index, rate, clip_steps, rot_t, local, out):
  """The interpolation's derivative in frame `index` at clip rate `rate`
  (clip seconds per second, times fps) into out (K, 3)."""
  for j in range(local.shape[0]):
    for c in range(3):
      local[j, c] = clip_steps[index, j, c] * rate
  rotate(local, rot_t, out)


@_jit
def play_within_clip(linear, offset, episode_time, dt, end, fps, last,
                     clip_positions, clip_steps, rot_t, trans, positions,
                     times, now_positions, now_velocities):
  """Player._advance_within_clip for len(times) steps of dt: returns
  (True, linear, episode time) after writing each step's keypoints
  (n, K, 3) and episode time, and the player's outputs after the last
  (positions and velocities (K, 3)); (False, linear, episode_time),
  writing nothing, if the clip time reaches `end` within the steps."""
  n = times.shape[0]
  clock = linear
  for _ in range(n):
    clock += dt
  if not clock - offset < end:   # The clip time grows: the last decides.
    return False, linear, episode_time
  local = np.empty((clip_positions.shape[1], 3))
  t = 0.0
  index = 0
  for k in range(n):
    linear += dt
    episode_time += dt
    times[k] = episode_time
    t = linear - offset
    index = _pose(t, fps, last, clip_positions, clip_steps, rot_t, trans,
                  local, positions[k])
  # The outputs (Player._update_outputs): the last step's keypoints, and
  # the interpolation's derivative at clip rate 1 (0 before the clip).
  now_positions[:] = positions[n - 1]
  _velocities(index, (0.0 if t < 0.0 else 1.0) * fps, clip_steps, rot_t,
              local, now_velocities)
  return True, linear, episode_time


@_jit
def play_waiting(linear, offset, anchor, episode_time, dt, amplitudes,
                 omegas, speeds, duration, fps, last, clip_positions,
                 clip_steps, rot_t, trans, positions, times, now_positions,
                 now_velocities):
  """advance_many for len(times) steps of dt in an idle phase (the wait
  lasts until an event, which comes between RL steps): each step's clip
  time t_I + sum u sin(w s) (Player._warped, clamped to the clip as
  Player._clip_time_and_rate) and keypoints, as play_within_clip.
  Returns (linear, episode time)."""
  n = times.shape[0]
  local = np.empty((clip_positions.shape[1], 3))
  t = 0.0
  rate = 0.0
  index = 0
  for k in range(n):
    episode_time += dt
    linear += dt
    times[k] = episode_time
    s = linear - offset - anchor
    t = anchor
    for i in range(amplitudes.shape[0]):
      t += amplitudes[i] * math.sin(omegas[i] * s)
    rate = 0.0
    for i in range(speeds.shape[0]):
      rate += speeds[i] * math.cos(omegas[i] * s)
    if t <= 0.0:
      t, rate = 0.0, (0.0 if t < 0.0 else rate)
    elif t >= duration:
      t, rate = duration, (0.0 if t > duration else rate)
    index = _pose(t, fps, last, clip_positions, clip_steps, rot_t, trans,
                  local, positions[k])
  now_positions[:] = positions[n - 1]
  _velocities(index, rate * fps, clip_steps, rot_t, local, now_velocities)
  return linear, episode_time


_warm = False


def warm_up():
  """Compiles (or loads from the cache) the kernels for the argument types
  the Player passes, once per process: the first idle phase or clip step
  of an episode then does not pay for it (loading play_waiting from the
  cache took 43 ms inside an RL step of stacking; compiling it, seconds)."""
  global _warm
  if _warm:
    return
  frames, keypoints = 2, 1
  clip = np.zeros((frames, keypoints, 3))
  rot_t, trans = np.eye(3), np.zeros(3)
  positions, times = np.zeros((1, keypoints, 3)), np.zeros(1)
  now = np.zeros((keypoints, 3))
  place(now, rot_t, trans, np.empty((keypoints, 3)))
  rotate(now, rot_t, np.empty((keypoints, 3)))
  play_within_clip(0.0, 0.0, 0.0, 0.004, 1.0, 1.0, frames - 1, clip, clip,
                   rot_t, trans, positions, times, now, np.zeros_like(now))
  waves = np.zeros(1)
  play_waiting(0.0, 0.0, 0.0, 0.0, 0.004, waves, waves, waves, 1.0, 1.0,
               frames - 1, clip, clip, rot_t, trans, positions, times, now,
               np.zeros_like(now))
  _warm = True
