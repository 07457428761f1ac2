"""A task's clips from a folder: saved clips, BVH recordings, or the
reference's layout, with recordings converted once into a cache.

`task_kwargs={'motions': DIR}` comes here. DIR may hold
* clips (<name>.json + <name>.npz): loaded as they are;
* BVH files (+ `<n>_info.json`): imported for the task (`bvh_import`);
* one sub-folder per task, named as the reference names them
  (`human-robot-animations/`: RobotHumanHandover, ...) or by our task name:
  the task's sub-folder is used.

Conversion takes seconds per recording, so its clips are written to
CACHE_DIR/<key>/, where the key hashes the recordings' paths, sizes and
modification times and CONVERTER_VERSION: a changed file or importer makes
a new entry. The cache is written through a temporary folder renamed into
place, so a run that is interrupted leaves no half-written entry.
"""

import hashlib
import os
import pathlib
import shutil
import tempfile

from hrc_suite.human import bvh
from hrc_suite.human import bvh_import
from hrc_suite.human import clip as clip_lib

# Bump when the importer's output changes (placement, targets, phases).
CONVERTER_VERSION = 7
CACHE_ENV = 'HRC_SUITE_CACHE'
# Reference folders a task also looks in besides its own
# (bvh_import.REFERENCE_FOLDER_TASKS): hammering/default converts the
# reference's hammering recordings too, so that a user who points it at
# them learns why they do not fit (task_targets: no blows, the reference's
# robot hammers) rather than that no folder was found.
SHARED_FOLDERS = {'hammering': ('CollaborativeHammering',)}


def cache_dir():
  """$HRC_SUITE_CACHE, else $XDG_CACHE_HOME/hrc_suite, else ~/.cache/..."""
  if os.environ.get(CACHE_ENV):
    return pathlib.Path(os.environ[CACHE_ENV])
  base = os.environ.get('XDG_CACHE_HOME') or pathlib.Path.home() / '.cache'
  return pathlib.Path(base) / 'hrc_suite' / 'recordings'


def bvh_files(folder):
  """The .bvh files of `folder`, sorted."""
  return sorted(p for p in folder.iterdir()
                if p.is_file() and p.suffix.lower() == '.bvh')


def _has_clips(folder):
  return any(p.suffix == '.json' and not p.stem.endswith('_info')
             for p in folder.iterdir())


def task_folder(folder, task):
  """The folder of `task`'s motions in `folder` (itself or a sub-folder)."""
  folder = pathlib.Path(folder)
  if not folder.is_dir():
    raise clip_lib.ClipError(f'{folder}: not a folder of motions')
  if _has_clips(folder) or bvh_files(folder):
    return folder
  names = [name for name, t in bvh_import.REFERENCE_FOLDER_TASKS.items()
           if t == task] + list(SHARED_FOLDERS.get(task, ())) + [task]
  for name in names:
    if (folder / name).is_dir():
      return folder / name
  subs = sorted(p.name for p in folder.iterdir() if p.is_dir())
  raise clip_lib.ClipError(
      f'{folder}: no clips or .bvh files, and no sub-folder for task '
      f'{task!r} (expected one of {names}; found {subs or "none"})')


def _key(files, task):
  digest = hashlib.sha256(f'v{CONVERTER_VERSION}:{task}'.encode())
  for path in files:
    stat = path.stat()
    digest.update(f'|{path.resolve()}:{stat.st_size}:{stat.st_mtime_ns}'
                  .encode())
  return digest.hexdigest()[:20]


def _recordings(folder):
  files = bvh_files(folder)
  infos = [bvh_import.info_path_for(f) for f in files]
  return files + [i for i in infos if i.is_file()]


def convert_folder(folder, task, out):
  """Imports every BVH file of `folder` for `task` into clips in `out`."""
  out = pathlib.Path(out)
  for path in bvh_files(pathlib.Path(folder)):
    try:
      clip = bvh_import.import_clip(path, task=task)
    except bvh.BvhError as e:
      raise clip_lib.ClipError(str(e)) from e
    clip_lib.save_clip(clip, out)


def load_task_folder(folder, task, use_cache=True):
  """`task`'s clips from `folder` (module doc)."""
  folder = task_folder(folder, task)
  if _has_clips(folder):
    return clip_lib.load_folder(folder)
  if not use_cache:
    with tempfile.TemporaryDirectory() as tmp:
      convert_folder(folder, task, tmp)
      return clip_lib.load_folder(tmp)
  entry = cache_dir() / _key(_recordings(folder), task)
  if not entry.is_dir():
    entry.parent.mkdir(parents=True, exist_ok=True)
    tmp = pathlib.Path(tempfile.mkdtemp(prefix='.converting-',
                                        dir=entry.parent))
    try:
      convert_folder(folder, task, tmp)
      try:
        tmp.rename(entry)
      except OSError:
        if not entry.is_dir():   # Not a concurrent conversion that won.
          raise
    finally:
      shutil.rmtree(tmp, ignore_errors=True)
  return clip_lib.load_folder(entry)
