r"""Converts a folder of BVH recordings (+ `<n>_info.json`) into clips.

  python -m hrc_suite.motion_tools.convert SRC_DIR DST_DIR [--task=TASK]
      [--units=mm|cm|m] [--up_axis=y|z]

SRC_DIR holds .bvh files, or sub-folders that do (like the reference's
`human-robot-animations/`, one folder per task); then each sub-folder goes to
DST_DIR/<task>/ so DST_DIR can stand in for the shipped library. One line is
printed per file; a broken file is reported with its name and line and the
command exits with status 1 after converting the others.
"""

import argparse
import pathlib
import sys

from hrc_suite.human import bvh
from hrc_suite.human import bvh_import
from hrc_suite.human import clip as clip_lib
from hrc_suite.human import recording_cache


def plan(src, dst, task=None):
  """[(bvh path, destination folder, task or None)] for a source folder."""
  src, dst = pathlib.Path(src), pathlib.Path(dst)
  if not src.is_dir():
    raise FileNotFoundError(f'{src}: not a folder')
  files = recording_cache.bvh_files(src)
  if files:
    return [(f, dst, task) for f in files]
  jobs = []
  for sub in sorted(p for p in src.iterdir() if p.is_dir()):
    sub_task = task or bvh_import.REFERENCE_FOLDER_TASKS.get(sub.name)
    folder = dst / (sub_task or sub.name)
    jobs.extend((f, folder, sub_task) for f in recording_cache.bvh_files(sub))
  if not jobs:
    raise FileNotFoundError(f'{src}: no .bvh files in it or its sub-folders')
  return jobs


def describe(clip):
  peak = float(clip_lib.keypoint_speeds(clip).max())
  return (f'{clip.num_frames} frames at {clip.fps:g} fps '
          f'({clip.duration:.1f} s), task {clip.task}, '
          f'{len(clip.idle_phases)} idle phase(s) '
          f'{[p.event for p in clip.idle_phases]}, '
          f'{len(clip.fast_phases)} fast phase(s), peak keypoint speed '
          f'{peak:.1f} m/s')


def convert(src, dst, task=None, units=None, up_axis='y', out=sys.stdout,
            err=sys.stderr):
  """Converts every file; returns the number that failed."""
  failures = 0
  for path, folder, file_task in plan(src, dst, task):
    try:
      clip = bvh_import.import_clip(path, task=file_task, units=units,
                                    up_axis=up_axis)
      written = clip_lib.save_clip(clip, folder)
    except (bvh.BvhError, clip_lib.ClipError) as e:
      failures += 1
      print(f'FAILED {path}: {e}', file=err)
      continue
    print(f'{path} -> {written}: {describe(clip)}', file=out)
  return failures


def main(argv=None):
  parser = argparse.ArgumentParser(
      prog='python -m hrc_suite.motion_tools.convert',
      description='Convert BVH recordings into hrc_suite motion clips.')
  parser.add_argument('src_dir', help='folder of .bvh (+ _info.json) files, '
                      'or of such folders')
  parser.add_argument('dst_dir', help='output folder for <name>.npz/.json')
  parser.add_argument('--task', choices=clip_lib.CLIP_TASKS, default=None,
                      help='task of every clip (default: from the reference '
                      'folder name, else "other")')
  parser.add_argument('--units', choices=sorted(bvh.UNITS), default=None,
                      help='BVH length unit (default: detect from size)')
  parser.add_argument('--up_axis', choices=('y', 'z'), default='y')
  args = parser.parse_args(argv)
  try:
    failures = convert(args.src_dir, args.dst_dir, args.task, args.units,
                       args.up_axis)
  except FileNotFoundError as e:
    print(f'error: {e}', file=sys.stderr)
    return 2
  if failures:
    print(f'{failures} file(s) failed', file=sys.stderr)
    return 1
  return 0


if __name__ == '__main__':
  sys.exit(main())
