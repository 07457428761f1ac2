"""An RL step's physics steps in one composer substep (the fast path).

composer.Environment runs every physics step as a Python round trip: the
task's before_substep, the entities' and the extra before_substep hooks,
dm_control's `Physics.step` (mj_step2, mj_step1, then a check for new
MuJoCo warnings), the after_substep hooks and an observation update
(docs/benchmarks.md, "Where the time of an RL step goes"). On the fast
path, environments made by `suite.load` tell composer that an RL step is
one substep (`HrcTask.physics_steps_per_control_step`), and that substep
is the task's (`suite.Environment._substep` calls
`HrcTask.run_physics_steps`, which its `ShieldedStepper` runs,
tasks/runtime/shielded_stepping.py): it runs the L physics steps itself, each
exactly as composer would: task hook, entity hooks, extra hooks, the
physics step, then the after hooks in the same order.

composer's contracts, and how they are kept:

* Entity substep hooks run every physics step (every hook an entity
  overrides; composer leaves out those with an empty body, a no-op).
* Extra substep hooks (`env.add_extra_hook`) run every physics step:
  `suite.Environment` hands them to the task (`add_extra_hook` here).
* Observables: composer reads an observable between physics steps only
  if it has a delay, a buffer of more than one value or an update
  interval other than one physics step; otherwise once per RL step after
  after_step, as it does with one substep. The one-substep mode is only
  used when no enabled observable is read between physics steps
  (`read_between_steps`), and an episode refuses to start if one is
  later.
* Physics errors: a PhysicsError with dm_control's message is raised right
  after the physics step that raised a MuJoCo warning counter (as
  `Physics.check_invalid_state`), inside the substep, where composer
  catches it; the steps after it do not run.
"""

from dm_control import composer
from dm_control.rl import control as rl_control
import mujoco
import numpy as np

HOOKS = ('before_substep', 'after_substep')
# dm_control.mujoco.engine's message for a physics step that raised a
# MuJoCo warning (check_invalid_state).
_INVALID_STATE = 'Physics state is invalid. Warning(s) raised: {}'
_WARNING_NAMES = list(mujoco.mjtWarning.__members__)


def read_between_steps(observables):
  """Names of enabled observables that composer must read between
  physics steps (a delay, a buffer or an update interval); () if none."""
  names = []
  for name, value in observables.items():
    if value.enabled and (value.update_interval not in (None, 1)
                          or value.delay not in (None, 0)
                          or value.buffer_size not in (None, 1)):
      names.append(name)
  return tuple(names)


class PhysicsSteps:
  """The hooks and the physics step of one physics step, run by the task."""

  def __init__(self):
    self._extra = {name: [] for name in HOOKS}
    self._entity = {name: [] for name in HOOKS}
    self._data = None

  def add_extra_hook(self, hook_name, hook_callable):
    """An extra substep hook (`composer.Environment.add_extra_hook`)."""
    if hook_name not in HOOKS:
      raise ValueError(f'{hook_name!r} is not a substep hook: expected one '
                       f'of {", ".join(HOOKS)}')
    if not callable(hook_callable):
      raise ValueError(f'{hook_callable!r} is not a callable')
    self._extra[hook_name].append(hook_callable)

  def bind(self, physics, root_entity):
    """Entity hooks and MuJoCo's model and data of a compiled physics."""
    self._owners = []
    for name in HOOKS:
      trivial = getattr(composer.Entity, name)
      owners = [entity for entity in root_entity.iter_entities()
                if getattr(type(entity), name) is not trivial]
      self._entity[name] = [getattr(entity, name) for entity in owners]
      self._owners += owners
    self._model, self._data = physics.model.ptr, physics.data.ptr
    self._warnings = physics.data.warning.number   # a view into MjData
    # dm_control's legacy step (mj_step2, then mj_step1) with Euler-type
    # integrators; else its own Physics.step.
    self._raw = bool(physics.legacy_step) and (
        physics.model.opt.integrator != mujoco.mjtIntegrator.mjINT_RK4.value)

  @property
  def raw(self):
    """Whether a physics step is MuJoCo's mj_step2 then mj_step1."""
    return self._raw

  def idle(self):
    """Whether no hook has work to do: no extra hooks, and every entity
    with hooks says they are idle (`substep_hooks_idle`)."""
    return not (self._extra['before_substep'] or self._extra['after_substep']
                or any(not getattr(entity, 'substep_hooks_idle', False)
                       for entity in self._owners))

  def raise_warnings(self, before):
    """dm_control's PhysicsError for the warnings raised since `before`
    (counters, as `warning.number`)."""
    self._check_warnings(np.asarray(before, self._warnings.dtype).tobytes())

  def step(self, physics, action, random_state):
    """One physics step with the hooks composer runs around it; the
    task's own parts are run by the caller before and after."""
    for hook in self._entity['before_substep']:
      hook(physics, random_state)
    for hook in self._extra['before_substep']:
      hook(physics, action, random_state)
    if self._raw:
      before = self._warnings.tobytes()   # cheaper than a copy and compare
      mujoco.mj_step2(self._model, self._data)
      mujoco.mj_step1(self._model, self._data)
      if self._warnings.tobytes() != before:
        self._check_warnings(before)
    else:
      physics.step()

  def _check_warnings(self, before):
    """dm_control's check: an error if a warning counter went up."""
    before = np.frombuffer(before, dtype=self._warnings.dtype)
    raised = self._warnings > before
    if raised.any():
      raise rl_control.PhysicsError(_INVALID_STATE.format(
          ', '.join(np.compress(raised, _WARNING_NAMES))))

  def after(self, physics, random_state):
    """The entity and extra after_substep hooks of a physics step."""
    for hook in self._entity['after_substep']:
      hook(physics, random_state)
    for hook in self._extra['after_substep']:
      hook(physics, random_state)
