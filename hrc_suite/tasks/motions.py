"""A task's human motions: the shipped library, a folder, a list of clips, or
one side of a train/test split of any of those.

The reference's overfitting ablation (reference-benchmark.md) trains on 7 of
the 9 lifting motions and tests on the other 2, over 5 splits. Here

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

from hrc_suite.human import clip as clip_lib

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


def load_motions(motions, task):
  """Clips from None (the task's shipped library `task`), a folder, a
  non-empty list of Clips, or a MotionSplit / split dict of any of those."""
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
    return clip_lib.load_folder(motions)
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
