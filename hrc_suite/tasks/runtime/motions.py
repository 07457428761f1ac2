"""A task's human motions: the shipped library, a folder, a list of clips, or
one side of a train/test split of any of those.

The reference's overfitting ablation (docs/reference_benchmark.md, Human
motions) trains on 7 of the 9 lifting motions and tests on the other 2, over
5 splits. Here

  motions={'split': 'train', 'test_clips': 2, 'split_seed': k}

(or `MotionSplit('train', 2, k)`) gives the train side of split k of the
task's shipped clips; 'test' the other side. The partition is a permutation
of the clips sorted by name drawn from `split_seed`: the test side is its
first `test_clips` clips. It depends only on the clip names and the seed
(not on load order), and the two sides of one split are disjoint and cover
the library. `source` splits a folder or a list of clips instead.
"""

import dataclasses
import pathlib
from typing import Any

import numpy as np

from hrc_suite import rotations
from hrc_suite.human import clip as clip_lib
from hrc_suite.human import keypoints as keypoints_lib
from hrc_suite.human import recording_cache
from hrc_suite.human import synthesis

SPLITS = ('train', 'test')


@dataclasses.dataclass(frozen=True)
class MotionSplit:
  """One side of a train/test split of a clip library (module doc).

  Attributes:
    split: 'train' or 'test'.
    test_clips: clips on the test side (1 .. library size - 1).
    split_seed: integer >= 0 that draws the partition.
    source: None (the task's shipped library), a folder or a list of Clips.
  """
  split: str
  test_clips: int = 2
  split_seed: int = 0
  source: Any = None

  def __post_init__(self):
    if self.split not in SPLITS:
      raise ValueError(f'Unknown motion split {self.split!r}: expected '
                       f'{" or ".join(map(repr, SPLITS))}')
    for name in ('test_clips', 'split_seed'):
      value = getattr(self, name)
      low = 1 if name == 'test_clips' else 0
      if (isinstance(value, bool) or not isinstance(value, (int, np.integer))
          or value < low):
        raise ValueError(f'motion split {name} must be an integer >= {low}, '
                         f'got {value!r}')

  @classmethod
  def from_dict(cls, spec):
    """A MotionSplit from {'split', 'test_clips', 'split_seed', 'source'}."""
    fields = [f.name for f in dataclasses.fields(cls)]
    unknown = sorted(set(spec) - set(fields))
    if unknown:
      raise ValueError(f'Unknown motion split keys {unknown}: expected some '
                       f'of {fields}')
    if 'split' not in spec:
      raise ValueError(f"motion split needs 'split' ('train' or 'test'), "
                       f'got {spec!r}')
    return cls(**spec)

  def partition(self, clips):
    """(train clips, test clips) of `clips`, each sorted by name."""
    clips = sorted(clips, key=lambda c: c.name)
    names = [c.name for c in clips]
    if len(set(names)) != len(names):
      raise ValueError(f'cannot split clips with duplicate names: {names}')
    if self.test_clips >= len(clips):
      raise ValueError(
          f'test_clips must be less than the library size ({len(clips)} '
          f'clips: {names}) so both sides have clips, got {self.test_clips}')
    order = np.random.RandomState(self.split_seed).permutation(len(clips))
    test = set(order[:self.test_clips].tolist())
    train_side = [c for i, c in enumerate(clips) if i not in test]
    test_side = [c for i, c in enumerate(clips) if i in test]
    return train_side, test_side

  def select(self, clips):
    """This split's side of `clips`."""
    train_side, test_side = self.partition(clips)
    return train_side if self.split == 'train' else test_side


def recorded_people_kwargs(motions: Any) -> dict:
  """Task kwargs that play the people of `motions` (a folder, a clip list
  or a sub-folder per task: `load_motions`), allowed to move beyond the
  shield's human model as recordings may (docs/motion_library.md); {} for
  None (the shipped synthetic library).

  Args:
    motions: the people, or None.

  Returns:
    {'motions': motions, 'outside_human_model': 'allow'}, or {}.
  """
  if motions is None:
    return {}
  return {'motions': motions, 'outside_human_model': 'allow'}


def load_motions(motions, task):
  """Clips from None (the task's shipped library `task`), a folder, a
  non-empty list of Clips, or a MotionSplit / split dict of any of those.

  A folder holds clips (<name>.json + .npz), BVH recordings (+ their
  `_info.json`), or the reference's layout (one sub-folder per task, as
  `human-robot-animations/`): recordings are converted on first use into
  a cache (`recording_cache`).
  """
  if isinstance(motions, dict):
    motions = MotionSplit.from_dict(motions)
  if isinstance(motions, MotionSplit):
    if isinstance(motions.source, (dict, MotionSplit)):
      raise ValueError('a motion split cannot split another split; give its '
                       'source as None, a folder or a list of clips')
    return motions.select(load_motions(motions.source, task))
  if motions is None:
    return clip_lib.shipped_library(task)
  if isinstance(motions, (str, pathlib.Path)):
    return recording_cache.load_task_folder(motions, task)
  try:
    clips = list(motions)
  except TypeError:
    clips = []
  if not clips or not all(isinstance(c, clip_lib.Clip) for c in clips):
    raise ValueError(
        'motions must be None (shipped library), a folder path, a non-empty '
        "list of Clips or a train/test split ({'split': 'train'|'test', "
        f"'test_clips': n, 'split_seed': k}}), got {motions!r}")
  return clips


# What a task does with a clip over the shield's human model
# (`check_motions`): refuse it, or play it outside the guarantee and count
# the RL steps in which the person moved faster than the model
# ('steps_outside_human_model').
OUTSIDE_MODEL_POLICIES = ('refuse', 'allow')
# Keypoints stay inside the workcell: within the floor (entities/workcell.py
# FLOOR_HALF_SIZE 4 m) and below this height (m; a raised hand of a 95th
# percentile man reaches ~2.2 m, DIN 33402-2).
MAX_KEYPOINT_HEIGHT = 2.5


def _clip_source(clip):
  source = clip.metadata.get('file')   # validate() made metadata a dict.
  return f'clip {clip.name!r}' + (f' ({source})' if source else '')


def _check_task_fields(clip, task, events, source):
  missing = [t for t in clip_lib.TASK_TARGETS.get(task, ())
             if t not in clip.targets]
  if missing:
    raise clip_lib.ClipError(
        f'{source}: task {task!r} needs the targets {missing}; the clip has '
        f'{sorted(clip.targets) or "none"}')
  needed = clip_lib.TASK_KEYFRAMES.get(task, 0)
  if len(clip.keyframes) < needed:
    raise clip_lib.ClipError(
        f'{source}: task {task!r} needs at least {needed} keyframes, the '
        f'clip has {list(clip.keyframes)}')
  waits = [str(p.event) for p in clip.idle_phases]
  expected = [str(e) for e in events]
  if waits != expected:
    raise clip_lib.ClipError(
        f'{source}: the task triggers the events {expected} in this order '
        f'(its EVENTS), the clip\'s idle phases wait for {waits}')


def _check_workcell(clip, station, floor_half_size, source):
  x, y, yaw = station
  p = clip.positions.astype(np.float64)
  world = p @ rotations.yaw_to_mat(yaw).T
  world_x, world_y = x + world[..., 0], y + world[..., 1]
  outside = ((np.abs(world_x) > floor_half_size)
             | (np.abs(world_y) > floor_half_size)
             | (p[..., 2] < 0.0) | (p[..., 2] > MAX_KEYPOINT_HEIGHT))
  if outside.any():
    frame, k = (int(v) for v in np.argwhere(outside)[0])
    raise clip_lib.ClipError(
        f'{source}: keypoint {keypoints_lib.KEYPOINT_NAMES[k]!r} at frame '
        f'{frame} stands at world ({world_x[frame, k]:.3g}, '
        f'{world_y[frame, k]:.3g}, {p[frame, k, 2]:.3g}) m, outside the '
        f'workcell (|x|, |y| <= {floor_half_size} m, 0 <= z <= '
        f'{MAX_KEYPOINT_HEIGHT} m)')


def speed_excess(clip, v_max):
  """(keypoint, m/s, clip time s) of the worst speed over `v_max` (per
  keypoint, m/s), idle phases' fastest replay included; None if within."""
  speeds = clip_lib.keypoint_speeds(clip)
  ratio = speeds / v_max
  frame, k = np.unravel_index(int(np.argmax(ratio)), ratio.shape)
  worst = (float(ratio[frame, k]), keypoints_lib.KEYPOINT_NAMES[k],
           float(speeds[frame, k]), frame / float(clip.fps))
  limit = float(np.min(v_max))
  for phase in clip.idle_phases:
    bound = synthesis.idle_speed_bound(clip, phase)
    if bound / limit > worst[0]:
      worst = (bound / limit, f'any keypoint (idle phase {phase.event!r})',
               bound, clip.keyframe_time(phase.keyframe))
  if worst[0] <= 1.0:
    return None
  return worst[1:]


def check_motions(clips, task, events, station, v_max,
                  outside_model='refuse', floor_half_size=4.0):
  """Raises ClipError unless every clip can be played by a task of the
  motion library `task` that triggers `events` (its EVENTS, in order).

  Checks the library's targets and keyframes, the events (the clips' idle
  phases wait for exactly `events`), keypoints inside the workcell at
  `station`, and speeds within the shield's human model (`v_max`, per
  keypoint); over the model, `outside_model` 'allow' accepts the clip (the
  task then counts 'steps_outside_human_model').
  """
  if outside_model not in OUTSIDE_MODEL_POLICIES:
    raise ValueError(f'Unknown outside_human_model {outside_model!r}: '
                     f'expected one of {OUTSIDE_MODEL_POLICIES}')
  v_max = np.asarray(v_max, dtype=np.float64)
  for clip in clips:
    source = _clip_source(clip)
    _check_task_fields(clip, task, events, source)
    _check_workcell(clip, station, floor_half_size, source)
    excess = speed_excess(clip, v_max)
    if excess is not None and outside_model == 'refuse':
      name, speed, time = excess
      raise clip_lib.ClipError(
          f'{source}: {name} moves at {speed:.2f} m/s at t = {time:.2f} s, '
          f'over the shield\'s human model ({float(np.min(v_max)):g}-'
          f'{float(np.max(v_max)):g} m/s, assets/human/'
          f'shield_human_model.json): the safety guarantee would not hold. '
          f"Pass task_kwargs={{'outside_human_model': 'allow'}} to play it "
          f"anyway; the episode metric 'steps_outside_human_model' then "
          f'counts the RL steps outside the guarantee')
  return clips
