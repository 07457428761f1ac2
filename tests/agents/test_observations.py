"""Tests of agents/observations.py."""

import collections

from dm_env import specs
import numpy as np
import pytest

from agents import observations


def _spec(with_image=False):
  spec = collections.OrderedDict()
  spec['b_vector'] = specs.Array((3,), np.float64, 'b_vector')
  spec['a_matrix'] = specs.Array((2, 2), np.float64, 'a_matrix')
  spec['scalar'] = specs.Array((), np.float64, 'scalar')
  if with_image:
    spec['camera_front'] = specs.Array((4, 5, 3), np.uint8, 'camera_front')
  return spec


def _observation(with_image=False):
  observation = collections.OrderedDict(
      b_vector=np.array([1.0, 2.0, 3.0]),
      a_matrix=np.array([[4.0, 5.0], [6.0, 7.0]]),
      scalar=np.float64(8.0))
  if with_image:
    observation['camera_front'] = np.full((4, 5, 3), 255, np.uint8)
  return observation


def test_order_is_the_specs_key_order():
  flattener = observations.ObservationFlattener(_spec())
  assert flattener.keys == ('b_vector', 'a_matrix', 'scalar')
  assert flattener.size == 8
  vector = flattener(_observation())
  assert vector.dtype == np.float32
  np.testing.assert_array_equal(vector, np.arange(1.0, 9.0))
  assert flattener.slices['a_matrix'] == slice(3, 7)
  # Key order of the observation itself does not matter.
  shuffled = dict(reversed(list(_observation().items())))
  np.testing.assert_array_equal(flattener(shuffled), vector)


def test_rejects_missing_extra_and_misshapen_entries():
  flattener = observations.ObservationFlattener(_spec())
  observation = _observation()
  del observation['scalar']
  with pytest.raises(ValueError, match=r"missing \['scalar'\]"):
    flattener(observation)
  observation = _observation()
  observation['other'] = np.zeros(1)
  with pytest.raises(ValueError, match=r"unexpected \['other'\]"):
    flattener(observation)
  observation = _observation()
  observation['b_vector'] = np.zeros(4)
  with pytest.raises(ValueError, match=r"'b_vector' has shape \(4,\)"):
    flattener(observation)


def test_images_error_unless_asked():
  with pytest.raises(ValueError, match="camera_front.*images='skip'"):
    observations.ObservationFlattener(_spec(with_image=True))
  skipping = observations.ObservationFlattener(_spec(with_image=True),
                                               images='skip')
  assert skipping.size == 8
  np.testing.assert_array_equal(skipping(_observation(with_image=True)),
                                np.arange(1.0, 9.0))
  including = observations.ObservationFlattener(_spec(with_image=True),
                                                images='include')
  assert including.size == 8 + 60
  vector = including(_observation(with_image=True))
  np.testing.assert_array_equal(vector[8:], np.ones(60))
  with pytest.raises(ValueError, match="images='all'"):
    observations.ObservationFlattener(_spec(), images='all')


def test_flatten_batch_matches_single_flattening():
  flattener = observations.ObservationFlattener(_spec())
  random_state = np.random.RandomState(0)
  singles = [{name: random_state.randn(*spec.shape)
              for name, spec in _spec().items()} for _ in range(5)]
  batch = {name: np.stack([single[name] for single in singles])
           for name in _spec()}
  expected = np.stack([flattener(single) for single in singles])
  np.testing.assert_array_equal(flattener.flatten_batch(batch), expected)
  batch['scalar'] = batch['scalar'][:4]
  with pytest.raises(ValueError, match='batch size 4, expected 5'):
    flattener.flatten_batch(batch)
