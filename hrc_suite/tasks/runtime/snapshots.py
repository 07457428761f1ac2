"""Snapshots of a running episode: taken and restored (`EpisodeSnapshots`,
which a task's get_state / set_state call: `SnapshottedTask`).

A snapshot of a running episode is a dict: 'physics' (MuJoCo's
integration state), 'player' (the person's), 'shield', 'task' (the
episode's progress, tasks/runtime/episode.py, the stepping's time, contact flags
and last command, tasks/runtime/shielded_stepping.py, the metrics and the task's
own state, `SnapshottedTask._task_state`) and 'grips' (the person's grips
and welds, which change the model: tasks/runtime/grips.py).

A snapshot is a nested value of dicts, lists, tuples, arrays and scalars,
which tasks/runtime/snapshot_arrays.py stores as arrays plus a JSON spec.
"""

import collections
import copy
from typing import Any, Mapping

from dm_control import mjcf
import mujoco
import numpy as np

_STATE_SPEC = mujoco.mjtState.mjSTATE_INTEGRATION   # 'physics'


class EpisodeSnapshots:
  """Takes and restores snapshots of an HrcTask's running episode from the
  parts that hold it."""

  def __init__(self, player, playback, shield, grips, stepper, metrics,
               task_state, set_task_state):
    """Snapshots of the episode these parts hold.

    Args:
      player: the person's `human.player.Player`.
      playback: its `entities.human_playback.HumanPlayback`.
      shield: the `safety.shield.Shield`.
      grips: the person's `grips.HumanGrips`.
      stepper: the `shielded_stepping.ShieldedStepper`.
      metrics: the `metrics.EpisodeMetrics`.
      task_state: task_state(physics) is the task's own episode state
        (HrcTask._task_state; deep-copied here).
      set_task_state: set_task_state(physics, state) restores it, given a
        deep copy, after the rest (HrcTask._set_task_state).
    """
    self._player = player
    self._playback = playback
    self._shield = shield
    self._grips = grips
    self._stepper = stepper
    self._metrics = metrics
    self._task_state = task_state
    self._set_task_state = set_task_state
    self._episode_data = None   # MjData of the last initialised episode.
    self._restored = False      # a running episode, since the last step

  def episode_started(self, physics):
    """Notes that an episode was initialised in `physics` (restore needs
    one).

    Args:
      physics: the environment's physics.
    """
    self._episode_data = physics.data.ptr

  @property
  def restored(self):
    """Whether a running episode was restored since the last RL step
    began (`step_started`)."""
    return self._restored

  def step_started(self):
    """Notes that an RL step began (the restored episode goes on)."""
    self._restored = False

  def take(self, physics, progress):
    """A snapshot of the episode (module doc).

    Args:
      physics: the environment's physics.
      progress: the episode's `episode.EpisodeProgress`.

    Returns:
      The snapshot, for `restore`.
    """
    size = mujoco.mj_stateSize(physics.model.ptr, _STATE_SPEC)
    physics_state = np.empty(size)
    mujoco.mj_getState(physics.model.ptr, physics.data.ptr, physics_state,
                       _STATE_SPEC)
    stepper = self._stepper
    return {
        'physics': physics_state,
        'player': self._player.get_state(),
        'shield': self._shield.get_state(),   # arrays and scalars only
        'task': {
            'q_goal': progress.q_goal.copy(), 'time': stepper.time,
            'steps': progress.steps, 'reward': progress.reward,
            'pending_rewards': list(progress.pending_rewards),
            'terminate': progress.terminate, 'discount': progress.discount,
            'step_flags': stepper.step_flags.copy(),
            'command_dq': stepper.command_dq.copy(),
            'cp_random': progress.cp_random.get_state(),
            'metrics': copy.deepcopy(self._metrics.state()),
            'clip_index': progress.clip_index,
            'clip_ended': progress.clip_ended,
            'own': copy.deepcopy(self._task_state(physics)),
        },
        # Human.hold changes the model, which the physics state lacks.
        'grips': self._grips.state(physics),
    }

  def restore(self, physics, state, progress):
    """Restores a snapshot from `take` (same task configuration) into
    `physics`, `progress` and the parts, the physics forwarded, then the
    task's own state (a deep copy). A snapshot of a running episode
    restored after a LAST step continues at the next step (environments
    of suite.load: `restored`) instead of being discarded by a reset.

    Args:
      physics: the environment's physics, of an episode that has begun.
      state: the snapshot.
      progress: the episode's `episode.EpisodeProgress`.

    Raises:
      ValueError: an environment that has not been reset, or a physics
        state of another model's size.
    """
    if physics.data.ptr is not self._episode_data:
      # composer.Environment resets at its first step, which would draw a
      # new episode over the restored one.
      raise ValueError('set_state needs an environment that has been reset: '
                       'this physics has no episode yet (call env.reset() '
                       'before env.task.set_state(env.physics, state))')
    size = mujoco.mj_stateSize(physics.model.ptr, _STATE_SPEC)
    physics_state = np.asarray(state['physics'], dtype=np.float64)
    if physics_state.shape != (size,):
      raise ValueError(f'physics state must have {size} entries for this '
                       f'model, got shape {physics_state.shape}')
    # Grips first: hold/release switch welds on and off, the physics state
    # then restores which are active.
    self._grips.restore(physics, state['grips'])
    mujoco.mj_setState(physics.model.ptr, physics.data.ptr, physics_state,
                       _STATE_SPEC)
    self._player.set_state(state['player'])
    self._playback.show_clip(physics)
    self._shield.set_state(state['shield'])
    task = state['task']
    progress.q_goal = np.array(task['q_goal'], dtype=float)
    progress.steps = int(task['steps'])
    progress.reward = float(task['reward'])
    progress.pending_rewards = collections.deque(task['pending_rewards'])
    progress.terminate = bool(task['terminate'])
    progress.discount = float(task['discount'])
    self._stepper.set_state(task['time'], task['step_flags'],
                            task['command_dq'])
    progress.cp_random.set_state(task['cp_random'])
    self._metrics.set_state(copy.deepcopy(task['metrics']))
    progress.clip_index = int(task['clip_index'])
    progress.clip_ended = bool(task['clip_ended'])
    mujoco.mj_forward(physics.model.ptr, physics.data.ptr)
    self._set_task_state(physics, copy.deepcopy(task['own']))
    self._restored = not progress.terminate


class SnapshottedTask:
  """An HrcTask's side of its EpisodeSnapshots (`self._snapshots`, of the
  episode `self._episode`): get_state, set_state, `restored`, and the
  hooks of the task's own state, which tasks override where TASK_STATE
  (the attributes that hold it) is not enough."""

  @property
  def restored(self) -> bool:
    """Whether a running episode was restored since the last RL step
    began (`EpisodeSnapshots.restored`)."""
    return self._snapshots.restored

  def get_state(self, physics: mjcf.Physics) -> dict[str, Any]:
    """A snapshot of the episode: physics, person, shield, task, metrics
    and grips (module doc; `EpisodeSnapshots.take`).

    Args:
      physics: the environment's physics.

    Returns:
      The snapshot, for `set_state`.
    """
    return self._snapshots.take(physics, self._episode)

  def set_state(self, physics: mjcf.Physics,
                state: Mapping[str, Any]) -> None:
    """Restores a snapshot of `get_state` (same task configuration) into an
    environment that has been reset (`EpisodeSnapshots.restore`).

    Args:
      physics: the environment's physics.
      state: a snapshot of `get_state`.

    Raises:
      ValueError: an environment that has not been reset, or a physics
        state of another model's size.
    """
    self._snapshots.restore(physics, state, self._episode)

  def _task_state(self, physics):
    """The task's own episode state: the TASK_STATE attributes
    (deep-copied by get_state); grips and welds are saved by the base."""
    del physics
    return {name: getattr(self, name) for name in self.TASK_STATE}

  def _set_task_state(self, physics, state):
    """Restores `_task_state` (a deep copy); physics is already restored."""
    del physics
    for name in self.TASK_STATE:
      setattr(self, name, state[name])
