"""Realism check: the shipped synthetic library against real recordings.

  python -m hrc_suite.human.compare --recordings=DIR
      [--out=docs/motion_library.md]

DIR holds the reference's recordings (one folder per task of BVH files, e.g.
human-robot-animations/), imported with `bvh_import`. Per task and clip the
statistics are: hand speed median and 95th percentile, peak hand speed, the
largest hand distance from the chest (reach), upper-arm / forearm / torso
lengths, and the largest frame-to-frame keypoint jump. Speeds and jumps are
taken after resampling every clip to COMMON_FPS, so recordings at 100 fps and
clips at 30 fps are measured alike. The table gives the range over clips of
each statistic for real and synthetic motion, and flags a synthetic range
that leaves the real one.
"""

import argparse
import datetime
import pathlib

import numpy as np

from hrc_suite.human import bvh_import
from hrc_suite.human import clip as clip_lib
from hrc_suite.human import keypoints

COMMON_FPS = 30.0
HANDS = keypoints.index(['left_hand', 'right_hand'])
CHEST = keypoints.KEYPOINT_INDEX['chest']
SEGMENT_STATS = {'upper_arm': ('left_shoulder', 'left_elbow'),
                 'forearm': ('left_elbow', 'left_wrist'),
                 'torso': ('pelvis', 'neck')}
STATISTICS = ('hand_speed_median', 'hand_speed_p95', 'hand_speed_peak',
              'reach', 'upper_arm', 'forearm', 'torso', 'max_jump')
UNITS = {'hand_speed_median': 'm/s', 'hand_speed_p95': 'm/s',
         'hand_speed_peak': 'm/s', 'reach': 'm', 'upper_arm': 'm',
         'forearm': 'm', 'torso': 'm', 'max_jump': 'm/frame'}


def resample(clip, fps=COMMON_FPS):
  """(T', K, 3) positions linearly interpolated at `fps`."""
  times = np.arange(0.0, clip.duration + 1e-9, 1.0 / fps)
  src = np.arange(clip.num_frames) / clip.fps
  pos = clip.positions.astype(np.float64).reshape(clip.num_frames, -1)
  out = np.stack([np.interp(times, src, pos[:, j])
                  for j in range(pos.shape[1])], -1)
  return out.reshape(len(times), -1, 3)


def clip_statistics(clip):
  """The STATISTICS of one clip, as a dict of floats."""
  pos = resample(clip)
  steps = np.linalg.norm(np.diff(pos, axis=0), axis=-1)
  hand_speed = steps[:, HANDS].ravel() * COMMON_FPS
  k = keypoints.KEYPOINT_INDEX
  stats = {
      'hand_speed_median': float(np.median(hand_speed)),
      'hand_speed_p95': float(np.percentile(hand_speed, 95)),
      'hand_speed_peak': float(hand_speed.max()),
      'reach': float(np.linalg.norm(pos[:, HANDS] - pos[:, [CHEST]],
                                    axis=-1).max()),
      'max_jump': float(steps.max()),
  }
  raw = clip.positions.astype(np.float64)
  for name, (a, b) in SEGMENT_STATS.items():
    stats[name] = float(np.median(np.linalg.norm(raw[:, k[b]] - raw[:, k[a]],
                                                 axis=-1)))
  return stats


def load_recordings(directory):
  """{task: [Clip]} imported from the BVH folders under `directory`."""
  directory = pathlib.Path(directory)
  if not directory.is_dir():
    raise FileNotFoundError(f'{directory}: no such folder of recordings')
  out = {}
  for folder, task in sorted(bvh_import.REFERENCE_FOLDER_TASKS.items()):
    files = sorted((directory / folder).glob('*.bvh'))
    if files:
      out[task] = [bvh_import.import_clip(f, task=task) for f in files]
  if not out:
    raise FileNotFoundError(
        f'{directory}: no task folders with .bvh files (expected some of '
        f'{", ".join(bvh_import.REFERENCE_FOLDER_TASKS)})')
  return out


def compare(recordings, library):
  """Rows (task, statistic, real (lo, hi), synthetic (lo, hi), within)."""
  rows = []
  for task in clip_lib.MOTION_TASKS:
    synthetic = [clip_statistics(c) for c in library[task]]
    real_clips = recordings.get(task)
    pooled = real_clips is None
    if pooled:   # No recordings of this task: compare with all of them.
      real_clips = [c for clips in recordings.values() for c in clips]
    real = [clip_statistics(c) for c in real_clips]
    for stat in STATISTICS:
      r = np.array([s[stat] for s in real])
      y = np.array([s[stat] for s in synthetic])
      within = bool(y.min() >= r.min() and y.max() <= r.max())
      rows.append({'task': task, 'statistic': stat, 'pooled': pooled,
                   'real': (float(r.min()), float(r.max())),
                   'synthetic': (float(y.min()), float(y.max())),
                   'synthetic_median': float(np.median(y)),
                   'median_within': bool(r.min() <= np.median(y) <= r.max()),
                   'within': within, 'real_count': len(r),
                   'synthetic_count': len(y)})
  return rows


def markdown_table(rows):
  lines = ['| task | statistic | real (min-max) | synthetic (min-max) | '
           'synthetic median | verdict |', '|---|---|---|---|---|---|']
  for row in rows:
    if row['within']:
      verdict = 'within'
    elif row['median_within']:
      verdict = 'median within, range exceeds'
    else:
      verdict = '**outside**'
    task = row['task'] + (' (vs all recordings)' if row['pooled'] else '')
    unit = UNITS[row['statistic']]
    lines.append(
        f'| {task} | {row["statistic"]} ({unit}) | '
        f'{row["real"][0]:.3f}-{row["real"][1]:.3f} | '
        f'{row["synthetic"][0]:.3f}-{row["synthetic"][1]:.3f} | '
        f'{row["synthetic_median"]:.3f} | {verdict} |')
  return '\n'.join(lines)


_BEGIN = '<!-- compare:begin -->'
_END = '<!-- compare:end -->'


def write_report(rows, path, command):
  """Replaces the generated section of `path` (or creates the file)."""
  path = pathlib.Path(path)
  today = datetime.datetime.now(datetime.timezone.utc).strftime('%Y-%m-%d')
  outside = sorted({(r['task'], r['statistic']) for r in rows
                    if not r['within']})
  body = [_BEGIN, f'Generated by `{command}` on {today} (UTC). Speeds and '
          f'jumps after resampling to {COMMON_FPS:g} fps.', '',
          markdown_table(rows), '',
          f'{len(rows) - len(outside)} of {len(rows)} task statistics have the '
          'whole synthetic range inside the real range.', _END]
  section = '\n'.join(body)
  text = path.read_text() if path.is_file() else ''
  if _BEGIN in text and _END in text:
    head, rest = text.split(_BEGIN, 1)
    text = head + section + rest.split(_END, 1)[1]
  else:
    text = (text + '\n' if text else '# Motion library\n\n') + section + '\n'
  path.parent.mkdir(parents=True, exist_ok=True)
  path.write_text(text)
  return path


def main(argv=None):
  parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
  parser.add_argument('--recordings', required=True,
                      help='folder of task folders of BVH recordings')
  parser.add_argument('--out', default='docs/motion_library.md')
  args = parser.parse_args(argv)
  recordings = load_recordings(args.recordings)
  library = {t: clip_lib.shipped_library(t) for t in clip_lib.MOTION_TASKS}
  rows = compare(recordings, library)
  print(markdown_table(rows))
  command = f'python -m hrc_suite.human.compare --recordings={args.recordings}'
  print(f'written to {write_report(rows, args.out, command)}')


if __name__ == '__main__':
  main()
