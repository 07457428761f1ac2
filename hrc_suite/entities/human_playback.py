"""The human's motion for one RL step, computed at once, played per substep.

The player's motion depends on the task only through events, which tasks
trigger between RL steps (after_step). So at the start of an RL step the
player is advanced through all L substeps in one call
(`Player.advance_many`: the keypoints of each substep, one array operation
per clip), and the capsule frames of all L x S segments come from one
vectorised call instead of L calls: compiled=True (the default) its
kernel, `human_kernels.segment_frames`; compiled=False the NumPy
reference `human_segments.segment_frames` (the same values). Each substep
only copies its rows into MuJoCo's mocap arrays and hands its keypoints
to the shield, exactly as if the player had been advanced in that
substep.

The capsule frames follow `Human.set_keypoints` (same segments, same
reference lines: shoulder line for head, torso and arms, hip line for the
legs, world z for the pelvis); tests check the two agree.
"""

import numpy as np

from hrc_suite.entities import human_kernels
from hrc_suite.entities import human_segments
from hrc_suite.human import keypoints

_LEG_PARTS = ('thigh', 'shin')
_NO_ROWS = np.zeros((0, 1, 3))   # playback_frames without mocap rows


def _as_slice(ids):
  """A slice if the ids are consecutive (a cheaper index), else the ids."""
  ids = np.asarray(ids, dtype=np.intp)
  if ids.size and np.array_equal(ids, np.arange(ids[0], ids[0] + ids.size)):
    return slice(int(ids[0]), int(ids[0]) + ids.size)
  return ids.copy()


class HumanPlayback:
  """Batches a Player's keypoints over an RL step onto a Human."""

  def __init__(self, human, player, substeps, compiled=True):
    self._human = human
    self._compiled = bool(compiled)
    self._player = player
    self.substeps = int(substeps)
    k, s = keypoints.NUM_KEYPOINTS, len(human_segments.SEGMENTS)
    index = keypoints.KEYPOINT_INDEX
    proximal = np.array(keypoints.index([seg[1] for seg in
                                         human_segments.SEGMENTS]))
    distal = np.array(keypoints.index([seg[2] for seg in
                                       human_segments.SEGMENTS]))
    offsets = (k * np.arange(self.substeps))[:, None]
    self._proximal = (proximal[None] + offsets).ravel()
    self._distal = (distal[None] + offsets).ravel()
    names = [seg[0] for seg in human_segments.SEGMENTS]
    self._hip_line = np.array([any(p in n for p in _LEG_PARTS)
                               for n in names])
    self._vertical = np.array([n == 'pelvis' for n in names])
    self._shoulder_line = ~(self._hip_line | self._vertical)
    self._shoulders = (index['left_shoulder'], index['right_shoulder'])
    self._hips = (index['left_hip'], index['right_hip'])
    # The kernel's reference lines: keypoint rows (of positions (L * K, 3))
    # whose difference is each of the L x S segments' line (-1: vertical).
    left = np.where(self._hip_line, self._hips[0], self._shoulders[0])
    right = np.where(self._hip_line, self._hips[1], self._shoulders[1])
    left = np.where(self._vertical, -1, left[None] + offsets)
    self._line_left = left.ravel()
    self._line_right = (right[None] + offsets).ravel()
    self.positions = np.zeros((self.substeps, k, 3))
    self.times = np.zeros(self.substeps)
    self.clips = [None] * self.substeps
    self._reference = np.zeros((self.substeps, s, 3))
    self._reference[:, self._vertical] = (0.0, 0.0, 1.0)
    self._middles = np.zeros((self.substeps, s, 3))
    self._quaternions = np.zeros((self.substeps, s, 4))
    # The mocap rows of capsules and keypoints side by side, where the
    # model holds them so (`bind`): one write per substep instead of two.
    self._mocap_rows = np.zeros((self.substeps, s + k, 3))
    self._together = None
    self._physics_ptr = None
    self._shown_clip = None
    if self._compiled:
      human_kernels.warm_up()

  def _frames_compiled(self):
    """The reference lines, segment frames and mocap rows of `positions`
    by the kernel."""
    human_kernels.playback_frames(
        self.positions.reshape(-1, 3), self._proximal, self._distal,
        self._line_left, self._line_right, self._reference.reshape(-1, 3),
        self._middles.reshape(-1, 3), self._quaternions.reshape(-1, 4),
        self._mocap_rows if self._together is not None else _NO_ROWS)

  def bind(self, physics):
    """Mocap indices of the human's capsules and keypoints in `physics`."""
    model = physics.model
    bodies = [model.name2id(frame.full_identifier, 'body')
              for frame in self._human.segment_bodies]
    self._segment_mocap = _as_slice(model.body_mocapid[bodies])
    sites = physics.bind(list(self._human.keypoint_sites)).element_id
    self._keypoint_mocap = _as_slice(
        model.body_mocapid[model.site_bodyid[sites]])
    segments, keypoint_rows = self._segment_mocap, self._keypoint_mocap
    self._together = None
    if (isinstance(segments, slice) and isinstance(keypoint_rows, slice)
        and segments.stop == keypoint_rows.start):
      self._together = slice(segments.start, keypoint_rows.stop)
    self._mocap_pos = physics.data.ptr.mocap_pos
    self._mocap_quat = physics.data.ptr.mocap_quat
    self._physics_ptr = physics.data.ptr

  def show_current(self, physics):
    """Puts the human at the player's current pose (episode start,
    snapshots); resizes the capsules to the current clip."""
    self._resize(physics, self._player.clip)
    self._human.set_keypoints(physics, self._player.positions)

  def show_clip(self, physics):
    """Sizes the capsules for the player's current clip (after restoring a
    snapshot, whose physics state already holds the human's pose)."""
    self._shown_clip = None
    self._resize(physics, self._player.clip)

  def _resize(self, physics, clip):
    if clip is not self._shown_clip:
      self._human.resize(physics, clip)
      self._shown_clip = clip

  def forget_clip(self):
    self._shown_clip = None

  def advance(self, dt):
    """Advances the player through the RL step's substeps."""
    self._player.advance_many(dt, self.positions, self.times, self.clips)
    if self._compiled:
      self._frames_compiled()
      return
    reference = self._reference
    left, right = self._shoulders
    reference[:, self._shoulder_line] = (self.positions[:, left]
                                        - self.positions[:, right])[:, None]
    left, right = self._hips
    reference[:, self._hip_line] = (self.positions[:, left]
                                   - self.positions[:, right])[:, None]
    middles, _, quaternions = human_segments.segment_frames(
        self.positions.reshape(-1, 3), self._proximal, self._distal,
        reference.reshape(-1, 3))
    self._middles[:] = middles.reshape(self._middles.shape)
    self._quaternions[:] = quaternions.reshape(self._quaternions.shape)
    if self._together is not None:
      count = self._middles.shape[1]
      self._mocap_rows[:, :count] = self._middles
      self._mocap_rows[:, count:] = self.positions

  def mocap_layout(self):
    """(mocap_pos, the mocap rows of every substep, their first row,
    mocap_quat, the capsules' quaternions, their first row) for
    tasks/runtime/physics_loop.py, or None where the rows are not one block."""
    if self._together is None or not isinstance(self._segment_mocap, slice):
      return None
    return (self._mocap_pos, self._mocap_rows, self._together.start,
            self._mocap_quat, self._quaternions, self._segment_mocap.start)

  def segment_poses(self, segment):
    """(centres (L, 3), quaternions (L, 4)) of capsule `segment` at the RL
    step's substeps: the mocap pose `apply` gives it."""
    return self._middles[:, segment], self._quaternions[:, segment]

  def same_clip_until(self, k, stop):
    """The first substep in [k, stop) whose clip is not the one shown
    (`apply` resizes the capsules there), else stop."""
    shown, clips = self._shown_clip, self.clips
    for i in range(k, stop):
      if clips[i] is not shown:
        return i
    return stop

  def apply(self, physics, k):
    """Moves the human to substep k's pose; returns its keypoints."""
    if self.clips[k] is not self._shown_clip:
      self._resize(physics, self.clips[k])
    if self._together is not None:
      self._mocap_pos[self._together] = self._mocap_rows[k]
    else:
      self._mocap_pos[self._segment_mocap] = self._middles[k]
      self._mocap_pos[self._keypoint_mocap] = self.positions[k]
    self._mocap_quat[self._segment_mocap] = self._quaternions[k]
    return self.positions[k]
