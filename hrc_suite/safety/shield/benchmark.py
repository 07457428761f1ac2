"""Time of one shield cycle per robot, with the human close and far.

`python -m hrc_suite.safety.shield.benchmark` prints the median and 95th
percentile (microseconds) of `Shield.step` for every robot in two scenes,
with a new random goal every 12 cycles (the reference's 20 Hz policy at a
4 ms cycle; replanning is included), in SSM, PFL or off mode (--mode):
* close: a person across the table reaching back and forth at the robot's
  gripper, so verification needs the full human reachable sets and the
  shield intervenes;
* across: the same person standing still across the table (1.45 m from
  the base, the tasks' usual station): the second broad phase settles it;
* far: the same person 3.5 m away (the first broad phase settles it).

--rl_step times what a task runs instead: the 25 cycles of one
RL step in one `batch.step_many` call, a new goal at each RL step's
start, thread CPU time per RL step, compiled and (same scenes and goals)
the reference loop of `Shield.step`.
"""

import argparse
import math
import time

import numpy as np

from hrc_suite import robot_description
from hrc_suite import rotations
from hrc_suite.human import keypoints
from hrc_suite.safety.shield import batch
from hrc_suite.safety.shield import modes as modes_lib
from hrc_suite.safety.shield import shield as shield_lib

# Policy period in shield cycles: 20 Hz at 4 ms (docs/shield_maths.md, 4).
GOAL_EVERY = 12
SCENES = ('close', 'across', 'far')
# Distance (m) of a standing person from the robot base along x.
SCENE_DISTANCE = {'across': 1.45, 'far': 3.5}
# A standing person facing +x (m): spine over the pelvis, arms down.
_STANDING = {
    'pelvis': (0.0, 0.0, 0.95), 'torso': (0.0, 0.0, 1.12),
    'chest': (0.0, 0.0, 1.30), 'neck': (0.0, 0.0, 1.48),
    'head': (0.0, 0.0, 1.62), 'shoulder': (0.0, 0.19, 1.43),
    'elbow': (0.02, 0.21, 1.13), 'wrist': (0.05, 0.22, 0.88),
    'hand': (0.06, 0.22, 0.79), 'hip': (0.0, 0.09, 0.92),
    'knee': (0.02, 0.09, 0.50), 'ankle': (0.0, 0.09, 0.08),
}


def standing_person(x, y, yaw):
  """Keypoints (N, 3) of a standing person at (x, y) facing yaw."""
  points = []
  for name in keypoints.KEYPOINT_NAMES:
    side, _, part = name.partition('_')
    if part:
      px, py, pz = _STANDING[part]
      points.append((px, py if side == 'left' else -py, pz))
    else:
      points.append(_STANDING[name])
  return (np.array(points) @ rotations.yaw_to_mat(yaw).T
          + np.array([x, y, 0.0]))


def reaching_person(target, x=1.3, period=1.5):
  """A person across the table whose right forearm and hand move to
  `target` and back with period `period` s (peak speed below 2 m/s)."""
  body = standing_person(x, 0.0, math.pi)
  arm = keypoints.index(['right_elbow', 'right_wrist', 'right_hand'])
  offset = np.asarray(target) - body[arm[-1]]

  def at(t):
    out = body.copy()
    out[arm] += offset * 0.5 * (1.0 - math.cos(2 * math.pi * t / period))
    return out
  return at


def _scene(name, mode, scene):
  """(description, shield, human(t) -> keypoints) of one timing row."""
  description = robot_description.load(name)
  shield = shield_lib.Shield(description, mode=mode)
  _, p2, _ = shield.robot.capsules(description.q_home)
  if scene == 'close':
    return description, shield, reaching_person(p2[-1])
  body = standing_person(SCENE_DISTANCE[scene], 0.0, math.pi)
  return description, shield, lambda t: body


def time_cycles(name, scene, cycles, seed=0, mode='ssm'):
  """Per-cycle wall and thread CPU times (s) of `cycles` shield steps for one
  robot and scene, and the fraction of cycles with an intervention."""
  description, shield, human = _scene(name, mode, scene)
  rng = np.random.RandomState(seed)
  limits = description.limits
  times = np.empty(cycles)
  cpu_times = np.empty(cycles)
  interventions = 0
  for i in range(cycles):
    if i % GOAL_EVERY == 0:
      shield.new_goal(np.clip(description.q_home + rng.uniform(
          -1.0, 1.0, description.dof), limits.q_min, limits.q_max))
    t = i * shield.cycle_time
    points = human(t)
    start, cpu_start = time.perf_counter(), time.thread_time()
    shield.step(points, t)
    times[i] = time.perf_counter() - start
    cpu_times[i] = time.thread_time() - cpu_start
    interventions += shield.intervened
  return times, cpu_times, interventions / cycles


# Cycles per RL step (tasks.runtime.options.DEFAULT_SHIELD_SUBSTEPS).
RL_STEP_CYCLES = 25


def time_rl_steps(name, scene, rl_steps, seed=0, mode='ssm', compiled=True):
  """Thread CPU times (s) of `rl_steps` RL steps' shield cycles
  (batch.step_many of RL_STEP_CYCLES cycles, a new goal before each) and
  the fraction of cycles with an intervention."""
  description, shield, human = _scene(name, mode, scene)
  rng = np.random.RandomState(seed)
  limits = description.limits
  cpu_times = np.empty(rl_steps)
  interventions = 0
  for i in range(rl_steps):
    shield.new_goal(np.clip(description.q_home + rng.uniform(
        -1.0, 1.0, description.dof), limits.q_min, limits.q_max))
    times = (i * RL_STEP_CYCLES + np.arange(RL_STEP_CYCLES)) * (
        shield.cycle_time)
    frames = np.array([human(t) for t in times])
    cpu_start = time.thread_time()
    _, flags = batch.step_many(shield, frames, times, compiled=compiled)
    cpu_times[i] = time.thread_time() - cpu_start
    interventions += int(flags.sum())
  return cpu_times, interventions / (rl_steps * RL_STEP_CYCLES)


def main_rl_steps(args):
  print(f'Shield ({args.mode}): CPU time of one RL step\'s '
        f'{RL_STEP_CYCLES} cycles (ms), {args.rl_steps} RL steps per row, '
        'a new goal per RL step; compiled (batch.step_many) and reference '
        '(Shield.step)')
  print('| robot | scene | median [ms] | p95 [ms] | reference median [ms] | '
        'reference p95 [ms] | interventions |')
  print('|---|---|---|---|---|---|---|')
  rows = []
  for name in args.robots:
    for scene in SCENES:
      row = [name, scene]
      for compiled in (True, False):
        cpu, interventions = time_rl_steps(name, scene, args.rl_steps,
                                           mode=args.mode, compiled=compiled)
        cpu = cpu[4:] * 1e3   # The first plans (warm-up).
        row += [float(np.median(cpu)), float(np.percentile(cpu, 95))]
      row.append(interventions)
      rows.append(row)
      print(f'| {name} | {scene} | {row[2]:.3f} | {row[3]:.3f} | '
            f'{row[4]:.3f} | {row[5]:.3f} | {100 * interventions:.0f}% |',
            flush=True)
  return rows


def main(argv=None):
  parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
  parser.add_argument('--cycles', type=int, default=1500)
  parser.add_argument('--robots', nargs='*',
                      default=list(robot_description.ROBOT_NAMES))
  parser.add_argument('--mode', choices=modes_lib.names(), default='ssm')
  parser.add_argument('--rl_step', action='store_true',
                      help='Time the RL step\'s cycles in one call.')
  parser.add_argument('--rl_steps', type=int, default=200)
  args = parser.parse_args(argv)
  if args.rl_step:
    return main_rl_steps(args)
  print(f'Shield ({args.mode}) cycle time (us), {args.cycles} cycles per '
        f'row, new goal every {GOAL_EVERY} cycles; wall clock and thread CPU '
        'time (the latter is immune to preemption by other processes)')
  print(f'{"robot":10s} {"scene":6s} {"median":>8s} {"p95":>8s} '
        f'{"cpu med":>8s} {"cpu p95":>8s} {"interventions":>14s}')
  rows = []
  for name in args.robots:
    for scene in SCENES:
      times, cpu_times, interventions = time_cycles(
          name, scene, args.cycles, mode=args.mode)
      skip = GOAL_EVERY * 4   # The first plans (warm-up).
      times, cpu_times = times[skip:] * 1e6, cpu_times[skip:] * 1e6
      row = (name, scene, float(np.median(times)),
             float(np.percentile(times, 95)), interventions,
             float(np.median(cpu_times)), float(np.percentile(cpu_times, 95)))
      rows.append(row)
      print(f'{name:10s} {scene:6s} {row[2]:8.1f} {row[3]:8.1f} '
            f'{row[5]:8.1f} {row[6]:8.1f} {100 * interventions:13.0f}%')
  return rows


if __name__ == '__main__':
  main()
