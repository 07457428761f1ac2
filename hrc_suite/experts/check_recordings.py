r"""Checks a folder of recordings before training on them: per clip, what
the import derives, how fast the person moves against the shield's human
model, and how the task's expert does with that person alone.

  python -m hrc_suite.experts.check_recordings --motions=DIR
  python -m hrc_suite.experts.check_recordings --motions=DIR \
      --tasks=handover/human_to_robot --robots=schunk,panda \
      --policies=expert,noisy_expert --episodes=3 --workers=2

DIR is what `task_kwargs={'motions': DIR}` takes (docs/motion_library.md,
"Real recordings in the tasks"): BVH files with their `<n>_info.json`, or
one sub-folder per task as the reference's `human-robot-animations/`.
For every task with an expert (or those of --tasks) whose motions DIR
holds, each recording is imported on its own (`bvh_import.import_clip`:
placement, targets, idle phases) and printed:

* derived: the placement (turn, shift, anchor frame), the holding or
  placing hand, the keyframes (s) and the task's targets (clip frame, m);
  a recording the rules refuse is printed with the import's error;
* speed: the fastest keypoint and the share of frames over the shield's
  human model (v_max, assets/human/shield_human_model.json), and the worst
  case the task's check finds (idle phases' fastest replay included;
  `tasks/runtime/motions.speed_excess`);
* expert: per robot and policy, episodes (seeds 0..N-1) with only this
  clip as the task's people (played with outside_human_model='allow'):
  successes, mean length, episodes with a critical human contact while the
  person was inside the shield's human model (and, where any, outside
  it: evaluation_rows.critical_inside_model), and per
  episode the shield's interventions, collision prevention's replaced
  actions, failed IK steps and steps outside the human model.

A summary per task, robot and policy follows. Exit status: 0 when every
recording was derived and every row reaches the experts' bar
(evaluation_rows.SUCCESS_BAR, no critical contact inside the human
model), 1 otherwise, 2 on bad
arguments. Clips go to --work (a folder of one folder per clip, reused
by the episodes' worker processes).
"""

import collections
import pathlib
import sys
import tempfile
from typing import Any, Mapping, Sequence, TextIO, Union

from absl import app
from absl import flags
import numpy as np

from hrc_suite import experts
from hrc_suite import registry_flags
from hrc_suite import suite
from hrc_suite.experts import evaluation_episodes
from hrc_suite.experts import evaluation_rows
from hrc_suite.human import bvh
from hrc_suite.human import bvh_import
from hrc_suite.human import clip as clip_lib
from hrc_suite.human import keypoints
from hrc_suite.human import recording_cache
from hrc_suite.motion_tools import compare
from hrc_suite.tasks.runtime import motions as motions_lib

# The people label of the episodes' rows (evaluation_episodes.people).
LABEL = 'check'
# Per-episode metrics printed per clip (name, what), means per episode.
EPISODE_COLUMNS = (('shield_interventions', 'shield'),
                   ('action_replacements', 'replaced'),
                   ('ik_failures', 'ik failed'),
                   ('steps_outside_human_model', 'outside model'))


def task_motions(tasks: Sequence[tuple[str, str]]
                 ) -> dict[str, list[tuple[str, str]]]:
  """The tasks grouped by the clips they play (their MOTIONS).

  Args:
    tasks: (domain, task) pairs; unregistered ones are left out.

  Returns:
    {clip task: [(domain, task), ...]}, in the tasks' order.
  """
  grouped = collections.OrderedDict()
  for domain, task in tasks:
    task_class = suite.task_class(domain, task)
    if task_class is None:
      continue
    grouped.setdefault(task_class.MOTIONS, []).append((domain, task))
  return grouped


def import_folder(folder: Union[str, pathlib.Path], clip_task: str
                  ) -> list[tuple[str, Union[clip_lib.Clip, str]]]:
  """The recordings (or saved clips) in a folder, each imported for a
  task on its own.

  Args:
    folder: the folder of BVH recordings (or saved clips).
    clip_task: the clips' task (a task class's MOTIONS).

  Returns:
    [(source name, Clip, or the import's error message)].
  """
  folder = pathlib.Path(folder)
  files = recording_cache.bvh_files(folder)
  if not files:
    return [(c.name, c) for c in clip_lib.load_folder(folder)]
  out = []
  for path in files:
    try:
      out.append((path.name, bvh_import.import_clip(path, task=clip_task)))
    except (bvh.BvhError, clip_lib.ClipError) as e:
      out.append((path.name, str(e)))
  return out


def _point(value):
  return '(' + ', '.join(f'{v:.2f}' for v in np.asarray(value)) + ')'


def derived_lines(clip: clip_lib.Clip) -> list[str]:
  """Lines describing what the import derived for a clip.

  Args:
    clip: an imported clip.

  Returns:
    The placement, hands and keyframes, and targets lines.
  """
  lines = []
  placement = clip.metadata.get('import', {}).get('placement')
  if placement:
    lines.append(f"placement: turn {placement['facing_turn_deg']:.0f} deg, "
                 f"shift {_point(placement['shift_m'])} m, anchor frame "
                 f"{placement['anchor_frame']}")
  hands = [f'{name} {value}' for name, value in (
      ('holding hand', clip.holding_hand),
      ('placing hand', clip.placing_hand)) if value]
  keys = ', '.join(f'{clip.keyframe_time(i):.1f}'
                   for i in range(len(clip.keyframes)))
  lines.append('; '.join(hands + [f'keyframes [{keys}] s']))
  if clip.targets:
    lines.append('targets: ' + ', '.join(
        f'{name} {_point(point)}' for name, point in
        sorted(clip.targets.items())))
  return lines


def speed_line(clip: clip_lib.Clip, v_max: np.ndarray) -> str:
  """The clip's speed against the shield's human model, one line.

  Args:
    clip: an imported clip.
    v_max: the human model's speed limits (K,), m/s, in
      keypoints.KEYPOINT_NAMES order (`compare.shield_limits`).

  Returns:
    The line.
  """
  speeds = clip_lib.keypoint_speeds(clip)
  frame, k = np.unravel_index(int(np.argmax(speeds)), speeds.shape)
  over = float(np.mean((speeds > v_max).any(axis=1))) * 100.0
  line = (f'speed: peak {speeds[frame, k]:.2f} m/s '
          f'({keypoints.KEYPOINT_NAMES[k]}, t = {frame / clip.fps:.1f} s), '
          f'{over:.1f} % of frames over the human model '
          f'({float(np.min(v_max)):g} m/s)')
  excess = motions_lib.speed_excess(clip, v_max)
  if excess is None:
    return line + '; within the model'
  name, speed, time = excess
  return line + f'; worst {name} {speed:.2f} m/s at t = {time:.1f} s'


def _critical_episodes(done):
  """(episodes with a critical contact inside the human model, episodes
  with one outside it) of episodes that ran."""
  inside = sum(1 for r in done
               if evaluation_rows.critical_inside_model(r['metrics']))
  outside = sum(1 for r in done if r['metrics'].get(
      'contacts_human_critical_outside_model', 0))
  return inside, outside


def outcome_line(robot: str, policy: str,
                 results: Sequence[Mapping[str, Any]]) -> str:
  """One line of a clip's episodes with a robot and policy.

  Args:
    robot: the robot's name.
    policy: the policy's name.
    results: the episodes' results (`evaluation_episodes.run`).

  Returns:
    The line.
  """
  done = [r for r in results if r['metrics']]
  successes = sum(int(r['metrics']['success'] > 0.5) for r in done)
  critical, outside = _critical_episodes(done)
  parts = [f'{robot} {policy}: success {successes}/{len(results)}']
  if done:
    length = np.mean([r['metrics']['steps'] for r in done])
    parts.append(f'length {length:.0f} steps')
    parts.append(f'critical contacts in {critical}')
    if outside:
      parts.append(f'outside the human model in {outside}')
    for name, what in EPISODE_COLUMNS:
      mean = np.mean([r['metrics'].get(name) or 0 for r in done])
      parts.append(f'{what} {mean:.0f}')
  errors = [r['error'] for r in results if r['error']]
  if errors:
    parts.append(f'{len(errors)} error(s), first: {errors[0]}')
  return ', '.join(parts)


def passed(results: Sequence[Mapping[str, Any]]) -> bool:
  """Whether episodes reach the experts' bar.

  Args:
    results: the episodes' results (`evaluation_episodes.run`).

  Returns:
    True if every episode ran, the success rate is at least
    evaluation_rows.SUCCESS_BAR and no episode had a critical contact
    inside the human model.
  """
  done = [r for r in results if r['metrics']]
  if len(done) < len(results) or not results:
    return False
  rate = np.mean([r['metrics']['success'] > 0.5 for r in done])
  return bool(rate >= evaluation_rows.SUCCESS_BAR and not any(
      evaluation_rows.critical_inside_model(r['metrics']) for r in done))


def check(motions: Union[str, pathlib.Path],
          tasks: Sequence[tuple[str, str]],
          pairs: Sequence[tuple[str, str]], episodes: int,
          work: Union[str, pathlib.Path], workers: int = 1,
          out: TextIO = sys.stdout) -> bool:
  """Runs the check (module doc).

  Args:
    motions: the folder of recordings (`task_kwargs={'motions': ...}`).
    tasks: (domain, task) pairs to check (those whose motions it holds).
    pairs: (robot, policy) pairs of the episodes.
    episodes: episodes (seeds 0..episodes-1) per clip, robot and policy.
    work: the folder the imported clips are saved in.
    workers: parallel processes of the episodes.
    out: where the report is printed.

  Returns:
    Whether every recording was derived and every row reaches the bar.
  """
  v_max, _ = compare.shield_limits()
  ok = True
  grouped = task_motions(tasks)
  plan = []   # (domain, task, clip name, clip folder)
  for clip_task, names in grouped.items():
    try:
      folder = recording_cache.task_folder(motions, clip_task)
    except clip_lib.ClipError:
      continue
    if folder.name in recording_cache.SHARED_FOLDERS.get(clip_task, ()):
      continue   # Another task's recordings (recording_cache).
    tasks_text = ', '.join(f'{d}/{t}' for d, t in names)
    print(f'== {clip_task} ({folder}; tasks {tasks_text})', file=out)
    for source, clip in import_folder(folder, clip_task):
      if isinstance(clip, str):
        ok = False
        print(f'{source}: REFUSED: {clip}', file=out)
        continue
      clip_folder = pathlib.Path(work) / clip_task / clip.name
      clip_folder.mkdir(parents=True, exist_ok=True)
      clip_lib.save_clip(clip, clip_folder)
      print(f'{source}: {clip.num_frames} frames at {clip.fps:g} fps '
            f'({clip.duration:.1f} s)', file=out)
      for line in derived_lines(clip) + [speed_line(clip, v_max)]:
        print(f'  {line}', file=out)
      plan.extend((domain, task, clip.name, str(clip_folder))
                  for domain, task in names)
  if not plan:
    print(f'{motions}: no recordings of the tasks '
          f'{", ".join(f"{d}/{t}" for d, t in tasks)}', file=out)
    return False
  job_list = [(domain, task, robot, None, policy, None, seed,
               [LABEL, folder], None)
              for domain, task, _, folder in plan
              for robot, policy in pairs for seed in range(episodes)]
  results = evaluation_episodes.run(job_list, workers=workers)
  by_clip = collections.OrderedDict()
  for (domain, task, name, _), start in zip(
      plan, range(0, len(job_list), len(pairs) * episodes)):
    by_clip[(domain, task, name)] = results[start:start + len(pairs)
                                            * episodes]
  print('\n== expert outcomes per clip', file=out)
  totals = collections.OrderedDict()
  for (domain, task, name), clip_results in by_clip.items():
    print(f'{domain}/{task} {name}:', file=out)
    for i, (robot, policy) in enumerate(pairs):
      chunk = clip_results[i * episodes:(i + 1) * episodes]
      print(f'  {outcome_line(robot, policy, chunk)}', file=out)
      totals.setdefault((domain, task, robot, policy), []).extend(chunk)
  print('\n== summary', file=out)
  for (domain, task, robot, policy), group in totals.items():
    good = passed(group)
    ok = ok and good
    done = [r for r in group if r['metrics']]
    rate = (np.mean([r['metrics']['success'] > 0.5 for r in done])
            if done else 0.0)
    critical, outside = _critical_episodes(done)
    print(f'{domain}/{task} {robot} {policy}: success {rate:.2f} over '
          f'{len(group)} episodes, {critical} with critical contacts'
          + (f' ({outside} outside the human model)' if outside else '')
          + ': '
          f'{"ok" if good else "BELOW THE BAR"}', file=out)
  return ok


def _task_name(name):
  if name.count('/') != 1:
    raise ValueError(f'--tasks: expected domain/task names, got {name!r}')
  domain, task = name.split('/')
  if (domain, task) not in experts.registered():
    raise ValueError(f'--tasks: no expert for {name!r}; experts exist for '
                     + ', '.join(f'{d}/{t}' for d, t in experts.registered()))
  return domain, task


def define_flags(flag_values: flags.FlagValues = flags.FLAGS) -> None:
  """Defines the command's flags.

  Args:
    flag_values: where they are defined.
  """
  fv = flag_values
  flags.DEFINE_string('motions', None, 'Folder of recordings (BVH + '
                      '<n>_info.json, or one sub-folder per task).',
                      flag_values=fv)
  flags.DEFINE_list('tasks', [], 'domain/task names (default: every task '
                    'with an expert whose motions the folder holds).',
                    flag_values=fv)
  flags.DEFINE_list('robots', ['schunk', 'panda'], 'Robots.', flag_values=fv)
  flags.DEFINE_list('policies', ['expert'], 'expert and/or noisy_expert.',
                    flag_values=fv)
  flags.DEFINE_integer('episodes', 2, 'Episodes per clip, robot and policy.',
                       lower_bound=0, flag_values=fv)
  flags.DEFINE_integer('workers', 1, 'Parallel processes.', lower_bound=1,
                       flag_values=fv)
  flags.DEFINE_string('work', None, 'Folder for the imported clips '
                      '(default: a temporary one).', flag_values=fv)
  flags.mark_flag_as_required('motions', flag_values=fv)
  registry_flags.check_robot('robots', flag_values=fv)


def main(argv: Sequence[str],
         flag_values: flags.FlagValues = flags.FLAGS) -> None:
  """The command (module doc); exits with its status.

  Args:
    argv: the command line (no positional arguments).
    flag_values: the flags of `define_flags`.

  Raises:
    app.UsageError: bad arguments.
  """
  if len(argv) > 1:
    raise app.UsageError(f'Unexpected arguments: {argv[1:]}')
  f = flag_values
  bad = [p for p in f.policies if p not in evaluation_episodes.EXPERT_POLICIES]
  if bad:
    raise app.UsageError(f'--policies: unknown {bad[0]!r}: expected '
                         f'{" or ".join(evaluation_episodes.EXPERT_POLICIES)}')
  try:
    tasks = ([_task_name(t) for t in f.tasks] if f.tasks
             else list(experts.registered()))
  except ValueError as e:
    raise app.UsageError(str(e)) from None
  if not pathlib.Path(f.motions).is_dir():
    raise app.UsageError(f'--motions={f.motions}: not a folder')
  pairs = [(robot, policy) for robot in f.robots for policy in f.policies]
  if f.work is None:
    with tempfile.TemporaryDirectory() as work:
      ok = check(f.motions, tasks, pairs, f.episodes, work, f.workers)
  else:
    ok = check(f.motions, tasks, pairs, f.episodes, f.work, f.workers)
  sys.exit(0 if ok else 1)


if __name__ == '__main__':
  define_flags()
  app.run(main)
