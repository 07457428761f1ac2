"""Snapshots stored as arrays plus a JSON spec (no pickling).

A snapshot (tasks/runtime/snapshots.py) is a nested value of dicts (string
keys), lists, tuples, NumPy arrays, NumPy scalars, Python bool/int/float,
None and strings. `flatten` splits it into

* a spec: the same tree, JSON-able, whose leaves say what they were and
  where their numbers are: None, {'str': s}, {'bool'|'int'|'float': i},
  {'scalar': dtype, 'at': i}, {'array': dtype, 'at': i, 'shape': [...]}
  (plus 'dtype': the dtype string if not in native byte order),
  {'dict': [[key, spec], ...]}, {'list': [...]}, {'tuple': [...]}, and
  for a list or tuple of Python floats {'floats': i, 'n': n, 'as': 'list'
  or 'tuple'};
* buffers: one flat array per dtype name ('float64', 'int64', 'bool',
  'uint32', ...) holding every number of that dtype, in tree order.

`unflatten(spec, buffers)` rebuilds an equal snapshot, types included
(float vs np.float64, tuple vs list, int vs bool), bit for bit: floats are
stored as float64, Python ints as int64. The spec of a snapshot depends
only on its structure (keys, types, shapes, strings), not on its numbers,
so the snapshots of an episode share a handful of specs and datasets store
one spec per structure and the numbers per step.

`to_arrays` / `from_arrays` put one snapshot into a {name: array} dict for
np.savez (the spec as a JSON string array, allow_pickle=False suffices).
`equal` compares two snapshots bit for bit.
"""

import json

import numpy as np

SPEC_KEY = 'spec'           # to_arrays: the JSON spec, a 0-d str array
BUFFER_PREFIX = 'buffer_'   # to_arrays: buffer_<dtype name>
_INT64 = np.iinfo(np.int64)
_PYTHON_SCALARS = (('bool', bool, np.bool_), ('int', int, np.int64),
                   ('float', float, np.float64))


class _Writer:
  """Collects leaves into per-dtype chunks while building the spec."""

  def __init__(self):
    self.chunks = {}    # dtype name -> list of 1-D arrays or Python lists
    self.sizes = {}     # dtype name -> numbers so far

  def _chunks(self, name):
    chunks = self.chunks.get(name)
    if chunks is None:
      chunks = self.chunks[name] = []
      self.sizes[name] = 0
    return chunks

  def scalars(self, name, values):
    """Python numbers of dtype `name`; returns the offset of the first."""
    chunks = self._chunks(name)
    if not chunks or not isinstance(chunks[-1], list):
      chunks.append([])
    chunks[-1].extend(values)
    at = self.sizes[name]
    self.sizes[name] = at + len(values)
    return at

  def array(self, array):
    """A native-byte-order array; returns (dtype name, offset)."""
    name = array.dtype.name
    self._chunks(name).append(array.reshape(-1))
    at = self.sizes[name]
    self.sizes[name] = at + array.size
    return name, at

  def buffers(self):
    return {name: np.concatenate([
        np.asarray(chunk, dtype=name) if isinstance(chunk, list) else chunk
        for chunk in chunks]) for name, chunks in self.chunks.items()}


class _Unstorable(ValueError):
  """A value flatten cannot store; `path` is filled in on the way up."""

  def __init__(self, message):
    super().__init__(message)
    self.message = message
    self.path = []


def _check_dtype(array):
  if array.dtype.kind not in 'biufc' or array.dtype.fields is not None:
    raise _Unstorable(f'is an array of dtype {array.dtype}: only bool, '
                      'integer, float and complex arrays can be stored')


def _flatten(value, writer):
  kind = type(value)
  # Exact type checks: bool is an int subclass, np.float64 a float one.
  if kind is float:
    return {'float': writer.scalars('float64', (value,))}
  if kind is bool:
    return {'bool': writer.scalars('bool', (value,))}
  if kind is int:
    if not _INT64.min <= value <= _INT64.max:
      raise _Unstorable(f'is the int {value}, outside the int64 range')
    return {'int': writer.scalars('int64', (value,))}
  if value is None:
    return None
  if kind is str:
    return {'str': value}
  if kind is dict:
    items = []
    for key, item in value.items():
      if type(key) is not str:   # pylint: disable=unidiomatic-typecheck
        raise _Unstorable(f'has the key {key!r} of type '
                          f'{type(key).__name__}: keys must be strings')
      try:
        items.append([key, _flatten(item, writer)])
      except _Unstorable as e:
        e.path.append(f'/{key}')
        raise
    return {'dict': items}
  if kind is list or kind is tuple:
    tag = kind.__name__
    if value and all(type(item) is float for item in value):   # pylint: disable=unidiomatic-typecheck
      # Fast path for the common list of floats.
      return {'floats': writer.scalars('float64', value), 'n': len(value),
              'as': tag}
    nodes = []
    for i, item in enumerate(value):
      try:
        nodes.append(_flatten(item, writer))
      except _Unstorable as e:
        e.path.append(f'[{i}]')
        raise
    return {tag: nodes}
  if isinstance(value, np.ndarray):
    _check_dtype(value)
    native = value.astype(value.dtype.newbyteorder('='), copy=False)
    name, at = writer.array(native)
    node = {'array': name, 'at': at, 'shape': list(value.shape)}
    if native.dtype.str != value.dtype.str:   # e.g. big-endian data
      node['dtype'] = value.dtype.str
    return node
  if isinstance(value, np.generic):
    array = np.asarray(value)
    _check_dtype(array)
    name, at = writer.array(array.astype(array.dtype.newbyteorder('=')))
    return {'scalar': name, 'at': at}
  raise _Unstorable(
      f'has the type {kind.__name__} ({value!r:.60}): expected dict, list, '
      'tuple, str, None, bool, int, float, a NumPy scalar or a numeric NumPy '
      'array')


def flatten(state):
  """(spec, buffers): a JSON-able spec and {dtype name: 1-D array}."""
  writer = _Writer()
  try:
    spec = _flatten(state, writer)
  except _Unstorable as e:
    path = ''.join(reversed(e.path)) or '/'
    raise ValueError(f'Snapshot value at {path} {e.message}') from None
  return spec, writer.buffers()


def _buffer(buffers, name, at, size):
  if name not in buffers:
    raise ValueError(f'Snapshot spec needs a {name!r} buffer; the buffers '
                     f'are {sorted(buffers)}')
  data = buffers[name]
  if at < 0 or at + size > data.shape[0]:
    raise ValueError(f'Snapshot spec reads {name}[{at}:{at + size}] but that '
                     f'buffer has {data.shape[0]} entries')
  return data[at:at + size]


def _unflatten(spec, buffers):
  if spec is None:
    return None
  if not isinstance(spec, dict) or len(spec) not in (1, 2, 3, 4):
    raise ValueError(f'Bad snapshot spec node {spec!r:.80}')
  if 'dict' in spec:
    return {key: _unflatten(item, buffers) for key, item in spec['dict']}
  if 'list' in spec:
    return [_unflatten(item, buffers) for item in spec['list']]
  if 'tuple' in spec:
    return tuple(_unflatten(item, buffers) for item in spec['tuple'])
  if 'floats' in spec:
    values = _buffer(buffers, 'float64', int(spec['floats']),
                     int(spec['n'])).tolist()
    return tuple(values) if spec['as'] == 'tuple' else values
  if 'str' in spec:
    return str(spec['str'])
  if 'array' in spec:
    shape = tuple(int(n) for n in spec['shape'])
    size = int(np.prod(shape, dtype=np.int64))
    data = _buffer(buffers, spec['array'], int(spec['at']), size)
    return data.reshape(shape).astype(spec.get('dtype', data.dtype))
  if 'scalar' in spec:
    return _buffer(buffers, spec['scalar'], int(spec['at']), 1)[0]
  for tag, python_type, dtype in _PYTHON_SCALARS:
    if tag in spec:
      return python_type(_buffer(buffers, np.dtype(dtype).name,
                                 int(spec[tag]), 1)[0])
  raise ValueError(f'Bad snapshot spec node {spec!r:.80}')


def unflatten(spec, buffers):
  """The snapshot `flatten` split into (spec, buffers)."""
  return _unflatten(spec, buffers)


def spec_to_json(spec):
  """A compact, canonical JSON string of a spec (equal specs, equal
  strings)."""
  return json.dumps(spec, separators=(',', ':'), allow_nan=False)


def spec_from_json(text):
  try:
    return json.loads(text)
  except json.JSONDecodeError as e:
    raise ValueError(f'Snapshot spec is not valid JSON: {e}') from e


def to_arrays(state, prefix=''):
  """{name: array} of one snapshot, for np.savez (no pickling needed)."""
  spec, buffers = flatten(state)
  arrays = {prefix + SPEC_KEY: np.array(spec_to_json(spec))}
  for name, data in buffers.items():
    arrays[prefix + BUFFER_PREFIX + name] = data
  return arrays


def from_arrays(arrays, prefix=''):
  """The snapshot stored by `to_arrays` (any mapping, e.g. an NpzFile)."""
  key = prefix + SPEC_KEY
  if key not in arrays:
    raise ValueError(f'No snapshot spec {key!r} among the arrays '
                     f'{sorted(arrays)[:10]}')
  start = prefix + BUFFER_PREFIX
  buffers = {name[len(start):]: np.asarray(arrays[name])
             for name in arrays if name.startswith(start)}
  return unflatten(spec_from_json(str(np.asarray(arrays[key]))), buffers)


def equal(first, second):
  """True if two snapshots are equal: same structure, same types, arrays
  with the same dtype, shape and bits (NaN equals NaN)."""
  if type(first) is not type(second):   # pylint: disable=unidiomatic-typecheck
    return False
  if isinstance(first, dict):
    return (list(first) == list(second)
            and all(equal(first[k], second[k]) for k in first))
  if isinstance(first, (list, tuple)):
    return len(first) == len(second) and all(
        equal(a, b) for a, b in zip(first, second))
  if isinstance(first, (np.ndarray, np.generic)):
    first, second = np.asarray(first), np.asarray(second)
    return (first.dtype == second.dtype and first.shape == second.shape
            and first.tobytes() == second.tobytes())
  if isinstance(first, float):
    return np.float64(first).tobytes() == np.float64(second).tobytes()
  return first == second

