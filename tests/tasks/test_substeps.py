"""One composer substep per RL step (tasks/runtime/substeps.py): composer's
hooks still run every physics step, in composer's order, at the same states."""

from dm_control import composer
from dm_control import mjcf
import numpy as np
import pytest

from hrc_suite import suite
from hrc_suite.tasks import reach

RL_STEPS = 3


class _Probe(composer.Entity):
  """An entity whose substep hooks record what they see."""

  def _build(self, log):
    self._mjcf_root = mjcf.RootElement(model='probe')
    self.log = log

  @property
  def mjcf_model(self):
    return self._mjcf_root

  def before_substep(self, physics, random_state):
    self.log.append(('entity before', round(physics.time(), 9)))

  def after_substep(self, physics, random_state):
    self.log.append(('entity after', round(physics.time(), 9)))


class _ProbedReach(reach.Reach):

  def _build_task(self):
    super()._build_task()
    self.log = []
    self.probe = _Probe(self.log)
    self._arena.attach(self.probe)


def _run(fast_path, **task_kwargs):
  """RL steps with extra hooks; the hooks' log and the joint states."""
  task = _ProbedReach(robot='panda', fast_path=fast_path, **task_kwargs)
  env = suite.Environment(task, random_state=0,
                          strip_singleton_obs_buffer_dim=True)
  log = task.log

  def extra_before(physics, action, random_state):
    log.append(('extra before', round(physics.time(), 9)))

  def extra_after(physics, random_state):
    log.append(('extra after', round(physics.time(), 9),
                physics.data.qpos.tobytes()))

  env.add_extra_hook('before_substep', extra_before)
  env.add_extra_hook('after_substep', extra_after)
  env.reset()
  rng = np.random.RandomState(1)
  spec = env.action_spec()
  observations = []
  for _ in range(RL_STEPS):
    timestep = env.step(rng.uniform(spec.minimum, spec.maximum))
    observations.append(timestep.observation)
  return env, log, observations


def test_hooks_run_every_physics_step_as_with_composers_substeps():
  fast_env, fast_log, fast_obs = _run(True)
  slow_env, slow_log, slow_obs = _run(False)
  assert fast_env.task.one_substep and not slow_env.task.one_substep
  assert fast_env.task.physics_steps_per_control_step == 1
  assert slow_env.task.physics_steps_per_control_step == 25
  steps = RL_STEPS * fast_env.task.shield_substeps
  # Per physics step: entity, extra before; entity, extra after.
  assert len(slow_log) == 4 * steps
  assert [entry[0] for entry in slow_log[:4]] == [
      'entity before', 'extra before', 'entity after', 'extra after']
  assert fast_log == slow_log
  for fast, slow in zip(fast_obs, slow_obs):
    assert fast.keys() == slow.keys()
    for name in fast:
      np.testing.assert_array_equal(fast[name], slow[name])


def test_observables_read_between_physics_steps_keep_composers_substeps():
  task = reach.Reach(robot='panda', observations='full',
                     observation_delay={'joint_positions': 0.008})
  env = suite.Environment(task, random_state=0)
  assert not task.one_substep
  assert task.physics_steps_per_control_step == 25
  env.reset()
  env.step(np.zeros(env.action_spec().shape))


def test_an_observable_delayed_after_the_environment_is_refused():
  env = suite.load('reach', 'dense', task_kwargs=dict(robot='panda',
                                                      seed=0))
  assert env.task.one_substep
  name = env.task.observation_names[0]
  env.task.observables[name].delay = 2
  with pytest.raises(ValueError, match=name):
    env.reset()


def test_extra_hooks_are_checked():
  env = suite.load('reach', 'dense', task_kwargs=dict(robot='panda'))
  with pytest.raises(ValueError, match='not a callable'):
    env.add_extra_hook('after_substep', 3)
