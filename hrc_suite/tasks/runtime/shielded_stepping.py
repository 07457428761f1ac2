"""ShieldedStepper: the physics steps of an HrcTask's RL steps.

One RL step runs L = shield_substeps physics steps; the shield is verified
once per physics step, so an RL step is exactly L shield cycles. The task
owns a ShieldedStepper and calls it from its composer hooks (its side,
the stepping's attributes composer and suite.Environment read and the
hooks the stepper calls, is `stepped_task.SteppedTask`):

* before_step (`begin_step`, after the shield's new goal): the person's
  player is advanced through the RL step's physics steps (one
  `HumanPlayback.advance` call; events only change between RL steps, so
  this is the same motion, computed with one vectorised call per RL step),
  whose poses are then played back step by step.
* before_substep (`prepare_physics_step`; the task's hook runs before the
  entities', so nothing relies on entity hooks): the person's pose ->
  the shield's command -> the controller -> the task's own work
  (`stepped_task.SteppedTask._before_physics_step`). On the fast path
  (fast_path=True, the default) the shield's cycles of the rest of the RL
  step run at once
  (`safety.shield.batch.step_many`: the playback's frames are known in
  advance) and each physics step hands the controller its precomputed,
  verified set-point; the same commands as `Shield.step` every physics step
  (fast_path=False, the reference). The set-points and the shield's
  rewinding are tasks/runtime/shield_setpoints.py's.
* One composer substep per RL step (fast path, environments of
  `suite.load`; tasks/runtime/substeps.py): composer sees one substep,
  `run_physics_steps`: the RL step's L physics steps, each with the same
  hooks in composer's order (the task's, the entities', the extra ones),
  mj_step2 and mj_step1 as dm_control's physics.step, and the task's
  after_substep; stretches where nothing needs Python run in one compiled
  call (tasks/runtime/physics_loop.py).
* after_substep (`after_physics_step`): the tracking check, then the
  contact monitor (`contacts`). The measured joints are compared with
  where the shield's command puts them; farther than the shield's tracking
  tolerance (its secure radius; the shield's `tracking`,
  tracking.TrackingBounds: its `bound` every step, then its `error` when
  the bound exceeds the tolerance), the person has
  pushed the robot: robot-human contacts of that physics step are judged
  at the commanded configuration (`human_pushed` or `human_critical`) and
  the shield is re-synchronised to the measured pose (`Shield.resync`;
  docs/safety.md, "Pushed robots"). On the fast path the shield is first
  rewound to that physics step (a checkpoint and a replay of the
  precomputed cycles) and the rest of the RL step's set-points are
  computed again after the resync.
* A physics error (a MuJoCo warning such as mjWARN_BADQACC) cuts the RL
  step short (`cut_short`); the shield is then rewound to the physics step
  that failed (`stop_at_physics_error`), so that its metrics are those of
  the reference path.
* What the RL step's physics steps add up to (interventions, resyncs, the
  largest tracking error, contact flags and counts) and the step metrics
  from it: tasks/runtime/step_tally.py.
"""

from typing import Optional

import numpy as np

from hrc_suite.control import controller as controller_lib
from hrc_suite.entities import human_kernels
from hrc_suite.tasks.runtime import contacts
from hrc_suite.tasks.runtime import physics_loop
from hrc_suite.tasks.runtime import shield_setpoints
from hrc_suite.tasks.runtime import step_tally
from hrc_suite.tasks.runtime import substeps as substeps_lib


class ShieldedStepper:
  """An HrcTask's physics steps: the person's poses, the shield's
  commands (`shield_setpoints.ShieldSetpoints`), the controller, the
  tracking check and the contact monitor, and the state they keep within
  and across RL steps (the RL step's record: `step_tally.StepTally`)."""

  def __init__(self, task, options, shield, playback, robot):
    """Stepping for `task` (not yet bound to a physics: `bind`).

    Args:
      task: the HrcTask whose hooks run around every physics step: its
        `stepped_task.SteppedTask` hooks and its composer hook
        `after_substep`.
      options: the task's `options.TaskOptions` (shield_substeps,
        fast_path).
      shield: the task's `safety.shield.Shield`.
      playback: the task's `entities.human_playback.HumanPlayback`.
      robot: the task's robot entity (its joints and dof).
    """
    self._task = task
    self._options = options
    self._shield = shield
    self._playback = playback
    self._robot = robot
    self._human_v_max = shield.human.config.v_max.copy()
    self._one_substep = False
    self._physics_steps = substeps_lib.PhysicsSteps()
    self._compiled_steps = None   # tasks/runtime/physics_loop.py, once bound
    self._controller = None
    self._monitor = None
    self._tally = step_tally.StepTally()
    self._setpoints = shield_setpoints.ShieldSetpoints(
        shield, playback, robot.dof, options.fast_path)
    self._command_dq = np.zeros(robot.dof)
    # Tracking check (after_physics_step): where the command puts the
    # joints after the physics step, and how far the robot may be from it
    # (m; the levers turn joint errors into a cheap upper bound).
    self._expected_q = np.zeros(robot.dof)
    self._tracking = shield.tracking
    self._tracking_levers = shield.tracking.levers
    self._tracking_tolerance = shield.tracking.tolerance
    self.reset()

  def reset(self):
    """The state of an episode's start."""
    self._time = 0.0
    self._substep = 0
    self._completed_substeps = 0
    self._playback.forget_clip()
    self._tally.reset()
    self._command_dq[:] = 0.0
    self._setpoints.forget()

  def bind(self, physics, root_entity, monitor):
    """Binds the stepping to a compiled physics.

    Args:
      physics: the environment's physics.
      root_entity: the task's root entity (its entities' substep hooks).
      monitor: the `contacts.ContactMonitor` of this physics.
    """
    fast_path = self._options.fast_path
    self._dt = float(physics.model.opt.timestep)
    self._setpoints.bind(self._dt)
    self._physics_steps.bind(physics, root_entity)
    self._playback.bind(physics)
    self._controller = controller_lib.JointTrackingController(
        physics, self._robot, compiled=fast_path)
    self._monitor = monitor
    # A view of the arm's joint positions (consecutive: the controller
    # requires it), read every physics step without a copy.
    first = int(physics.bind(self._robot.joints).qposadr[0])
    self._q_measured = physics.data.qpos[first:first + self._robot.dof]
    self._compiled_steps = None
    if fast_path and self._physics_steps.raw:
      try:
        self._compiled_steps = physics_loop.CompiledSteps(
            physics, self._controller, self._playback, self._monitor,
            self._tracking_levers, self._tracking_tolerance,
            self._q_measured, self._command_dq, self._tally.step_flags,
            self._tally.contact_steps, self._shield.robot)
      except ValueError:
        pass   # The Python loop runs every physics step.

  # ------------------------------------------------------------- accessors

  @property
  def controller(self) -> controller_lib.JointTrackingController:
    """The joint tracking controller of the bound physics."""
    return self._controller

  @property
  def monitor(self) -> contacts.ContactMonitor:
    """The contact monitor of the bound physics."""
    return self._monitor

  @property
  def compiled_steps(self) -> Optional[physics_loop.CompiledSteps]:
    """The compiled loop of the bound physics (None: the Python loop)."""
    return self._compiled_steps

  @property
  def physics_steps(self) -> substeps_lib.PhysicsSteps:
    """The hooks of every physics step (`substeps.PhysicsSteps`)."""
    return self._physics_steps

  @property
  def one_substep(self) -> bool:
    """Whether `run_physics_steps` runs an RL step's physics steps as
    composer's one substep."""
    return self._one_substep

  @property
  def physics_step(self) -> int:
    """The index in its RL step of the physics step being run (in
    `_before_physics_step`: the one about to run)."""
    return self._substep - 1

  @property
  def cut_short(self) -> bool:
    """Whether the RL step ended before its L physics steps (a physics
    error)."""
    return self._completed_substeps < self._options.shield_substeps

  @property
  def time(self):
    """s, the playback time of the last physics step's person pose."""
    return self._time

  @property
  def step_flags(self) -> np.ndarray:
    """Contact flags of this RL step (contacts.CONTACT_TYPES), updated in
    place (observables read the array)."""
    return self._tally.step_flags

  @property
  def illegal_contact(self) -> bool:
    """Whether this RL step had a static or critical human contact
    (`step_tally.StepTally.illegal_contact`)."""
    return self._tally.illegal_contact

  @property
  def command_dq(self) -> np.ndarray:
    """The joint velocities of the last command."""
    return self._command_dq

  def set_state(self, time, step_flags, command_dq):
    """Restores what a snapshot keeps of the stepping.

    Args:
      time: s, as `time`.
      step_flags: contact flags; a snapshot from before a contact type was
        added holds fewer (new types go last: contacts.CONTACT_TYPES).
      command_dq: as `command_dq`.
    """
    self._tally.set_flags(step_flags)
    self._time = float(time)
    self._command_dq[:] = command_dq

  # --------------------------------------------------- one composer substep

  def use_one_substep(self, observables) -> bool:
    """One composer substep per RL step if the fast path is on and no
    enabled observable needs reading between physics steps (before the
    environment is built); returns whether it is used.

    Args:
      observables: the task's observables (name -> observable).
    """
    self._one_substep = self._options.fast_path and not (
        substeps_lib.read_between_steps(observables))
    return self._one_substep

  def check_one_substep(self, observables):
    """Raises ValueError if an enabled observable needs reading between
    physics steps, which one composer substep per RL step cannot do.

    Args:
      observables: the task's observables (name -> observable).
    """
    names = substeps_lib.read_between_steps(observables)
    if names:
      raise ValueError(
          f'Observables {", ".join(names)} need reading between physics '
          'steps (a delay, a buffer or an update interval), which this '
          'environment runs in one composer substep per RL step: set them '
          'before suite.load (observation_delay) or use fast_path=False')

  # -------------------------------------------------------------- RL steps

  def begin_step(self):
    """Starts an RL step (after the shield's new goal): clears its flags
    and counters and advances the person's playback through it."""
    self._monitor.reset()
    self._substep = 0
    self._completed_substeps = 0
    self._setpoints.forget()
    self._playback.advance(self._dt)
    self._tally.begin_step(outside_model=self._faster_than_model())

  def _faster_than_model(self):
    """Whether a keypoint moves faster than the shield's human model between
    this RL step's physics steps. (The interval into the step is left out:
    it would make the metric depend on playback state that snapshots do
    not keep; check_motions has checked every frame of every clip.)"""
    frames = self._playback.positions
    if self._options.fast_path:   # The same decision, compiled.
      return human_kernels.faster_than(frames, self._dt, self._human_v_max)
    speeds = np.linalg.norm(np.diff(frames, axis=0), axis=-1) / self._dt
    return bool(np.any(speeds > self._human_v_max))

  def run_physics_steps(self, physics, action, random_state):
    """The RL step's physics steps, each with the hooks composer runs
    around a substep (`one_substep`: suite.Environment's only substep;
    tasks/runtime/substeps.py): stretches in one compiled call where nothing
    needs Python (tasks/runtime/physics_loop.py), the others one by one.

    Args:
      physics: the environment's physics.
      action: the RL step's action (for extra substep hooks).
      random_state: the environment's random state.
    """
    task = self._task
    stop = self._options.shield_substeps
    steps, compiled = self._physics_steps, self._compiled_steps
    if compiled is not None and (not steps.idle()
                                 or not compiled.has_headroom()):
      compiled = None
    writes, hold = (), None
    if compiled is not None and task._works_before_physics_steps():
      writes = task._physics_step_writes(physics)
      hold = task._physics_step_hold(physics)
      if writes is None:
        compiled = None
    while self._substep < stop:
      k = self._substep
      if compiled is not None:
        end = self._playback.same_clip_until(k, stop)
        if end > k:
          self._run_compiled(physics, random_state, compiled, k, end,
                             writes, hold)
          continue
      self.prepare_physics_step(physics)
      steps.step(physics, action, random_state)
      task.after_substep(physics, random_state)
      steps.after(physics, random_state)

  def _run_compiled(self, physics, random_state, compiled, k, end,
                    writes, hold):
    """Physics steps k..end-1 in the compiled call, then what it left to
    Python (physics_loop.run's status)."""
    setpoints = self._setpoints
    setpoints.plan(k)
    record = compiled.record
    record.largest_tracking_bound[0] = self._tally.max_tracking_error
    record.intervened[0] = False
    record.largest_contact_speed[0] = self._monitor.max_human_contact_speed
    stopped, status = compiled.run(k, end, setpoints.setpoints,
                                   setpoints.flags, setpoints.start,
                                   setpoints.expected_rows, writes, hold)
    self._completed_substeps += stopped - k
    self._tally.add_compiled(float(record.largest_tracking_bound[0]),
                             bool(record.intervened[0]))
    self._monitor.max_human_contact_speed = float(
        record.largest_contact_speed[0])
    last = stopped - 1 if status == physics_loop.DONE else stopped
    self._substep = last + 1
    self._time = self._playback.times[last]
    self._expected_q = setpoints.expected_at(last)
    if status == physics_loop.PHYSICS_WARNING:
      self._physics_steps.raise_warnings(compiled.warnings_before)
    elif status == physics_loop.PYTHON_AFTER:
      self._task.after_substep(physics, random_state)
      self._physics_steps.after(physics, random_state)

  def prepare_physics_step(self, physics):
    """Before a physics step: the person's pose, the shield's command, the
    controller, then the task's `_before_physics_step`.

    Args:
      physics: the environment's physics.
    """
    k = self._substep
    self._substep = k + 1
    positions = self._playback.apply(physics, k)
    self._time = self._playback.times[k]
    (q, dq, ddq), intervened, self._expected_q = self._setpoints.command(
        k, positions, self._time)
    self._tally.add_intervention(intervened)
    self._command_dq[:] = dq
    self._controller(physics, q, dq, ddq)
    self._task._before_physics_step(physics)

  def after_physics_step(self):
    """After a physics step: the tracking check (a push resynchronises the
    shield), then the contact monitor."""
    self._completed_substeps += 1
    distance = physics_loop.tracking_bound(   # TrackingBounds.bound
        self._q_measured, self._expected_q, self._tracking_levers)
    pushed = distance > self._tracking_tolerance
    if pushed:   # Rare: the exact distance (forward kinematics) decides.
      distance = self._tracking.error(self._q_measured, self._expected_q)
      pushed = distance > self._tracking_tolerance
    self._tally.add_tracking_error(distance)
    self._tally.add_contacts(self._monitor.update(
        self._command_dq, self._expected_q if pushed else None))
    if pushed:
      # The robot is not where the shield believes: it plans from the
      # measured pose from the next physics step on.
      self._setpoints.rewind(self._substep - 1)
      self._shield.resync(self._q_measured)
      self._tally.add_resync()

  def stop_at_physics_error(self):
    """After an RL step cut short by a physics error: the shield as after
    the physics step that failed (the fast path had planned the RL step's
    later cycles), so that its metrics are those of the reference."""
    self._setpoints.rewind(self._substep - 1)

  def add_step_metrics(self, step):
    """Adds the RL step's shield, tracking and contact metrics to `step`
    (a dict) and restarts the contact counts
    (`step_tally.StepTally.add_step_metrics`).

    Args:
      step: the RL step's metrics so far.
    """
    self._tally.add_step_metrics(step, self._shield.min_distance,
                                 self._monitor.max_human_contact_speed)

  def contact_energy_maxima(self) -> Optional[dict]:
    """The RL step's largest robot-human contact energies and ratios
    (`step_tally.contact_energy_maxima`), or None where it measured none.

    Returns:
      {name: value} of metrics.CONTACT_ENERGY_MAXIMA, or None.
    """
    return step_tally.contact_energy_maxima(self._monitor)
