"""Replays motion clips in the workcell: idle phases, clip sequences, placement.

Episode time t advances by `advance(dt)` every physics step. Clip time is the
linear time since the clip started minus an offset, except during an idle
phase: from t_I (the phase's keyframe time) until its event is triggered,

  t_A = t_I + sum_i u_i sin((t - t_I) w_i),   w_i = S_i / u_i,

with u_i, S_i the clip's amplitudes (seconds) and speeds, each multiplied per
episode by factor ** clip(N(0, 1), -3, 3). Replay may run backwards. On the
event the offset takes up the delay so the clip continues from t_A without a
jump. Positions interpolate linearly between frames; velocities are the exact
derivative of that interpolation times dt_A / dt.

When a clip ends the next one, drawn from the episode's random stream, starts;
if its first pose differs from the last pose, the body moves between them on a
minimum-jerk path slow enough to stay under `transition_speed`. The whole
sequence is placed at a station (x, y, yaw) plus a uniform random offset.
"""

import math

import numpy as np

from hrc_suite import rotations
from hrc_suite.human import clip as clip_lib
from hrc_suite.human import keypoints
from hrc_suite.human import player_kernels

# Peak keypoint speed while blending from one clip's last pose to the next
# clip's first pose: half the 2 m/s the shield assumes
# (docs/shield_maths.md, 8).
TRANSITION_SPEED = 1.0
# Poses closer than this (max keypoint distance, m) switch without a blend.
TRANSITION_TOLERANCE = 1e-4
# Minimum-jerk blend w(s) = 10 s^3 - 15 s^4 + 6 s^5 peaks at w' = 15/8.
_MIN_JERK_PEAK_RATE = 1.875
_SEED_RANGE = 2**31 - 1


def _min_jerk(s):
  """Blend weight and its derivative (per unit s) at s in [0, 1]."""
  s = min(max(s, 0.0), 1.0)
  return (s**3 * (10.0 - 15.0 * s + 6.0 * s * s),
          30.0 * s * s * (1.0 - s) ** 2)


def _resample(clip, fps):
  """The clip linearly resampled to `fps` frames per second."""
  times = np.arange(0.0, clip.duration + 0.5 / fps, 1.0 / fps)
  times = np.minimum(times, clip.duration)
  frames = times * clip.fps
  lo = np.minimum(frames.astype(int), clip.num_frames - 2)
  frac = (frames - lo)[:, None, None]
  pos = clip.positions.astype(np.float64)
  positions = pos[lo] + frac * (pos[lo + 1] - pos[lo])
  scale = fps / clip.fps

  def frame(f):
    return int(min(round(f * scale), len(times) - 1))

  return clip_lib.validate(clip.replace(
      fps=float(fps), positions=positions.astype(np.float32),
      keyframes=tuple(frame(k) for k in clip.keyframes),
      fast_phases=tuple((frame(s), frame(e)) for s, e in clip.fast_phases)),
      source=f'clip {clip.name!r} resampled to {fps} fps')


class _Prepared:
  """Arrays of one clip precomputed for cheap per-step sampling."""

  def __init__(self, clip):
    self.clip = clip
    self.positions = clip.positions.astype(np.float64)
    self.steps = np.diff(self.positions, axis=0)   # (T - 1, K, 3) per frame
    self.fps = float(clip.fps)
    self.last = clip.num_frames - 2
    self.duration = clip.duration
    self.anchors = [clip.keyframe_time(p.keyframe) for p in clip.idle_phases]
    self.events = [p.event for p in clip.idle_phases]


class Player:
  """Plays a random sequence of clips placed at a station; see module doc."""

  def __init__(self, clips, station=(0.0, 0.0, 0.0),
               placement_range=(0.0, 0.0, 0.0), fps_out=None,
               sequence_length=None, transition_speed=TRANSITION_SPEED,
               compiled: bool = True):
    """Args:
      clips: the clips to play (at least one).
      station: (x, y, yaw) where the sequence is placed.
      placement_range: (x, y, yaw) half widths of the uniform random
        offset from the station.
      fps_out: frames per second the clips are resampled to (None: as
        they are).
      sequence_length: clips per episode (None: endless).
      transition_speed: m/s, the peak keypoint speed of a blend.
      compiled: whether `advance_many` plays a block of steps within a
        clip or an idle phase in one compiled call (player_kernels); False
        runs the readable Python path, step by step (the reference, the
        same values).
    """
    clips = list(clips)
    if not clips:
      raise ValueError('Player needs at least one clip, got none')
    for i, clip in enumerate(clips):
      clip_lib.validate(clip, source=f'clip {i}')
    if fps_out is not None:
      if not fps_out > 0:
        raise ValueError(f'fps_out must be positive or None, got {fps_out!r}')
      clips = [_resample(c, fps_out) for c in clips]
    self._station = tuple(float(v) for v in station)
    self._range = tuple(float(v) for v in placement_range)
    if len(self._station) != 3 or len(self._range) != 3:
      raise ValueError(f'station and placement_range are (x, y, yaw), got '
                       f'{station!r} and {placement_range!r}')
    if any(r < 0 for r in self._range):
      raise ValueError(f'placement_range must be >= 0, got {placement_range}')
    if sequence_length is not None and sequence_length < 1:
      raise ValueError(f'sequence_length must be >= 1 or None (endless), got '
                       f'{sequence_length!r}')
    if not transition_speed > 0:
      raise ValueError(f'transition_speed must be positive, got '
                       f'{transition_speed!r}')
    self._clips = [_Prepared(c) for c in clips]
    self._sequence_length = sequence_length
    self._transition_speed = float(transition_speed)
    k = keypoints.NUM_KEYPOINTS
    self._positions = np.zeros((k, 3))
    self._velocities = np.zeros((k, 3))
    self._local = np.zeros((k, 3))
    self._local_vel = np.zeros((k, 3))
    self._from = np.zeros((k, 3))
    self._delta = np.zeros((k, 3))
    self._ready = False
    self._compiled = bool(compiled)
    player_kernels.warm_up()   # Once per process, not mid-episode.

  # ---------------------------------------------------------------- episode
  def reset(self, random_state):
    """Draws placement and the clip stream; starts the first clip."""
    dx, dy, dyaw = self._range
    x, y, yaw = self._station
    self._placement = (x + random_state.uniform(-dx, dx),
                       y + random_state.uniform(-dy, dy),
                       yaw + random_state.uniform(-dyaw, dyaw))
    self._seed = int(random_state.randint(_SEED_RANGE))
    self._set_placement()
    self._episode_time = 0.0
    self._finished = False
    self._start_clip(0)
    self._transition = None
    self._ready = True
    self._update_outputs()

  def _set_placement(self):
    x, y, yaw = self._placement
    self._rot_t = rotations.yaw_to_mat(yaw).T.copy()
    self._trans = np.array([x, y, 0.0])

  def _draw(self, k):
    """Clip index and randomised idle parameters of the k-th clip."""
    rs = np.random.RandomState([self._seed, k])
    index = int(rs.randint(len(self._clips)))
    amplitudes, omegas, speeds = [], [], []
    for phase in self._clips[index].clip.idle_phases:
      d = phase.amplitudes.shape[0]
      fa = phase.amplitude_std_factor ** np.clip(rs.standard_normal(d), -3, 3)
      fs = phase.speed_std_factor ** np.clip(rs.standard_normal(d), -3, 3)
      u = phase.amplitudes * fa
      sp = phase.speeds * fs
      amplitudes.append(tuple(float(v) for v in u))
      speeds.append(tuple(float(v) for v in sp))
      omegas.append(tuple(float(v) for v in sp / u))
    return index, amplitudes, omegas, speeds

  def _start_clip(self, k):
    self._k = k
    self._index, self._u, self._omega, self._speed = self._draw(k)
    # The idle phases' (amplitudes, omegas, speeds) as arrays (kernels).
    self._idle_arrays = [tuple(np.array(x, dtype=float) for x in phase)
                         for phase in zip(self._u, self._omega, self._speed)]
    self._current = self._clips[self._index]
    prepared = self._current
    # The clip as player_kernels take it (kernels.as_fields).
    self._frames = tuple(player_kernels.ClipFrames(
        prepared.fps, prepared.last, prepared.positions, prepared.steps,
        self._rot_t, self._trans))
    self._linear = 0.0
    self._offset = 0.0
    self._phase = 0
    self._waiting = False
    self._anchor = 0.0
    clip = self._current.clip
    self._targets_world = {}
    for name, point in clip.targets.items():
      placed = np.empty((1, 3))
      self._place(np.asarray(point, dtype=float).reshape(1, 3), placed)
      self._targets_world[name] = placed[0]

  def _place(self, local, out):
    """out = local @ rot_t + trans (rows (n, 3); player_kernels.place)."""
    player_kernels.place(local, self._rot_t, self._trans, out)

  # ------------------------------------------------------------------ time
  def _warped(self, s):
    """t_A at s seconds into the current idle phase."""
    t = self._anchor
    for u, w in zip(self._u[self._phase], self._omega[self._phase]):
      t += u * math.sin(w * s)
    return t

  def _clip_time_and_rate(self):
    """Current clip time (clamped to the clip) and d(clip time)/dt."""
    prepared = self._current
    if self._waiting:
      s = self._linear - self._offset - self._anchor
      t = self._warped(s)
      rate = 0.0
      for speed, w in zip(self._speed[self._phase], self._omega[self._phase]):
        rate += speed * math.cos(w * s)
    else:
      t = self._linear - self._offset
      rate = 1.0
    if t <= 0.0:
      return 0.0, 0.0 if t < 0.0 else rate
    if t >= prepared.duration:
      return prepared.duration, 0.0 if t > prepared.duration else rate
    return t, rate

  def advance(self, dt):
    """Moves episode time forward by dt seconds (dt >= 0)."""
    self._check_advance(dt)
    self._advance_time(dt)
    self._update_outputs()

  def advance_many(self, dt, positions, times, clips):
    """advance(dt) once per row of `positions` (n, NUM_KEYPOINTS, 3),
    writing after each the keypoints there, the episode time in times[k]
    and the clip in clips[k]: the same values as n advance calls (the
    same operations, with one array operation per clip instead of one
    per step). Afterwards the player is as after the n calls."""
    self._check_advance(dt)
    n = len(positions)
    if len(times) < n or len(clips) < n:
      raise ValueError(f'times and clips need {n} entries, got '
                       f'{len(times)} and {len(clips)}')
    if self._compiled and (
        self._advance_within_clip(dt, positions, times, clips)
        or self._advance_waiting(dt, positions, times, clips)):
      return
    frames = {}     # prepared clip -> (rows, frame index, fraction)
    blends = []     # (rows, weights, from, delta, clip number) per blend
    for k in range(n):
      self._advance_time(dt)
      times[k] = self._episode_time
      clips[k] = self._current.clip
      if self._transition is not None:
        elapsed, duration = self._transition
        if not blends or blends[-1][4] != self._k:   # a new blend
          blends.append(([], [], self._from.copy(), self._delta.copy(),
                         self._k))
        blends[-1][0].append(k)
        blends[-1][1].append(_min_jerk(elapsed / duration)[0])
        continue
      prepared = self._current
      frame = self._clip_time_and_rate()[0] * prepared.fps
      i = min(int(frame), prepared.last)
      rows, index, fraction = frames.setdefault(prepared, ([], [], []))
      rows.append(k)
      index.append(i)
      fraction.append(frame - i)
    for prepared, (rows, index, fraction) in frames.items():
      local = prepared.steps[index] * np.array(fraction)[:, None, None]
      local += prepared.positions[index]
      placed = np.empty_like(local)
      self._place(local.reshape(-1, 3), placed.reshape(-1, 3))
      positions[rows] = placed
    for rows, weights, start, delta, _ in blends:
      blended = delta * np.array(weights)[:, None, None]
      blended += start
      positions[rows] = blended
    self._update_outputs()

  def _advance_within_clip(self, dt, positions, times, clips):
    """advance_many where all n steps play the current clip: no blend, no
    wait, no end, the next anchor and the clip's end not reached
    (player_kernels.play_within_clip: _advance_time's and
    _update_outputs' operations, step by step). Returns False, changing
    nothing, if a step leaves that case."""
    prepared = self._current
    n = len(positions)
    if (not n or self._transition is not None or self._waiting
        or self._finished):
      return False
    end = prepared.duration
    if self._phase < len(prepared.anchors):
      end = min(end, prepared.anchors[self._phase])
    within, linear, episode_time = player_kernels.play_within_clip(
        self._clock(), float(dt), end, self._frames, self._played(
            positions, times[:n]))
    if not within:
      return False
    self._linear, self._episode_time = linear, episode_time
    clips[:n] = [prepared.clip] * n
    return True

  def _advance_waiting(self, dt, positions, times, clips):
    """advance_many where all n steps wait in an idle phase (the wait ends
    only at an event, between calls): player_kernels.play_waiting, the
    operations of _advance_time, _clip_time_and_rate and _update_outputs
    step by step. Returns False, changing nothing, if not waiting."""
    n = len(positions)
    if (not n or not self._waiting or self._transition is not None
        or self._finished):
      return False
    prepared = self._current
    waves = tuple(player_kernels.IdleWaves(self._anchor,
                                           *self._idle_arrays[self._phase]))
    self._linear, self._episode_time = player_kernels.play_waiting(
        self._clock(), float(dt), waves, prepared.duration, self._frames,
        self._played(positions, times[:n]))
    clips[:n] = [prepared.clip] * n
    return True

  def _clock(self):
    """The clock, as player_kernels take it (kernels.as_fields)."""
    return tuple(player_kernels.PlayerClock(self._linear, self._offset,
                                            self._episode_time))

  def _played(self, positions, times):
    """player_kernels' outputs (the steps' rows, then the player's), as
    they take them (kernels.as_fields)."""
    return tuple(player_kernels.PlayedSteps(positions, times,
                                            self._positions,
                                            self._velocities))

  def _check_advance(self, dt):
    if not self._ready:
      raise RuntimeError('Player.advance before reset(random_state)')
    if not dt >= 0:
      raise ValueError(f'dt must be >= 0, got {dt!r}')

  def _advance_time(self, dt):
    """advance's clock: episode, clip and blend times (no outputs)."""
    self._episode_time += dt
    remaining = dt
    while not self._finished:
      if self._transition is not None:
        elapsed, duration = self._transition
        elapsed += remaining
        if elapsed < duration:
          self._transition = (elapsed, duration)
          break
        remaining = elapsed - duration
        self._transition = None
        continue
      before = self._linear - self._offset
      self._linear += remaining
      remaining = 0.0
      if self._waiting:
        break
      t = self._linear - self._offset
      prepared = self._current
      if self._phase < len(prepared.anchors) and t >= prepared.anchors[
          self._phase]:
        self._waiting = True
        self._anchor = max(prepared.anchors[self._phase], before)
        break
      if t < prepared.duration:
        break
      remaining = t - prepared.duration
      self._next_clip()

  def _next_clip(self):
    """Ends the current clip: the next one, after a blend, or the end."""
    if (self._sequence_length is not None
        and self._k + 1 >= self._sequence_length):
      self._finished = True
      self._linear = self._offset + self._current.duration
      return
    self._place(self._current.positions[-1], self._from)
    self._start_clip(self._k + 1)
    self._place(self._current.positions[0], self._delta)
    self._delta -= self._from
    distance = float(np.max(np.linalg.norm(self._delta, axis=1)))
    if distance > TRANSITION_TOLERANCE:
      duration = _MIN_JERK_PEAK_RATE * distance / self._transition_speed
      self._transition = (0.0, duration)

  def trigger(self, event):
    """The task reports `event`; ends the current wait if it is for it.

    Returns whether it ended a wait. Events while not waiting for them are
    ignored, so a task calls this every step while its predicate holds.
    """
    if not self._ready or not self._waiting:
      return False
    if self._current.events[self._phase] != event:
      return False
    t_a = self._warped(self._linear - self._offset - self._anchor)
    self._offset = self._linear - t_a
    self._waiting = False
    self._phase += 1
    self._update_outputs()
    return True

  # --------------------------------------------------------------- outputs
  def _update_outputs(self):
    if self._transition is not None:
      elapsed, duration = self._transition
      weight, rate = _min_jerk(elapsed / duration)
      np.multiply(self._delta, weight, out=self._positions)
      self._positions += self._from
      np.multiply(self._delta, rate / duration, out=self._velocities)
      return
    prepared = self._current
    t, rate = self._clip_time_and_rate()
    if self._finished:
      rate = 0.0
    frame = t * prepared.fps
    i = min(int(frame), prepared.last)
    step = prepared.steps[i]
    np.multiply(step, frame - i, out=self._local)
    self._local += prepared.positions[i]
    self._place(self._local, self._positions)
    np.multiply(step, rate * prepared.fps, out=self._local_vel)
    player_kernels.rotate(self._local_vel, self._rot_t, self._velocities)

  @property
  def positions(self):
    """(NUM_KEYPOINTS, 3) world positions now (a view; copy to keep)."""
    return self._positions

  @property
  def velocities(self):
    """(NUM_KEYPOINTS, 3) world velocities now, m/s (a view)."""
    return self._velocities

  @property
  def waiting_for(self):
    """The event the human waits for now, or None."""
    if self._waiting and self._transition is None:
      return self._current.events[self._phase]
    return None

  @property
  def clips(self):
    """The clips this player draws from, in the order given."""
    return tuple(p.clip for p in self._clips)

  @property
  def clip(self):
    return self._current.clip

  @property
  def clip_index(self):
    """How many clips of the episode started before the current one (0
    during the first; it grows by one each time a clip ends)."""
    return self._k

  @property
  def clip_time(self):
    """Seconds into the current clip (0 during a blend into it)."""
    if self._transition is not None:
      return 0.0
    return self._clip_time_and_rate()[0]

  @property
  def episode_time(self):
    return self._episode_time

  @property
  def in_transition(self):
    return self._transition is not None

  @property
  def motion_finished(self):
    """True once the last clip of a finite sequence has played to its end."""
    return self._finished

  @property
  def placement(self):
    """(x, y, yaw) of the clip frame in the world this episode."""
    return self._placement

  @property
  def idle_parameters(self):
    """Per idle phase of the current clip: (amplitudes u_i, speeds S_i) drawn
    for this episode; w_i = S_i / u_i."""
    return [(np.array(u), np.array(sp)) for u, sp in zip(self._u, self._speed)]

  @property
  def targets_world(self):
    """The current clip's targets placed in the world."""
    return self._targets_world

  # ------------------------------------------------------------------ state
  def get_state(self):
    """Everything needed to restore this exact moment (JSON-able values)."""
    if not self._ready:
      raise RuntimeError('Player.get_state before reset(random_state)')
    return {
        'seed': self._seed, 'k': self._k,
        'placement': list(self._placement),
        'episode_time': self._episode_time, 'linear': self._linear,
        'offset': self._offset, 'phase': self._phase,
        'waiting': self._waiting, 'anchor': self._anchor,
        'finished': self._finished,
        'transition': None if self._transition is None else list(
            self._transition),
        'transition_from': self._from.tolist(),
        'transition_delta': self._delta.tolist(),
    }

  def set_state(self, state):
    """Restores a state from get_state (same clips and constructor args)."""
    try:
      self._placement = tuple(float(v) for v in state['placement'])
      self._seed = int(state['seed'])
      self._set_placement()
      self._start_clip(int(state['k']))
      self._episode_time = float(state['episode_time'])
      self._linear = float(state['linear'])
      self._offset = float(state['offset'])
      self._phase = int(state['phase'])
      self._waiting = bool(state['waiting'])
      self._anchor = float(state['anchor'])
      self._finished = bool(state['finished'])
      transition = state['transition']
      self._transition = None if transition is None else (
          float(transition[0]), float(transition[1]))
      self._from[:] = state['transition_from']
      self._delta[:] = state['transition_delta']
    except (KeyError, TypeError, ValueError) as e:
      raise ValueError(f'Bad player state: {e!r}') from e
    if self._phase > len(self._current.anchors):
      raise ValueError(f'Bad player state: phase {self._phase} of a clip with '
                       f'{len(self._current.anchors)} idle phases')
    self._ready = True
    self._update_outputs()
