"""Gripper-down reachability of every task's regions, per robot.

    python scripts/reachability.py [--robots=a,b] [--tasks=d/t,...]
        [--motions=DIR] [--out=FILE.md]

For each robot (on its layout.robot_mount) and task name it collects the
task's regions as world points (`task_points`) and counts those the
robot's gripper-down IK (at the task's CARTESIAN_YAW, either half turn)
reaches free of static and self-collision (the task's collision
prevention model), solving from q_home and then from up to RESTARTS
uniform random joint vectors (fixed seed). Points:

* reach: the Cartesian goal box (`Reach`'s box: ik.table_workspace_box,
  at least GOAL_MIN_HEIGHT above the table), GOALS uniform samples (as the
  task draws its goals, keeping the reached ones);
* pick_place, inspection: the cube region (base frame, the modules'
  REGION constants or the robot's layout.cube_region_x) as a GRID^2 grid at the grasp (TCP 1 cm above the
  cube's centre) and APPROACH above it;
* handover: every clip's `handover_point` (the person's palm) at the
  station and at both ends of its y placement range, moved the handle's
  grip-to-end length (experts/handover.GRIP_TO_HANDLE_END, 0.226 m)
  towards the robot's base: the TCP holds the hammer there;
  human_to_robot adds the table region where the hammer is put down (at
  the expert's RELEASE_HEIGHT);
* inspection: every clip's `inspection_point` as the clip has it (the task
  moves an unreachable one towards home: docs/tasks.md);
* lifting: the board handle's grip point where the task puts it (seeds
  0..SEEDS-1) and LIFT above it (lifting.LIFT_CHECK);
* hammering/default: every clip's `nail` target (the board is held around
  it); robot_hammers: the TCP with the hammer's face HOVER over the nail
  head of the plank the person puts down at each clip's `board_place`
  (plank along the person's facing; the face-to-TCP offset as gripped at
  reset).

--motions=DIR takes the clips' points from a folder of people
(task_kwargs['motions']: clips, BVH recordings or one sub-folder per task,
docs/motion_library.md; played with outside_human_model='allow') instead
of the shipped library. A point is a TCP position; in hammering/default
the nail's offset from the TCP (~0.1 m, the board in the gripper) is not
added. Prints a Markdown table: reached / points per robot and task, and
the unreached points' names.
"""

import argparse
import collections
import os
import textwrap

import numpy as np

from hrc_suite import layout
from hrc_suite import robot_description
from hrc_suite import suite
from hrc_suite.control import ik as ik_lib
from hrc_suite.entities import nail_board
from hrc_suite.experts import hammering_robot as hammering_robot_expert
from hrc_suite.experts import handover as handover_expert
from hrc_suite.tasks import hammering_robot
from hrc_suite.tasks import inspection
from hrc_suite.tasks import lifting
from hrc_suite.tasks import pick_place

GRID = 4
GOALS = 64
RESTARTS = 30
SEED = 0
SEEDS = 3
APPROACH = 0.1          # m, pick_place.APPROACH_HEIGHT
GRASP_ABOVE = 0.01      # m, TCP above a cube's centre (pick_place)
CUBE_HALF = 0.02        # m, the 4 cm cubes
TASKS = ('reach/dense', 'pick_place/default', 'pick_place/close',
         'handover/robot_to_human', 'handover/human_to_robot',
         'inspection/default', 'lifting/default', 'hammering/default',
         'hammering/robot_hammers')


def _grid(low, high, n):
  axes = [np.linspace(a, b, n) for a, b in zip(low, high)]
  return np.stack(np.meshgrid(*axes, indexing='ij'), -1).reshape(-1, len(low))


def _base_points(task, local):
  base = task.kinematics.base_pose
  return local @ base[:3, :3].T + base[:3, 3]


def _cube_region(task, region_x, region_y, both_sides):
  ys = [region_y] + ([(-region_y[1], -region_y[0])] if both_sides else [])
  points = []
  for y in ys:
    local = _grid((region_x[0], y[0]), (region_x[1], y[1]), GRID)
    world = _base_points(task, np.c_[local, np.zeros(len(local))])
    world[:, 2] = layout.TABLE_TOP_Z + CUBE_HALF + GRASP_ABOVE
    points += [('cube grasp', p) for p in world]
    points += [('cube approach', p + (0, 0, APPROACH)) for p in world]
  return points


def _clip_points(task, name, towards_base=0.0):
  """(label, point) of target `name` of every clip, at the station and the
  ends of its placement range in y, moved `towards_base` closer to the
  robot's base (horizontally)."""
  x, y, yaw = task.HUMAN_STATION
  dy = task.HUMAN_PLACEMENT_RANGE[1]
  points = []
  for clip in task._player.clips:   # pylint: disable=protected-access
    local = np.asarray(clip.targets[name], dtype=float)
    for shift in sorted({-dy, 0.0, dy}):
      c, s = np.cos(yaw), np.sin(yaw)
      world = np.array([c * local[0] - s * local[1] + x,
                        s * local[0] + c * local[1] + y + shift,
                        local[2]])
      back = task.kinematics.base_pose[:2, 3] - world[:2]
      world[:2] += towards_base * back / np.linalg.norm(back)
      points.append((name, world))
  return points


def task_points(env, domain, task_name):
  """[(label, world point)] of the task's regions (module doc)."""
  task = env.task
  if domain == 'reach':
    low, high = task._goal_box   # pylint: disable=protected-access
    local = np.random.RandomState(SEED).uniform(low, high, (GOALS, 3))
    return [('goal box', p) for p in _base_points(task, local)]
  if domain == 'pick_place':
    return _cube_region(task, task.region_x, pick_place.REGION_ABS_Y, True)
  if domain == 'handover':
    points = _clip_points(task, 'handover_point',
                          towards_base=handover_expert.GRIP_TO_HANDLE_END)
    if task_name == 'human_to_robot':
      low, high = task._region   # pylint: disable=protected-access
      table = _grid(low, high, GRID)
      release = layout.TABLE_TOP_Z + handover_expert.RELEASE_HEIGHT
      points += [('put-down region', np.r_[p, release]) for p in table]
    return points
  if domain == 'inspection':
    return (_cube_region(task, layout.cube_region_x(
        task.robot.description.name, inspection.OBJECT_REGION_X),
                         inspection.OBJECT_REGION_Y, False)
            + _clip_points(task, 'inspection_point'))
  if domain == 'lifting':
    points = []
    for seed in range(SEEDS):
      env.random_state.seed(seed)
      env.reset()
      grip = env.physics.bind(task.robot.tcp_site).xpos.copy()
      points += [('handle', grip),
                 ('lifted handle', grip + (0, 0, lifting.LIFT_CHECK))]
    return points
  if task_name == 'default':
    return _clip_points(task, 'nail')
  return _strike_points(env)


def _strike_points(env):
  """robot_hammers: the TCP where the hammer's face hovers over the nail
  head (experts/hammering_robot.HOVER), for every clip's plank place."""
  task, physics = env.task, env.physics
  face = physics.bind(task.hammer.head_site).xpos
  tcp_from_face = physics.bind(task.robot.tcp_site).xpos - face
  yaw = task.HUMAN_STATION[2]
  facing = np.array([np.cos(yaw), np.sin(yaw), 0.0])   # the person's
  head_z = (layout.TABLE_TOP_Z + 2 * hammering_robot.PLANK_HALF_SIZE[2]
            + nail_board.NAIL_LENGTH - nail_board.NAIL_START_DEPTH)
  points = []
  for label, handle in _clip_points(task, 'board_place'):
    nail = handle + facing * (hammering_robot.PLANK_NAIL_X
                              - hammering_robot.PLANK_HANDLE_X)
    nail[2] = head_z + hammering_robot_expert.HOVER
    points.append(('strike over ' + label, nail + tcp_from_face))
  return points


def reached(env, points):
  """Flags: gripper-down IK reaches each point collision-free (from
  q_home, then from up to RESTARTS uniform random seeds, until a solution
  is free of static and self-collision)."""
  task = env.task
  model = task.kinematics
  solver = ik_lib.InverseKinematics(model)
  checker = task.collision_checker
  rs = np.random.RandomState(SEED)
  flags = []
  for _, point in points:
    seed, ok = task.robot.description.q_home, False
    for _ in range(RESTARTS + 1):
      result = solver.solve(point, seed, task.CARTESIAN_YAW)
      if result.success and not checker.in_collision(result.q):
        ok = True
        break
      seed = rs.uniform(model.q_min, model.q_max)
    flags.append(ok)
  return np.array(flags)


def main():
  parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
  parser.add_argument('--robots', default=','.join(
      robot_description.ROBOT_NAMES))
  parser.add_argument('--tasks', default=','.join(TASKS))
  parser.add_argument('--out', default=None)
  parser.add_argument('--motions', default=None, help='A folder of people '
                      "(task_kwargs['motions']; default: the shipped "
                      'library).')
  args = parser.parse_args()
  kwargs = {}
  if args.motions is not None:
    if not os.path.isdir(args.motions):
      parser.error(f'--motions={args.motions}: not a folder')
    kwargs = {'motions': args.motions, 'outside_human_model': 'allow'}
  robots, tasks = args.robots.split(','), args.tasks.split(',')
  lines = ['| task | ' + ' | '.join(robots) + ' |',
           '|---|' + '---|' * len(robots)]
  missed = collections.defaultdict(list)
  for name in tasks:
    domain, task_name = name.split('/')
    cells = []
    for robot in robots:
      env = suite.load(domain, task_name,
                       task_kwargs={'robot': robot, **kwargs},
                       environment_kwargs={'random_state': SEED})
      env.reset()
      points = task_points(env, domain, task_name)
      flags = reached(env, points)
      cells.append(f'{flags.sum()}/{len(flags)}')
      counts = collections.Counter(label for (label, _), ok
                                   in zip(points, flags) if not ok)
      if counts:
        missed[robot].append(f'{name}: ' + ', '.join(
            f'{n} {label}' for label, n in sorted(counts.items())))
      print(name, robot, cells[-1], dict(counts), flush=True)
    lines.append(f'| {name} | ' + ' | '.join(cells) + ' |')
  lines.append('')
  for robot in robots:
    if missed[robot]:
      lines += textwrap.wrap(
          f'* {robot} misses: ' + '; '.join(missed[robot]) + '.', 79,
          subsequent_indent='  ', break_long_words=False,
          break_on_hyphens=False)
  text = '\n'.join(lines) + '\n'
  print(text)
  if args.out:
    with open(args.out, 'w') as f:
      f.write(text)


if __name__ == '__main__':
  main()
