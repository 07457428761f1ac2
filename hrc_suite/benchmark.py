"""Speed benchmarks: `python -m hrc_suite.benchmark [--section=physics,shield,tasks]`.

Prints, per robot, the median wall time of one 4 ms physics step of the
workcell with robot, gripper and tracking controller, next to a bare
`mujoco.mj_step` of the same model, so the overhead is a ratio; and the
shield's cycle time with the human close, across the table and far; and the
RL-step throughput of every task (random actions, shield on, human moving,
L = 25) next to the same number of bare physics steps. Numbers are recorded
in docs/benchmarks.md.
"""

import platform
import time

from absl import app
from absl import flags
import mujoco
import numpy as np

from hrc_suite import robot_description

SECTIONS = ('physics', 'shield', 'tasks')
_SECTIONS = flags.DEFINE_list(
    'section', list(SECTIONS), 'Which benchmarks to run: ' + ', '.join(SECTIONS))
_ROBOTS = flags.DEFINE_list('robots', list(robot_description.ROBOT_NAMES),
                            'Robots to benchmark.')
_STEPS = flags.DEFINE_integer('steps', 2000, 'Physics steps per measurement.')
_TASK_ROBOTS = flags.DEFINE_list('task_robots', ['schunk', 'panda'],
                                 'Robots of the RL-step throughput section.')
_RL_STEPS = flags.DEFINE_integer('rl_steps', 300,
                                 'RL steps per task throughput measurement.')


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
  from hrc_suite.safety import benchmark as shield_benchmark
  print('\n## Shield cycle\n')
  shield_benchmark.main(['--robots', *robots])


def rl_step_throughput(domain, task, robot, rl_steps, seed=0):
  """(RL steps/s, s per RL step, s per same number of bare mj_steps).

  Random actions, the task's default shield on, the human moving, L = 25.
  Resets (at episode ends) are excluded from the time.
  """
  from hrc_suite import suite
  env = suite.load(domain, task, task_kwargs=dict(robot=robot, seed=seed))
  spec = env.action_spec()
  rng = np.random.RandomState(seed)
  timestep = env.reset()
  elapsed, done = 0.0, 0
  while done < rl_steps:
    if timestep.last():
      timestep = env.reset()
    action = rng.uniform(spec.minimum, spec.maximum, spec.shape)
    start = time.perf_counter()
    timestep = env.step(action)
    elapsed += time.perf_counter() - start
    done += 1
  substeps = env.task.shield_substeps
  model, data = env.physics.model.ptr, env.physics.data.ptr
  start = time.perf_counter()
  for _ in range(rl_steps * substeps):
    mujoco.mj_step(model, data)
  bare = time.perf_counter() - start
  env.close()
  return rl_steps / elapsed, elapsed / rl_steps, bare / rl_steps


def run_tasks(robots, rl_steps):
  from hrc_suite import suite
  print('\n## RL step throughput (random actions, shield on, human moving, '
        'L = 25)\n')
  print('| task | robot | RL steps/s | ms per RL step | ms of 25 bare '
        'mj_step | ratio |')
  print('|---|---|---|---|---|---|')
  for domain, task in suite.ALL_TASKS:
    for robot in robots:
      rate, per_step, bare = rl_step_throughput(domain, task, robot, rl_steps)
      print(f'| {domain}/{task} | {robot} | {rate:.0f} | {1e3 * per_step:.2f} '
            f'| {1e3 * bare:.2f} | {per_step / bare:.1f} |', flush=True)


def main(argv):
  del argv
  print(f'# hrc_suite benchmark, {time.strftime("%Y-%m-%d")}')
  print(f'machine: {machine_summary()}')
  sections = set(_SECTIONS.value)
  unknown = sections - set(SECTIONS)
  if unknown:
    raise app.UsageError(f'Unknown sections {sorted(unknown)}: expected '
                         f'{", ".join(SECTIONS)}')
  for name in _ROBOTS.value:
    if name not in robot_description.ROBOT_NAMES:
      raise app.UsageError(f'Unknown robot {name!r}: expected one of '
                           f'{", ".join(robot_description.ROBOT_NAMES)}')
  if 'physics' in sections:
    run_physics(_ROBOTS.value, _STEPS.value)
  if 'shield' in sections:
    run_shield(_ROBOTS.value)
  if 'tasks' in sections:
    run_tasks(_TASK_ROBOTS.value, _RL_STEPS.value)


if __name__ == '__main__':
  app.run(main)
