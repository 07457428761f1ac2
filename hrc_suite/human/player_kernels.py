"""Compiled (numba) playback of the player (human/player.py).

`place` is the player's one placement of clip-local points in the world,
`local @ rot_t + trans`, for both of its paths. np.matmul leaves that
product to BLAS, whose rounding depends on the BLAS kernel the CPU gets;
`place` fixes it: each entry is fma(l2, r2, fma(l1, r1, l0 * r0)), the
order of OpenBLAS's Haswell/Zen kernel (on such CPUs it equals np.matmul
bit for bit, and it is the same on every CPU). `play_within_clip` is
`Player._advance_within_clip` (an RL step's frames inside one clip) and
the outputs after it, `play_waiting` its steps in an idle phase, the same
operations in the same order as the Player's Python path (its
`compiled=False` reference). They take named groups: the clip being
played (`ClipFrames`), the player's clock (`PlayerClock`), the idle
phase's waves (`IdleWaves`) and the arrays they write (`PlayedSteps`),
each as the plain tuple of its fields (kernels.as_fields: they are
called every RL step).
Same
compilation settings as the shield's kernels (safety/kernels.py: cache,
IEEE arithmetic: no contraction but the explicit fma).
"""

import math
import typing

import numpy as np
from numba import types
from numba.extending import intrinsic

from hrc_suite.safety import kernels

_jit = kernels._jit


class ClipFrames(typing.NamedTuple):
  """A clip's frames as played (player._Prepared) and where it is placed
  (Player._set_placement)."""
  fps: float               # frames per second
  last: int                # the last frame an interpolation starts at
  positions: np.ndarray    # (T, K, 3) keypoints per frame
  steps: np.ndarray        # (T - 1, K, 3) change per frame
  rot_t: np.ndarray        # (3, 3) placement rotation, transposed
  trans: np.ndarray        # (3,) placement translation


class PlayerClock(typing.NamedTuple):
  """The player's clock: linear time since the clip started, the clip
  time's offset from it, and the episode time (s)."""
  linear: float
  offset: float
  episode_time: float


class IdleWaves(typing.NamedTuple):
  """An idle phase's clip time t_I + sum u sin(w s) (Player._warped) and
  rate sum S cos(w s): its keyframe time and waves."""
  anchor: float              # t_I, s
  amplitudes: np.ndarray     # u (s)
  omegas: np.ndarray         # w (rad/s)
  speeds: np.ndarray         # S


class PlayedSteps(typing.NamedTuple):
  """What the playback writes: each step's keypoints and episode time,
  and the player's outputs after the last step."""
  positions: np.ndarray        # (n, K, 3)
  times: np.ndarray            # (n,)
  now_positions: np.ndarray    # (K, 3)
  now_velocities: np.ndarray   # (K, 3)


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
def play_within_clip(clock, dt, end, clip, out):
  """Player._advance_within_clip for len(out.times) steps of dt from the
  PlayerClock `clock` in the ClipFrames `clip`: returns (True, linear,
  episode time) after writing each step's keypoints (n, K, 3) and
  episode time, and the player's outputs after the last (positions and
  velocities (K, 3)) into the PlayedSteps `out`; (False, linear,
  episode_time), writing nothing, if the clip time reaches `end` within
  the steps. Groups as fields (kernels.as_fields)."""
  clock, clip, out = PlayerClock(*clock), ClipFrames(*clip), PlayedSteps(*out)
  linear, offset, episode_time = clock.linear, clock.offset, clock.episode_time
  positions, times = out.positions, out.times
  n = times.shape[0]
  clock_time = linear
  for _ in range(n):
    clock_time += dt
  if not clock_time - offset < end:   # The clip time grows: the last decides.
    return False, linear, episode_time
  local = np.empty((clip.positions.shape[1], 3))
  t = 0.0
  index = 0
  for k in range(n):
    linear += dt
    episode_time += dt
    times[k] = episode_time
    t = linear - offset
    index = _pose(t, clip.fps, clip.last, clip.positions, clip.steps,
                  clip.rot_t, clip.trans, local, positions[k])
  # The outputs (Player._update_outputs): the last step's keypoints, and
  # the interpolation's derivative at clip rate 1 (0 before the clip).
  out.now_positions[:] = positions[n - 1]
  _velocities(index, (0.0 if t < 0.0 else 1.0) * clip.fps, clip.steps,
              clip.rot_t, local, out.now_velocities)
  return True, linear, episode_time


@_jit
def play_waiting(clock, dt, waves, duration, clip, out):
  """advance_many for len(out.times) steps of dt from the PlayerClock
  `clock` in an idle phase of the ClipFrames `clip` (the wait lasts until
  an event, which comes between RL steps): each step's clip time t_I +
  sum u sin(w s) (IdleWaves; Player._warped, clamped to the clip's
  `duration` as Player._clip_time_and_rate) and keypoints, as
  play_within_clip, into the PlayedSteps `out`. Returns (linear, episode
  time). Groups as fields (kernels.as_fields)."""
  clock, waves = PlayerClock(*clock), IdleWaves(*waves)
  clip, out = ClipFrames(*clip), PlayedSteps(*out)
  linear, offset, episode_time = clock.linear, clock.offset, clock.episode_time
  anchor, amplitudes, omegas, speeds = (waves.anchor, waves.amplitudes,
                                        waves.omegas, waves.speeds)
  positions, times = out.positions, out.times
  n = times.shape[0]
  local = np.empty((clip.positions.shape[1], 3))
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
    index = _pose(t, clip.fps, clip.last, clip.positions, clip.steps,
                  clip.rot_t, clip.trans, local, positions[k])
  out.now_positions[:] = positions[n - 1]
  _velocities(index, rate * clip.fps, clip.steps, clip.rot_t, local,
              out.now_velocities)
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
  clock = tuple(PlayerClock(0.0, 0.0, 0.0))
  frames_ = tuple(ClipFrames(1.0, frames - 1, clip, clip, rot_t, trans))
  out = tuple(PlayedSteps(positions, times, now, np.zeros_like(now)))
  play_within_clip(clock, 0.004, 1.0, frames_, out)
  waves = np.zeros(1)
  play_waiting(clock, 0.004, tuple(IdleWaves(0.0, waves, waves, waves)),
               1.0, frames_, out)
  _warm = True
