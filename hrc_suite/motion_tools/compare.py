"""Realism check: the shipped synthetic library against real recordings.

  python -m hrc_suite.motion_tools.compare --recordings=DIR
      [--out=docs/motion_library.md]

DIR holds the reference's recordings, one folder per task of BVH files
(human-robot-animations/, folder names in bvh_import.REFERENCE_FOLDER_TASKS).
They are imported as the tasks play them: placed at the task's station with
their targets and idle phases (recording_cache.load_task_folder, cached in
$HRC_SUITE_CACHE). Per clip, real and synthetic alike, STATISTICS measures
what matters to the shield and to learning: keypoint speeds and
accelerations against the shield's human model, reach, speeds while the
person waits, the time to the task's event and the closest approach to the
robot (docs/motion_library.md, "Realism against the recordings"). Per task
the report gives the median and range over clips of each.
"""

import datetime
import math
import os
import pathlib
import platform
import shlex
import subprocess

from absl import app
from absl import flags
import numpy as np

from hrc_suite import layout
from hrc_suite import rotations
from hrc_suite.human import bvh_import
from hrc_suite.human import clip as clip_lib
from hrc_suite.human import keypoints
from hrc_suite.human import recording_cache
from hrc_suite.human import synthesis
from hrc_suite.safety.shield import human_reach

# Every clip is resampled to the synthetic library's rate (synthesis.
# DEFAULT_FPS, 25 fps; the recordings are at 100 fps): speeds are then
# finite differences over the same 40 ms in both sets, and the library's
# frames are used as they are (resampling 25 fps data to any other rate
# would interpolate it).
COMMON_FPS = synthesis.DEFAULT_FPS
# Accelerations are second differences, which multiply any frame-to-frame
# error by COMMON_FPS**2 (+-1 mm errors give up to 2.5 m/s^2). Positions
# are first smoothed by a centred moving average of this many frames
# (0.12 s): it removes single-frame spikes (tracking errors in the
# recordings, kinks where the library's moves join) and keeps arm motion
# (gain 0.92 at 2 Hz). A quadratic keeps its second difference under it, so
# a constant acceleration is measured exactly.
SMOOTHING_FRAMES = 3
HANDS = keypoints.index(['left_hand', 'right_hand'])
CHEST = keypoints.KEYPOINT_INDEX['chest']
# The robot's base frame on the default mount (layout.ROBOT_BASE_POS, every
# robot but the Schunk, whose base stands 0.15 m forward and 0.40 m higher:
# layout.SCHUNK_MOUNT).
ROBOT_BASE = np.array(layout.ROBOT_BASE_POS, dtype=np.float64)

# (name, unit, what) of each per-clip statistic, in table order.
STATISTICS = (
    ('hand_speed_median', 'm/s', 'hand speed, median'),
    ('hand_speed_p95', 'm/s', 'hand speed, 95th percentile'),
    ('hand_speed_peak', 'm/s', 'hand speed, peak'),
    ('over_v_max', '%', "frames with a keypoint over the shield's v_max"),
    ('hand_accel_p95', 'm/s^2', 'hand acceleration, 95th percentile'),
    ('hand_accel_peak', 'm/s^2', 'hand acceleration, peak'),
    ('over_a_max', '%', "frames with a keypoint over the shield's a_max"),
    ('reach_chest', 'm', 'hand from chest, largest'),
    ('reach_forward', 'm', 'hand ahead of the station, farthest'),
    ('idle_speed_median', 'm/s', 'waiting: fastest keypoint as recorded, '
     'median'),
    ('idle_speed_peak', 'm/s', 'waiting: fastest keypoint as recorded, '
     'peak'),
    ('idle_bound', 'm/s', "waiting: worst-case replay speed (task's check)"),
    ('time_to_event', 's', 'time to the event'),
    ('duration', 's', 'clip length'),
    ('closest_to_robot', 'm', 'any keypoint to the robot base, closest'),
)
UNITS = {name: unit for name, unit, _ in STATISTICS}


def shield_limits():
  """(v_max, a_max), each (K,) in keypoints.KEYPOINT_NAMES order, from the
  shield's human model (assets/human/shield_human_model.json)."""
  model = human_reach.HumanModelConfig.load()
  order = [model.keypoint_names.index(n) for n in keypoints.KEYPOINT_NAMES]
  return model.v_max[order], model.a_max[order]


def task_stations():
  """{task: (x, y, yaw)} where each task stands its person (tasks' classes).

  Pick and place uses its 'close' variant, the one the reference's
  PickPlaceCloseHuman recordings were made for (tests/tasks/
  test_real_motions.py); the default stands 0.15 m farther to the side.
  """
  # Imported here: the tasks pull in MuJoCo and dm_control.
  from hrc_suite.tasks import hammering
  from hrc_suite.tasks import hammering_robot
  from hrc_suite.tasks import handover
  from hrc_suite.tasks import inspection
  from hrc_suite.tasks import lifting
  from hrc_suite.tasks import pick_place
  from hrc_suite.tasks import reach
  from hrc_suite.tasks import stacking
  classes = (reach.Reach, pick_place.PickPlaceClose, inspection.Inspection,
             lifting.Lifting, handover.RobotToHuman, handover.HumanToRobot,
             hammering.Hammering, hammering_robot.RobotHammers,
             stacking.Stacking)
  return {c.MOTIONS: tuple(c.HUMAN_STATION) for c in classes}


def resample(clip, fps=COMMON_FPS):
  """(T', K, 3) positions linearly interpolated at `fps` from time 0."""
  pos = clip.positions.astype(np.float64)
  t = np.arange(0.0, clip.duration + 1e-9, 1.0 / fps) * clip.fps
  lo = np.minimum(np.floor(t).astype(int), clip.num_frames - 2)
  frac = (t - lo)[:, None, None]
  return pos[lo] * (1.0 - frac) + pos[lo + 1] * frac


def smooth(positions, frames=SMOOTHING_FRAMES):
  """Centred moving average over `frames` along time ('valid' part only)."""
  count = len(positions) - frames + 1
  return sum(positions[i:i + count] for i in range(frames)) / frames


def speeds(positions, fps=COMMON_FPS):
  """(T - 1, K) speeds (m/s) from frame i to i + 1."""
  return np.linalg.norm(np.diff(positions, axis=0), axis=-1) * fps


def accelerations(positions, fps=COMMON_FPS, frames=SMOOTHING_FRAMES):
  """(T - 1 - frames, K) acceleration magnitudes (m/s^2) of the smoothed
  positions, by central second differences."""
  s = smooth(positions, frames)
  return np.linalg.norm(s[2:] - 2.0 * s[1:-1] + s[:-2], axis=-1) * fps**2


def world_positions(positions, station):
  """Clip-frame positions (..., 3) in the world at `station` (x, y, yaw)."""
  x, y, yaw = station
  return (np.asarray(positions, dtype=np.float64)
          @ rotations.yaw_to_mat(yaw).T + [x, y, 0.0])


def _interval_mask(spans, count, fps=COMMON_FPS):
  """Which of `count` resampled intervals [i, i + 1] / fps overlap any of
  `spans`, (start, end) in seconds."""
  start = np.arange(count) / fps
  mask = np.zeros(count, dtype=bool)
  for t0, t1 in spans:   # Intervals that only touch a span's end are out.
    mask |= (start + 1.0 / fps > t0 + 1e-9) & (start < t1 - 1e-9)
  return mask


def idle_windows(clip):
  """(start, end) s of clip time each idle phase's warp can replay: the
  keyframe +- synthesis.idle_window (the widest randomisation)."""
  return [(clip.keyframe_time(p.keyframe) - synthesis.idle_window(p),
           clip.keyframe_time(p.keyframe) + synthesis.idle_window(p))
          for p in clip.idle_phases]


def time_to_event(clip):
  """s to the first idle phase's keyframe (the person starts waiting for
  the robot) in clips that wait for events; to the first keyframe in tasks
  that need keyframes but wait for nothing (lifting: the grasp); else NaN."""
  if clip.idle_phases:
    return clip.keyframe_time(clip.idle_phases[0].keyframe)
  if clip_lib.TASK_KEYFRAMES.get(clip.task) and clip.keyframes:
    return clip.keyframe_time(0)
  return math.nan


def clip_statistics(clip, station=None, limits=None):
  """The STATISTICS of one clip standing at `station` (None: its task's),
  as a dict of floats (NaN where one does not apply: the idle ones without
  idle phases). `limits`: shield_limits() (None: read them)."""
  station = task_stations()[clip.task] if station is None else station
  v_max, a_max = shield_limits() if limits is None else limits
  pos = resample(clip)
  vel = speeds(pos)
  acc = accelerations(pos)
  hand_vel = vel[:, HANDS]
  hand_acc = acc[:, HANDS]
  reach = np.linalg.norm(pos[:, HANDS] - pos[:, [CHEST]], axis=-1)
  base = np.linalg.norm(world_positions(pos, station) - ROBOT_BASE, axis=-1)
  stats = {
      'hand_speed_median': float(np.median(hand_vel)),
      'hand_speed_p95': float(np.percentile(hand_vel, 95)),
      'hand_speed_peak': float(hand_vel.max()),
      'over_v_max': 100.0 * float(np.mean((vel > v_max).any(axis=1))),
      'hand_accel_p95': float(np.percentile(hand_acc, 95)),
      'hand_accel_peak': float(hand_acc.max()),
      'over_a_max': 100.0 * float(np.mean((acc > a_max).any(axis=1))),
      'reach_chest': float(reach.max()),
      'reach_forward': float(pos[:, HANDS, 0].max()),
      'time_to_event': time_to_event(clip),
      'duration': float(clip.duration),
      'closest_to_robot': float(base.min()),
  }
  # While waiting: intervals inside the warp windows, fast phases (hammer
  # blows) left out as synthesis.idle_window_speed does.
  waiting = _interval_mask(idle_windows(clip), len(vel))
  fast = [(s / clip.fps, e / clip.fps) for s, e in clip.fast_phases]
  waiting &= ~_interval_mask(fast, len(vel))
  fastest = vel.max(axis=1)[waiting]
  stats['idle_speed_median'] = (float(np.median(fastest)) if fastest.size
                                else math.nan)
  stats['idle_speed_peak'] = float(fastest.max()) if fastest.size else math.nan
  stats['idle_bound'] = max(
      (synthesis.idle_speed_bound(clip, p) for p in clip.idle_phases),
      default=math.nan)
  return stats


def load_recordings(directory):
  """{task: [placed Clip]} of the reference's task folders in `directory`,
  imported and cached as the tasks do (recording_cache.load_task_folder)."""
  directory = pathlib.Path(directory)
  if not directory.is_dir():
    raise FileNotFoundError(f'{directory}: no such folder of recordings')
  out = {}
  for folder, task in bvh_import.REFERENCE_FOLDER_TASKS.items():
    if (directory / folder).is_dir():
      out[task] = recording_cache.load_task_folder(directory / folder, task)
  if not out:
    raise FileNotFoundError(
        f'{directory}: no task folders (expected some of '
        f'{", ".join(bvh_import.REFERENCE_FOLDER_TASKS)})')
  return out


def _summary(values):
  """(median, min, max) of the finite values; NaNs if there are none."""
  v = np.asarray(values, dtype=np.float64)
  v = v[np.isfinite(v)]
  if not v.size:
    return (math.nan,) * 3
  return float(np.median(v)), float(v.min()), float(v.max())


def compare(recordings, library, stations=None):
  """Rows {task, statistic, real, synthetic (median, min, max), counts} for
  every task with recordings, in clip_lib.MOTION_TASKS order."""
  stations = task_stations() if stations is None else stations
  limits = shield_limits()
  rows = []
  for task in clip_lib.MOTION_TASKS:
    if task not in recordings:
      continue
    real = [clip_statistics(c, stations[task], limits)
            for c in recordings[task]]
    synthetic = [clip_statistics(c, stations[task], limits)
                 for c in library[task]]
    for name, _, _ in STATISTICS:
      rows.append({'task': task, 'statistic': name,
                   'real': _summary([s[name] for s in real]),
                   'synthetic': _summary([s[name] for s in synthetic]),
                   'real_count': len(real),
                   'synthetic_count': len(synthetic)})
  return rows


def verdict(row):
  """Where the synthetic median lies against the real range."""
  median = row['synthetic'][0]
  _, lo, hi = row['real']
  if math.isnan(median) or math.isnan(lo):
    return ''
  if median < lo:
    return 'below'
  if median > hi:
    return 'above'
  return 'inside'


def _cell(summary, unit):
  if math.isnan(summary[0]):
    return '-'
  digits = 1 if unit in ('%', 'm/s^2', 's') else 2
  m, lo, hi = (f'{v:.{digits}f}' for v in summary)
  return f'{m} ({lo}-{hi})'


def markdown_tables(rows):
  """One table per task: real and synthetic median (range) per statistic."""
  what = {name: text for name, _, text in STATISTICS}
  lines = []
  for task in dict.fromkeys(r['task'] for r in rows):
    task_rows = [r for r in rows if r['task'] == task]
    first = task_rows[0]
    lines += [f'**{task}** ({first["real_count"]} recordings, '
              f'{first["synthetic_count"]} synthetic clips)', '',
              '| statistic | real median (range) | synthetic median (range) '
              '| synthetic median vs real range |', '|---|---|---|---|']
    for row in task_rows:
      unit = UNITS[row['statistic']]
      lines.append(f'| {what[row["statistic"]]} ({unit}) | '
                   f'{_cell(row["real"], unit)} | '
                   f'{_cell(row["synthetic"], unit)} | {verdict(row)} |')
    lines.append('')
  return '\n'.join(lines).rstrip('\n')


def machine():
  """A short description of this machine."""
  cpu = platform.processor() or platform.machine()
  try:
    with open('/proc/cpuinfo') as f:
      cpu = next((line.split(':', 1)[1].strip() for line in f
                  if line.startswith('model name')), cpu)
  except OSError:
    pass
  return (f'{cpu}, {os.cpu_count()} CPUs, {platform.platform()}, Python '
          f'{platform.python_version()}')


def git_commit():
  """The repository's short HEAD commit, or None."""
  try:
    out = subprocess.run(['git', 'rev-parse', '--short', 'HEAD'],
                         cwd=pathlib.Path(__file__).resolve().parent,
                         capture_output=True, text=True, timeout=10,
                         check=True)
  except (OSError, subprocess.SubprocessError):
    return None
  return out.stdout.strip() or None


_BEGIN = '<!-- compare:begin -->'
_END = '<!-- compare:end -->'


def write_report(rows, path, command, commit=None, host=None, date=None):
  """Replaces the generated part of `path` (or creates the file)."""
  path = pathlib.Path(path)
  date = date or datetime.datetime.now(datetime.timezone.utc).strftime(
      '%Y-%m-%d')
  body = [_BEGIN,
          f'Generated by `{command}` at commit {commit or "unknown"} on '
          f'{date} (UTC), {host or machine()}. Clips resampled to '
          f'{COMMON_FPS:g} fps; accelerations after a '
          f'{SMOOTHING_FRAMES}-frame moving average.', '',
          markdown_tables(rows), _END]
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


def define_flags(flag_values=flags.FLAGS):
  """Defines the command's flags (only when run as a program)."""
  flags.DEFINE_string('recordings', None, 'Folder of the reference\'s task '
                      'folders of BVH recordings (human-robot-animations/).',
                      flag_values=flag_values)
  flags.DEFINE_string('out', 'docs/motion_library.md', 'Markdown file whose '
                      'generated part is replaced.', flag_values=flag_values)
  flags.mark_flag_as_required('recordings', flag_values=flag_values)


def main(argv, flag_values=flags.FLAGS):
  if len(argv) > 1:
    raise app.UsageError(f'Unexpected arguments: {argv[1:]}')
  try:
    recordings = load_recordings(flag_values.recordings)
  except FileNotFoundError as e:
    raise app.UsageError(str(e)) from e
  library = {t: clip_lib.shipped_library(t) for t in recordings}
  rows = compare(recordings, library)
  print(markdown_tables(rows))
  command = ' '.join(shlex.quote(a) for a in
                     ['python', '-m', 'hrc_suite.motion_tools.compare']
                     + list(argv_flags(flag_values)))
  path = write_report(rows, flag_values.out, command, git_commit())
  print(f'written to {path}')


def argv_flags(flag_values):
  """The command's flags as given, for the report."""
  return [f'--recordings={flag_values.recordings}',
          f'--out={flag_values.out}']


if __name__ == '__main__':
  define_flags()
  app.run(main)
