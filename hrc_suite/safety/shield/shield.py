"""The reachability shield: verified joint commands, one every cycle.

Each cycle (docs/shield_maths.md, 4) the shield takes the human keypoints,
proposes the monitored path "one intended step along the long-term plan,
then brake to rest along it", and verifies it: the robot's reachable capsules
over time slices of that path must not meet the human's reachable capsules
(SSM), or, in PFL mode, the robot must be slower than v_safe wherever contact
is possible. If verified, the robot takes the intended step and the braking
path becomes the new verified path; if not, the robot keeps following the
last verified path, so repeated failures brake it to rest along the plan
(path-consistent braking). Nothing here reads the measured robot state: the
shield's own command is the robot state (the controller must track it within
the secure radius). When it does not (a person pushed the robot farther than
that: its `tracking`, tracking.TrackingBounds), the caller hands the
measured pose to `resync`, which restarts the shield at rest there.

Differences to the original (docs/shield_maths.md, 10), on purpose:
* B1: plan look-ups subtract the plan's start once (`long_term_plan`).
* B4: a new plan is only adopted when a monitored path on it verifies;
  until then the robot follows the verified path on the old plan.
* B6: consistent profile threshold (`path.plan_profile`).
* L4: the slice from the current command to the first monitored state is
  verified too (the robot moves during the cycle).
* Path bounds use the plan's nominal joint speed, not the commanded one
  (the commanded speed is s_dot times smaller while braking).
* PFL bounds the robot's speed over the whole rest of the plan, since the
  robot keeps moving at the limited path speed after the failsafe ends.
* Before the exact check, the maximal-velocity (VEL) model over the whole
  horizon (one ball per body) is tried against the robot's workspace ball
  and reach capsules (`path_check`, docs/shield_maths.md, 5.3).

State: everything a cycle reads and changes is one frozen record,
`state` (`shield_state.ShieldState`, with the human's measurement,
`HumanReach.state`); each cycle makes the next record, here or in the
compiled cycles (`batch`), and a checkpoint is the record itself. What a
mode checks comes from the mode (`modes.ShieldMode.failsafe_target`,
`verdict`, and their compiled twins, `mode_kernels`).

Parts: the cycle's constants (`terms`, cycle_terms.CycleTerms, and their
compiled twin `kernel_constants`), the check of a monitored path
(path_check.PathCheck), the tracking bounds (`tracking`), energy PFL's
inputs (`energy`, energy_setup.EnergySetup) and the state as a dict
(`get_state`, state_io). The shield's `tracking_*`, energy and table
members hand over to these parts.

Speed: the per-cycle geometry runs in compiled kernels (`kernels`, numba),
each tested against its readable NumPy reference (kept in `robot_reach`,
`human_reach`, `verification`, `long_term_plan`, `pfl_tables` and
tests/safety/safety_references.py); the verdict
stops at the first unsafe slice and `reach_distance` is computed when
asked.
"""

import dataclasses
import os
import pathlib
from typing import Any, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from hrc_suite import robot_description as robot_description_lib
from hrc_suite.safety import arm_energy
from hrc_suite.safety import clamping
from hrc_suite.safety import kernels
from hrc_suite.safety import long_term_plan as ltp
from hrc_suite.safety import plan_kernels
from hrc_suite.safety import robot_energy
from hrc_suite.safety import robot_reach as robot_reach_lib
from hrc_suite.safety.shield import cycle_kernels
from hrc_suite.safety.shield import cycle_terms
from hrc_suite.safety.shield import energy_setup
from hrc_suite.safety.shield import energy_verification
from hrc_suite.safety.shield import human_reach as human_reach_lib
from hrc_suite.safety.shield import modes as modes_lib
from hrc_suite.safety.shield import path as path_lib
from hrc_suite.safety.shield import path_check
from hrc_suite.safety.shield import pfl_tables
from hrc_suite.safety.shield import shield_state
from hrc_suite.safety.shield import speed_kernels
from hrc_suite.safety.shield import state_io
from hrc_suite.safety.shield import tracking as tracking_lib
from hrc_suite.safety.shield import verification

# Default shield cycle (s): human-robot-gym's control_sample_time
# (docs/shield_maths.md, 4).
DEFAULT_CYCLE_TIME = 0.004
# PFL: speeds are compared with this fraction of v_safe
# (safety/shield/modes.py).
PFL_SPEED_MARGIN = modes_lib.PFL_SPEED_MARGIN
# PFL: samples a slice's tables look ahead (pfl_tables.py).
PFL_WINDOW = pfl_tables.PFL_WINDOW
# The cycle's tolerances (cycle_terms.py).
_BROAD_PHASE_SLACK = cycle_terms.BROAD_PHASE_SLACK
_SAME_COMMAND = cycle_terms.SAME_COMMAND
REST_TOLERANCE = cycle_terms.REST_TOLERANCE
# PFL's speed tables from capsule speeds (pfl_tables.py).
pfl_speed_tables = pfl_tables.pfl_speed_tables


class Shield:
  """SaRA-style reachability shield for one robot in a registered mode
  (`modes`: 'ssm', 'pfl', 'off', 'pfl_energy' or one registered
  elsewhere).

  Args:
    robot_description: the robot's description, or its name or file path
      (robot_description.load).
    mode: the name of a registered mode (`modes.names()`).
    cycle_time: the shield's cycle (s), > 0.
    human_model: the human's reachable-set model: a `HumanReach` (used
      as it is), its `HumanModelConfig`, or a model file (None: the
      shipped model, docs/shield_maths.md, 8).
    base_pose: the robot base's pose, a 4x4 matrix or (x, y, z, roll,
      pitch, yaw) (None: the robot's mount, layout.robot_mount).
    tool_capsule: (p1 (3,), p2 (3,), radius) of the tool's capsule in the
      last link's frame, m (None: no tool).
    v_safe: the contact speed (m/s) the speed-limiting modes derive their
      limit from, > 0 (None: the description's).
    use_kalman_filter: whether the human's keypoint velocities come from a
      Kalman filter instead of finite differences (docs/shield_maths.md,
      8.1).
    use_combined_model: whether the human's reachable set is the combined
      model alone rather than POS, VEL and ACCEL together
      (docs/shield_maths.md, 8.3; None: the model file's).
    secure_radius: how far (m) the robot may be from its command (None:
      the description's; docs/shield_maths.md, 5.2).
    alpha: the path-curvature bound of the robot reach capsules, one value
      or one per joint (None: the description's alpha_i_max;
      docs/shield_maths.md, 5.2).
    q_init: the joint positions (dof,) the shield starts at rest at (None:
      the description's q_home).
    payload: what the last link carries, for energy PFL (None: the
      gripper, robot_energy.gripper_payload).
    static_boxes: the boxes a body can be clamped against, for energy PFL:
      name -> (min (3,), max (3,)), world frame (None: the workcell's,
      collision_prevention.workcell_boxes).

  Raises:
    ValueError: cycle_time or v_safe is not positive, the mode is not
      registered, or q_init is not dof finite joint positions within the
      joint limits.
  """

  def __init__(
      self,
      robot_description: Union[str, os.PathLike,
                               robot_description_lib.RobotDescription],
      mode: str = 'ssm', cycle_time: float = DEFAULT_CYCLE_TIME,
      human_model: Union[None, str, pathlib.Path,
                         human_reach_lib.HumanModelConfig,
                         human_reach_lib.HumanReach] = None,
      base_pose: Optional[Union[np.ndarray, Sequence[float]]] = None,
      tool_capsule: Optional[Tuple[np.ndarray, np.ndarray, float]] = None,
      v_safe: Optional[float] = None, use_kalman_filter: bool = False,
      use_combined_model: Optional[bool] = None,
      secure_radius: Optional[float] = None,
      alpha: Optional[Union[float, np.ndarray]] = None,
      q_init: Optional[np.ndarray] = None,
      payload: Optional[robot_energy.Payload] = None,
      static_boxes: Optional[Mapping[str, Tuple[Sequence[float],
                                                Sequence[float]]]] = None):
    if isinstance(robot_description, (str, os.PathLike)):
      robot_description = robot_description_lib.load(robot_description)
    elif not isinstance(robot_description,
                        robot_description_lib.RobotDescription):
      raise TypeError(
          f'robot_description: expected a RobotDescription, a robot name or '
          f'a description file path, got {robot_description!r}')
    kernels.warm_up()   # Compiled or loaded once per process, not mid-run.
    cycle_kernels.warm_up()
    plan_kernels.warm_up()   # Its plans' (long_term_plan).
    speed_kernels.warm_up()   # PFL's tables of its plans.
    if not cycle_time > 0:
      raise ValueError(f'cycle_time: expected > 0 s, got {cycle_time}')
    self.description = robot_description
    self.cycle_time = float(cycle_time)
    self.dof = robot_description.dof
    params = robot_description.shield
    self.v_safe = float(params.v_safe if v_safe is None else v_safe)
    if not self.v_safe > 0:
      raise ValueError(f'v_safe: expected > 0 m/s, got {v_safe}')
    self.mode = mode   # After v_safe: the mode's speed limit depends on it.
    self.interval = params.reachability_interval_cycles * self.cycle_time
    self.max_s_stop = params.max_s_stop
    self.robot = robot_reach_lib.RobotReach(
        robot_description, base_pose=base_pose, tool_capsule=tool_capsule,
        secure_radius=secure_radius, alpha=alpha)
    if isinstance(human_model, human_reach_lib.HumanReach):
      self.human = human_model
    else:
      self.human = human_reach_lib.HumanReach(
          human_model, use_kalman_filter=use_kalman_filter,
          use_combined_model=use_combined_model)
    self.limits = robot_description.limits
    # The cycle's constants of the robot and human models.
    self.terms = cycle_terms.cycle_terms(robot_description, self.robot,
                                         self.human, self.max_s_stop,
                                         tool_capsule)
    # The check of a monitored path (broad phases, the mode's verdict).
    self._path_check = path_check.PathCheck(
        self.terms, self.robot, self.human, self.cycle_time, self.interval)
    # How far the robot is from the command (docs/safety.md, Assumptions:
    # Tracking).
    self.tracking = tracking_lib.TrackingBounds(self.robot,
                                                robot_description,
                                                tool_capsule)
    # Energy PFL's inputs (docs/shield_maths.md, 9.4), made when a mode
    # first needs them.
    self.energy = energy_setup.EnergySetup(
        robot_description, self.human.config, self.robot.frame_index,
        self.cycle_time, payload=payload, static_boxes=static_boxes)
    self._kernel_constants = None   # kernel_constants, made when first asked.
    self.reset(robot_description.q_home if q_init is None else q_init)

  @property
  def mode(self) -> str:
    """The name of the shield's mode (`modes`); settable (ValueError for
    a name that is not registered)."""
    return self._mode.name

  @mode.setter
  def mode(self, name: str) -> None:
    self._mode = modes_lib.get(name)
    self._gates = self._mode.gates
    self.speed_limit = self._mode.speed_limit(self.v_safe)
    self._kernel_parameters = None   # kernel_parameters, made when asked.

  @property
  def gates(self) -> bool:
    """Whether the mode's verdict decides the command (`modes`)."""
    return self._gates

  # ------------------------------------------------------------ the state

  @property
  def state(self) -> shield_state.ShieldState:
    """Everything a cycle reads and changes (`shield_state.ShieldState`,
    frozen): a checkpoint; settable (a restore, or the compiled cycles'
    result, safety/shield/batch.py). Its `human` is `self.human.state`."""
    human = self.human.state
    if self._state.human is not human:   # Measured through self.human.
      self._state = self._state.replace(human=human)
    return self._state

  @state.setter
  def state(self, state: shield_state.ShieldState) -> None:
    if not isinstance(state, shield_state.ShieldState):
      raise TypeError(f'Shield.state: expected a ShieldState, got '
                      f'{type(state).__name__}')
    self._install(state)

  def _install(self, state, keep_readouts=False):
    """Makes `state` the shield's (and its human's) state; the lazy
    read-outs are those of the new state (keep_readouts: they are)."""
    self._state = state
    self.human.state = state.human
    if not keep_readouts:
      self._lazy = {}

  @property
  def kernel_constants(self) -> cycle_kernels.Constants:
    """The compiled cycles' constants of this shield
    (`cycle_kernels.Constants`; computed once)."""
    if self._kernel_constants is None:
      self._kernel_constants = cycle_terms.kernel_constants(
          self.terms, self.limits, self.robot, self.human, self.cycle_time,
          self.interval)
    return self._kernel_constants

  def kernel_parameters(self) -> tuple:
    """The mode's parameter group for the compiled cycles
    (`ShieldMode.kernel_parameters`, mode_kernels), made once per mode.

    Returns:
      The group: a NamedTuple registered with mode_kernels.register.
    """
    if self._kernel_parameters is None:
      self._kernel_parameters = self._mode.kernel_parameters(self)
    return self._kernel_parameters

  def kernel_tables(self, plan: ltp.LongTermPlan) -> tuple:
    """The mode's tables of a plan for the compiled cycles
    (`ShieldMode.plan_tables`).

    Args:
      plan: a plan of this shield (the adopted one or a candidate).

    Returns:
      The tables: one NamedTuple of mode_kernels, the same class for every
      plan of the mode.
    """
    return self._mode.plan_tables(self, plan)

  # --------------------------------------------------------------- commands

  def reset(self, q: np.ndarray, t: float = 0.0) -> None:
    """Restarts the shield: the robot at rest at q, no goal, no human
    measurement.

    Args:
      q: joint positions (dof,).
      t: the time (s) of the restart (`time`).

    Raises:
      ValueError: q is not dof finite joint positions within the joint
        limits.
    """
    q = np.asarray(q, dtype=float)
    if q.shape != (self.dof,) or not np.all(np.isfinite(q)):
      raise ValueError(f'q: expected {self.dof} finite joint positions for '
                       f'{self.description.name}, got {q.tolist()}')
    if not verification.within_joint_limits(q, self.description, 1e-9):
      raise ValueError(f'q: {q.tolist()} is outside the joint limits '
                       f'[{self.limits.q_min.tolist()}, '
                       f'{self.limits.q_max.tolist()}]')
    self.human.reset()
    plan = ltp.LongTermPlan.at_rest(q, self.cycle_time, 0.0)
    command = plan.state(0.0, 0.0, 0.0, 0.0)
    self._install(shield_state.ShieldState(
        command=command, previous_q=command[0],
        verified=path_lib.Path(0.0, 0.0, 0.0, 0.0), intended=None,
        plan=plan, goal=None, goal_pending=False, candidate=None,
        candidate_key=None, time=float(t), intervened=False,
        verification=shield_state.Verification(
            is_safe=not self._gates, first_unsafe_interval=-1,
            reach_distance=np.inf, edges=None),
        human=self.human.state))

  def new_goal(self, q_goal: np.ndarray,
               plan: Optional[ltp.LongTermPlan] = None) -> None:
    """Plans to rest at q_goal (clamped 0.01 rad inside the limits) from the
    next step on; the new plan is adopted once a step on it verifies.

    Args:
      q_goal: the goal's joint positions (dof,).
      plan: the plan to q_goal made already from this shield's command
        (`CollisionPrevention.filter_action` with plan_from=this shield):
        the first candidate where it is the plan the shield would make now
        (the same inputs, bit for bit: `LongTermPlan.made_from`), else
        ignored.
    """
    state = self.state
    goal = ltp.clamp_goal(q_goal, self.limits)
    candidate, key = None, None
    if plan is not None:
      s = state.verified.s
      if (self._can_plan_from(state.command)
          and plan.made_from(state.command, goal, self.limits,
                             self.cycle_time, s)):
        # What `candidate` would make (candidate_from's conditions).
        candidate, key = plan, (s, state.verified.s_dot)
    self._install(state.replace(goal=goal, goal_pending=True,
                                candidate=candidate, candidate_key=key),
                  keep_readouts=True)

  def resync(self, q: np.ndarray) -> None:
    """The robot was measured at q, off the command by more than the
    tracking tolerance (a person pushed it): restart at rest at q.

    The shield assumes the robot stays within the secure radius of its
    command (docs/safety.md, Assumptions: Tracking; L1 of
    docs/shield_maths.md, 10); a robot pushed further is not on the
    verified path, which then no longer describes it. The new verified
    path is the failsafe from the measured
    pose in its strictest form: stand still there (q clipped to the joint
    limits). The measured velocity is not taken over: it is the push, not
    the robot's own motion, and continuing it would make the robot carry
    on the person's shove of its own accord (to brake later, moving, at the
    person). The goal is kept: it is planned again from q and adopted once
    a step on it verifies, as after new_goal. The last cycle's verdict and
    reach capsules stay readable (they describe that cycle's check).

    Args:
      q: the measured joint positions (dof,).

    Raises:
      ValueError: q is not dof finite joint positions.
    """
    q = np.asarray(q, dtype=float)
    if q.shape != (self.dof,) or not np.all(np.isfinite(q)):
      raise ValueError(f'q: expected {self.dof} finite joint positions for '
                       f'{self.description.name}, got {q.tolist()}')
    q = np.clip(q, self.limits.q_min, self.limits.q_max)
    state = self.state
    s = state.verified.s
    plan = ltp.LongTermPlan.at_rest(q, self.cycle_time, s)
    self._install(state.replace(
        plan=plan, verified=path_lib.Path(s, 0.0, 0.0, 0.0), intended=None,
        command=plan.state(s, 0.0, 0.0, 0.0),
        goal_pending=state.goal is not None, candidate=None,
        candidate_key=None))

  @property
  def tracking_tolerance(self) -> float:
    """How far (m) the robot may be from its command
    (`TrackingBounds.tolerance` of `tracking`)."""
    return self.tracking.tolerance

  @property
  def tracking_levers(self) -> np.ndarray:
    """Lever arms (dof,) in m/rad, read-only (`TrackingBounds.levers` of
    `tracking`)."""
    return self.tracking.levers

  def tracking_bound(self, q: np.ndarray,
                     reference: Optional[np.ndarray] = None) -> float:
    """A cheap upper bound (m) on `tracking_error(q, reference)`
    (`TrackingBounds.bound` of `tracking`).

    Args:
      q: joint positions (dof,), e.g. the measured ones.
      reference: joint positions (dof,) to compare with (None: the
        command's).

    Returns:
      The bound, m.
    """
    return self.tracking.bound(
        q, self._state.command[0] if reference is None else reference)

  def tracking_error(self, q: np.ndarray,
                     reference: Optional[np.ndarray] = None) -> float:
    """How far (m) the robot's capsules at joint positions q are from where
    they are at `reference` (`TrackingBounds.error` of `tracking`).

    Args:
      q: joint positions (dof,), e.g. the measured ones.
      reference: joint positions (dof,) to compare with (None: the
        command's).

    Returns:
      The largest displacement of a capsule axis end, m.
    """
    return self.tracking.error(
        q, self._state.command[0] if reference is None else reference)

  @property
  def goal(self) -> Optional[np.ndarray]:
    """The goal being planned to (None before the first new_goal)."""
    return self._state.goal

  @property
  def plan(self) -> ltp.LongTermPlan:
    """The adopted (verified) long-term plan."""
    return self._state.plan

  @property
  def goal_pending(self) -> bool:
    """A goal was given whose plan has not been adopted yet."""
    return self._state.goal_pending

  # ------------------------------------------------------------- read-outs

  @property
  def q(self) -> np.ndarray:
    """The command's joint positions (dof,), rad."""
    return self._state.command[0]

  @property
  def dq(self) -> np.ndarray:
    """The command's joint velocities (dof,), rad/s."""
    return self._state.command[1]

  @property
  def ddq(self) -> np.ndarray:
    """The command's joint accelerations (dof,), rad/s^2."""
    return self._state.command[2]

  @property
  def dddq(self) -> np.ndarray:
    """The command's joint jerks (dof,), rad/s^3."""
    return self._state.command[3]

  @property
  def s(self) -> float:
    """Position along the adopted plan (plan time, s)."""
    return self._state.verified.s

  @property
  def s_dot(self) -> float:
    """Path velocity along the adopted plan (plan time per time; 1: the
    plan's nominal speed)."""
    return self._state.verified.s_dot

  @property
  def time(self) -> float:
    """Time (s) of the last cycle (or of `reset`)."""
    return self._state.time

  @property
  def intervened(self) -> bool:
    """The last cycle did not take the step its plan wanted."""
    return self._state.intervened

  def _check_now(self):
    """Mode 'off': runs this cycle's check when a read-out needs it."""
    state = self._state
    pending = state.verification.pending
    if pending is not None:
      self._state = state.replace(verification=self._path_check.verify(
          pending.plan, pending.current, pending.failsafe, state.previous_q,
          state.time, self._mode, self, self._lazy))

  @property
  def is_safe(self) -> bool:
    """The last cycle's monitored path verified (mode 'off': computed when
    first asked; True before the first step)."""
    self._check_now()
    return self._state.verification.is_safe

  @property
  def first_unsafe_interval(self) -> int:
    """First slice of the last check that was not verified (-1: none)."""
    self._check_now()
    return self._state.verification.first_unsafe_interval

  @property
  def robot_reach_capsules(
      self) -> Optional[Tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Robot reach capsules of the last check: c1, c2 (K, L, 3), r (K, L);
    slice 0 is the current step, then the failsafe (None before a check)."""
    self._check_now()
    if 'robot_reach' not in self._lazy:
      edges = self._state.verification.edges
      if edges is None:
        return None
      self._lazy['robot_reach'] = self.robot.reach_capsules(
          edges.q_edges, np.array(edges.s_edges))
    return self._lazy['robot_reach']

  @property
  def human_reach_capsules(
      self) -> Optional[Tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Human reach capsules of the last check: c1, c2 (M, K, B, 3), r (M, K,
    B) (None without a measurement or check)."""
    self._check_now()
    if 'human_reach' not in self._lazy:
      edges = self._state.verification.edges
      if edges is None or self.human.positions is None:
        return None
      self._lazy['human_reach'] = self.human.reach_capsules(
          self._state.time, np.array(edges.t_edges))
    return self._lazy['human_reach']

  @property
  def reach_distance(self) -> float:
    """Clearance (m) of the last check: verification.ssm_verdict's
    min_distance (inf when nothing was near; a broad phase's lower bound
    when one settled the cycle; -inf when no path could be checked).
    Computed when first asked (the verdict itself stops early)."""
    self._check_now()
    checked = self._state.verification
    if checked.reach_distance is None:
      distance = verification.ssm_verdict(
          self.robot_reach_capsules, self.human_reach_capsules,
          compiled=True)[2]
      self._state = self._state.replace(verification=dataclasses.replace(
          checked, reach_distance=distance))
    return self._state.verification.reach_distance

  @property
  def max_cartesian_speed(self) -> float:
    """Largest surface speed of any robot capsule at the command (m/s)."""
    if 'speed' not in self._lazy:
      command = self._state.command
      self._lazy['speed'] = float(self.robot.surface_speeds(
          command[0], command[1]).max())
    return self._lazy['speed']

  @property
  def min_distance(self) -> float:
    """Distance (m) between the robot's real capsules at the command and
    the human's real body capsules at the last measurement (inf without a
    measurement; negative when they overlap)."""
    if 'distance' not in self._lazy:
      if self.human.positions is None:
        self._lazy['distance'] = np.inf
      else:   # NumPy reference: tests/safety/safety_references.py.
        human = self.human
        self._lazy['distance'] = float(kernels.capsules_min_distance(
            self._state.command[0], *self.robot.kernel_model,
            self.robot.kernel_frames, self.robot.kernel_radii,
            np.ascontiguousarray(human.positions, dtype=float),
            human.kernel_ends, human.half_thickness))
    return self._lazy['distance']

  # -------------------------------------------------------------- snapshots

  def get_state(self) -> dict[str, Any]:
    """The shield's state as a flat dict for np.savez / JSON
    (`state_io.state_dict`); `set_state` restores it so that continuing
    gives identical commands.

    Returns:
      The snapshot: name -> value.
    """
    return state_io.state_dict(self)

  def set_state(self, state: Mapping[str, Any]) -> None:
    """Restores a `get_state` of a shield of the same robot, mode and cycle
    (`state_io.restore`).

    Args:
      state: a `get_state` (arrays may be lists, as after JSON; 0-d arrays
        as after np.load).
    """
    state_io.restore(self, state)

  # ------------------------------------------------------------------ step

  def step(self, human_keypoints: Optional[np.ndarray], t: float
           ) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One cycle at time t.

    Call once every cycle_time (the command advances the path by one
    cycle); the robot should reach the command within the cycle.

    Args:
      human_keypoints: (N_kp, 3) positions measured at t, or None if there
        is no new measurement (the last one then ages; with no measurement
        ever the workcell is taken to be empty).
      t: the cycle's time, s.

    Returns:
      The command: joint positions, velocities and accelerations (dof,)
      each.
    """
    t = float(t)
    if human_keypoints is not None:
      self.human.measure(human_keypoints, t)
    state = self._state
    previous_q = state.command[0]
    dt = self.cycle_time

    # Replanning: a candidate plan starts at the current command with path
    # velocity 1 (its first sample is the commanded q, dq, ddq). From rest
    # every path velocity matches the command (the plan starts at rest):
    # a candidate that does not verify at 1 may start at 0 and accelerate
    # along the path as a stopped robot resumes its plan, so a robot
    # stopped next to a person can start again (docs/safety.md,
    # "Starting from rest").
    plan, current = state.plan, state.verified
    candidate, key = (self.candidate(state) if state.goal_pending
                      else (None, None))
    starts = (None,)
    if candidate is not None:
      plan = candidate
      starts = (1.0, 0.0) if self._at_rest(state.command) else (1.0,)
    nominal = None   # The first start's intended step: what was wanted.
    for start in starts:
      self._lazy = {}   # Read-outs are those of this cycle and start.
      if start is not None:
        current = path_lib.Path(state.verified.s, start, 0.0, 0.0)
      intended, failsafe = self._monitored(state, plan, current,
                                           candidate)
      nominal = intended if start != 0.0 else nominal
      checked = self._check(state, plan, current, intended, failsafe,
                            previous_q, t)
      if checked.is_safe is not False:
        break
    safe = checked.is_safe

    follow = failsafe is not None and (safe or not self._gates)
    kept = {}
    if follow:
      if candidate is not None:   # Adopted: the goal's plan is verified.
        kept = dict(plan=candidate, goal_pending=False)
        candidate, key = None, None
      verified, kept_intended = failsafe, intended
      command = plan.state(intended.s, intended.s_dot, intended.s_ddot,
                           intended.jerk)
      intervened = False
    else:
      verified = state.verified.copy()
      verified.advance(dt)
      kept_intended = None
      v = verified
      command = state.plan.state(v.s, v.s_dot, v.s_ddot, v.jerk)
      if nominal is None:
        intervened = True
      else:
        wanted = plan.state(nominal.s, nominal.s_dot, nominal.s_ddot,
                            nominal.jerk)
        intervened = not (
            np.abs(wanted[0] - command[0]).max() <= _SAME_COMMAND and
            np.abs(wanted[1] - command[1]).max() <= _SAME_COMMAND)
    rates = command[1:4]   # np.clip's max-then-min, without its overhead.
    terms = self.terms
    np.minimum(np.maximum(rates, terms.clip_low, out=rates), terms.clip,
               out=rates)
    self._install(shield_state.ShieldState(
        command=command, previous_q=previous_q, verified=verified,
        intended=kept_intended, plan=kept.get('plan', state.plan),
        goal=state.goal,
        goal_pending=kept.get('goal_pending', state.goal_pending),
        candidate=candidate, candidate_key=key, time=t,
        intervened=intervened, verification=checked,
        human=self.human.state), keep_readouts=True)
    return command[0], command[1], command[2]

  # -------------------------------------------------------------- internals

  def _at_rest(self, command):
    """Whether command (5, dof) is at rest (velocity and acceleration
    zero)."""
    rates = command[1:3]
    return bool((np.abs(rates) <= REST_TOLERANCE).all())

  def _monitored(self, state, plan, current, candidate):
    """The monitored path from `current` on `plan` in `state`: (intended
    step, failsafe); None for what does not exist."""
    dt = self.cycle_time
    max_acc, max_jerk = self._path_limits(state.command[4])
    intended = None
    kept = state.intended
    if candidate is None and kept is not None and not (
        kept.is_finished() and kept.s_dot != 1.0):
      intended = kept
    if intended is None:
      intended = path_lib.plan_profile(
          current.s, current.s_dot, current.s_ddot, 1.0, max_acc, max_jerk, dt)
    failsafe = None
    if intended is not None:
      intended = intended.copy()
      intended.advance(dt)
      target = self._mode.failsafe_target(self, plan, intended.s)
      failsafe = path_lib.plan_profile(
          intended.s, intended.s_dot, intended.s_ddot,
          0.0 if target is None else target, max_acc, max_jerk, dt)
    return intended, failsafe

  def _check(self, state, plan, current, intended, failsafe, previous_q,
             now):
    """Verifies the monitored path: a `shield_state.Verification` whose
    is_safe is True, False, or None (mode 'off': the check runs when a
    read-out needs it)."""
    if failsafe is None or intended.s < current.s:
      # No monitored path: keep braking on the verified one.
      return shield_state.Verification(False, 0, -np.inf, None)
    if not self._gates:
      # Unshielded: the check only feeds read-outs; run it when one is
      # read (its inputs do not change until the next step).
      last = state.verification
      return shield_state.Verification(
          None, last.first_unsafe_interval, last.reach_distance, None,
          shield_state.PendingCheck(plan, current, failsafe))
    return self._path_check.verify(plan, current, failsafe, previous_q, now,
                                   self._mode, self, self._lazy)

  def _path_limits(self, v_nominal):
    """path.path_limits for this robot with precomputed per-joint terms."""
    terms = self.terms
    dens = [abs(v) + c for v, c in zip(v_nominal.tolist(), terms.den_offset)]
    acc = min(n / d for n, d in zip(terms.acc_numerator, dens))
    acc = acc if acc > 0.0 else 0.0
    jerk = min((n - c * acc) / d for n, c, d in zip(
        terms.jerk_numerator, terms.jerk_acc, dens))
    return acc, (jerk if jerk > 0.0 else 0.0)

  def candidate(self, state: shield_state.ShieldState
                ) -> Tuple[Optional[ltp.LongTermPlan], Optional[tuple]]:
    """The plan to the pending goal from a state's command as a cycle from
    that state takes it: the state's candidate while the verified path has
    not moved since it was planned, else a new one (`candidate_from`). The
    compiled cycles make the same test (cycle_kernels.ssm_cycles stops for
    a candidate only where a plan may start).

    Args:
      state: a state of this shield with a pending goal.

    Returns:
      (the plan, its key: the verified path's (s, s_dot) it starts from),
      or (None, None) where none can be made.
    """
    key = (state.verified.s, state.verified.s_dot)
    if state.candidate is not None and state.candidate_key == key:
      return state.candidate, key   # The robot has not moved: still valid.
    if not self._can_plan_from(state.command):
      return None, None
    made = self.candidate_from(state.command, *key)
    return (None, None) if made is None else made

  def _can_plan_from(self, command):
    """Whether a plan may start at `command` (q, dq, ddq rows first):
    not while braking harder than the planning limits
    (docs/shield_maths.md, 1)."""
    return not (np.abs(command[2]) > self.limits.a_max_ltt).any()

  def candidate_from(self, command: np.ndarray, s: float, s_dot: float,
                     recent: bool = True
                     ) -> Optional[Tuple[ltp.LongTermPlan, tuple]]:
    """The plan to the pending goal from a command; the caller has found
    that a plan may start there (`_can_plan_from`).

    Args:
      command: (5, dof), the command's q, dq, ddq rows first.
      s: the verified path's position (plan time, s) at the command.
      s_dot: the verified path's velocity there.
      recent: as plan_to_goal's (False: a command moved since anyone
        planned from it).

    Returns:
      (the plan, its key (s, s_dot)), or None where none can be made.
    """
    try:
      plan = ltp.plan_to_goal(command[0], command[1], command[2],
                              self._state.goal, self.limits, self.cycle_time,
                              s, recent=recent)
    except ltp.PlanningError:
      return None
    return plan, (s, s_dot)

  def plan_speeds(self, plan: ltp.LongTermPlan
                  ) -> Tuple[np.ndarray, np.ndarray]:
    """PFL tables of a plan's largest capsule surface speed at nominal
    path speed. Kept on the plan for this robot (`LongTermPlan.derived`):
    a candidate's tables stay its own when it is adopted, and a plan
    shared through long_term_plan's cache of recent plans is not tabled
    twice.

    Args:
      plan: a plan of this shield.

    Returns:
      (window, suffix), both (N,), m/s: the largest speed over the next
      PFL_WINDOW samples, and from each sample to the end.
    """
    robot = self.robot   # pfl_speed_tables(surface_speeds(q, dq)):
    return plan.derived('pfl_speed_tables', robot,
                        lambda: speed_kernels.plan_speed_tables(
                            plan.samples(), *robot.kernel_model,
                            robot.kernel_frames, robot.kernel_radii,
                            PFL_WINDOW))

  # ------------------------------------------------------- energy PFL

  @property
  def energy_model(self) -> arm_energy.ArmEnergyModel:
    """The arm's energy model with its payload (`EnergySetup.model` of
    `energy`)."""
    return self.energy.model

  def set_payload(self, payload: Optional[robot_energy.Payload]) -> None:
    """Sets what the last link carries from now on
    (`EnergySetup.set_payload` of `energy`).

    Args:
      payload: the gripper and an object grasped, or the gripper alone
        after a release (None: the gripper).
    """
    self.energy.set_payload(payload)

  @property
  def energy_limits(self) -> energy_verification.EnergyLimits:
    """The allowed energies per body of the human model
    (`EnergySetup.limits` of `energy`)."""
    return self.energy.limits

  @property
  def clamp_geometry(self) -> clamping.ClampGeometry:
    """What a body can be clamped against (`EnergySetup.clamp_geometry` of
    `energy`)."""
    return self.energy.clamp_geometry

  def plan_energies(self, plan: ltp.LongTermPlan
                    ) -> Tuple[np.ndarray, np.ndarray]:
    """Energy PFL tables of a plan (`EnergySetup.plan_energies` of
    `energy`).

    Args:
      plan: a plan of this shield.

    Returns:
      (window (N, dof), suffix (N,)), J.
    """
    return self.energy.plan_energies(plan)
