"""Task motions: train/test splits of clip libraries, errors."""

import numpy as np
import pytest

from hrc_suite import suite
from hrc_suite.human import clip as clip_lib
from hrc_suite.tasks.runtime import motions
from hrc_suite.tasks import reach

LIFTING = clip_lib.shipped_library('lifting')


def _names(clips):
  return [c.name for c in clips]


def test_lifting_ablation_splits_seven_and_two():
  """The reference's ablation: 9 lifting motions, 7 train / 2 test, 5
  splits."""
  assert len(LIFTING) == 9
  test_sets = set()
  for k in range(5):
    split = {'split': 'train', 'test_clips': 2, 'split_seed': k}
    train = motions.load_motions(split, 'lifting')
    test = motions.load_motions(dict(split, split='test'), 'lifting')
    assert len(train) == 7 and len(test) == 2
    assert not set(_names(train)) & set(_names(test))
    assert sorted(_names(train) + _names(test)) == _names(LIFTING)
    assert _names(train) == sorted(_names(train))
    test_sets.add(tuple(_names(test)))
  assert len(test_sets) > 1   # The seed changes the partition.


def test_split_is_deterministic_and_independent_of_order():
  split = motions.MotionSplit('test', test_clips=3, split_seed=4)
  first = split.select(LIFTING)
  again = split.select(list(reversed(LIFTING)))
  assert _names(first) == _names(again) and len(first) == 3
  # Same clip objects, not copies.
  assert all(any(c is d for d in LIFTING) for c in first)


def test_dict_and_dataclass_agree_and_sources_split():
  as_dict = motions.load_motions(
      {'split': 'train', 'test_clips': 1, 'split_seed': 2,
       'source': LIFTING[:4]}, 'reach')
  as_class = motions.load_motions(
      motions.MotionSplit('train', 1, 2, source=LIFTING[:4]), 'reach')
  assert _names(as_dict) == _names(as_class)
  assert len(as_dict) == 3 and set(_names(as_dict)) <= set(
      _names(LIFTING[:4]))


def test_task_plays_only_its_side_of_the_split():
  split = {'split': 'test', 'test_clips': 2, 'split_seed': 1}
  test_names = set(_names(motions.load_motions(split, 'reach')))
  env = suite.load('reach', 'dense', task_kwargs={
      'motions': split, 'time_limit': 1.0},
                   environment_kwargs={'random_state': 0})
  seen = set()
  for _ in range(6):
    env.reset()
    seen.add(env.task.player.clip.name)
  assert seen <= test_names and seen


@pytest.mark.parametrize('spec, message', [
    ({'split': 'validation'}, 'Unknown motion split .validation.'),
    ({'test_clips': 2}, "needs 'split'"),
    ({'split': 'train', 'test_clips': 0}, 'test_clips must be an integer'),
    ({'split': 'train', 'test_clips': 1.5}, 'test_clips must be an integer'),
    ({'split': 'train', 'split_seed': -1}, 'split_seed must be an integer'),
    ({'split': 'train', 'fold': 3}, r"Unknown motion split keys \['fold'\]"),
    ({'split': 'train', 'test_clips': 9}, 'less than the library size'),
    ({'split': 'train', 'source': {'split': 'test'}}, 'cannot split'),
])
def test_bad_splits_raise_clearly(spec, message):
  with pytest.raises(ValueError, match=message):
    motions.load_motions(spec, 'lifting')


def test_bad_motions_raise_clearly():
  with pytest.raises(ValueError, match='train/test split'):
    motions.load_motions(42, 'reach')
  with pytest.raises(ValueError, match='motions must be'):
    reach.Reach(motions=['not a clip'])


def test_duplicate_clip_names_cannot_be_split():
  clips = [LIFTING[0], LIFTING[0].replace(positions=np.array(
      LIFTING[0].positions)), LIFTING[1]]
  with pytest.raises(ValueError, match='duplicate names'):
    motions.MotionSplit('train', 1).select(clips)
