"""HrcTask: the shielded step loop every benchmark task shares.

One RL step (control_timestep, 0.1 s) runs L = shield_substeps physics steps
of physics_timestep (4 ms), so control_timestep must equal L x
physics_timestep: the shield is verified once per physics step, and an RL
step is exactly L shield cycles.

* before_step: validate the action (NaN/inf or a wrong shape raise a
  ValueError; entries outside [-1, 1] are clipped), map it to a joint goal
  (`actions.step_goal`), let collision prevention replace it if its
  straight joint path hits the workcell or the robot itself, then
  `shield.new_goal`. The last action dimension drives the gripper where
  the task has one.
* The RL step's physics steps: the person's pose, the shield's command,
  the joint tracking controller, the task's own work
  (`_before_physics_step`), the physics step, the tracking check (a
  pushed robot resynchronises the shield) and the contact monitor, run by
  the task's `shielded_stepping.ShieldedStepper` from composer's substep
  hooks (before_substep, after_substep) or, on the fast path, as
  composer's one substep (`run_physics_steps`; tasks/substeps.py,
  tasks/physics_loop.py).
* after_step: self-collision check (capsule model; `self_collision`),
  the task's own logic (`_update_task`, `_human_events`), reward (with
  optional delay and the collision penalty), termination, metrics
  (`metrics`). Where the episode stands between RL steps is an
  `episode.EpisodeProgress`.
* Physics errors (MuJoCo warnings such as mjWARN_BADQACC): `suite.load`
  makes the environment end the episode instead of raising
  (raise_exception_on_physics_error=False): the step is LAST with reward 0
  and discount 0, and after_step, seeing the RL step cut short, records
  `physics_errors` = 1 and skips the task's logic (MuJoCo has reset the
  state). A physics error while initialising an episode (e.g. lifting's
  settling steps) raises composer.EpisodeInitializationError, so the
  environment draws the episode again (docs/safety.md, "Physics errors").

The scene (workcell, robot, gripper, person, shield, collision
prevention, the person's clips) is built by `scene.build`, the
observables by `observations`.

Subclasses set the class constants below (tasks/defaults.py documents
them) and override `_build_task`, `_initialize_task`, `_update_task`,
`_task_reward`, `_task_reward_range` (tasks/reward_bounds.py), and
optionally `_human_events`, `_failed` and `_task_observables` (name ->
observable; an entity's own observable where the entity declares the
quantity, e.g. `self._board.observables.position`). Hooks they use:

* TASK_STATE names the attributes that hold the task's episode state;
  snapshots copy them (or override `_task_state(physics)` /
  `_set_task_state(physics, state)`; get_state and set_state:
  `snapshots.EpisodeSnapshots`).
* `_before_physics_step(physics)`: work before every physics step (the
  index of the coming one: `self._stepper.physics_step`); for the
  compiled loop also `_works_before_physics_steps`, `_physics_step_writes`
  and `_physics_step_hold`. `self._stepper.controller` is the joint
  tracking controller (e.g. for settling steps at an episode's start).
* `_add_holdable(body)` makes an object holdable by the human; `_hold` /
  `_release` grab and let go of it. Grips change the model (weld pose,
  collision bits), so get_state/set_state save and restore every grip and
  weld (`grips`), and after_step calls physics.forward() when a grip
  changed (a restored snapshot starts from the same derived quantities).
  A task that writes weld data itself calls `_model_changed()`.
* `clip_ended` (the human's clip ended in the RL step just done; the
  player's sequence is endless) and `clips_completed` express "success
  once the human's motion is over" (e.g. after the retreat).
* FINGERTIP_TABLE_CLEARANCE lets the tool capsule into the table (to grasp
  objects lying on it), CARTESIAN_YAW sets the Cartesian gripper yaw.
"""

import functools
import operator
from typing import Any, Mapping, Optional, Sequence, Union

from dm_control import composer
from dm_control import mjcf
from dm_control.rl import control as rl_control
from dm_env import specs
import numpy as np

from hrc_suite import layout
from hrc_suite.entities import gripper as gripper_lib
from hrc_suite.tasks import actions
from hrc_suite.tasks import contacts
from hrc_suite.tasks import cost as cost_lib
from hrc_suite.tasks import defaults as defaults_lib
from hrc_suite.tasks import episode as episode_lib
from hrc_suite.tasks import grips as grips_lib
from hrc_suite.tasks import metrics as metrics_lib
from hrc_suite.tasks import observations as observations_lib
from hrc_suite.tasks import options as options_lib
from hrc_suite.tasks import reward_bounds
from hrc_suite.tasks import scene as scene_lib
from hrc_suite.tasks import shielded_stepping
from hrc_suite.tasks import snapshots

# The options' defaults (tasks/options.py), for the signature below.
DEFAULT_SHIELD_SUBSTEPS = options_lib.DEFAULT_SHIELD_SUBSTEPS
DEFAULT_PHYSICS_TIMESTEP = options_lib.DEFAULT_PHYSICS_TIMESTEP
DEFAULT_CONTROL_TIMESTEP = options_lib.DEFAULT_CONTROL_TIMESTEP
DEFAULT_V_SAFE = options_lib.DEFAULT_V_SAFE
DEFAULT_COLLISION_REWARD = options_lib.DEFAULT_COLLISION_REWARD
DEFAULT_CAMERA_SIZE = observations_lib.DEFAULT_CAMERA_SIZE
_SEED_RANGE = 2**31 - 1
# Flag positions of the contacts that cost collision_reward.
_ILLEGAL_FLAGS = np.array([int(kind) for kind in contacts.ILLEGAL_TYPES])


def _read(path, doc):
  """A read-only property: the task's attribute at `path` ('a.b')."""
  return property(operator.attrgetter(path), doc=doc)


class HrcTask(composer.Task, options_lib.OptionNames,
              reward_bounds.RewardBounds):
  """A robot, a gripper and a human in the workcell, shielded. Its options
  read as attributes by their names (`options.OptionNames`: horizon,
  reward_kind, fast_path, ...), its reward bounds come from its reward
  hooks (`reward_bounds.RewardBounds`: reward_range, min_task_return)."""

  # Task facts (docs/reference_benchmark.md, Tasks); subclasses override.
  # Each is documented at its field of `defaults.TaskDefaults`, which
  # `defaults()` checks.
  MOTIONS = 'reach'                          # shipped library name
  EVENTS = ()                                # ends of the idle phases
  HUMAN_STATION = layout.HUMAN_STATION_ACROSS
  TABLE = layout.DEFAULT_TABLE               # layout.Table
  HUMAN_PLACEMENT_RANGE = (0.0, 0.0, 0.0)    # uniform +- (x, y, yaw)
  DEFAULT_SHIELD = 'ssm'
  DEFAULT_ACTION_SPACE = 'cartesian'
  REWARDS = ('sparse',)                      # first is the default
  DEFAULT_REWARD_DELAY = 0                   # RL steps
  HORIZON = 1000                             # RL steps
  HAS_GRIPPER_ACTION = True
  OBSERVATION_PRESETS = {}                   # name -> observable names
  EXTRA_COUNTERS = ()
  FINGERTIP_TABLE_CLEARANCE = None           # m, or None
  CARTESIAN_YAW = actions.GRIPPER_YAW        # rad, gripper yaw of IK goals
  GRIP_FORCE = gripper_lib.GRIP_FORCE        # N, the gripper's squeeze
  TASK_STATE = ()                            # attributes, for snapshots

  def __init__(self, robot: str = 'panda', action_space: Optional[str] = None,
               shield: Optional[str] = None,
               shield_substeps: int = DEFAULT_SHIELD_SUBSTEPS,
               physics_timestep: float = DEFAULT_PHYSICS_TIMESTEP,
               control_timestep: float = DEFAULT_CONTROL_TIMESTEP,
               motions: Any = None, reward: Optional[str] = None,
               reward_delay: Optional[int] = None,
               done_at_success: bool = True,
               collision_prevention: str = 'zero',
               time_limit: Optional[float] = None,
               observations: Union[str, Sequence[str]] = 'paper',
               observation_noise: Optional[Mapping[str, float]] = None,
               observation_delay: Optional[Mapping[str, float]] = None,
               cameras: Sequence[str] = (),
               camera_size: Sequence[int] = DEFAULT_CAMERA_SIZE,
               v_safe: float = DEFAULT_V_SAFE,
               critical_speed: Optional[float] = None,
               collision_reward: float = DEFAULT_COLLISION_REWARD,
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
    options = options_lib.TaskOptions.of(
        defaults, robot=robot, action_space=action_space,
        shield=shield, shield_substeps=shield_substeps,
        physics_timestep=physics_timestep,
        control_timestep=control_timestep, reward=reward,
        reward_delay=reward_delay, done_at_success=done_at_success,
        collision_prevention=collision_prevention, time_limit=time_limit,
        v_safe=v_safe, critical_speed=critical_speed,
        collision_reward=collision_reward, fast_path=fast_path)
    self.options = options
    self._scene = scene = scene_lib.build(defaults, options, motions,
                                          outside_human_model)
    self._arena, self._robot = scene.arena, scene.robot
    self._gripper, self._human = scene.gripper, scene.human
    self._kinematics, self._shield = scene.kinematics, scene.shield
    self.tool_table_allowance = scene.tool_table_allowance
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
    self._cost = cost_lib.CostSpec.of(cost)
    self._metrics = metrics_lib.EpisodeMetrics(
        self.EXTRA_COUNTERS + (cost_lib.metric_names() if self._cost
                               else ()))
    self._snapshots = snapshots.EpisodeSnapshots(
        self._player, self._playback, self._shield, self._grips,
        self._stepper, self._metrics)
    self._physics_ptr = None
    self._restored = False      # set_state since the last step
    self._init_episode_state()
    self._task_obs, names = observations_lib.task_observables(
        self._robot, self._gripper, self._human, self._stepper.step_flags,
        self._task_observables, self.OBSERVATION_PRESETS,
        self._metrics if self._cost is not None else None, observations)
    self.observation_names = observations_lib.add_cameras(
        self._task_obs, names, self._arena.mjcf_model, cameras, camera_size)
    observations_lib.configure_noise_and_delay(
        self._task_obs, observation_noise, observation_delay,
        options.physics_timestep)

  @classmethod
  def defaults(cls) -> defaults_lib.TaskDefaults:
    """The task's class constants, checked (`defaults.TaskDefaults`).

    Raises:
      ValueError: a class constant of the wrong kind.
    """
    return defaults_lib.TaskDefaults.of(cls)

  # The task's parts and what it reports, read-only.
  root_entity = arena = _read('_arena', 'The workcell (entities/).')
  robot = _read('_robot', 'The robot arm (entities/robot.py).')
  gripper = _read('_gripper', 'The parallel gripper (entities/gripper.py).')
  human = _read('_human', 'The person (entities/human.py).')
  player = _read('_player', "The person's clip player (human/player.py).")
  shield = _read('_shield', 'The shield (safety/shield/shield.py).')
  kinematics = _read('_kinematics', "The robot's kinematic model for IK.")
  tool_capsule = _read('_scene.tool_capsule',
                       '(p1, p2, radius) in the last link frame.')
  collision_checker = _read('_collision_checker', 'Collision prevention.')
  action_space_name = _read('_action_space.name', "'joint' or 'cartesian'.")
  episode_metrics = _read('_metrics.episode', 'The episode so far: a dict.')
  step_metrics = _read('_metrics.step', 'The last RL step: a dict.')
  clip_ended = _read('_episode.clip_ended', 'A clip ended in the last step.')
  clips_completed = _read('_episode.clip_index', 'Clips done this episode.')
  # The observation's observables, under the task's names only (e.g. the
  # robot's `joint_positions`, a prop's `position` as 'object_position'),
  # not under composer's 'entity/name'.
  observables = task_observables = _read('_task_obs', 'name -> observable.')
  one_substep = _read('_stepper.one_substep',
                      "The RL step's physics steps: one composer substep.")
  physics_steps = _read('_stepper.physics_steps', 'substeps.PhysicsSteps.')
  restored = _read('_restored', 'An episode was restored since the step.')

  @property
  def q_goal(self) -> np.ndarray:
    """The joint goal given to the shield by the last action."""
    return self._episode.q_goal.copy()

  def start_robot_at(self, physics: mjcf.Physics, q: np.ndarray) -> None:
    """Starts the episode's robot at rest elsewhere than home (in
    `_initialize_task`): the joints, the joint goal and the shield; forwards
    the physics.

    Args:
      physics: the episode's physics.
      q: (dof,) joint positions.
    """
    physics.data.qpos[self._qpos_index] = q
    self._episode.q_goal = q.copy()
    self._shield.reset(q, 0.0)
    physics.forward()

  def set_cartesian_yaw(self, yaw: float) -> None:
    """Sets the gripper yaw of Cartesian actions' IK goals (nothing in
    joint action spaces).

    Args:
      yaw: rad about world z.
    """
    if self._action_space.name == 'cartesian':
      self._action_space.yaw = yaw

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

  def _task_observables(self):
    """Task-specific observables: name -> observable."""
    return {}

  def _add_holdable(self, body):
    """Makes `body` holdable by the human (before compiling); returns its
    welds {hand: weld element}."""
    return self._grips.add(body)

  def _hold(self, physics, body, hand, relative_pose=None):
    """The human's `hand` grabs `body` (`Human.hold`)."""
    self._grips.hold(physics, body, hand, relative_pose)

  def _release(self, physics, body):
    """The human lets go of `body` (nothing if not held)."""
    self._grips.release(physics, body)

  def _model_changed(self):
    """The task changed the model (e.g. weld data): forward after the step."""
    self._grips.mark_changed()

  def _init_episode_state(self):
    self._episode = episode_lib.EpisodeProgress(
        q_goal=self._robot.description.q_home.copy())
    self._step_info = {}
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
    self._scene.home(physics, self._joint_indices)
    self._episode.cp_random = np.random.RandomState(
        random_state.randint(_SEED_RANGE))
    self._grips.release_all(physics)
    self._player.reset(random_state)
    self._episode.clip_index = self._player.clip_index
    self._playback.show_current(physics)
    self._shield.reset(self._robot.description.q_home, 0.0)
    self._metrics.reset()
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
    self._restored = False
    goal = actions.step_goal(
        action, self._action_space, self.HAS_GRIPPER_ACTION,
        physics.data.qpos[self._qpos_index], self._episode.q_goal,
        self._collision_checker, self.collision_prevention_policy,
        self._episode.cp_random, self._shield)
    self._episode.q_goal = goal.q_goal
    self._shield.new_goal(goal.q_goal, goal.plan)
    if self.HAS_GRIPPER_ACTION:
      self._gripper.set_command(physics, goal.gripper)
    self._step_info = {'action_replacements': int(goal.replaced),
                       'ik_failures': int(goal.ik_failed)}
    self._stepper.begin_step()

  # The physics steps (tasks/shielded_stepping.py).

  @property
  def physics_steps_per_control_step(self) -> int:
    """Composer's substeps per RL step: shield_substeps, or 1 when the
    task runs the RL step's physics steps itself (`one_substep`)."""
    return (1 if self._stepper.one_substep
            else super().physics_steps_per_control_step)

  def use_one_substep(self) -> bool:
    """One composer substep per RL step if the fast path is on and no
    enabled observable needs reading between physics steps (call before
    the environment is built).

    Returns:
      Whether it is used.
    """
    return self._stepper.use_one_substep(self.observables)

  def before_substep(self, physics: mjcf.Physics, action: np.ndarray,
                     random_state: np.random.RandomState) -> None:
    """Prepares a physics step: person, shield, controller (composer's hook).

    Args:
      physics: the environment's physics.
      action: the RL step's action (unused).
      random_state: unused.
    """
    self._stepper.prepare_physics_step(physics)

  def run_physics_steps(self, physics: mjcf.Physics, action: np.ndarray,
                        random_state: np.random.RandomState) -> None:
    """The RL step's physics steps as suite.Environment's only substep
    (`one_substep`; `ShieldedStepper.run_physics_steps`).

    Args:
      physics: the environment's physics (its proxy).
      action: the RL step's action.
      random_state: the environment's random state.
    """
    self._stepper.run_physics_steps(physics, action, random_state)

  def after_substep(self, physics: mjcf.Physics,
                    random_state: np.random.RandomState) -> None:
    """Checks tracking and contacts after a physics step (composer's hook).

    Args:
      physics: unused (the stepper holds its views).
      random_state: unused.
    """
    del physics, random_state
    self._stepper.after_physics_step()

  def _works_before_physics_steps(self):
    """Whether `_before_physics_step` has work in this RL step (a task
    that overrides it may say when it has none)."""
    return (type(self)._before_physics_step
            is not HrcTask._before_physics_step)

  def _physics_step_writes(self, physics):
    """What `_before_physics_step` writes before each of this RL step's
    physics steps, for the compiled loop (tasks/physics_loop.py): up to two
    (target (n,), indices (m,), values (L, m)), target[indices] = values[k]
    before physics step k; None: the Python loop runs."""
    del physics
    return None

  def _physics_step_hold(self, physics):
    """The compliant hold (tool_hold.CompliantHold.kernel_arguments) that
    `_before_physics_step` applies after its writes before every physics
    step, for the compiled loop; None if there is none."""
    del physics
    return None

  def _before_physics_step(self, physics):
    """A task's own work before every physics step (e.g. a grip)."""

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
    if self._stepper.cut_short:
      self._end_at_physics_error()
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
    illegal = self_collision or bool(
        self._stepper.step_flags[_ILLEGAL_FLAGS].any())
    task_reward = float(self._task_reward(physics))
    success = bool(step.get('success', 0.0))
    failed = bool(self._failed(physics))
    progress.finish_step(task_reward, success, failed, illegal, self.options)
    step.update(self._step_info, reward=progress.reward,
                self_collisions=int(self_collision), goals_reached=int(success))
    self._record(step)

  def _end_at_physics_error(self):
    """Ends an RL step cut short by a physics error (module doc): the
    task's logic is skipped, contacts up to the error are counted."""
    self._episode.stop_at_physics_error()
    self._stepper.stop_at_physics_error()
    self._record({'success': 0.0, **self._step_info, 'reward': 0.0,
                  'self_collisions': 0, 'goals_reached': 0,
                  'physics_errors': 1})

  def _record(self, step):
    """Adds the metrics every RL step reports; records the step."""
    self._stepper.add_step_metrics(step)
    if self._cost is not None:
      step.update(self._cost.step_metrics(step, self._shield.reach_distance))
    self._metrics.record(step)
    self._metrics.record_episode_maxima(
        self._stepper.contact_energy_maxima())

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

  def get_state(self, physics: mjcf.Physics) -> dict[str, Any]:
    """A snapshot of the episode: physics, human, shield, task, metrics.

    Args:
      physics: the environment's physics.

    Returns:
      The snapshot (`snapshots.EpisodeSnapshots.take`), for `set_state`.
    """
    return self._snapshots.take(
        physics, self._episode, functools.partial(self._task_state, physics))

  def set_state(self, physics: mjcf.Physics, state: Mapping[str, Any]
                ) -> None:
    """Restores a snapshot from get_state (same task configuration) into
    an environment that has been reset. A snapshot of a running episode
    restored after a LAST step continues at the next step (environments
    of suite.load) instead of being discarded by a reset.

    Args:
      physics: the environment's physics.
      state: a snapshot of `get_state`.

    Raises:
      ValueError: an environment that has not been reset, or a physics
        state of another model's size.
    """
    own = self._snapshots.restore(physics, state, self._episode)
    self._set_task_state(physics, own)
    self._restored = not self._episode.terminate
