"""The compiled shield cycles (safety.shield.batch, cycle_kernels, path_kernels)
against the readable reference (Shield.step, path.Path)."""

import dataclasses
import math

import numpy as np
import pytest

from hrc_suite import robot_description
from hrc_suite.safety import long_term_plan as ltp
from hrc_suite.safety import shield as shield_lib
from hrc_suite.safety.shield import batch
from hrc_suite.safety.shield import mode_kernels
from hrc_suite.safety.shield import modes
from hrc_suite.safety.shield import path as path_lib
from hrc_suite.safety.shield import path_kernels
from hrc_suite.safety.shield import shield_state

import safety_references
import shield_harness as harness

L = 25   # Cycles per RL step (tasks.runtime.options.DEFAULT_SHIELD_SUBSTEPS).


def _path_array(path):
  return shield_state.path_array(path)


def test_path_kernels_match_path():
  rs = np.random.RandomState(0)
  dt = 0.004
  out = np.empty(path_kernels.PATH_SIZE)
  pieces = np.empty((path_kernels.MAX_PIECES, 5))
  for _ in range(3000):
    s, v, a = rs.uniform(0, 3), rs.uniform(0, 1.2), rs.uniform(-3, 3)
    target = rs.choice([0.0, 1.0, rs.uniform(0, 1)])
    acc, jerk = rs.uniform(0, 6), rs.uniform(1e-3, 80)
    reference = path_lib.plan_profile(s, v, a, target, acc, jerk, dt)
    ok = path_kernels.plan_profile(out, s, v, a, target, acc, jerk, dt)
    assert ok == (reference is not None)
    if reference is None:
      continue
    assert np.array_equal(out, _path_array(reference))
    count = path_kernels.segments(out, pieces)
    expected = reference.segments()
    assert np.array_equal(pieces[:count], np.array(expected))
    for t in rs.uniform(0, reference.end_time() + 0.1, 5):
      s_ref, v_ref = (x[0] for x in reference.sample([t])[:2])
      assert path_kernels.sample_s(pieces, count, t) == s_ref
      assert path_kernels.sample_s_dot(pieces, count, t) == v_ref
      after = rs.uniform(0, t)
      assert path_kernels.max_s_dot(pieces, count, after, t) == (
          reference.max_s_dot(after, t))
    assert path_kernels.final_s_dot(out) == reference.final()[1]
    duration = rs.choice([dt, rs.uniform(0, 0.5)])
    reference.advance(duration)
    path_kernels.advance(out, duration)
    assert np.array_equal(out, _path_array(reference))


def _scenario(name, human, seconds, seed, mode='ssm'):
  """Keypoints and times of `seconds` of cycles, goals every L cycles."""
  description = robot_description.load(name)
  make = lambda: shield_lib.Shield(
      description, mode=mode,
      base_pose=harness.layout.robot_mount(name).base_pose(),
      tool_capsule=harness.tool_capsule(description))
  goal = harness.random_goals(description, np.random.RandomState(seed))
  goals = [goal() for _ in range(int(round(seconds / 0.1)))]
  times = np.arange(len(goals) * L) * 0.004
  frames = np.array([human(t) for t in times])
  return make, goals, frames, times


def _run(make, goals, frames, times, compiled):
  shield = make()
  points, flags, states = [], [], []
  for i, goal in enumerate(goals):
    shield.new_goal(goal)
    rows = slice(i * L, (i + 1) * L)
    p, f = batch.step_many(shield, frames[rows], times[rows],
                           compiled=compiled)
    points.append(p)
    flags.append(f)
    states.append(shield.get_state())
  return np.concatenate(points), np.concatenate(flags), states


@pytest.mark.parametrize('name,human,mode', [
    ('schunk', 'attack', 'ssm'), ('panda', 'walk', 'ssm'),
    ('ur5e', 'far', 'ssm'), ('panda', 'attack', 'pfl'),
    ('schunk', 'walk', 'pfl'), ('iiwa', 'attack', 'off'),
    ('schunk', 'attack', 'pfl_energy'), ('panda', 'walk', 'pfl_energy'),
    ('iiwa', 'attack', 'pfl_energy')])
def test_compiled_cycles_match_the_reference(name, human, mode):
  motion = {'attack': harness.hand_attack((0.5, 0.1, 0.9)),
            'walk': harness.walk_in_and_leave(),
            'far': harness.far_away()}[human]
  case = _scenario(name, motion, 3.0, seed=1, mode=mode)
  fast, fast_flags, fast_states = _run(*case, compiled=True)
  slow, slow_flags, slow_states = _run(*case, compiled=False)
  # Bit for bit: the kernels perform the reference's operations in its
  # order (tests/tasks/test_fast_path.py).
  assert np.array_equal(fast, slow)
  assert np.array_equal(fast_flags, slow_flags)
  if human == 'attack' and mode != 'off':   # The shield intervenes.
    assert slow_flags.mean() > 0.05
  for a, b in zip(fast_states, slow_states):
    assert set(a) == set(b)
    for key in a:
      x, y = np.asarray(a[key]), np.asarray(b[key])
      assert np.array_equal(x, y, equal_nan=x.dtype.kind == 'f'), key


def test_checkpoint_replay_gives_the_same_set_points():
  case = _scenario('schunk', harness.hand_attack((0.5, 0.1, 0.9)), 1.0, 2)
  make, goals, frames, times = case
  shield = make()
  shield.new_goal(goals[0])
  batch.step_many(shield, frames[:L], times[:L])
  shield.new_goal(goals[1])
  saved = batch.checkpoint(shield)
  first, flags = batch.step_many(shield, frames[L:2 * L], times[L:2 * L])
  end = shield.get_state()
  batch.restore(shield, saved)
  again, again_flags = batch.step_many(shield, frames[L:2 * L],
                                       times[L:2 * L])
  assert np.array_equal(first, again)
  assert np.array_equal(flags, again_flags)
  for key, value in shield.get_state().items():
    assert np.array_equal(np.asarray(value), np.asarray(end[key])), key
  assert math.isfinite(first.sum())


def test_plan_state_kernel_matches_the_matrix_reference():
  description = robot_description.load('panda')
  limits = description.limits
  rs = np.random.RandomState(4)
  for _ in range(20):
    q0 = rs.uniform(limits.q_min + 0.3, limits.q_max - 0.3)
    goal = rs.uniform(limits.q_min + 0.3, limits.q_max - 0.3)
    plan = ltp.plan_to_goal(q0, np.zeros_like(q0), np.zeros_like(q0), goal,
                            limits, 0.004, rs.uniform(0, 5))
    for _ in range(10):
      s = plan.start_time + rs.uniform(-0.1, plan.end_time - plan.start_time
                                       + 0.1)
      args = (s, rs.uniform(0, 1), rs.uniform(-5, 5), rs.uniform(-50, 50))
      assert np.allclose(plan.state(*args),
                         safety_references.plan_state(plan, *args),
                         rtol=1e-12, atol=1e-12)


def test_rl_step_benchmark_runs_both_paths():
  from hrc_suite.safety.shield import benchmark as shield_benchmark
  rows = shield_benchmark.main(['--rl_step', '--robots', 'panda',
                                '--rl_steps', '8'])
  assert [row[1] for row in rows] == list(shield_benchmark.SCENES)
  close = rows[0]
  assert close[-1] > 0.0   # The close scene makes the shield intervene.
  assert all(value > 0.0 for value in close[2:6])


def test_mode_parameter_groups_and_their_registration():
  assert isinstance(shield_lib.Shield('panda').kernel_parameters(),
                    mode_kernels.SsmParameters)
  pfl = shield_lib.Shield('panda', mode='pfl')
  assert pfl.kernel_parameters() == mode_kernels.SpeedLimitParameters(
      pfl.speed_limit, modes.S_DOT_TOLERANCE)
  energy = shield_lib.Shield('panda', mode='pfl_energy')
  parameters = energy.kernel_parameters()
  assert isinstance(parameters, mode_kernels.EnergyParameters)
  np.testing.assert_array_equal(parameters.transient,
                                energy.energy_limits.transient)
  assert parameters.coasting == energy.energy_limits.coasting
  assert parameters.frame_index.tolist() == (
      energy.robot.frame_index.tolist())
  assert isinstance(energy.kernel_tables(energy.plan),
                    mode_kernels.EnergyTables)
  with pytest.raises(TypeError, match='NamedTuple class'):
    mode_kernels.register(dict, mode_kernels._ssm_failsafe_target,
                          mode_kernels._ssm_verdict)
  with pytest.raises(TypeError, match='numba-jitted'):
    mode_kernels.register(mode_kernels.NoTables, lambda *a: 0.0,
                          mode_kernels._ssm_verdict)
  with pytest.raises(ValueError, match='already has'):
    mode_kernels.register(mode_kernels.SsmParameters,
                          mode_kernels._ssm_failsafe_target,
                          mode_kernels._ssm_verdict)


def test_a_checkpoint_is_the_frozen_state_record():
  case = _scenario('panda', harness.hand_attack((0.5, 0.1, 0.9)), 0.2, 3)
  make, goals, frames, times = case
  shield = make()
  shield.new_goal(goals[0])
  batch.step_many(shield, frames[:L], times[:L])
  saved = batch.checkpoint(shield)
  assert saved is shield.state
  assert saved.human is shield.human.state
  with pytest.raises(dataclasses.FrozenInstanceError):
    saved.time = 0.0
  batch.step_many(shield, frames[L:2 * L], times[L:2 * L])
  assert shield.state is not saved and shield.time > saved.time
  batch.restore(shield, saved)
  assert shield.state is saved and shield.human.state is saved.human
  with pytest.raises(TypeError, match='ShieldState'):
    shield.state = {}
