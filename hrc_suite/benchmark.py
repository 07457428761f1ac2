"""Speed benchmarks: `python -m hrc_suite.benchmark [--section=physics,shield,tasks]`.

Prints, per robot, the median wall time of one 4 ms physics step of the
workcell with robot, gripper and tracking controller, next to a bare
`mujoco.mj_step` of the same model, so the overhead is a ratio; and the
shield's cycle time with the human close, across the table and far; and the
RL-step throughput of every task (random actions, shield on, human moving,
L = 25) in CPU time (time.process_time: other processes on the machine do
not inflate it) next to the same number of bare physics steps, on the fast
path and (--reference) on the readable reference path (fast_path=False)
in the same run. --motions=DIR plays the people of a folder
(task_kwargs['motions'], with outside_human_model='allow') in the tasks and
profile sections instead of the shipped library. Numbers are recorded in
docs/benchmarks.md.
"""

import os
import platform
import time

from absl import app
from absl import flags
import mujoco
import numpy as np

from hrc_suite import registry_flags
from hrc_suite import robot_description
from hrc_suite.tasks.runtime import motions as task_motions

SECTIONS = ('physics', 'shield', 'tasks', 'profile')
_SECTIONS = flags.DEFINE_list(
    'section', list(SECTIONS), 'Which benchmarks to run: ' + ', '.join(SECTIONS))
_ROBOTS = flags.DEFINE_list('robots', list(robot_description.ROBOT_NAMES),
                            'Robots to benchmark.')
_STEPS = flags.DEFINE_integer('steps', 2000, 'Physics steps per measurement.')
_TASK_ROBOTS = flags.DEFINE_list('task_robots', ['schunk', 'panda'],
                                 'Robots of the RL-step throughput section.')
registry_flags.check_robot('robots')
registry_flags.check_robot('task_robots')
_RL_STEPS = flags.DEFINE_integer('rl_steps', 300,
                                 'RL steps per task throughput measurement.')
_REFERENCE = flags.DEFINE_boolean(
    'reference', False, 'Also measure the reference path (fast_path=False).')
_TASKS = flags.DEFINE_list('tasks', [], 'domain/task names of the '
                           'throughput section (default: all).')
_ACTION_SPACE = flags.DEFINE_string(
    'action_space', None, "Action space of the throughput section ('joint' "
    "or 'cartesian'; default: each task's own).")
_MOTIONS = flags.DEFINE_string(
    'motions', None, "A folder of people for the tasks and profile sections "
    "(task_kwargs['motions']: clips, BVH recordings or one sub-folder per "
    "task; docs/motion_library.md), played with outside_human_model='allow' "
    '(default: the shipped synthetic library).')
# The throughput is the best of this many equal windows of the RL steps
# (the least disturbed by other processes sharing the cores).
_WINDOWS = 3
# RL steps between two measurements of the bare physics (the alternating
# ratio: docs/benchmarks.md, "RL step throughput of every task").
_CHUNK = 10


def machine_summary() -> str:
  cpu = platform.processor() or platform.machine()
  try:
    with open('/proc/cpuinfo') as f:
      for line in f:
        if line.startswith('model name'):
          cpu = line.split(':', 1)[1].strip()
          break
  except OSError:
    pass
  import os
  return (f'{cpu}, {os.cpu_count()} cores, Python '
          f'{platform.python_version()}, MuJoCo {mujoco.__version__}')


def _median_us(durations):
  return 1e6 * float(np.median(durations))


def physics_step_times(robot_name: str, steps: int):
  """Median µs of: controller + physics.step, physics.step alone, mj_step."""
  from dm_control import mjcf
  from hrc_suite.control import controller as controller_lib
  from hrc_suite.control import trajectory
  from hrc_suite.entities import gripper as gripper_lib
  from hrc_suite.entities import robot as robot_lib
  from hrc_suite.entities import workcell as workcell_lib

  arena = workcell_lib.Workcell()
  robot = robot_lib.make_robot(robot_name)
  robot.attach_gripper(gripper_lib.ParallelGripper())
  arena.attach_robot(robot)
  physics = mjcf.Physics.from_mjcf_model(arena.mjcf_model)
  desc = robot.description
  home = desc.q_home
  span = 0.3 * (desc.limits.q_max - desc.limits.q_min)
  waypoints = [home, np.clip(home + np.minimum(span, 0.5),
                             desc.limits.q_min, desc.limits.q_max), home]
  q_d, dq_d, ddq_d = trajectory.jerk_limited_trajectory(desc, waypoints)
  robot.set_joint_positions(physics, home)
  physics.forward()
  controller = controller_lib.JointTrackingController(physics, robot)

  controlled = np.empty(steps)
  for k in range(steps):
    i = k % len(q_d)
    start = time.perf_counter()
    controller(physics, q_d[i], dq_d[i], ddq_d[i])
    physics.step()
    controlled[k] = time.perf_counter() - start

  wrapped = np.empty(steps)
  for k in range(steps):
    start = time.perf_counter()
    physics.step()
    wrapped[k] = time.perf_counter() - start

  model, data = physics.model.ptr, physics.data.ptr
  bare = np.empty(steps)
  for k in range(steps):
    start = time.perf_counter()
    mujoco.mj_step(model, data)
    bare[k] = time.perf_counter() - start
  return _median_us(controlled), _median_us(wrapped), _median_us(bare)


def run_physics(robots, steps):
  print('\n## Physics step (workcell + robot + gripper + controller)\n')
  print('| robot | controller + physics.step [µs] | dm_control physics.step '
        '[µs] | bare mj_step [µs] | ratio to bare |')
  print('|---|---|---|---|---|')
  for name in robots:
    controlled, wrapped, bare = physics_step_times(name, steps)
    print(f'| {name} | {controlled:.1f} | {wrapped:.1f} | {bare:.1f} | '
          f'{controlled / bare:.2f} |')


def run_shield(robots):
  from hrc_suite.safety.shield import benchmark as shield_benchmark
  print('\n## Shield cycle\n')
  shield_benchmark.main(['--robots', *robots])


def rl_step_throughput(domain, task, robot, rl_steps, seed=0, fast_path=True,
                       action_space=None, motions=None):
  """(RL steps/s, s per RL step, s per same number of bare mj_steps,
  median ratio of the two in alternating chunks), CPU time.

  Random actions, the task's default shield on, the human moving, L = 25.
  The RL steps run in _WINDOWS windows of rl_steps / _WINDOWS steps, each
  in chunks of _CHUNK steps, every chunk followed by as many bare
  mj_steps on a copy of the environment's MjData (same model, same
  scene). The first three numbers take the best window of each (the
  least disturbed by other processes); the ratio is the median over the
  chunks of RL step time over bare time measured moments apart, which
  holds where the host's own speed drifts between windows. Resets (at
  episode ends) are excluded from the time.
  """
  from hrc_suite import suite
  kwargs = dict(robot=robot, seed=seed, fast_path=fast_path,
                **task_motions.recorded_people_kwargs(motions))
  if action_space:
    kwargs['action_space'] = action_space
  env = suite.load(domain, task, task_kwargs=kwargs)
  spec = env.action_spec()
  rng = np.random.RandomState(seed)
  timestep = env.reset()
  substeps = env.task.shield_substeps
  model = env.physics.model.ptr
  data = mujoco.MjData(model)
  mujoco.mj_copyData(data, model, env.physics.data.ptr)
  window = max(1, rl_steps // _WINDOWS)
  best = bare = np.inf
  ratios = []
  for _ in range(_WINDOWS):
    elapsed = bare_elapsed = 0.0
    for first in range(0, window, _CHUNK):
      count = min(_CHUNK, window - first)
      chunk = 0.0
      for _ in range(count):
        if timestep.last():
          timestep = env.reset()
        action = rng.uniform(spec.minimum, spec.maximum, spec.shape)
        start = time.process_time()
        timestep = env.step(action)
        chunk += time.process_time() - start
      start = time.process_time()
      for _ in range(count * substeps):
        mujoco.mj_step(model, data)
      chunk_bare = time.process_time() - start
      elapsed += chunk
      bare_elapsed += chunk_bare
      ratios.append(chunk / chunk_bare)
    best = min(best, elapsed / window)
    bare = min(bare, bare_elapsed / window)
  env.close()
  return 1.0 / best, best, bare, float(np.median(ratios))


def run_tasks(robots, rl_steps, tasks=(), reference=False,
              action_space=None, motions=None):
  """The throughput table; tasks: 'domain/task' names (default: all);
  motions: a folder of people (None: the shipped library)."""
  from hrc_suite import suite
  names = [f'{d}/{t}' for d, t in suite.ALL_TASKS]
  for name in tasks:
    if name not in names:
      raise app.UsageError(f'Unknown task {name!r}: expected some of '
                           f'{", ".join(names)}')
  print('\n## RL step throughput (CPU time; random actions, shield on, human '
        f'moving, L = 25; actions: {action_space or "task default"}; '
        f'people: {motions or "shipped library"})\n')
  head = ('| task | robot | RL steps/s | ms per RL step | ms of 25 bare '
          'mj_step | ratio | ratio, alternating (median) |')
  rule = '|---|---|---|---|---|---|---|'
  if reference:
    head += ' reference RL steps/s | reference ms | reference ratio |'
    rule += '---|---|---|'
  print(head)
  print(rule)
  for name in tasks or names:
    domain, task = name.split('/')
    for robot in robots:
      rate, per_step, bare, ratio = rl_step_throughput(
          domain, task, robot, rl_steps, action_space=action_space,
          motions=motions)
      row = (f'| {name} | {robot} | {rate:.0f} | {1e3 * per_step:.2f} '
             f'| {1e3 * bare:.2f} | {per_step / bare:.1f} | {ratio:.1f} |')
      if reference:
        rate, per_step, bare, _ = rl_step_throughput(
            domain, task, robot, rl_steps, fast_path=False,
            action_space=action_space, motions=motions)
        row += f' {rate:.0f} | {1e3 * per_step:.2f} | {per_step / bare:.1f} |'
      print(row, flush=True)


# Tasks of the profile section: (domain, task, robot, action space).
PROFILED = (('reach', 'dense', 'schunk', 'cartesian'),
            ('handover', 'robot_to_human', 'schunk', None),
            ('stacking', 'default', 'panda', None))   # The slowest task.


def run_profile(rl_steps, motions=None):
  from hrc_suite import benchmark_profile
  print('\n## Where the time of an RL step goes (CPU time, µs per RL step)\n')
  tables = [benchmark_profile.profile(d, t, r, rl_steps, action_space=a,
                                      motions=motions)
            for d, t, r, a in PROFILED]
  names = [f'{d}/{t} {r} {a or "default"}' for d, t, r, a in PROFILED]
  print('| part | ' + ' | '.join(names) + ' |')
  print('|---|' + '---|' * len(names))
  for label in tables[0]:
    depth = (len(label) - len(label.lstrip())) // 2   # Nested parts.
    shown = '· ' * depth + label.strip()
    print(f'| {shown} | ' + ' | '.join(f'{table[label]:.0f}'
                                      for table in tables) + ' |')


def main(argv):
  del argv
  print(f'# hrc_suite benchmark, {time.strftime("%Y-%m-%d")}')
  print(f'machine: {machine_summary()}')
  sections = set(_SECTIONS.value)
  if _MOTIONS.value is not None and not os.path.isdir(_MOTIONS.value):
    raise app.UsageError(f'--motions={_MOTIONS.value}: not a folder')
  unknown = sections - set(SECTIONS)
  if unknown:
    raise app.UsageError(f'Unknown sections {sorted(unknown)}: expected '
                         f'{", ".join(SECTIONS)}')
  if 'physics' in sections:
    run_physics(_ROBOTS.value, _STEPS.value)
  if 'shield' in sections:
    run_shield(_ROBOTS.value)
  if 'profile' in sections:
    run_profile(_RL_STEPS.value, _MOTIONS.value)
  if 'tasks' in sections:
    run_tasks(_TASK_ROBOTS.value, _RL_STEPS.value, _TASKS.value,
              _REFERENCE.value, _ACTION_SPACE.value, _MOTIONS.value)


if __name__ == '__main__':
  app.run(main)
