"""Video overlays: the shield's reachable sets in the scene, event markers
and a caption on the frame.

Two layers:

* `ShieldOverlay`, a `scene_callback` for dm_control's renderer: after the
  model's geoms are in the MuJoCo scene it adds the capsules the shield
  checked in its last cycle as transparent geoms (mjv_initGeom +
  mjv_connector), the robot's reachable capsules in one colour and the
  human's in another. Every slice of the monitored path is drawn (the
  robot's capsules over each interval of "one step, then brake to rest";
  the human's over the same intervals), minus capsules contained in another
  capsule of the same link or body, which add nothing to the union. With
  several human models (POS, VEL, ACCEL) the shield accepts an interval if
  any model is collision-free, so each body shows the smallest of its
  models' capsules (each one encloses the body's reachable set).
* `annotate`, on the RGB frame (Pillow): a border and a badge when the shield
  intervened in the RL step, a badge per contact type that occurred (static,
  human safe, human critical), and a caption line with time, reward,
  cumulative return and success.
"""

import dataclasses
import functools
import math
from typing import Optional, Tuple

import mujoco
import numpy as np

from hrc_suite.safety import geometry

# Colours (RGBA in [0, 1]) of the reachable capsules: robot blue, human
# orange; low alpha so the robot and the person stay visible through them.
ROBOT_REACH_RGBA = (0.1, 0.4, 1.0, 0.1)
HUMAN_REACH_RGBA = (1.0, 0.45, 0.0, 0.1)
# Containment tolerance (m) when dropping capsules inside others: a capsule
# within 0.5 mm of another's inside looks the same on screen.
_CONTAINED_TOLERANCE = 5e-4
# Capsules shorter than this (m) are drawn as spheres (no axis direction).
_MIN_AXIS_LENGTH = 1e-9

# Frame markers (RGB 0-255), by event; contact kinds as in
# `tasks.runtime.contacts.CONTACT_TYPES` (robot_object and human_object are
# normal task contacts and get no marker).
MARKER_COLOURS = {
    'intervention': (255, 215, 0),       # yellow: the shield intervened
    'static': (150, 90, 255),            # violet: robot hit the workcell
    'human_allowed': (40, 190, 70),      # green: human contact, robot slow
    'human_critical': (235, 20, 20),     # red: human contact, robot fast
    'human_pushed': (30, 144, 255),      # blue: the person pushed the robot
}
MARKER_LABELS = {
    'intervention': 'SHIELD',
    'static': 'STATIC CONTACT',
    'human_allowed': 'HUMAN CONTACT (SAFE)',
    'human_critical': 'HUMAN CONTACT (CRITICAL)',
    'human_pushed': 'PUSHED BY THE PERSON',
}
MARKERS = tuple(MARKER_COLOURS)
CAPTION_BACKGROUND = (20, 20, 20)
CAPTION_TEXT = (240, 240, 240)


# ------------------------------------------------------------- capsules


def smallest_model(c1, c2, r):
  """(M, K, B) capsules of M human models -> (K, B): per interval and body
  the model capsule of least volume."""
  c1, c2, r = (np.asarray(x, dtype=float) for x in (c1, c2, r))
  if c1.ndim != 4 or c1.shape[:3] != r.shape or c2.shape != c1.shape:
    raise ValueError(f'expected c1, c2 (M, K, B, 3) and r (M, K, B), got '
                     f'{c1.shape}, {c2.shape}, {r.shape}')
  if c1.shape[0] == 1:
    return c1[0], c2[0], r[0]
  length = np.linalg.norm(c2 - c1, axis=-1)
  volume = np.pi * r**2 * length + 4.0 / 3.0 * np.pi * r**3
  best = np.argmin(volume, axis=0)[None, ..., None]
  return (np.take_along_axis(c1, best, 0)[0],
          np.take_along_axis(c2, best, 0)[0],
          np.take_along_axis(r, best[..., 0], 0)[0])


def union_capsules(c1, c2, r, tolerance=_CONTAINED_TOLERANCE):
  """Capsules (K, L) of K slices of L links -> the ones that are not inside
  another slice's capsule of the same link, flattened: c1, c2 (N, 3), r (N,).
  Of identical capsules the latest slice is kept."""
  c1, c2, r = (np.asarray(x, dtype=float) for x in (c1, c2, r))
  if c1.ndim != 3 or c1.shape[:2] != r.shape or c2.shape != c1.shape:
    raise ValueError(f'expected c1, c2 (K, L, 3) and r (K, L), got '
                     f'{c1.shape}, {c2.shape}, {r.shape}')
  k = c1.shape[0]
  # inside[i, j, l]: slice i's capsule of link l lies in slice j's.
  inside = geometry.capsule_contains_capsule(
      c1[None], c2[None], r[None], c1[:, None], c2[:, None], r[:, None],
      tolerance)
  later = np.arange(k)[None, :] > np.arange(k)[:, None]     # j > i
  # Drop i if some other j contains it, unless i also contains j and i is
  # the later slice (then j is dropped instead).
  covered = inside & (~np.swapaxes(inside, 0, 1) | later[..., None])
  covered[np.arange(k), np.arange(k)] = False
  keep = ~covered.any(axis=1)
  return c1[keep], c2[keep], r[keep]


def shield_capsules(shield):
  """The union capsules of the shield's last check: {'robot': (c1, c2, r),
  'human': (c1, c2, r)} flattened; a side without a check is empty."""
  empty = (np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0))
  robot = shield.robot_reach_capsules
  human = shield.human_reach_capsules
  return {
      'robot': empty if robot is None else union_capsules(*robot),
      'human': empty if human is None else union_capsules(
          *smallest_model(*human)),
  }


def add_capsules(scene, c1, c2, r, rgba):
  """Appends capsules to a mujoco.MjvScene as decoration geoms; returns how
  many did not fit (the scene's maxgeom)."""
  rgba = np.asarray(rgba, dtype=np.float32)
  identity = np.eye(3).ravel()
  size = np.zeros(3)
  dropped = 0
  for p1, p2, radius in zip(c1, c2, r):
    if scene.ngeom >= scene.maxgeom:
      dropped += 1
      continue
    scene.ngeom += 1   # `geoms` only reaches up to ngeom.
    geom = scene.geoms[scene.ngeom - 1]
    if np.linalg.norm(p2 - p1) < _MIN_AXIS_LENGTH:
      size[:] = radius
      mujoco.mjv_initGeom(geom, mujoco.mjtGeom.mjGEOM_SPHERE, size, p1,
                          identity, rgba)
    else:
      mujoco.mjv_initGeom(geom, mujoco.mjtGeom.mjGEOM_CAPSULE, size, p1,
                          identity, rgba)
      mujoco.mjv_connector(geom, mujoco.mjtGeom.mjGEOM_CAPSULE, float(radius),
                           p1, p2)
    geom.category = mujoco.mjtCatBit.mjCAT_DECOR
  return dropped


class ShieldOverlay:
  """Scene callback drawing a shield's reachable capsules (read after each
  cycle through its `robot_reach_capsules` / `human_reach_capsules`)."""

  def __init__(self, shield, robot_rgba=ROBOT_REACH_RGBA,
               human_rgba=HUMAN_REACH_RGBA):
    for name, rgba in (('robot_rgba', robot_rgba), ('human_rgba', human_rgba)):
      rgba = np.asarray(rgba, dtype=float)
      if rgba.shape != (4,) or np.any(rgba < 0) or np.any(rgba > 1):
        raise ValueError(f'{name}: expected 4 numbers in [0, 1], got '
                         f'{rgba.tolist()}')
    self._shield = shield
    self._rgba = {'robot': robot_rgba, 'human': human_rgba}
    self.dropped = 0        # Capsules that did not fit into a scene.
    self.drawn = {'robot': 0, 'human': 0}   # Capsules in the last scene.

  def __call__(self, physics, scene):
    del physics
    for side, (c1, c2, r) in shield_capsules(self._shield).items():
      self.dropped += add_capsules(scene, c1, c2, r, self._rgba[side])
      self.drawn[side] = len(r)


# ---------------------------------------------------------------- frames


@dataclasses.dataclass(frozen=True)
class FrameInfo:
  """What a frame's caption and markers show."""
  time: float                     # s, simulated time of the frame
  reward: Optional[float]         # reward of the RL step (None: first frame)
  episode_return: float           # return up to and including that step
  success: bool                   # success reached so far
  intervened: bool = False        # the shield intervened in the RL step
  contacts: Tuple[str, ...] = ()  # contact kinds (MARKERS) in the RL step

  def markers(self):
    """The markers this frame carries, in MARKERS order."""
    events = set(self.contacts) | ({'intervention'} if self.intervened
                                   else set())
    return tuple(m for m in MARKERS if m in events)

  def caption(self):
    reward = '-' if self.reward is None else f'{self.reward:+.2f}'
    return (f't {self.time:5.1f} s   reward {reward}   return '
            f'{self.episode_return:+.2f}   success '
            f'{"yes" if self.success else "no"}')


def frame_info(step_metrics, episode_metrics, time):
  """FrameInfo of the RL step whose metrics are given (a task's
  step_metrics / episode_metrics dicts)."""
  contacts = tuple(kind for kind in MARKERS if kind != 'intervention'
                   and step_metrics.get(f'contacts_{kind}', 0) > 0)
  return FrameInfo(
      time=float(time), reward=float(step_metrics.get('reward', 0.0)),
      episode_return=float(episode_metrics.get('return', 0.0)),
      success=bool(episode_metrics.get('success', 0.0)),
      intervened=bool(step_metrics.get('shield_interventions', 0)),
      contacts=contacts)


def _font_size(height):
  return max(9, height // 28)


@functools.lru_cache(maxsize=8)
def _font(height):
  """Pillow's bundled scalable font at the size for frames `height` tall."""
  from PIL import ImageFont  # pylint: disable=g-import-not-at-top
  return ImageFont.load_default(size=_font_size(height))


def caption_height(height):
  """Pixels of the caption bar at the bottom of a frame `height` tall."""
  return _font_size(height) + 8


def border_width(height):
  """Pixels of the intervention border."""
  return max(3, height // 60)


def marker_box(marker, width, height):
  """(left, top, right, bottom) of a marker's badge: a column of badges at
  the top left, inside the border, one fixed slot per marker (in frames
  under about 115 pixels the last slot reaches into the caption bar,
  which badges are drawn over)."""
  if marker not in MARKER_COLOURS:
    raise ValueError(f'Unknown marker {marker!r}: expected one of '
                     f'{", ".join(MARKERS)}')
  inset = border_width(height) + 3
  badge_height = _font_size(height) + 6
  text = max(_font(height).getlength(label) for label in MARKER_LABELS.values())
  badge_width = min(width - 2 * inset, int(math.ceil(text)) + 8)
  top = inset + MARKERS.index(marker) * (badge_height + 3)
  return inset, top, inset + badge_width, top + badge_height


def annotate(frame, info, legend=False):
  """A copy of an RGB frame (H, W, 3) uint8 with the markers and caption of
  `info` (a FrameInfo); legend=True names the capsule colours."""
  from PIL import Image  # pylint: disable=g-import-not-at-top
  from PIL import ImageDraw  # pylint: disable=g-import-not-at-top
  frame = np.asarray(frame)
  if frame.ndim != 3 or frame.shape[2] != 3 or frame.dtype != np.uint8:
    raise ValueError(f'frame: expected (H, W, 3) uint8, got {frame.shape} '
                     f'{frame.dtype}')
  height, width = frame.shape[:2]
  image = Image.fromarray(frame)
  draw = ImageDraw.Draw(image)
  font = _font(height)
  markers = info.markers()
  if 'intervention' in markers:
    draw.rectangle((0, 0, width - 1, height - 1),
                   outline=MARKER_COLOURS['intervention'],
                   width=border_width(height))
  bar = caption_height(height)
  draw.rectangle((0, height - bar, width - 1, height - 1),
                 fill=CAPTION_BACKGROUND)
  draw.text((4, height - bar + 3), info.caption(), fill=CAPTION_TEXT,
            font=font)
  for marker in markers:
    box = marker_box(marker, width, height)
    draw.rectangle(box, fill=MARKER_COLOURS[marker])
    draw.text((box[0] + 3, box[1] + 2), MARKER_LABELS[marker],
              fill=(0, 0, 0) if marker == 'intervention' else (255, 255, 255),
              font=font)
  if legend:
    x = width - border_width(height) - 3
    y = border_width(height) + 3
    for label, rgba in (('robot reach', ROBOT_REACH_RGBA),
                        ('human reach', HUMAN_REACH_RGBA)):
      colour = tuple(int(255 * c) for c in rgba[:3])
      left = x - draw.textlength(label, font=font) - 6
      draw.rectangle((left, y, x, y + _font_size(height) + 4),
                     fill=(255, 255, 255))
      draw.text((left + 3, y + 1), label, fill=colour, font=font)
      y += _font_size(height) + 7
  return np.asarray(image)
