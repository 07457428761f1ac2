"""Snapshots through .npz: flatten, save, load, unflatten, restore."""

import numpy as np
import pytest

from hrc_suite import suite
from hrc_suite.tasks import pick_place
from hrc_suite.tasks.runtime import snapshot_arrays

import checks    # tests/tasks/checks.py
import oracles   # tests/tasks/oracles.py

ROBOTS = ('schunk', 'panda')
STEPS_IN = 8        # RL steps before the snapshot
CONTINUATION = 10   # RL steps compared after restoring


def _save_and_load(state, path):
  np.savez(path, **snapshot_arrays.to_arrays(state))
  with np.load(path, allow_pickle=False) as saved:
    return snapshot_arrays.from_arrays(dict(saved))


def _nested():
  return {
      'float': 0.1, 'np_float': np.float64(0.3000000000000002),
      'np_int': np.int32(-7), 'np_bool': np.bool_(True),
      'int': 2**40, 'bool': False, 'none': None, 'str': 'right',
      'inf': float('inf'), 'nan': float('nan'), 'negative_zero': -0.0,
      'list': [1, 2.5, None, 'a', [True]], 'tuple': (None, {'x': 1.0}),
      'empty': ([], (), {}), 'array': np.arange(6.0).reshape(2, 3),
      'floats': [[0.5, -1e300], (2.0, float('nan'))],
      'uint32': np.arange(4, dtype=np.uint32), 'mask': np.array([True]),
      'empty_array': np.zeros((0, 4, 6)), 'column': np.ones((3, 1), '>f4'),
      'rng': np.random.RandomState(5).get_state(),
  }


def test_nested_values_round_trip_with_their_types(tmp_path):
  state = _nested()
  loaded = _save_and_load(state, tmp_path / 'state.npz')
  assert snapshot_arrays.equal(loaded, state)
  assert type(loaded['np_float']) is np.float64
  assert type(loaded['int']) is int and type(loaded['bool']) is bool
  assert isinstance(loaded['tuple'], tuple) and isinstance(
      loaded['list'], list)
  assert np.signbit(loaded['negative_zero'])
  assert type(loaded['floats'][1]) is tuple
  assert type(loaded['floats'][0][0]) is float
  assert loaded['column'].dtype == np.dtype('>f4')
  # Arrays are independent copies (set_state may keep and modify them).
  assert loaded['array'].flags.writeable and loaded['array'].base is None


def test_equal_sees_types_and_bits():
  state = _nested()
  assert snapshot_arrays.equal(state, _nested())
  for key, other in (('float', np.float64(0.1)), ('tuple', [None, {'x': 1.0}]),
                     ('bool', 0), ('array', np.arange(6).reshape(2, 3)),
                     ('negative_zero', 0.0)):
    changed = dict(state, **{key: other})
    assert not snapshot_arrays.equal(state, changed), key


def test_spec_depends_on_structure_not_numbers():
  first, _ = snapshot_arrays.flatten({'a': 1.0, 'b': np.zeros(3), 'c': [1]})
  second, _ = snapshot_arrays.flatten({'a': 2.0, 'b': np.ones(3), 'c': [5]})
  assert (snapshot_arrays.spec_to_json(first)
          == snapshot_arrays.spec_to_json(second))


@pytest.mark.parametrize('value, message', [
    ({'x': np.array([object()])}, r'at /x is an array of dtype object'),
    ({'x': {1: 2.0}}, r"at /x has the key 1 of type int"),
    ({'x': [object()]}, r'at /x\[0\] has the type object'),
    ({'x': 2**70}, r'at /x is the int 1180591620717411303424, outside'),
    ({'x': {'a', 'b'}}, r'at /x has the type set'),
])
def test_unstorable_values_name_their_path(value, message):
  with pytest.raises(ValueError, match=message):
    snapshot_arrays.flatten(value)


def test_corrupt_arrays_give_clear_errors():
  arrays = snapshot_arrays.to_arrays({'q': np.zeros(4)})
  with pytest.raises(ValueError, match="No snapshot spec 'spec'"):
    snapshot_arrays.from_arrays({'buffer_float64': np.zeros(4)})
  with pytest.raises(ValueError, match=r'reads float64\[0:4\] but that buffer '
                     'has 2 entries'):
    snapshot_arrays.from_arrays(dict(arrays, buffer_float64=np.zeros(2)))
  with pytest.raises(ValueError, match="needs a 'float64' buffer"):
    snapshot_arrays.from_arrays({'spec': arrays['spec']})
  with pytest.raises(ValueError, match='not valid JSON'):
    snapshot_arrays.from_arrays(dict(arrays, spec=np.array('{"dict": [')))


def _make(domain, task, robot, seed=0):
  return suite.load(domain, task, task_kwargs={
      'robot': robot, 'observations': 'full', 'done_at_success': False},
                    environment_kwargs={'random_state': seed})


def _assert_restores_from_file(env, make_fresh, path):
  """Snapshot -> .npz -> fresh environment: same continuation, bit for
  bit."""
  state = env.task.get_state(env.physics)
  loaded = _save_and_load(state, path)
  assert snapshot_arrays.equal(loaded, state)
  # Gripper closed: tasks that start with an object gripped (hammering's
  # board, the handover's hammer) keep it, so the episode goes on.
  actions = checks.random_actions(env, CONTINUATION, seed=3, gripper=1.0)
  expected = checks.rollout(env, actions)
  # A snapshot holds one episode; the next reset draws from the
  # environment's random_state, which it does not hold.
  assert expected[-1][1] == 1.0 and not env.task.should_terminate_episode(
      env.physics), 'the episode ended during the continuation'
  fresh = make_fresh()
  fresh.reset()
  fresh.task.set_state(fresh.physics, loaded)
  checks.assert_same(expected, checks.rollout(fresh, actions))
  assert fresh.task.episode_metrics == env.task.episode_metrics


@pytest.mark.parametrize('robot', ROBOTS)
@pytest.mark.parametrize('domain, task', suite.all_tasks())
def test_every_task_restores_from_a_saved_snapshot(domain, task, robot,
                                                   tmp_path):
  env = _make(domain, task, robot)
  env.reset()
  checks.rollout(env, checks.random_actions(env, STEPS_IN, seed=1,
                                             gripper=1.0))
  _assert_restores_from_file(env, lambda: _make(domain, task, robot),
                             tmp_path / 'state.npz')


def test_restores_with_the_cube_in_the_gripper(tmp_path):
  env = _make('pick_place', 'default', 'panda')
  env.reset()
  driver = oracles.WaypointDriver(env)
  task, physics = env.task, env.physics
  grasp = pick_place.GRASP_TCP_ABOVE_CENTRE
  # Hover above the cube, descend to the grasp point, close (4 steps).
  for height, gripper, tolerance in ((0.15, -1.0, 0.02),
                                     (grasp, -1.0, 0.008), (grasp, 1.0, None)):
    for k in range(60):
      goal = task.object_position(physics) + (0.0, 0.0, height)
      if (np.linalg.norm(goal - driver.tcp()) < tolerance if tolerance
          else k == 4):
        break
      env.step(driver.action(goal, gripper))
  for _ in range(5):   # Lift.
    timestep = env.step(driver.action(driver.tcp() + (0.0, 0.0, 0.05), 1.0))
  assert timestep.observation['object_gripped'][0] == 1.0, (
      'the scripted grasp failed; the test needs the cube in the gripper')
  _assert_restores_from_file(
      env, lambda: _make('pick_place', 'default', 'panda'),
      tmp_path / 'state.npz')
