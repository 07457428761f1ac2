"""HrcTask: the shielded step loop every benchmark task shares.

One RL step (control_timestep, 0.1 s) runs L = shield_substeps physics steps
of physics_timestep (4 ms), so control_timestep must equal L x
physics_timestep: the shield is verified once per physics step, and an RL
step is exactly L shield cycles (docs/tasks.md, "The step loop").

* before_step: the action's joint goal (`actions.step_goal`: checked,
  clipped, filtered by collision prevention) goes to `shield.new_goal`;
  the last action entry drives the gripper where the task has one.
* The RL step's physics steps: the task's ShieldedStepper
  (tasks/runtime/shielded_stepping.py), from composer's substep hooks or as
  composer's one substep (`run_physics_steps`).
* after_step: self-collision check (`self_collision`), the task's own
  logic (`_update_task`, `_human_events`), reward (delay and collision
  penalty) and termination (`episode.EpisodeProgress`), metrics
  (`step_recorder.StepRecorder`).
* A physics error (a MuJoCo warning such as mjWARN_BADQACC) cuts the RL
  step short: after_step records `physics_errors` = 1 and skips the
  task's logic (MuJoCo has reset the state); in environments of
  `suite.load` the step is LAST with reward 0 and discount 0. One while
  initialising an episode raises composer.EpisodeInitializationError, so
  the environment draws the episode again (docs/safety.md, "Physics
  errors").

`scene.build` builds the scene (workcell, robot, gripper, person, shield,
collision prevention, the person's clips), `observations` the
observables, `snapshots.EpisodeSnapshots` takes and restores snapshots.
Subclasses set the class constants (`defaults.TaskConstants`) and
override `_build_task`, `_initialize_task`, `_update_task`,
`_task_reward`, `_task_reward_range` (`reward_bounds.RewardBounds`), and
optionally `_human_events`, `_failed`, `_task_observables` (name ->
observable; an entity's own where it declares the quantity, e.g.
`self._board.observables.position`), the physics-step hooks
(`stepped_task.SteppedTask`) and, where TASK_STATE (the attributes
snapshots copy) is not enough, the snapshot hooks
(`snapshots.SnapshottedTask`). The person's grips on the task's objects
are `self._grips` (`grips.HumanGrips`).
"""

import operator
from typing import Any, Mapping, Optional, Sequence, Union

from dm_control import composer
from dm_control import mjcf
from dm_control.rl import control as rl_control
from dm_env import specs
import numpy as np

from hrc_suite.tasks.runtime import actions
from hrc_suite.tasks.runtime import cost as cost_lib
from hrc_suite.tasks.runtime import defaults as defaults_lib
from hrc_suite.tasks.runtime import episode as episode_lib
from hrc_suite.tasks.runtime import grips as grips_lib
from hrc_suite.tasks.runtime import observations as observations_lib
from hrc_suite.tasks.runtime import options as options_lib
from hrc_suite.tasks.runtime import reward_bounds
from hrc_suite.tasks.runtime import scene as scene_lib
from hrc_suite.tasks.runtime import shielded_stepping
from hrc_suite.tasks.runtime import stepped_task
from hrc_suite.tasks.runtime import snapshots
from hrc_suite.tasks.runtime import step_recorder

_SEED_RANGE = 2**31 - 1


def _read(path, doc):
  """A read-only property: the task's attribute at `path` ('a.b')."""
  return property(operator.attrgetter(path), doc=doc)


class HrcTask(scene_lib.SceneParts, stepped_task.SteppedTask,
              snapshots.SnapshottedTask, episode_lib.ProgressOfTask,
              composer.Task, defaults_lib.TaskConstants,
              options_lib.OptionNames, reward_bounds.RewardBounds):
  """A robot, a gripper and a human in the workcell, shielded: composer's
  hooks, the scene and the reward. Its other attributes come from its
  bases, each in the module of what it shows (the scene's parts, the
  stepping, snapshots, the episode's progress, the class constants, the
  options, the reward bounds)."""

  def __init__(self, robot: str = 'panda', action_space: Optional[str] = None,
               shield: Optional[str] = None,
               shield_substeps: int = options_lib.DEFAULT_SHIELD_SUBSTEPS,
               physics_timestep: float = options_lib.DEFAULT_PHYSICS_TIMESTEP,
               control_timestep: float = options_lib.DEFAULT_CONTROL_TIMESTEP,
               motions: Any = None, reward: Optional[str] = None,
               reward_delay: Optional[int] = None,
               done_at_success: bool = True,
               collision_prevention: str = 'zero',
               time_limit: Optional[float] = None,
               observations: Union[str, Sequence[str]] = 'paper',
               observation_noise: Optional[Mapping[str, float]] = None,
               observation_delay: Optional[Mapping[str, float]] = None,
               cameras: Sequence[str] = (),
               camera_size: Sequence[int] = (
                   observations_lib.DEFAULT_CAMERA_SIZE),
               v_safe: float = options_lib.DEFAULT_V_SAFE,
               critical_speed: Optional[float] = None,
               collision_reward: float = options_lib.DEFAULT_COLLISION_REWARD,
               outside_human_model: str = 'refuse', cost: Any = None,
               fast_path: bool = True):
    """Builds the scene from the checked arguments (`self.options`).

    Args:
      robot, ..., fast_path: the task's options, each documented in
        `options.TaskOptions` (its fields, `TaskOptions.of`'s arguments,
        and in its docstring motions, outside_human_model, observations,
        observation_noise, observation_delay, cameras, camera_size and
        cost); docs/tasks.md, "Task kwargs" is the table.

    Raises:
      ValueError: an option's bad value, naming the option, the value and
        what was expected.
    """
    defaults = type(self).defaults()
    self.options = options = options_lib.TaskOptions.of(
        defaults, robot=robot, action_space=action_space,
        shield=shield, shield_substeps=shield_substeps,
        physics_timestep=physics_timestep,
        control_timestep=control_timestep, reward=reward,
        reward_delay=reward_delay, done_at_success=done_at_success,
        collision_prevention=collision_prevention, time_limit=time_limit,
        v_safe=v_safe, critical_speed=critical_speed,
        collision_reward=collision_reward, fast_path=fast_path)
    self._scene = scene = scene_lib.build(defaults, options, motions,
                                          outside_human_model)
    self._arena, self._robot = scene.arena, scene.robot
    self._gripper, self._human = scene.gripper, scene.human
    self._kinematics, self._shield = scene.kinematics, scene.shield
    self._collision_checker = scene.collision_checker
    self._action_space = scene.action_space
    self._player, self._playback = scene.player, scene.playback
    self._stepper = shielded_stepping.ShieldedStepper(
        self, options, self._shield, self._playback, self._robot)

    self._object_geoms = []
    self._grips = grips_lib.HumanGrips(self._human)
    self._build_task()
    self.set_timesteps(options.control_timestep, options.physics_timestep)
    if cost is None and observations == observations_lib.SAFE_RL:
      cost = True
    self._recorder = recorder = step_recorder.StepRecorder(
        self.EXTRA_COUNTERS, cost_lib.CostSpec.of(cost), self._stepper,
        self._shield)
    self._snapshots = snapshots.EpisodeSnapshots(
        self._player, self._playback, self._shield, self._grips,
        self._stepper, recorder.metrics, self._task_state,
        self._set_task_state)
    self._physics_ptr = None
    self._init_episode_state()
    self._task_obs, names = observations_lib.task_observables(
        self._robot, self._gripper, self._human, self._stepper.step_flags,
        self._task_observables, self.OBSERVATION_PRESETS,
        recorder.metrics if recorder.cost is not None else None,
        observations)
    self.observation_names = observations_lib.add_cameras(
        self._task_obs, names, self._arena.mjcf_model, cameras, camera_size)
    observations_lib.configure_noise_and_delay(
        self._task_obs, observation_noise, observation_delay,
        options.physics_timestep)

  # What the task reports, read-only.
  episode_metrics = _read('_recorder.metrics.episode',
                          'The episode so far: a dict.')
  step_metrics = _read('_recorder.metrics.step', 'The last RL step: a dict.')
  # The observation's observables, under the task's names only (e.g. the
  # robot's `joint_positions`, a prop's `position` as 'object_position'),
  # not under composer's 'entity/name'.
  observables = task_observables = _read('_task_obs', 'name -> observable.')

  def action_spec(self, physics: mjcf.Physics) -> specs.BoundedArray:
    """The agent's action: in [-1, 1], the arm's then the gripper's.

    Args:
      physics: unused (composer's signature).

    Returns:
      The spec; its name lists the entries, tab-separated.
    """
    del physics
    return actions.action_spec(self._action_space, self.HAS_GRIPPER_ACTION)

  def _build_task(self):
    """Adds the task's entities; append object geoms to _object_geoms."""

  def _initialize_task(self, physics, random_state):
    """Samples the episode's goals and objects (physics positions set)."""

  def _update_task(self, physics):
    """After every RL step: updates success, phase, counters. Returns a
    dict of step metrics (must contain 'success')."""
    return {'success': 0.0}

  def _task_reward(self, physics):
    """The task's reward for the RL step just done (before delay)."""
    return 0.0

  def _human_events(self, physics):
    """Events of EVENTS whose predicates hold now (triggered on the
    player)."""
    return ()

  def _failed(self, physics):
    """True if the episode ends in failure now (e.g. a dropped board)."""
    return False

  def _task_observables(self):
    """Task-specific observables: name -> observable."""
    return {}

  def _init_episode_state(self):
    self._episode = episode_lib.EpisodeProgress(
        q_goal=self._robot.description.q_home.copy())
    self._recorder.reset()
    self._stepper.reset()

  def after_compile(self, physics: mjcf.Physics,
                    random_state: np.random.RandomState) -> None:
    """Binds the task to the newly compiled physics (composer's hook).

    Args:
      physics: the compiled physics.
      random_state: unused.
    """
    del random_state
    self._bind(physics)

  def _bind(self, physics):
    """Caches joint addresses, the contact monitor and the stepping's
    views for a compiled physics."""
    self._physics_ptr = physics.data.ptr
    monitor, self._joint_indices = self._scene.bind(
        physics, self._object_geoms, self.critical_speed, self.fast_path)
    self._stepper.bind(physics, self._arena, monitor)
    (self._qpos_index, self._qvel_index,
     self._finger_qpos_index) = self._joint_indices

  def initialize_episode(self, physics: mjcf.Physics,
                         random_state: np.random.RandomState) -> None:
    """Starts an episode: robot home, person, shield, task (composer's hook).

    Args:
      physics: the environment's physics.
      random_state: the episode's random numbers.

    Raises:
      composer.EpisodeInitializationError: a MuJoCo physics error while
        initialising (the environment draws the episode again).
    """
    try:
      self._initialize_episode(physics, random_state)
    except rl_control.PhysicsError as error:
      # The environment draws the episode again (max_reset_attempts).
      raise composer.EpisodeInitializationError(
          f'MuJoCo physics error while initialising the episode: {error}'
      ) from error
    self._snapshots.episode_started(physics)   # set_state needs one.

  def _initialize_episode(self, physics, random_state):
    if physics.data.ptr is not self._physics_ptr:
      self._bind(physics)
    if self._stepper.one_substep:
      self._stepper.check_one_substep(self.observables)
    self._init_episode_state()
    self._episode.cp_random = np.random.RandomState(
        random_state.randint(_SEED_RANGE))   # Drawn before the person's.
    self._grips.release_all(physics)
    self._scene.start_episode(physics, self._joint_indices, random_state)
    self._episode.clip_index = self._player.clip_index
    self._recorder.metrics.reset()
    physics.forward()
    self._initialize_task(physics, random_state)

  def before_step(self, physics: mjcf.Physics, action: np.ndarray,
                  random_state: np.random.RandomState) -> None:
    """Turns the action into the shield's new goal (composer's hook).

    Args:
      physics: the environment's physics.
      action: the agent's action (`action_spec`).
      random_state: unused (collision prevention draws from the episode's
        own seeded stream).

    Raises:
      ValueError: an action of the wrong shape or with non-finite entries.
    """
    del random_state
    self._snapshots.step_started()
    goal = actions.step_goal(
        action, self._action_space, self.HAS_GRIPPER_ACTION,
        physics.data.qpos[self._qpos_index], self._episode.q_goal,
        self._collision_checker, self.collision_prevention_policy,
        self._episode.cp_random, self._shield)
    self._episode.q_goal = goal.q_goal
    self._shield.new_goal(goal.q_goal, goal.plan)
    if self.HAS_GRIPPER_ACTION:
      self._gripper.set_command(physics, goal.gripper)
    self._recorder.action_taken(goal)
    self._stepper.begin_step()

  def before_substep(self, physics: mjcf.Physics, action: np.ndarray,
                     random_state: np.random.RandomState) -> None:
    """Prepares a physics step: person, shield, controller (composer's hook).

    Args:
      physics: the environment's physics.
      action: the RL step's action (unused).
      random_state: unused.
    """
    self._stepper.prepare_physics_step(physics)

  def after_substep(self, physics: mjcf.Physics,
                    random_state: np.random.RandomState) -> None:
    """Checks tracking and contacts after a physics step (composer's hook).

    Args:
      physics: unused (the stepper holds its views).
      random_state: unused.
    """
    del physics, random_state
    self._stepper.after_physics_step()

  def after_step(self, physics: mjcf.Physics,
                 random_state: np.random.RandomState) -> None:
    """Updates the task, the person's events, reward and metrics after an
    RL step (composer's hook).

    Args:
      physics: the environment's physics.
      random_state: unused.
    """
    del random_state
    progress = self._episode
    progress.steps += 1
    if self._stepper.cut_short:   # A physics error (module doc).
      progress.stop_at_physics_error()
      self._stepper.stop_at_physics_error()
      self._recorder.record_physics_error()
      return
    self_collision = self._scene.self_colliding(
        physics.data.qpos[self._qpos_index])
    progress.follow_clips(self._player.clip_index)
    self._grips.clear()
    step = dict(self._update_task(physics))
    for event in self._human_events(physics):
      self._player.trigger(event)
    if self._grips.changed:
      # The model changed: what the next step starts from is recomputed,
      # as restoring a snapshot does, so snapshots are exact.
      physics.forward()
    illegal = self_collision or self._stepper.illegal_contact
    task_reward = float(self._task_reward(physics))
    success = bool(step.get('success', 0.0))
    failed = bool(self._failed(physics))
    progress.finish_step(task_reward, success, failed, illegal, self.options)
    self._recorder.record(step, progress.reward, self_collision, success)

  def get_reward(self, physics: mjcf.Physics) -> float:
    """The reward of the RL step just done.

    Args:
      physics: unused.

    Returns:
      The reward, delayed and with collision_reward, as `after_step` set it.
    """
    del physics
    return self._episode.reward

  def should_terminate_episode(self, physics: mjcf.Physics) -> bool:
    """Whether the episode ends now (success with done_at_success, failure,
    a physics error).

    Args:
      physics: unused.

    Returns:
      Whether it ends.
    """
    del physics
    return self._episode.terminate

  def get_discount(self, physics: mjcf.Physics) -> float:
    """The discount of the RL step: 0 where the task ended the episode.

    Args:
      physics: unused.

    Returns:
      0.0 or 1.0.
    """
    del physics
    return self._episode.discount
