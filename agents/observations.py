"""Flattening of dm_env observation dicts into one float32 vector.

The order is the observation spec's key order (composer environments return
an OrderedDict in the order the task declares its observables), each entry
raveled in C order. Image observations (uint8 arrays of rank 3, the tasks'
`camera_<name>` observables) have no place in a low-dimensional MLP input:
by default they raise an error; `images='skip'` leaves them out and
`images='include'` flattens them scaled to [0, 1]. Signals that are no
state of the task, such as the safety cost observables of the 'safe_rl'
preset (hrc_suite/tasks/runtime/observations.py, COST_OBSERVABLES), are left out
by name (`exclude`).
"""

import collections
import collections.abc
from typing import Any, Dict, Mapping, Sequence, Tuple

from dm_env import specs
import numpy as np

IMAGE_MODES = ('error', 'skip', 'include')


def is_image_spec(spec: specs.Array) -> bool:
  """Whether a spec is an image's: uint8 of rank 3 (height, width,
  channels).

  Args:
    spec: a dm_env spec.

  Returns:
    Whether it is.
  """
  return np.dtype(spec.dtype) == np.uint8 and len(spec.shape) == 3


class ObservationFlattener:
  """Maps an observation dict to a float32 vector in the spec's key order."""

  def __init__(self, observation_spec: Mapping[str, specs.Array],
               images: str = 'error', exclude: Sequence[str] = ()):
    """Initializes the flattener.

    Args:
      observation_spec: {name: dm_env spec}, in the observation's order.
      images: what to do with image observations (module docstring):
        'error', 'skip' or 'include'.
      exclude: names left out of the vector when the spec has them.

    Raises:
      ValueError: an unknown images mode, or image observations with
        images='error'.
      TypeError: an observation_spec that is not a mapping.
    """
    if images not in IMAGE_MODES:
      raise ValueError(f'images={images!r}: expected one of '
                       f'{", ".join(IMAGE_MODES)}')
    if not isinstance(observation_spec, collections.abc.Mapping):
      raise TypeError('observation_spec must be a mapping of names to '
                      f'specs, got {type(observation_spec).__name__}')
    image_names = [name for name, spec in observation_spec.items()
                   if is_image_spec(spec)]
    if image_names and images == 'error':
      raise ValueError(
          f'Image observations {image_names} cannot be flattened for an MLP: '
          "pass images='skip' to leave them out or images='include' to "
          'flatten them')
    self._all_names = tuple(observation_spec)
    self._skipped = frozenset(image_names if images == 'skip' else ()) | (
        frozenset(exclude) & frozenset(observation_spec))
    self._scales = {}
    self._shapes = collections.OrderedDict()
    self._slices = collections.OrderedDict()
    start = 0
    for name, spec in observation_spec.items():
      if name in self._skipped:
        continue
      shape = tuple(spec.shape)
      size = int(np.prod(shape, dtype=np.int64))
      self._shapes[name] = shape
      self._slices[name] = slice(start, start + size)
      self._scales[name] = 1.0 / 255.0 if is_image_spec(spec) else None
      start += size
    self._size = start

  @property
  def size(self) -> int:
    """Length of the flat vector."""
    return self._size

  @property
  def keys(self) -> Tuple[str, ...]:
    """Names of the flattened observations, in order."""
    return tuple(self._shapes)

  @property
  def slices(self) -> Dict[str, slice]:
    """{name: slice of the flat vector}."""
    return dict(self._slices)

  def _check_keys(self, observation):
    missing = [name for name in self._all_names if name not in observation]
    extra = [name for name in observation if name not in self._all_names]
    if missing or extra:
      raise ValueError(f'Observation keys do not match the spec: missing '
                       f'{missing}, unexpected {extra}')

  def __call__(self, observation: Mapping[str, Any]) -> np.ndarray:
    """The flat vector of one observation.

    Args:
      observation: {name: array} with the spec's names and shapes.

    Returns:
      float32 (size,).

    Raises:
      ValueError: other names or shapes than the spec's.
    """
    self._check_keys(observation)
    out = np.empty(self._size, dtype=np.float32)
    for name, shape in self._shapes.items():
      value = np.asarray(observation[name])
      if value.shape != shape:
        raise ValueError(f'Observation {name!r} has shape {value.shape}, '
                         f'expected {shape}')
      out[self._slices[name]] = value.ravel()
      if self._scales[name] is not None:
        out[self._slices[name]] *= self._scales[name]
    return out

  def flatten_batch(self, observations: Mapping[str, Any]) -> np.ndarray:
    """The flat vectors of batched observations.

    Args:
      observations: {name: (batch,) + the spec's shape}.

    Returns:
      float32 (batch, size).

    Raises:
      ValueError: other names or shapes than the spec's, or unequal batch
        sizes.
    """
    self._check_keys(observations)
    batch = None
    for name, shape in self._shapes.items():
      value = np.asarray(observations[name])
      if value.shape[1:] != shape or value.ndim != len(shape) + 1:
        raise ValueError(f'Batched observation {name!r} has shape '
                         f'{value.shape}, expected (batch,) + {shape}')
      if batch is None:
        batch = value.shape[0]
        out = np.empty((batch, self._size), dtype=np.float32)
      elif value.shape[0] != batch:
        raise ValueError(f'Batched observation {name!r} has batch size '
                         f'{value.shape[0]}, expected {batch}')
      out[:, self._slices[name]] = value.reshape(batch, -1)
      if self._scales[name] is not None:
        out[:, self._slices[name]] *= self._scales[name]
    if batch is None:
      return np.empty((0, 0), dtype=np.float32)
    return out
