"""The synthetic motion library: every task's scripted clips, rendered.

`synthesise(task, index)` runs clip `index` of a task's script
(`task_motions.py`, written with `synthesis.Script`) into a checked
`Clip`; `python -m hrc_suite.motion_tools.synthetic_library --out=DIR` writes
the library the package ships (docs/motion_library.md).
"""

import argparse
import pathlib

import numpy as np

from hrc_suite.human import body as body_lib
from hrc_suite.human import clip as clip_lib
from hrc_suite.human import synthesis
from hrc_suite.human import task_motions


def synthesise(task, index, seed=synthesis.LIBRARY_SEED, fps=synthesis.DEFAULT_FPS, attempts=6):
  """Clip `index` of `task`: deterministic in (task, index, seed).

  If a keypoint would exceed clip.MAX_KEYPOINT_SPEED outside the documented
  fast phases, the same motion is re-timed with a slower tempo. Idle phases
  are then slowed where their worst case would exceed IDLE_SPEED_LIMIT
  (`fit_idle_phases`).
  """
  if task not in task_motions.TASK_SCRIPTS:
    raise ValueError(f'Unknown motion task {task!r}: expected one of '
                     f'{", ".join(task_motions.TASK_SCRIPTS)}')
  task_number = clip_lib.MOTION_TASKS.index(task)
  slow_down = 1.0
  for _ in range(attempts):
    random_state = np.random.RandomState([seed, task_number, index])
    body = body_lib.sample_body(random_state)
    tempo = random_state.uniform(0.85, 1.2) * slow_down
    script = synthesis.Script(body, random_state, f'{task}_{index:02d}', task, tempo)
    script.metadata['seed'] = [int(seed), task_number, int(index)]
    task_motions.TASK_SCRIPTS[task](script, random_state)
    clip = script.render(fps)
    if not len(clip_lib.speed_violations(clip)):
      return synthesis.fit_idle_phases(clip)
    slow_down *= 1.2
  speeds = clip_lib.keypoint_speeds(clip).max()
  raise RuntimeError(f'{task} clip {index}: keypoint speed {speeds:.2f} m/s '
                     f'above {clip_lib.MAX_KEYPOINT_SPEED} m/s outside fast '
                     f'phases after {attempts} re-timings')


def generate_library(out, seed=synthesis.LIBRARY_SEED, fps=synthesis.DEFAULT_FPS, tasks=None):
  """Writes every task's clips into out/<task>/; returns {task: count}."""
  out = pathlib.Path(out)
  counts = {}
  for task in tasks or clip_lib.MOTION_TASKS:
    folder = out / task
    if folder.is_dir():
      for old in list(folder.glob('*.json')) + list(folder.glob('*.npz')):
        old.unlink()
    for index in range(task_motions.CLIP_COUNTS[task]):
      clip_lib.save_clip(synthesise(task, index, seed, fps), folder)
    counts[task] = task_motions.CLIP_COUNTS[task]
  return counts


def main(argv=None):
  parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
  parser.add_argument('--out', required=True,
                      help='folder for <task>/<clip>.{npz,json}')
  parser.add_argument('--seed', type=int, default=synthesis.LIBRARY_SEED)
  parser.add_argument('--fps', type=float, default=synthesis.DEFAULT_FPS)
  parser.add_argument('--tasks', nargs='*', default=None,
                      choices=clip_lib.MOTION_TASKS)
  args = parser.parse_args(argv)
  counts = generate_library(args.out, args.seed, args.fps, args.tasks)
  for task, count in counts.items():
    print(f'{task}: {count} clips')


if __name__ == '__main__':
  main()
