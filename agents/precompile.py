"""Compiles hrc_suite's numba kernels on two cores before a run starts.

A fresh checkout has no numba cache, so the first environment of a process
compiles its kernels, one function at a time: on reach/dense (Schunk) the
shield's (`safety.kernels`, `safety.shield.cycle_kernels`) about 25 s of a
core, collision prevention's (`safety.collision_prevention.kernels`) 15 s
and inverse kinematics' (`control.ik_kernels`) 6 s; the person's
playback, the plans' sampling and the gripper's grasp check 14 s on a
slower day of the same machine
(docs/benchmarks.md, "Kernel compilation on a fresh checkout"). `warm_up`
compiles all but the shield's in a second Python process while this one
compiles the shield, then waits for it. Both write numba's on-disk cache
(the kernels are `cache=True`), from which this process's environment
loads what the other process compiled. With a warm cache both halves only
load (about a second). The RL step's compiled physics
(`tasks.runtime.physics_loop`) compiles in the environment's first step (its
argument types come from a built environment).

  python -m agents.precompile --robot=schunk   # The second process's half.
"""

import os
import subprocess
import sys
import time
from typing import Sequence

from absl import app
from absl import flags
from absl import logging

from hrc_suite import layout
from hrc_suite import robot_description
from hrc_suite.control import ik as ik_lib
from hrc_suite.control import kinematics
from hrc_suite.entities import gripper_kernels
from hrc_suite.entities import human_kernels
from hrc_suite.human import player_kernels
from hrc_suite.safety import energy_kernels
from hrc_suite.safety import kernels
from hrc_suite.safety import plan_kernels
from hrc_suite.safety.collision_prevention import kernels as collision_kernels
from hrc_suite.safety.shield import cycle_kernels
from hrc_suite.safety.shield import energy_check_kernels
from hrc_suite.safety.shield import speed_kernels


def compile_second_half(robot: str) -> None:
  """Compiles (or loads) the kernels of the second process's half for the
  argument types the tasks pass: collision prevention's
  (`collision_kernels.warm_up`), IK's (the TCP position and one IK solve through
  `control.ik`, as the tasks' Cartesian actions and goal sampling call
  them), and those every environment warms up when it is built: the
  person's playback (`player_kernels`, `human_kernels`), the plans'
  sampling (`plan_kernels`) and the gripper's grasp check
  (`gripper_kernels`); energy PFL's (`energy_kernels`,
  `energy_check_kernels`).

  Args:
    robot: the robot whose IK model is used.
  """
  player_kernels.warm_up()
  human_kernels.warm_up()
  plan_kernels.warm_up()
  gripper_kernels.warm_up()
  collision_kernels.warm_up()
  # Energy PFL's plan tables and readable check (shield mode pfl_energy).
  energy_kernels.warm_up()
  energy_check_kernels.warm_up()
  description = robot_description.load(robot)
  model = kinematics.KinematicModel(
      description, layout.robot_mount(description.name).base_pose())
  ik = ik_lib.InverseKinematics(model)
  # The TCP position (the Cartesian actions' start), then a contiguous
  # target, as the tasks pass (a column view compiles anew).
  target = ik.tcp_position(description.q_home).copy()
  ik.solve(target, description.q_home)


def _compiled_here():
  """True if this process compiled the shield's cycle kernel rather than
  loading it from numba's cache."""
  return bool(cycle_kernels.ssm_cycles.stats.cache_misses)


def warm_up(robot: str) -> float:
  """Compiles (or loads) the shield's kernels here and those of collision
  prevention and IK in a second process at the same time.

  If this half loaded from the cache (nothing compiled here), the second
  process is stopped instead of waited for: its half is cached too and
  loads in this process when first called (the second process's start
  would cost more). If it fails, its kernels compile when the environment
  first calls them (a warning says so).

  Args:
    robot: the robot whose IK model the second process uses.

  Returns:
    The seconds it took.
  """
  start = time.perf_counter()
  # The child imports hrc_suite from where this process does.
  environ = dict(os.environ, PYTHONPATH=os.pathsep.join(
      path for path in sys.path if path))
  child = subprocess.Popen(
      [sys.executable, '-m', 'agents.precompile', f'--robot={robot}'],
      env=environ)
  try:
    kernels.warm_up()
    cycle_kernels.warm_up()
    speed_kernels.warm_up()
  except BaseException:
    child.kill()
    child.wait()
    raise
  if not _compiled_here():
    child.kill()
    child.wait()
    return time.perf_counter() - start
  status = child.wait()
  if status:
    logging.warning('agents.precompile for %s exited with status %d: its '
                    'kernels compile in this process instead', robot,
                    status)
  return time.perf_counter() - start


def main(argv: Sequence[str]) -> None:
  """Compiles the second process's half for --robot.

  Args:
    argv: the command line (unused).
  """
  del argv
  compile_second_half(flags.FLAGS.robot)


if __name__ == '__main__':
  flags.DEFINE_string('robot', 'schunk', 'Robot whose IK model is used.')
  app.run(main)
