"""Synthetic human motion: minimum-jerk movements between task key poses.

A `Script` is written move by move (walk, reach, lean, hold ...); each move
drives some pose channels from their current value to a new one along a
minimum-jerk profile (Flash & Hogan 1985: the smoothest point-to-point human
arm movement, straight hand path, bell-shaped speed). Hand targets are kept in
the pelvis heading frame, so hands travel with the body, and are met exactly
at the end of a reach by the arm's two-link solution (`body.py`). Steps are
planned under the pelvis during walks. On top come breathing, postural sway
and small idle drifts of the hands and head. `render` turns the script into a
`Clip`. The per-task scripts are `task_motions.py`;
hrc_suite/motion_tools/synthetic_library.py runs them into clips and writes
the shipped library. Every clip is checked
against the shield's 2 m/s human speed, also while an idle phase warps it
(`idle_speed_bound`, `fit_idle_phases`).
"""

import dataclasses
import math

import numpy as np

from hrc_suite import rotations
from hrc_suite.human import body as body_lib
from hrc_suite.human import clip as clip_lib

DEFAULT_FPS = 25.0
LIBRARY_SEED = 20240521

# Speeds. Peak pelvis speed while walking: the swing foot moves at about
# pi times the pelvis speed, and every keypoint must stay below the shield's
# 2 m/s (clip.MAX_KEYPOINT_SPEED); slow walking suits work at a table.
MAX_WALK_SPEED = 0.55
# Peak hand speed of ordinary reaches (recorded HRC reaches peak at 0.5-2 m/s).
MAX_HAND_SPEED = 1.8
# Minimum-jerk peak speed = 15/8 x mean speed.
MIN_JERK_PEAK_RATIO = 1.875
# Foot swing: travel per step at most, lift height (metres).
MAX_STEP = 0.45
FOOT_LIFT = 0.05
# Quiet standing: knee flex lowers the pelvis below the straight-leg height.
STANDING_KNEE_DROP = 0.015
WALKING_KNEE_DROP = 0.035
# Stored positions are rounded to 2**-12 m (0.24 mm): the zeroed low mantissa
# bits let np.savez_compressed shrink the library about threefold.
POSITION_QUANTUM = 2.0 ** -12
# Breathing 12-20 breaths/min (0.2-0.33 Hz); postural sway of the body centre
# in quiet stance is a few millimetres at 0.1-0.5 Hz.
BREATH_HZ = (0.2, 0.33)
BREATH_LEAN = 0.008       # rad
SWAY_AMPLITUDE = 0.02     # m
SWAY_HZ = (0.1, 0.6)
TORSO_WANDER = 0.05       # rad, lean and twist
HAND_DRIFT = 0.02         # m
HAND_DRIFT_HZ = (0.2, 0.9)
# Arm swing while walking: forward/back excursion of a free hand (m) at the
# step rhythm, opposite to the leg on its side.
ARM_SWING = 0.09
# A free hand follows the other hand's excursion from rest by this fraction
# (mirrored sideways): the idle arm moves along with a reach.
SYMPATHETIC_FRACTION = 0.3
HEAD_WANDER = 0.06        # rad

# Shortest duration of a move queued behind a still running one (s).
MIN_QUEUED_MOVE = 0.3

# Idle phases. The player replays a waiting clip at d t_A / dt = sum_i S_i
# cos(w_i (t - t_I)), at most sum_i S_i x f**3 with the randomisation factor
# f**clip(N(0, 1), -3, 3), anywhere in t_I +- sum_i u_i x f**3 (clip.py). The
# generator keeps (peak keypoint speed in that window, outside fast phases) x
# (peak replay rate) below this limit, a margin under the shield's 2 m/s
# (clip.MAX_KEYPOINT_SPEED), by slowing the phase's S_i where needed.
IDLE_SPEED_LIMIT = 1.9
# Slowest the generator may make an idle phase (fraction of its authored S_i);
# a script that needs more should hold still longer around its keyframe.
MIN_IDLE_SPEED_SCALE = 0.4
# Highest idle sine frequency w_i / 2 pi (Hz) under the widest randomisation
# (S_i x f**3 over u_i / f**3): a waiting person shifts and sways at a few
# tenths of a hertz (postural sway 0.1-0.5 Hz, see SWAY_HZ), never jitters.
MAX_IDLE_HZ = 0.5
# Stored idle slopes are rounded down to this step.
IDLE_SPEED_QUANTUM = 1e-3

SCALAR_CHANNELS = ('pelvis_drop', 'yaw', 'lean', 'side', 'twist',
                   'head_pitch', 'head_yaw', 'left_swivel', 'right_swivel',
                   'left_wrist', 'right_wrist')
HAND_CHANNELS = ('left_hand', 'right_hand')


def minimum_jerk(s):
  """Normalised minimum-jerk position profile on s in [0, 1]."""
  s = np.clip(s, 0.0, 1.0)
  return s ** 3 * (10 - 15 * s + 6 * s ** 2)


def _smooth_step(s):
  """Cosine profile: zero speed at both ends, peak pi/2 x mean speed."""
  return 0.5 - 0.5 * np.cos(np.pi * np.clip(s, 0.0, 1.0))


class Channel:
  """One pose parameter as a sequence of minimum-jerk segments."""

  def __init__(self, value):
    self.value = np.atleast_1d(np.asarray(value, dtype=np.float64)).copy()
    self.segments = []   # (t0, t1, v0, v1)
    self.end_time = 0.0

  def move(self, t0, t1, value):
    if t0 < self.end_time - 1e-9:
      # A move that starts while this channel is still moving begins when
      # the previous one ends; it keeps its end time if at least
      # MIN_QUEUED_MOVE is left, else it lasts MIN_QUEUED_MOVE.
      t0 = self.end_time
      t1 = max(t1, t0 + MIN_QUEUED_MOVE)
    value = np.atleast_1d(np.asarray(value, dtype=np.float64))
    self.segments.append((t0, t1, self.value.copy(), value.copy()))
    self.value = value.copy()
    self.end_time = t1

  def sample(self, times):
    out = np.empty((len(times), self.value.shape[0]))
    first = self.segments[0][2] if self.segments else self.value
    out[:] = first
    for t0, t1, v0, v1 in self.segments:
      after = times >= t0
      s = (times[after] - t0) / max(t1 - t0, 1e-9)
      out[after] = v0 + (v1 - v0) * minimum_jerk(s)[:, None]
    return out


class Script:
  """Builds one clip move by move; `t` is the script's time cursor (s)."""

  def __init__(self, body, random_state, name, task, tempo=1.0):
    self.body = body
    self.random_state = random_state
    self.name = name
    self.task = task
    self.tempo = tempo
    self.t = 0.0
    standing = body.hip_height - STANDING_KNEE_DROP
    self.standing_height = standing
    self.channels = {'pelvis_xy': Channel([0.0, 0.0])}
    for name_ in SCALAR_CHANNELS:
      self.channels[name_] = Channel(0.0)
    self.channels['left_wrist'] = Channel(0.2)
    self.channels['right_wrist'] = Channel(0.2)
    for side, hand in enumerate(HAND_CHANNELS):
      self.channels[hand] = Channel(self.rest_hand(side))
    self.walks = []
    self.keyframe_times = []
    self.idle_phases = []   # (keyframe index, event, amplitudes, speeds)
    self.fast_times = []
    self.targets = {}
    self.holding_hand = None
    self.placing_hand = None
    self.metadata = {}

  # ------------------------------------------------------------ state access

  def value(self, channel):
    v = self.channels[channel].value
    return v if v.shape[0] > 1 else float(v[0])

  def rest_hand(self, side, forward=0.04, height=None):
    """Palm centre of a relaxed hanging arm, pelvis heading frame."""
    b = self.body
    sign = 1.0 if side == 0 else -1.0
    if height is None:
      height = (self.body.hip_height - STANDING_KNEE_DROP) - 0.07 * b.stature
    return np.array([forward, sign * (b.shoulder_width / 2 + 0.03), height])

  def to_local(self, point, pelvis_xy=None, yaw=None):
    """A clip-frame point in the pelvis heading frame (z unchanged)."""
    pelvis_xy = self.value('pelvis_xy') if pelvis_xy is None else pelvis_xy
    yaw = self.value('yaw') if yaw is None else yaw
    d = np.asarray(point[:2]) - pelvis_xy
    return rotations.yaw_to_mat(yaw).T @ [d[0], d[1], point[2]]

  def to_world(self, local, pelvis_xy=None, yaw=None):
    pelvis_xy = self.value('pelvis_xy') if pelvis_xy is None else pelvis_xy
    yaw = self.value('yaw') if yaw is None else yaw
    return [pelvis_xy[0], pelvis_xy[1], 0.0] + rotations.yaw_to_mat(
        yaw) @ np.asarray(local, float)

  def hand_world(self, side):
    return self.to_world(self.value(HAND_CHANNELS[side]))

  def shoulder_world(self, side, lean=None, twist=None, drop=None):
    """Shoulder centre for the current (or given) torso parameters."""
    pose = self._static_pose(lean=lean, twist=twist, drop=drop)
    return body_lib.shoulder_positions(self.body, pose)[0, side]

  def _static_pose(self, lean=None, twist=None, drop=None):
    one = lambda v: np.array([float(v)])
    xy = self.value('pelvis_xy')
    drop = self.value('pelvis_drop') if drop is None else drop
    return body_lib.Pose(
        pelvis=np.array([[xy[0], xy[1], self.standing_height - drop]]),
        yaw=one(self.value('yaw')),
        lean=one(self.value('lean') if lean is None else lean),
        side=one(self.value('side')),
        twist=one(self.value('twist') if twist is None else twist),
        head_pitch=one(0), head_yaw=one(0), hands=np.zeros((1, 2, 3)),
        swivel=np.zeros((1, 2)), wrist_bend=np.zeros((1, 2)),
        ankles=np.zeros((1, 2, 3)))

  # ------------------------------------------------------------------ moves

  def move(self, duration, start=None, advance=True, **values):
    """Moves the given channels to new values over `duration` seconds."""
    t0 = self.t if start is None else start
    t1 = t0 + duration
    for name, value in values.items():
      if name not in self.channels:
        raise ValueError(f'Unknown channel {name!r}: expected one of '
                         f'{", ".join(self.channels)}')
      self.channels[name].move(t0, t1, value)
    if advance:
      self.t = max(self.t, t1)
    return t1

  def hold(self, duration):
    self.t += duration

  def mark(self):
    """Records a keyframe at the cursor; returns its index."""
    self.keyframe_times.append(self.t)
    return len(self.keyframe_times) - 1

  def idle(self, event, amplitudes, speeds):
    """An idle phase anchored at a new keyframe at the cursor."""
    index = self.mark()
    self.idle_phases.append((index, event, list(amplitudes), list(speeds)))
    return index

  def reach_duration(self, distance, speed_scale=1.0):
    """Duration of a reach over `distance`: tempo plus a hand-speed cap."""
    base = (0.35 + 0.9 * distance) * self.tempo
    cap = MIN_JERK_PEAK_RATIO * distance / (MAX_HAND_SPEED * speed_scale)
    return max(base, cap)

  def lean_for(self, side, target, margin=0.96, max_lean=0.7):
    """Smallest forward lean (and knee drop) that brings target in reach."""
    reach = self.body.arm_reach * margin
    base = self.value('lean')
    low = target[2] < self.body.hip_height * 0.9
    for lean in np.linspace(max(base, 0.0), max_lean, 36):
      drop = 0.0
      if low:
        drop = min(0.12, 0.2 * lean)
      shoulder = self.shoulder_world(side, lean=lean, drop=drop)
      if np.linalg.norm(np.asarray(target) - shoulder) <= reach:
        return float(lean), float(drop)
    return float(max_lean), 0.12

  def reach(self, side, target, duration=None, lean=None, swivel=None,
            wrist=None, advance=True, start=None, speed_scale=1.0, **extra):
    """Moves palm `side` (0 left, 1 right) to a clip-frame target."""
    target = np.asarray(target, dtype=np.float64)
    if lean is None and 'lean' not in extra:
      lean, drop = self.lean_for(side, target)
      extra.setdefault('pelvis_drop', drop)
    if lean is not None:
      extra['lean'] = lean
    distance = np.linalg.norm(target - self.hand_world(side))
    if duration is None:
      duration = self.reach_duration(distance, speed_scale)
    values = {HAND_CHANNELS[side]: self.to_local(target)}
    if swivel is not None:
      values[('left_swivel', 'right_swivel')[side]] = swivel
    if wrist is not None:
      values[('left_wrist', 'right_wrist')[side]] = wrist
    values.update(extra)
    return self.move(duration, start=start, advance=advance, **values)

  def reach_both(self, targets, duration=None, lean=None, speed_scale=1.0,
                 advance=True, **extra):
    """Moves both palms (left, right) to clip-frame targets together."""
    targets = [np.asarray(t, dtype=np.float64) for t in targets]
    if lean is None:
      leans = [self.lean_for(side, t) for side, t in enumerate(targets)]
      lean, drop = max(leans)
      extra.setdefault('pelvis_drop', drop)
    distance = max(np.linalg.norm(t - self.hand_world(side))
                   for side, t in enumerate(targets))
    if duration is None:
      duration = self.reach_duration(distance, speed_scale)
    values = {hand: self.to_local(t) for hand, t in zip(HAND_CHANNELS,
                                                        targets)}
    values.update(extra)
    return self.move(duration, advance=advance, lean=lean, **values)

  def start_at(self, xy, yaw=0.0):
    """Sets the initial pelvis position and heading (before any move)."""
    if any(c.segments for c in self.channels.values()):
      raise ValueError('start_at must come before the first move')
    self.channels['pelvis_xy'] = Channel(xy)
    self.channels['yaw'] = Channel(yaw)
    self.channels['pelvis_drop'] = Channel(WALKING_KNEE_DROP)

  def rest(self, side, duration=None, advance=True, start=None, **extra):
    """Lowers hand `side` to the relaxed hanging pose."""
    target = self.to_world(self.rest_hand(side))
    distance = np.linalg.norm(target - self.hand_world(side))
    if duration is None:
      duration = self.reach_duration(distance)
    values = {HAND_CHANNELS[side]: self.rest_hand(side),
              ('left_wrist', 'right_wrist')[side]: 0.2,
              ('left_swivel', 'right_swivel')[side]: 0.0}
    values.update(extra)
    return self.move(duration, start=start, advance=advance, **values)

  def fidget(self, duration, sides):
    """Holds for `duration` s while free hands make small idle gestures.

    Each hand in `sides` drifts to a few nearby spots (within ~0.15 m of its
    current place: adjusting, touching the table edge, resting on the hip)
    and comes back by the end of the hold.
    """
    rs = self.random_state
    t_end = self.t + duration
    for side in sides:
      channel = HAND_CHANNELS[side]
      home = self.channels[channel].value.copy()
      t = max(self.t, self.channels[channel].end_time)
      while t_end - t > 0.9:   # One gesture: out, short pause, back.
        total = min(t_end - t, rs.uniform(1.2, 2.0))
        offset = rs.uniform([-0.08, -0.1, -0.05], [0.2, 0.1, 0.2])
        offset *= min(1.0, total / 1.6)
        offset[1] *= 1.0 if side == 0 else -1.0
        self.move(0.45 * total, start=t, advance=False,
                  **{channel: home + offset})
        self.move(0.45 * total, start=t + 0.55 * total, advance=False,
                  **{channel: home})
        t += total
    self.t = max(self.t, t_end)

  def walk(self, to_xy, yaw=None, duration=None):
    """Walks the pelvis to `to_xy` (and heading `yaw`), stepping."""
    start = self.value('pelvis_xy')
    to_xy = np.asarray(to_xy, dtype=np.float64)
    yaw0 = self.value('yaw')
    yaw = yaw0 if yaw is None else yaw
    distance = float(np.linalg.norm(to_xy - start))
    turn = abs(yaw - yaw0)
    minimum = max(MIN_JERK_PEAK_RATIO * distance / MAX_WALK_SPEED,
                  1.2 * turn, 1.0)
    duration = max(minimum, (duration or 0.0))
    t0 = self.t
    t1 = self.move(duration, pelvis_xy=to_xy, yaw=yaw,
                   pelvis_drop=WALKING_KNEE_DROP, lean=0.0)
    self.walks.append((t0, t1))
    return t1

  def strike(self, side, contact, raised, up_time, down_time, rest_time):
    """One hammer blow: raise, strike (a documented fast phase), rest."""
    self.reach(side, raised, duration=up_time, lean=self.value('lean'))
    t0 = self.t
    self.reach(side, contact, duration=down_time, lean=self.value('lean'),
               speed_scale=10.0)
    self.fast_times.append((t0, self.t))
    self.hold(rest_time)

  # -------------------------------------------------------------- rendering

  def _feet(self, times, pelvis_xy_at, yaw_at):
    """(T, 2, 3) ankle positions from the walks: alternating steps."""
    b = self.body
    half = b.hip_width / 2 + 0.01

    def stance(t):
      xy = pelvis_xy_at(np.array([t]))[0]
      yaw = yaw_at(np.array([t]))[0]
      return [[xy[0], xy[1], b.ankle_height] + rotations.yaw_to_mat(yaw)
              @ [0.0, sign * half, 0.0] for sign in (1.0, -1.0)]

    steps = ([], [])   # per foot: (t0, t1, p0, p1)
    self._step_plans = []
    feet = stance(0.0)
    for t0, t1 in self.walks:
      travel = np.linalg.norm(pelvis_xy_at(np.array([t1]))[0]
                              - pelvis_xy_at(np.array([t0]))[0])
      turn = abs(yaw_at(np.array([t1]))[0] - yaw_at(np.array([t0]))[0])
      n = max(2, int(math.ceil(2 * travel / MAX_STEP)) + 1,
              int(math.ceil(turn / 0.6)) + 1)
      slot = (t1 - t0) / n
      first = self.random_state.randint(2)
      self._step_plans.append((slot, first))
      for k in range(n):
        foot = (first + k) % 2
        s0, s1 = t0 + k * slot, t0 + (k + 1) * slot
        if k >= n - 2:
          target = stance(t1)[foot]
        else:
          target = stance(min(s1 + slot / 2, t1))[foot]
        steps[foot].append((s0, s1, feet[foot].copy(), target))
        feet[foot] = target
    out = np.empty((len(times), 2, 3))
    initial = stance(0.0)
    for foot in range(2):
      out[:, foot] = initial[foot]
      for s0, s1, p0, p1 in steps[foot]:
        after = times >= s0
        s = (times[after] - s0) / (s1 - s0)
        blend = _smooth_step(s)[:, None]
        out[after, foot] = p0 + (p1 - p0) * blend
        inside = after & (times <= s1)
        lift = FOOT_LIFT * np.sin(np.pi * s[inside[after]]) ** 2
        out[inside, foot, 2] += lift
    return out

  def _free(self, local_hand, side):
    """1 where a hand hangs at rest, fading to 0 at 0.12 m from rest."""
    rest = self.rest_hand(side)
    return np.clip(1.0 - np.linalg.norm(local_hand - rest, axis=-1) / 0.12,
                   0.0, 1.0)

  def _arm_swing(self, times, side, local_hand):
    """Forward offset of a hanging hand swinging with the steps."""
    free = self._free(local_hand, side)
    swing = np.zeros(len(times))
    for (t0, t1), (slot, first) in zip(self.walks, self._step_plans):
      inside = (times > t0) & (times < t1)
      s = (times[inside] - t0) / (t1 - t0)
      envelope = np.sin(np.pi * s) ** 2
      # One full swing cycle per two steps; the hand on the side of the
      # first swinging foot starts backwards.
      phase = np.pi * (times[inside] - t0) / slot
      sign = 1.0 if side == first else -1.0
      swing[inside] = -sign * ARM_SWING * envelope * np.sin(phase)
    return swing * free

  def _idle_noise(self, times, amplitude, count=3, low=0.08, high=0.5):
    """Smooth zero-mean wander: a sum of sines with random frequencies."""
    rs = self.random_state
    freqs = rs.uniform(low, high, count)
    phases = rs.uniform(0, 2 * np.pi, count)
    weights = rs.uniform(0.5, 1.0, count)
    weights *= amplitude / weights.sum()
    return (weights * np.sin(2 * np.pi * freqs * times[:, None]
                             + phases)).sum(-1)

  def render(self, fps=DEFAULT_FPS, tail=0.5):
    """The script as a validated Clip."""
    self.hold(tail)
    duration = self.t
    num_frames = int(math.floor(duration * fps)) + 1
    times = np.arange(num_frames) / fps
    ch = {name: c.sample(times) for name, c in self.channels.items()}
    scalar = {name: ch[name][:, 0] for name in SCALAR_CHANNELS}
    sway = np.stack([self._idle_noise(times, SWAY_AMPLITUDE, 3, *SWAY_HZ),
                     self._idle_noise(times, SWAY_AMPLITUDE, 3, *SWAY_HZ)], -1)
    pelvis_xy = ch['pelvis_xy'] + sway
    yaw = scalar['yaw']
    breath_hz = self.random_state.uniform(*BREATH_HZ)
    lean = (scalar['lean'] + self._idle_noise(times, TORSO_WANDER)
            + BREATH_LEAN * np.sin(2 * np.pi * breath_hz * times
                                   + self.random_state.uniform(0, 6.28)))
    pelvis_channel = self.channels['pelvis_xy']
    yaw_channel = self.channels['yaw']
    ankles = self._feet(times, pelvis_channel.sample,
                        lambda t: yaw_channel.sample(t)[:, 0])
    hands = np.empty((num_frames, 2, 3))
    turns = rotations.yaw_to_mat(yaw)
    rest = [self.rest_hand(side) for side in range(2)]
    for side, hand in enumerate(HAND_CHANNELS):
      other = ch[HAND_CHANNELS[1 - side]] - rest[1 - side]
      other[:, 1] *= -1.0
      local = ch[hand] + self._free(ch[hand], side)[:, None] * (
          SYMPATHETIC_FRACTION * other)
      local = local + np.stack([self._idle_noise(
          times, HAND_DRIFT, 4, *HAND_DRIFT_HZ) for _ in range(3)], -1)
      local[:, 0] += self._arm_swing(times, side, ch[hand])
      hands[:, side, :2] = pelvis_xy + np.einsum(
          'fij,fj->fi', turns, local)[:, :2]
      hands[:, side, 2] = local[:, 2]
    pose = body_lib.Pose(
        pelvis=np.concatenate([pelvis_xy, (self.standing_height
                                           - scalar['pelvis_drop'])[:, None]],
                              -1),
        yaw=yaw, lean=lean, side=scalar['side'],
        twist=scalar['twist'] + self._idle_noise(times, TORSO_WANDER),
        head_pitch=scalar['head_pitch'],
        head_yaw=scalar['head_yaw'] + self._idle_noise(times, HEAD_WANDER),
        hands=hands,
        swivel=np.stack([scalar['left_swivel'], scalar['right_swivel']], -1),
        wrist_bend=np.stack([scalar['left_wrist'], scalar['right_wrist']], -1),
        ankles=ankles)
    positions = body_lib.forward_kinematics(self.body, pose)
    positions = np.round(positions / POSITION_QUANTUM) * POSITION_QUANTUM
    to_frame = lambda t: int(min(round(t * fps), num_frames - 1))
    keyframes = [to_frame(t) for t in self.keyframe_times]
    fast = []
    for t0, t1 in self.fast_times:
      start = max(0, int(math.floor(t0 * fps)) - 1)
      fast.append((start, min(num_frames - 1, int(math.ceil(t1 * fps)) + 1)))
    phases = tuple(clip_lib.IdlePhase(
        keyframe=k, event=event, amplitudes=np.array(a), speeds=np.array(sp))
                   for k, event, a, sp in self.idle_phases)
    metadata = dict(self.metadata)
    metadata.update({'source': 'hrc_suite.human.synthesis',
                     'anthropometrics': self.body.to_json(),
                     'tempo': round(float(self.tempo), 4)})
    clip = clip_lib.Clip(
        name=self.name, task=self.task, fps=float(fps),
        positions=positions.astype(np.float32), keyframes=tuple(keyframes),
        idle_phases=phases, holding_hand=self.holding_hand,
        placing_hand=self.placing_hand,
        targets={k: np.round(np.asarray(v, float), 4)
                 for k, v in self.targets.items()},
        fast_phases=tuple(_merge_spans(fast)), metadata=metadata)
    return clip_lib.validate(clip, source=f'synthesised clip {self.name!r}')


def idle_window(phase):
  """Largest |t_A - t_I| (s) of a phase's warp over all randomisations."""
  return float(np.sum(np.abs(phase.amplitudes))) * (
      phase.amplitude_std_factor ** 3)


def idle_max_rate(phase):
  """Largest replay rate |d t_A / dt| of a phase over all randomisations."""
  return float(np.sum(np.abs(phase.speeds))) * phase.speed_std_factor ** 3


def idle_max_hz(phase):
  """Highest sine frequency (Hz) of a phase over all randomisations."""
  omegas = np.abs(phase.speeds) / phase.amplitudes
  factor = (phase.speed_std_factor * phase.amplitude_std_factor) ** 3
  return float(omegas.max()) * factor / (2 * np.pi)


def idle_window_speed(clip, phase):
  """Peak keypoint speed (m/s) of `clip` in the phase's warp window.

  Frame intervals inside `clip.fast_phases` are left out; the window is
  widened by one frame on each side (the player anchors the wait at the
  first step at or after t_I).
  """
  speeds = clip_lib.keypoint_speeds(clip).max(axis=1)
  for start, end in clip.fast_phases:
    speeds[start:end] = 0.0
  t_i = clip.keyframe_time(phase.keyframe)
  reach = idle_window(phase)
  first = max(0, int(math.floor((t_i - reach) * clip.fps)) - 1)
  last = min(len(speeds), int(math.ceil((t_i + reach) * clip.fps)) + 1)
  return float(speeds[first:last].max()) if last > first else 0.0


def idle_speed_bound(clip, phase):
  """Worst-case keypoint speed (m/s) while `clip` waits in `phase`.

  (peak clip speed in the warp window) x (peak replay rate): a bound on every
  keypoint's speed outside fast phases for any randomisation and any wait.
  """
  return idle_window_speed(clip, phase) * idle_max_rate(phase)


def fit_idle_phases(clip, limit=IDLE_SPEED_LIMIT):
  """`clip` with each idle phase's S_i scaled so idle_speed_bound <= limit.

  The window depends on the amplitudes only, so one scaling suffices; the
  applied scales go into metadata['idle_speed_scales']. Raises ValueError if
  a phase jitters (above MAX_IDLE_HZ) or needs slowing below
  MIN_IDLE_SPEED_SCALE.
  """
  phases, scales = [], []
  for i, phase in enumerate(clip.idle_phases):
    if idle_max_hz(phase) > MAX_IDLE_HZ:
      raise ValueError(
          f'{clip.name} idle phase {i} ({phase.event}): sines up to '
          f'{idle_max_hz(phase):.2f} Hz, expected at most {MAX_IDLE_HZ} Hz '
          f'(u = {phase.amplitudes.tolist()} s, S = {phase.speeds.tolist()})')
    bound = idle_speed_bound(clip, phase)
    scale = 1.0
    if bound > limit:
      scale = limit / bound
      if scale < MIN_IDLE_SPEED_SCALE:
        raise ValueError(
            f'{clip.name} idle phase {i} ({phase.event}): worst-case speed '
            f'{bound:.2f} m/s needs the idle slopes scaled by {scale:.2f}, '
            f'expected at least {MIN_IDLE_SPEED_SCALE}: hold still longer '
            f'around the keyframe')
      speeds = np.floor(phase.speeds * scale / IDLE_SPEED_QUANTUM) * (
          IDLE_SPEED_QUANTUM)
      phase = dataclasses.replace(phase, speeds=speeds)
    phases.append(phase)
    scales.append(round(scale, 4))
  if not phases:
    return clip
  metadata = dict(clip.metadata, idle_speed_scales=scales)
  return clip.replace(idle_phases=tuple(phases), metadata=metadata)


def _merge_spans(spans):
  merged = []
  for start, end in sorted(spans):
    if merged and start <= merged[-1][1]:
      merged[-1] = (merged[-1][0], max(end, merged[-1][1]))
    else:
      merged.append((start, end))
  return merged
