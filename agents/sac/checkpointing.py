"""Checkpoint files: .npz (never pickled) and JSON, written atomically.

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

import numpy as np


@contextlib.contextmanager
def atomic_directory(path):
  """Context manager: write into the yielded folder, then move it to path."""
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


def save_arrays(path, arrays):
  """Writes {name: array} to an uncompressed .npz."""
  with open(path, 'wb') as handle:
    np.savez(handle, **{name: np.asarray(value)
                        for name, value in arrays.items()})


def load_arrays(path):
  """{name: array} of an .npz (allow_pickle=False)."""
  path = pathlib.Path(path)
  if not path.is_file():
    raise FileNotFoundError(f'Checkpoint file {path} does not exist')
  with np.load(path, allow_pickle=False) as data:
    return {name: data[name] for name in data.files}


def save_json(path, value):
  with open(path, 'w') as handle:
    json.dump(value, handle, indent=1, sort_keys=True)
    handle.write('\n')


def load_json(path):
  path = pathlib.Path(path)
  if not path.is_file():
    raise FileNotFoundError(f'Checkpoint file {path} does not exist')
  with open(path) as handle:
    return json.load(handle)
