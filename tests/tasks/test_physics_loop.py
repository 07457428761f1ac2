"""The compiled physics loop (tasks/runtime/physics_loop.py): where MjData keeps
its contacts, the hand-backs to Python, and agreement with the reference
path in the cases test_fast_path's random episodes may not reach."""

import mujoco
import numpy as np
import pytest

from hrc_suite import experts
from hrc_suite import suite
from hrc_suite.tasks.runtime import contact_kernels
from hrc_suite.tasks.runtime import contacts
from hrc_suite.tasks.runtime import physics_loop


def test_contact_memory_reads_the_bindings_contacts():
  model = mujoco.MjModel.from_xml_string(physics_loop._PROBE_XML)
  data = mujoco.MjData(model)
  mujoco.mj_forward(model, data)
  memory = physics_loop.ContactMemory(model, data)
  seen = set()
  for _ in range(300):
    mujoco.mj_step(model, data)
    assert memory.ncon[0] == data.ncon
    assert np.array_equal(memory.geom_pairs(), data.contact.geom)
    seen.add(data.ncon)
  assert len(seen) > 1   # The spheres roll apart: the count changes.


def test_contact_memory_refuses_a_layout_it_cannot_check():
  model = mujoco.MjModel.from_xml_string(physics_loop._PROBE_XML)
  data = mujoco.MjData(model)
  mujoco.mj_forward(model, data)

  class Moved:   # An MjData whose qpos view is not where mjData's is.
    def __getattr__(self, name):
      return getattr(data, name)
    qpos = np.zeros(model.nq)

  with pytest.raises(ValueError, match='qpos'):
    physics_loop.ContactMemory(model, Moved())


def _count_runs(env, statuses):
  compiled = env.task._stepper.compiled_steps
  run = compiled.run

  def counted(*args):
    k, status = run(*args)
    statuses.append(status)
    return k, status
  compiled.run = counted


def _count_writes(env, writes):
  compiled = env.task._stepper.compiled_steps
  run = compiled.run

  def counted(*args, **kwargs):
    groups = args[6] if len(args) > 6 else kwargs.get('writes', ())
    hold = args[7] if len(args) > 7 else kwargs.get('hold')
    writes.append(len(groups) + (hold is not None))
    return run(*args, **kwargs)
  compiled.run = counted


def _expert_episode(domain, task, fast_path, steps, statuses=None,
                    writes=None):
  env = suite.load(domain, task, task_kwargs=dict(
      robot='schunk', seed=1, fast_path=fast_path))
  policy = experts.make(env, seed=0)
  timestep = env.reset()
  if statuses is not None:
    _count_runs(env, statuses)
  if writes is not None:
    _count_writes(env, writes)
  qpos, metrics = [], []
  for _ in range(steps):
    timestep = env.step(policy(timestep))
    qpos.append(env.physics.data.qpos.copy())
    metrics.append(dict(env.task.episode_metrics, reward=timestep.reward))
    if timestep.last():
      break
  return np.array(qpos), metrics


def test_robot_human_contacts_are_judged_as_on_the_reference():
  # Robot-to-human handover (PFL): the expert's gripper meets the hand, and
  # the compiled call judges each contact by the commanded speed there.
  statuses = []
  fast_q, fast = _expert_episode('handover', 'robot_to_human', True, 150,
                                 statuses)
  slow_q, slow = _expert_episode('handover', 'robot_to_human', False, 150)
  assert physics_loop.DONE in statuses
  assert fast[-1]['contacts_human_allowed'] > 0
  assert np.array_equal(fast_q, slow_q)
  assert fast == slow


@pytest.mark.parametrize('domain,task,steps', [
    ('handover', 'human_to_robot', 200),    # the presenting grip
    ('hammering', 'robot_hammers', 60),     # the carried plank
    ('hammering', 'default', 150)])         # the hand's compliant hold
def test_work_before_physics_steps_computed_ahead_agrees(domain, task, steps):
  writes = []
  fast_q, fast = _expert_episode(domain, task, True, steps, writes=writes)
  slow_q, slow = _expert_episode(domain, task, False, steps)
  assert any(writes)   # Compiled calls that wrote the task's rows.
  assert np.array_equal(fast_q, slow_q)
  assert fast == slow


def _reach(robot, fast_path):
  """A reset reach/dense environment and the statuses of its compiled
  calls (collected on the fast path)."""
  env = suite.load('reach', 'dense', task_kwargs=dict(
      robot=robot, seed=0, fast_path=fast_path))
  statuses = []
  env.reset()
  if fast_path:
    _count_runs(env, statuses)
  return env, statuses


def _pushed_episode(fast_path):
  env, statuses = _reach('schunk', fast_path)
  rng = np.random.RandomState(0)
  qpos = []
  for step in range(12):
    if step in (3, 7):
      # A shove: joint velocities no command asked for, which put the
      # robot beyond the tracking tolerance within a physics step.
      env.physics.data.qvel[env.task._qvel_index] += 8.0
    env.step(rng.uniform(-1, 1, env.action_spec().shape))
    qpos.append(env.physics.data.qpos.copy())
  return np.array(qpos), env.task.episode_metrics, statuses


def test_a_push_is_handed_back_and_agrees_with_the_reference():
  fast_q, fast, statuses = _pushed_episode(True)
  slow_q, slow, _ = _pushed_episode(False)
  assert physics_loop.PYTHON_AFTER in statuses
  assert fast['shield_resyncs'] > 0
  assert np.array_equal(fast_q, slow_q)
  assert fast == slow


def _broken_episode(fast_path):
  env, statuses = _reach('panda', fast_path)
  timesteps = [env.step(np.zeros(7)) for _ in range(2)]
  # A joint velocity far beyond MuJoCo's limit: the next physics step (the
  # RL step's first, inside the compiled call) raises mjWARN_BADQACC.
  env.physics.data.qvel[env.task._qvel_index[1]] = 1e9
  timesteps.append(env.step(np.zeros(7)))
  return timesteps, env.task.step_metrics, statuses


def test_a_physics_warning_inside_the_compiled_call_ends_the_episode():
  fast, fast_metrics, statuses = _broken_episode(True)
  slow, slow_metrics, _ = _broken_episode(False)
  assert statuses[-1] == physics_loop.PHYSICS_WARNING
  assert fast[-1].last() and fast[-1].discount == 0.0
  assert fast_metrics['physics_errors'] == 1
  assert fast_metrics == slow_metrics
  assert [t.reward for t in fast] == [t.reward for t in slow]


@pytest.mark.parametrize('own_work,compiled', [(True, False),
                                                (False, True)])
def test_work_before_each_physics_step_keeps_the_python_loop(own_work,
                                                             compiled):
  # A task with work before every physics step that it does not hand to
  # the compiled call (_physics_step_writes: None) runs them in Python.
  env = suite.load('reach', 'dense', task_kwargs=dict(robot='schunk',
                                                      seed=0))
  calls = []
  if own_work:
    env.task.__class__ = type('WithOwnWork', (type(env.task),), {
        '_before_physics_step': lambda self, physics: calls.append(1)})
  statuses = []
  env.reset()
  _count_runs(env, statuses)
  for _ in range(3):
    env.step(np.zeros(env.action_spec().shape))
  assert bool(statuses) == compiled
  assert len(calls) == (75 if own_work else 0)


def test_a_full_arena_keeps_the_python_loop():
  def episode(headroom):
    env = suite.load('reach', 'dense', task_kwargs=dict(robot='schunk',
                                                        seed=2))
    env.reset()
    statuses = []
    _count_runs(env, statuses)
    if not headroom:
      env.task._stepper.compiled_steps._arena_limit = -1.0
    rng = np.random.RandomState(0)
    for _ in range(20):
      env.step(rng.uniform(-1, 1, env.action_spec().shape))
    return env.physics.data.qpos.copy(), statuses
  q_compiled, statuses = episode(True)
  q_python, none = episode(False)
  assert statuses and not none
  assert np.array_equal(q_compiled, q_python)


def test_contact_kernels_flag_robot_human_pairs_as_the_monitor_does():
  """contact_kernels' robot-human type is the monitor's human_allowed."""
  assert (contact_kernels.HUMAN_ALLOWED
          == int(contacts.ContactType.human_allowed))
  pair_types = np.full((3, 3), -1, dtype=np.int8)
  pair_types[0, 1] = pair_types[1, 0] = contacts.ContactType.human_allowed
  pair_types[0, 2] = pair_types[2, 0] = contacts.ContactType.static
  flags = np.zeros(len(contacts.CONTACT_TYPES), dtype=bool)
  geom = np.array([[2, 0]], dtype=np.int32)
  assert not contact_kernels.classify(geom, pair_types, flags)
  assert flags.tolist() == [True] + [False] * (len(flags) - 1)
  assert contact_kernels.classify(np.array([[1, 0]], dtype=np.int32),
                                  pair_types, flags)
  assert flags[contacts.ContactType.human_allowed]
