"""Tests of agents.precompile: the second process's half compiles the
kernels the tasks call, with the argument types they pass."""

import numba
import numpy as np

from agents import precompile
from hrc_suite import suite
from hrc_suite.control import ik_kernels
from hrc_suite.entities import gripper_kernels
from hrc_suite.entities import human_kernels
from hrc_suite.human import player_kernels
from hrc_suite.safety import plan_kernels
from hrc_suite.safety.collision_prevention import kernels as collision_kernels

# The second process's half (precompile.compile_second_half).
SECOND_HALF = (collision_kernels, ik_kernels, player_kernels, human_kernels,
               plan_kernels, gripper_kernels)


def _signatures(*modules):
  """{name: set of compiled signatures} of the modules' numba kernels."""
  found = {}
  for module in modules:
    for name, value in vars(module).items():
      if isinstance(value, numba.core.registry.CPUDispatcher):
        found[f'{module.__name__}.{name}'] = set(value.signatures)
  return found


def test_second_half_covers_what_reach_calls():
  precompile.compile_second_half('schunk')
  before = _signatures(*SECOND_HALF)
  for name in ('safety.collision_prevention.kernels.planned_path_collides',
               'control.ik_kernels.solve_gripper_down',
               'control.ik_kernels.tcp_pose',
               'human.player_kernels.play_within_clip',
               'entities.human_kernels.playback_frames',
               'safety.plan_kernels.sample_pieces',
               'entities.gripper_kernels.grasped'):
    assert before[f'hrc_suite.{name}'], name
  env = suite.load('reach', 'dense', task_kwargs={
      'robot': 'schunk', 'action_space': 'cartesian'},
                   environment_kwargs={'random_state': 0})
  random_state = np.random.RandomState(0)
  spec = env.action_spec()
  env.reset()
  for _ in range(30):   # New goals: IK, collision prevention's checks.
    if env.step(random_state.uniform(spec.minimum, spec.maximum)).last():
      env.reset()
  # Nothing new was compiled: the environment loads what the second
  # process wrote to numba's cache.
  assert _signatures(*SECOND_HALF) == before


def test_failed_second_process_warns(caplog, monkeypatch):
  # As on a cold cache: the second process is waited for.
  monkeypatch.setattr(precompile, '_compiled_here', lambda: True)
  with caplog.at_level('WARNING'):
    seconds = precompile.warm_up('no_such_robot')
  assert seconds > 0
  assert 'exited with status' in caplog.text
  assert 'no_such_robot' in caplog.text
