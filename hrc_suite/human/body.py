"""A parametric human body: anthropometrics and kinematics to keypoints.

Segment lengths follow the classic proportions of stature H (Drillis and
Contini 1966, as tabulated in D. A. Winter, "Biomechanics and Motor Control of
Human Movement", 4th ed. 2009, Fig. 4.1), with H drawn from the German adult
population of DIN 33402-2:2005-12 (18 to 65 years). Every sampled body lies
between the 5th-percentile woman and the 95th-percentile man of stature, and
each segment is varied by a few percent around its proportional length, so
segment lengths stay within `SEGMENT_RANGES`.

Kinematics: a pose is a handful of parameters per frame (pelvis position and
heading, torso lean / side bend / twist, head pitch / yaw, hand targets with
elbow swivel and wrist bend, ankle targets). Arms and legs are solved as
two-link chains, so every segment keeps its exact length in every frame.
"""

import dataclasses

import numpy as np

from hrc_suite import rotations
from hrc_suite.human import keypoints

_about = rotations.about_axis
X, Y, Z = rotations.X, rotations.Y, rotations.Z

# DIN 33402-2:2005-12, stature (Koerperhoehe) in metres: 5th / 50th / 95th
# percentile of women and of men, German adults 18-65 years.
STATURE_WOMEN = (1.535, 1.625, 1.720)
STATURE_MEN = (1.650, 1.750, 1.855)
STATURE_RANGE = (STATURE_WOMEN[0], STATURE_MEN[2])
# DIN 33402-2:2005-12, hand length (wrist crease to fingertip), 5th-percentile
# woman to 95th-percentile man, metres.
HAND_LENGTH_RANGE = (0.165, 0.206)

# Proportions of stature H (Winter 2009, Fig. 4.1, after Drillis & Contini).
HIP_HEIGHT_FRACTION = 0.530        # greater trochanter above the floor.
SHOULDER_HEIGHT_FRACTION = 0.818   # acromion above the floor.
UPPER_ARM_FRACTION = 0.186
FOREARM_FRACTION = 0.146
HAND_FRACTION = 0.108
THIGH_FRACTION = 0.245
SHIN_FRACTION = 0.246
ANKLE_HEIGHT_FRACTION = 0.039
SHOULDER_BREADTH_FRACTION = 0.259  # bideltoid breadth.
HIP_BREADTH_FRACTION = 0.191
EYE_HEIGHT_FRACTION = 0.936

# Modelling choices for joint centres (not in the tables): shoulder joint
# centres sit about 0.04 m inside the deltoid surface on each side, hip joint
# centres about a quarter of the hip breadth either side of the midline (Bell
# et al. 1990 place them ~0.36 of the inter-ASIS width from the midline), the
# neck keypoint (C7 / suprasternal level) 0.012 H above the acromion, the head
# keypoint at eye level (head centre), the hand keypoint at the middle of the
# palm (0.45 of the hand length from the wrist).
SHOULDER_JOINT_INSET = 0.04
HIP_JOINT_FRACTION_OF_BREADTH = 0.5
NECK_ABOVE_SHOULDER_FRACTION = 0.012
SHOULDER_BELOW_NECK_FRACTION = 0.03
PALM_FRACTION_OF_HAND = 0.45
TORSO_KEYPOINT_ALONG_SPINE = 0.33  # pelvis -> neck.
CHEST_KEYPOINT_ALONG_SPINE = 0.66

# Per-segment variation around the proportional length: relative standard
# deviation, truncated at +-2 sigma.
SEGMENT_VARIATION = 0.03
_TRUNCATION = 2.0


def _stature_sd(percentiles):
  # For a normal distribution P95 - P5 = 2 * 1.645 sd.
  return (percentiles[2] - percentiles[0]) / (2 * 1.645)


@dataclasses.dataclass(frozen=True)
class Anthropometrics:
  """Lengths (metres) of one body; keypoint-to-keypoint distances."""
  stature: float
  shoulder_width: float   # between shoulder joint centres.
  hip_width: float        # between hip joint centres.
  spine: float            # pelvis -> neck keypoint.
  head: float             # neck -> head keypoint.
  upper_arm: float
  forearm: float
  hand: float             # wrist -> palm centre (hand keypoint).
  thigh: float
  shin: float
  ankle_height: float

  @property
  def hip_height(self):
    return self.thigh + self.shin + self.ankle_height

  @property
  def arm_reach(self):
    """Shoulder to palm centre with the arm straight."""
    return self.upper_arm + self.forearm + self.hand

  def segment_lengths(self):
    """Length of each segment of `keypoints.SEGMENTS`, by name."""
    by_part = {'head': self.head, 'torso': self.spine,
               'upper_arm': self.upper_arm, 'forearm': self.forearm,
               'hand': self.hand, 'thigh': self.thigh, 'shin': self.shin}
    return {name: by_part[name.split('_', 1)[-1] if '_' in name else name]
            for name, _, _ in keypoints.SEGMENTS}

  def to_json(self):
    return {k: round(float(v), 5) for k, v in dataclasses.asdict(self).items()}


def proportional_body(stature):
  """The body of stature `stature` with exactly the tabulated proportions."""
  h = float(stature)
  if not STATURE_RANGE[0] - 1e-9 <= h <= STATURE_RANGE[1] + 1e-9:
    raise ValueError(f'Stature {h!r} m outside the DIN 33402-2 5th-95th '
                     f'percentile range {STATURE_RANGE}')
  neck_height = (SHOULDER_HEIGHT_FRACTION + NECK_ABOVE_SHOULDER_FRACTION) * h
  return Anthropometrics(
      stature=h,
      shoulder_width=SHOULDER_BREADTH_FRACTION * h - 2 * SHOULDER_JOINT_INSET,
      hip_width=HIP_JOINT_FRACTION_OF_BREADTH * HIP_BREADTH_FRACTION * h,
      spine=neck_height - HIP_HEIGHT_FRACTION * h,
      head=(EYE_HEIGHT_FRACTION * h) - neck_height,
      upper_arm=UPPER_ARM_FRACTION * h,
      forearm=FOREARM_FRACTION * h,
      hand=PALM_FRACTION_OF_HAND * HAND_FRACTION * h,
      thigh=THIGH_FRACTION * h,
      shin=SHIN_FRACTION * h,
      ankle_height=ANKLE_HEIGHT_FRACTION * h)


def _range(field):
  low = getattr(proportional_body(STATURE_RANGE[0]), field)
  high = getattr(proportional_body(STATURE_RANGE[1]), field)
  spread = _TRUNCATION * SEGMENT_VARIATION
  return (low * (1 - spread), high * (1 + spread))


_VARIED_FIELDS = ('shoulder_width', 'hip_width', 'spine', 'head', 'upper_arm',
                  'forearm', 'hand', 'thigh', 'shin')
# Allowed length of every measure: the DIN stature range times the proportion,
# widened by the truncated per-segment variation.
MEASURE_RANGES = {field: _range(field) for field in _VARIED_FIELDS}
SEGMENT_RANGES = {
    name: MEASURE_RANGES[{'head': 'head', 'torso': 'spine'}.get(
        name, name.split('_', 1)[-1])]
    for name, _, _ in keypoints.SEGMENTS}


def sample_body(random_state, sex=None):
  """A random adult body: stature by sex from DIN 33402-2, varied segments.

  Args:
    random_state: np.random.RandomState, the only source of randomness.
    sex: 'female', 'male' or None (either, with equal probability).
  """
  if sex is None:
    sex = ('female', 'male')[random_state.randint(2)]
  if sex not in ('female', 'male'):
    raise ValueError(f'Unknown sex {sex!r}: expected "female", "male" or None')
  table = STATURE_WOMEN if sex == 'female' else STATURE_MEN
  stature = table[1] + _stature_sd(table) * random_state.randn()
  stature = float(np.clip(stature, table[0], table[2]))
  base = proportional_body(stature)
  noise = np.clip(random_state.randn(len(_VARIED_FIELDS)), -_TRUNCATION,
                  _TRUNCATION)
  varied = {f: getattr(base, f) * (1 + SEGMENT_VARIATION * n)
            for f, n in zip(_VARIED_FIELDS, noise)}
  return dataclasses.replace(base, **varied)


# ---------------------------------------------------------------- kinematics


@dataclasses.dataclass
class Pose:
  """Pose parameters over T frames (clip frame: x forward, z up), radians.

  pelvis: (T, 3) pelvis keypoint; yaw: (T,) heading of pelvis and feet;
  lean / side / twist: (T,) torso forward pitch, side bend (positive to the
  left), yaw relative to the pelvis; head_pitch / head_yaw: (T,) relative to
  the torso (positive pitch looks down); hands: (T, 2, 3) palm-centre targets
  (left, right); swivel: (T, 2) elbow angle about the shoulder-wrist axis
  (0 = elbow down and out); wrist_bend: (T, 2) downward bend of the hand from
  the forearm line; ankles: (T, 2, 3) ankle targets.
  """
  pelvis: np.ndarray
  yaw: np.ndarray
  lean: np.ndarray
  side: np.ndarray
  twist: np.ndarray
  head_pitch: np.ndarray
  head_yaw: np.ndarray
  hands: np.ndarray
  swivel: np.ndarray
  wrist_bend: np.ndarray
  ankles: np.ndarray


def _normalise(v):
  return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-12)


def torso_frame(pose):
  """(T, 3, 3) torso orientation: yaw + twist, then lean, then side bend."""
  return (_about(Z, pose.yaw + pose.twist) @ _about(Y, pose.lean)
          @ _about(X, -pose.side))


def shoulder_positions(body, pose):
  """(T, 2, 3) shoulder joint centres (left, right) for a pose."""
  frame = torso_frame(pose)
  neck = pose.pelvis + body.spine * frame[..., :, 2]
  drop = SHOULDER_BELOW_NECK_FRACTION * body.stature
  offsets = np.array([[0.0, body.shoulder_width / 2, -drop],
                      [0.0, -body.shoulder_width / 2, -drop]])
  return neck[:, None, :] + np.einsum('tij,sj->tsi', frame, offsets)


# Arms straighten softly: beyond SOFT_REACH_START of full length the reached
# distance saturates smoothly at SOFT_REACH_END, so the elbow never whips
# through the straight-arm singularity (where its speed would be unbounded).
SOFT_REACH_START = 0.93
SOFT_REACH_END = 0.985


def two_link(root, target, first, second, bend_reference, swivel,
             soft=False):
  """Middle joint of a two-link chain reaching for `target` (clamped).

  Returns (middle, end): the end lies on the ray root->target at the reachable
  distance, so both links keep their lengths exactly. `bend_reference` gives
  the direction the middle joint bends towards at swivel 0. With `soft`, the
  distance saturates smoothly near full extension.
  """
  offset = target - root
  distance = np.linalg.norm(offset, axis=-1, keepdims=True)
  axis = offset / np.maximum(distance, 1e-9)
  full = first + second
  if soft:
    start, span = SOFT_REACH_START * full, (SOFT_REACH_END
                                            - SOFT_REACH_START) * full
    distance = np.where(distance > start,
                        start + span * np.tanh((distance - start) / span),
                        distance)
  distance = np.clip(distance, abs(first - second) + 1e-4, full - 1e-6)
  along = (first ** 2 - second ** 2 + distance ** 2) / (2 * distance)
  radius = np.sqrt(np.maximum(first ** 2 - along ** 2, 0.0))
  n1 = _normalise(bend_reference
                  - np.sum(bend_reference * axis, -1, keepdims=True) * axis)
  n2 = np.cross(axis, n1)
  swivel = swivel[..., None]
  middle = root + along * axis + radius * (np.cos(swivel) * n1
                                           + np.sin(swivel) * n2)
  return middle, root + distance * axis


def forward_kinematics(body, pose):
  """(T, NUM_KEYPOINTS, 3) float64 keypoints of `pose` for `body`."""
  num_frames = pose.pelvis.shape[0]
  out = np.zeros((num_frames, keypoints.NUM_KEYPOINTS, 3))
  k = keypoints.KEYPOINT_INDEX
  frame = torso_frame(pose)
  up = frame[..., :, 2]
  forward = frame[..., :, 0]
  left = frame[..., :, 1]
  pelvis = pose.pelvis
  out[:, k['pelvis']] = pelvis
  out[:, k['torso']] = pelvis + TORSO_KEYPOINT_ALONG_SPINE * body.spine * up
  out[:, k['chest']] = pelvis + CHEST_KEYPOINT_ALONG_SPINE * body.spine * up
  neck = pelvis + body.spine * up
  out[:, k['neck']] = neck
  head_frame = frame @ _about(Z, pose.head_yaw) @ _about(Y, pose.head_pitch)
  # The head keypoint sits slightly forward of the neck axis (eyes).
  head_dir = _normalise(head_frame[..., :, 2] + 0.25 * head_frame[..., :, 0])
  out[:, k['head']] = neck + body.head * head_dir
  shoulders = shoulder_positions(body, pose)
  pelvis_frame = rotations.yaw_to_mat(pose.yaw)
  for side, sign in ((0, 1.0), (1, -1.0)):
    name = ('left', 'right')[side]
    shoulder = shoulders[:, side]
    target = pose.hands[:, side]
    # Hand direction: from the shoulder towards the target, bent down.
    reach_dir = _normalise(target - shoulder)
    bend = pose.wrist_bend[:, side][:, None]
    hand_dir = _normalise(np.cos(bend) * reach_dir
                          - np.sin(bend) * up)
    wrist_target = target - body.hand * hand_dir
    # Elbows hang down, slightly out and back, at swivel 0.
    reference = -up + 0.35 * sign * left - 0.3 * forward
    elbow, wrist = two_link(shoulder, wrist_target, body.upper_arm,
                            body.forearm, reference,
                            sign * pose.swivel[:, side], soft=True)
    out[:, k[f'{name}_shoulder']] = shoulder
    out[:, k[f'{name}_elbow']] = elbow
    out[:, k[f'{name}_wrist']] = wrist
    out[:, k[f'{name}_hand']] = wrist + body.hand * hand_dir
    hip = pelvis + sign * (body.hip_width / 2) * pelvis_frame[..., :, 1]
    knee_reference = (pelvis_frame[..., :, 0]
                      + 0.1 * sign * pelvis_frame[..., :, 1])
    knee, ankle = two_link(hip, pose.ankles[:, side], body.thigh, body.shin,
                           knee_reference, np.zeros(num_frames))
    out[:, k[f'{name}_hip']] = hip
    out[:, k[f'{name}_knee']] = knee
    out[:, k[f'{name}_ankle']] = ankle
  return out


def segment_lengths(positions):
  """(T, len(SEGMENTS)) lengths of every segment in keypoint positions."""
  a = keypoints.index([s[1] for s in keypoints.SEGMENTS])
  b = keypoints.index([s[2] for s in keypoints.SEGMENTS])
  return np.linalg.norm(positions[:, b] - positions[:, a], axis=-1)
