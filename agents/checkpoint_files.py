"""Checkpoint files: .npz (never pickled) and JSON, written atomically;
pytrees (parameters, optimiser states) as {path name: array}.

A checkpoint is a directory. `atomic_directory(path)` yields a fresh
temporary sibling to write into; on success it replaces `path` with it by
renames (the old directory is removed last), so a reader sees either the old
or the new checkpoint, never a half-written one.
"""

import contextlib
import json
import os
import pathlib
import shutil
import tempfile
from typing import Any, Dict, Iterator, Mapping, Union

import jax
import jax.numpy as jnp
import numpy as np

# A file or folder's path.
Path = Union[str, os.PathLike]


@contextlib.contextmanager
def atomic_directory(path: Path) -> Iterator[pathlib.Path]:
  """Context manager: write into the yielded folder, then move it to path.

  Args:
    path: the directory to write (replaced if it exists).

  Yields:
    A fresh temporary sibling folder; removed if the block raises.
  """
  path = pathlib.Path(path)
  path.parent.mkdir(parents=True, exist_ok=True)
  staging = pathlib.Path(tempfile.mkdtemp(prefix=f'.{path.name}.tmp-',
                                          dir=path.parent))
  try:
    yield staging
    _fsync_tree(staging)
    old = None
    if path.exists():
      old = pathlib.Path(tempfile.mkdtemp(prefix=f'.{path.name}.old-',
                                          dir=path.parent))
      os.rmdir(old)
      os.rename(path, old)
    os.rename(staging, path)
    if old is not None:
      shutil.rmtree(old)
  except BaseException:
    shutil.rmtree(staging, ignore_errors=True)
    raise


def _fsync_tree(folder):
  for file in folder.iterdir():
    with open(file, 'rb') as handle:
      os.fsync(handle.fileno())


def save_arrays(path: Path, arrays: Mapping[str, Any]) -> None:
  """Writes arrays to an uncompressed .npz.

  Args:
    path: the file.
    arrays: {name: array}.
  """
  with open(path, 'wb') as handle:
    np.savez(handle, **{name: np.asarray(value)
                        for name, value in arrays.items()})


def load_arrays(path: Path) -> Dict[str, np.ndarray]:
  """The arrays of an .npz (allow_pickle=False).

  Args:
    path: the file.

  Returns:
    {name: array}.

  Raises:
    FileNotFoundError: if the file does not exist.
  """
  path = pathlib.Path(path)
  if not path.is_file():
    raise FileNotFoundError(f'Checkpoint file {path} does not exist')
  with np.load(path, allow_pickle=False) as data:
    return {name: data[name] for name in data.files}


def save_json(path: Path, value: Any) -> None:
  """Writes a JSON file (indented, keys sorted).

  Args:
    path: the file.
    value: JSON-able.
  """
  with open(path, 'w') as handle:
    json.dump(value, handle, indent=1, sort_keys=True)
    handle.write('\n')


def load_json(path: Path) -> Any:
  """Reads a JSON file.

  Args:
    path: the file.

  Returns:
    Its value.

  Raises:
    FileNotFoundError: if the file does not exist.
  """
  path = pathlib.Path(path)
  if not path.is_file():
    raise FileNotFoundError(f'Checkpoint file {path} does not exist')
  with open(path) as handle:
    return json.load(handle)


def _path_name(path):
  """'a/b/0' name of a jax.tree_util key path."""
  parts = []
  for entry in path:
    if isinstance(entry, jax.tree_util.DictKey):
      parts.append(str(entry.key))
    elif isinstance(entry, jax.tree_util.GetAttrKey):
      parts.append(entry.name)
    elif isinstance(entry, jax.tree_util.SequenceKey):
      parts.append(str(entry.idx))
    elif isinstance(entry, jax.tree_util.FlattenedIndexKey):
      parts.append(str(entry.key))
    else:
      parts.append(str(entry))
  return '/'.join(parts)


def flatten_to_arrays(tree: Any) -> Dict[str, np.ndarray]:
  """Every leaf of a pytree as a NumPy array.

  Args:
    tree: the pytree.

  Returns:
    {path name ('a/b/0'): a copy of the leaf}.
  """
  leaves = jax.tree_util.tree_flatten_with_path(tree)[0]
  return {_path_name(path): np.array(leaf, copy=True)
          for path, leaf in leaves}


def unflatten_from_arrays(template: Any,
                          arrays: Mapping[str, np.ndarray]) -> Any:
  """Pytree shaped like `template` with leaves from `flatten_to_arrays`.

  Args:
    template: a pytree of the structure, shapes and dtypes.
    arrays: of `flatten_to_arrays`.

  Returns:
    The pytree, its leaves JAX arrays.

  Raises:
    ValueError: names missing or unexpected, or other shapes or dtypes.
  """
  leaves, treedef = jax.tree_util.tree_flatten_with_path(template)
  names = [_path_name(path) for path, _ in leaves]
  missing = [name for name in names if name not in arrays]
  extra = sorted(set(arrays) - set(names))
  if missing or extra:
    raise ValueError(f'State arrays do not match: missing {missing}, '
                     f'unexpected {extra}')
  restored = []
  for name, (_, leaf) in zip(names, leaves):
    value = np.asarray(arrays[name])
    if value.shape != np.shape(leaf) or value.dtype != np.asarray(leaf).dtype:
      raise ValueError(f'State array {name!r} has shape {value.shape} and '
                       f'dtype {value.dtype}, expected {np.shape(leaf)} and '
                       f'{np.asarray(leaf).dtype}')
    restored.append(jnp.asarray(value))
  return jax.tree_util.tree_unflatten(treedef, restored)
