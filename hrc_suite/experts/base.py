"""The expert interface: a deterministic policy that reads its task through
the task's own (noise-free) observables.

An expert is called like any policy, `action = expert(timestep)`, on the
environment it was made for. It does not use `timestep.observation` (whose
preset, noise and delay the agent chooses): it evaluates the task's
observables by name, enabled or not, on the current physics (`observe`).
Fields that are not observables of the task (privileged: e.g. a state
machine's view of which cube the person placed last) are read from the task
object and listed in the expert's PRIVILEGED docstring section.

Experts keep as little memory as possible: the phase of a state machine is
derived from the observed state each step (with hysteresis where needed), so
that an expert can take over from any state, e.g. an episode started from a
dataset snapshot (reference-state initialisation) or when it is queried
online for an agent's action (action-based imitation reward). `reset()` is
called at every first timestep.

Re-planning (experts/replan.py): an expert whose actions collision
prevention replaces REPLAN_AFTER times in a row is taken on a detour to a
waypoint whose first step is accepted, then resumes its own actions
(`REPLANS`; an episode in which that never happens is unchanged).
"""

from typing import Mapping, Optional

from dm_control import composer
from dm_control import mjcf
import dm_env
import numpy as np

from hrc_suite.experts import replan


class Expert:
  """Base class: subclasses implement `action(observation) -> array`.

  Args:
    env: the environment (of hrc_suite.suite.load) whose task the expert
      solves.

  Raises:
    ValueError: the task lacks an OBSERVED observable.
  """

  # Names of the task observables the expert reads (see `observe`).
  OBSERVED = ()
  # (domain, task) pairs the expert solves; empty = any.
  TASKS = ()
  # Whether the expert re-plans when collision prevention keeps replacing
  # its actions (experts/replan.py).
  REPLANS = True
  # The re-planning `__init__` makes (None: the expert's actions as they
  # are, also for a subclass that sets up without `Expert.__init__`).
  _replanner = None

  def __init__(self, env: composer.Environment):
    self._env = env
    self._task = env.task
    missing = [name for name in self.OBSERVED
               if name not in self._task.task_observables]
    if missing:
      raise ValueError(
          f'{type(self).__name__} reads observables {missing} that the task '
          f'{type(self._task).__name__} does not have; it has '
          f'{sorted(self._task.task_observables)}')
    spec = env.action_spec()
    self._action_shape = spec.shape
    self._callables = None
    self._replanner = replan.Replanner(self._task) if self.REPLANS else None

  @property
  def env(self) -> composer.Environment:
    """The environment the expert acts in."""
    return self._env

  @property
  def task(self) -> composer.Task:
    """The environment's task (an HrcTask)."""
    return self._task

  @property
  def physics(self) -> mjcf.Physics:
    """The environment's current physics."""
    return self._env.physics

  @property
  def replanner(self) -> Optional[replan.Replanner]:
    """The re-planning of the expert's actions (None without `REPLANS`
    or after `disable_replanning`)."""
    return self._replanner

  def disable_replanning(self) -> None:
    """Answers every query with the expert's own action, never a detour.

    For an expert queried on states another policy reached (action-based
    imitation, agents/imitation/wrappers.py): its advice then depends on
    the state alone, not on how often that policy's actions were replaced.
    """
    self._replanner = None

  def reset(self) -> None:
    """Forgets the previous episode (called at every first timestep)."""

  def observe(self) -> dict[str, np.ndarray]:
    """The OBSERVED task observables now, without noise or delay.

    Returns:
      {name: value}.
    """
    if self._callables is None:
      observables = self._task.task_observables
      # The raw callables: no corruptor (noise) and no delay buffer.
      self._callables = {name: observables[name]._callable(self.physics)  # pylint: disable=protected-access
                         for name in self.OBSERVED}
    return {name: np.asarray(fn()) for name, fn in self._callables.items()}

  def action(self, observation: Mapping[str, np.ndarray]) -> np.ndarray:
    """The expert's action (subclasses implement it).

    Args:
      observation: `observe`'s values.

    Returns:
      The action, an array of the action spec's shape (clipped to [-1, 1]
      by `__call__`).
    """
    raise NotImplementedError

  def __call__(self, timestep: dm_env.TimeStep) -> np.ndarray:
    """The expert's action at a timestep (its observation is not read:
    `observe`), or a detour's where collision prevention kept replacing
    its actions (`replanner`); resets the expert at a first timestep.

    Args:
      timestep: the environment's current timestep.

    Returns:
      The action (float64, the action spec's shape, within [-1, 1]).

    Raises:
      ValueError: `action` returned another shape.
    """
    if timestep.first():
      self._callables = None   # The physics may have been rebuilt.
      if self._replanner is not None:
        self._replanner.reset()
      self.reset()
    action = np.asarray(self.action(self.observe()), dtype=np.float64)
    if action.shape != self._action_shape:
      raise ValueError(f'{type(self).__name__} produced an action of shape '
                       f'{action.shape}, expected {self._action_shape}')
    if self._replanner is not None:
      action = np.asarray(self._replanner.action(
          action, self.physics, timestep.first()), dtype=np.float64)
    return np.clip(action, -1.0, 1.0)
