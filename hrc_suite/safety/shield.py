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
that, `tracking_error` > `tracking_tolerance`; `tracking_bound` is a cheap
upper bound to check first), the caller hands the measured pose to
`resync`, which restarts the shield at rest there.

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
  and reach capsules: a cheap model that, if collision-free, settles the
  cycle under SSM's "some model is collision-free" rule. The reach
  capsules' test is first bounded from one forward kinematics
  (kernels.swept_balls_gap, docs/shield_maths.md, 5.3), which settles
  most such cycles without the reach capsules.

Speed: the per-cycle geometry runs in compiled kernels (`kernels`, numba),
each tested against its readable NumPy reference (kept in `robot_reach`,
`human_reach`, `verification`, `long_term_plan` and here); the verdict
stops at the first unsafe slice and `reach_distance` is computed when
asked.
"""

import math

import numpy as np

from hrc_suite import robot_description as robot_description_lib
from hrc_suite.human import keypoints
from hrc_suite.safety import cycle_kernels
from hrc_suite.safety import geometry
from hrc_suite.safety import human_reach as human_reach_lib
from hrc_suite.safety import kernels
from hrc_suite.safety import long_term_plan as ltp
from hrc_suite.safety import modes as modes_lib
from hrc_suite.safety import path as path_lib
from hrc_suite.safety import plan_kernels
from hrc_suite.safety import robot_reach as robot_reach_lib
from hrc_suite.safety import speed_kernels
from hrc_suite.safety import verification

# Default shield cycle (s): human-robot-gym's control_sample_time
# (docs/shield_maths.md, 4).
DEFAULT_CYCLE_TIME = 0.004
# PFL: speeds are compared with this fraction of v_safe (safety/modes.py).
PFL_SPEED_MARGIN = modes_lib.PFL_SPEED_MARGIN
# PFL: samples over which a reachable-set slice can extend (one slice is
# reachability_interval_cycles = 5 cycles of plan time at s_dot <= 1; one
# more for the Taylor step past the last sample).
PFL_WINDOW = 6
# Relative tolerance on path velocities in the PFL speed test.
_S_DOT_TOLERANCE = 1e-9
# Subtracted from broad-phase distance bounds (m): covers the round-off of
# computing distances from squared norms.
_BROAD_PHASE_SLACK = 1e-6
# Joint-space differences below this count as "the same command" (rad, rad/s).
_SAME_COMMAND = 1e-9
# The command is at rest when every joint's velocity (rad/s) and
# acceleration (rad/s^2) is within this of zero (braking ends at exactly
# zero; this only absorbs round-off).
REST_TOLERANCE = 1e-12


def _joint_list(values):
  return [float(x) for x in values]


class Shield:
  """SaRA-style reachability shield for one robot in a registered mode
  (`modes`: 'ssm', 'pfl', 'off' or one registered elsewhere)."""

  def __init__(self, robot_description, mode='ssm',
               cycle_time=DEFAULT_CYCLE_TIME, human_model=None,
               base_pose=None, tool_capsule=None, v_safe=None,
               use_kalman_filter=False, use_combined_model=None,
               secure_radius=None, alpha=None, q_init=None):
    if isinstance(robot_description, str):
      robot_description = robot_description_lib.load(robot_description)
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
    limits = robot_description.limits
    self.limits = limits
    # Per-joint terms of `path.path_limits` (docs/shield_maths.md, 3).
    a_ltt = np.abs(limits.a_max_ltt)
    self._den_offset = _joint_list(a_ltt * self.max_s_stop)
    self._den_offset[0] += 1e-9
    self._acc_numerator = _joint_list(limits.a_max - a_ltt)
    self._jerk_numerator = _joint_list(limits.j_max
                                       - np.abs(limits.j_max_ltt))
    self._jerk_acc = _joint_list(3.0 * a_ltt)
    self._q_min = _joint_list(limits.q_min)
    self._q_max = _joint_list(limits.q_max)
    # Clip bounds of a state's (dq, ddq, dddq) rows (docs/shield_maths.md, 2).
    self._clip = np.stack([limits.v_max, limits.a_max, limits.j_max])
    self._clip_low = -self._clip
    # Every robot point stays within this ball around the base (rotations
    # keep lengths: sum of the fixed translations up to the link, plus the
    # capsule's farther end, radius and secure radius).
    self._base = self.robot.base_pose[:3, 3].copy()
    lengths = np.cumsum([np.linalg.norm(l.fixed_translation)
                         for l in robot_description.links])
    p1, p2, radii = robot_description.capsule_arrays()
    extents = [lengths[i] + max(np.linalg.norm(p1[i]), np.linalg.norm(p2[i]))
               + radii[i] for i in range(self.dof)]
    if tool_capsule is not None:
      t1, t2, t_radius = tool_capsule
      extents.append(lengths[-1] + max(np.linalg.norm(t1), np.linalg.norm(t2))
                     + t_radius)
    self._workspace_radius = max(extents) + self.robot.secure_radius
    # Lever arms (m/rad): turning joint i by dq moves no point of a capsule
    # axis after it (links i.. and the tool) by more than lever_i |dq| (an
    # arc is longer than its chord; distances are bounded along the chain),
    # so sum_i lever_i |dq_i| bounds how far a joint error moves the robot
    # (`tracking_bound`, a per-step prefilter of `tracking_error`).
    axis_ends = [max(np.linalg.norm(p1[i]), np.linalg.norm(p2[i]))
                 for i in range(self.dof)]
    if tool_capsule is not None:
      axis_ends[-1] = max(axis_ends[-1], np.linalg.norm(t1),
                          np.linalg.norm(t2))
    self._levers = np.array([
        max(lengths[j] - lengths[i] + axis_ends[j]
            for j in range(i, self.dof)) for i in range(self.dof)])
    self._levers.flags.writeable = False
    # Keypoint indices (2, B) of the human bodies' proximal and distal ends.
    self._body_ends = np.ascontiguousarray([
        keypoints.index([b.proximal for b in self.human.config.bodies]),
        keypoints.index([b.distal for b in self.human.config.bodies])],
                                           dtype=np.int64)
    config = self.human.config
    self._half_thickness = np.array([b.thickness / 2 for b in config.bodies])
    self._human_v_max = np.ascontiguousarray(config.v_max, dtype=float)
    self._human_delay = float(config.delay)
    self._human_error_pos = float(config.measurement_error_pos)
    self.reset(robot_description.q_home if q_init is None else q_init)

  @property
  def mode(self):
    """The name of the shield's mode (`modes`); settable."""
    return self._mode.name

  @mode.setter
  def mode(self, name):
    self._mode = modes_lib.get(name)
    self._gates = self._mode.gates
    self.speed_limit = self._mode.speed_limit(self.v_safe)

  # --------------------------------------------------------------- commands

  def reset(self, q, t=0.0):
    """Robot at rest at q, no goal, no human measurement."""
    q = np.asarray(q, dtype=float)
    if q.shape != (self.dof,) or not np.all(np.isfinite(q)):
      raise ValueError(f'q: expected {self.dof} finite joint positions for '
                       f'{self.description.name}, got {q.tolist()}')
    if not verification.within_joint_limits(q, self.description, 1e-9):
      raise ValueError(f'q: {q.tolist()} is outside the joint limits '
                       f'[{self.limits.q_min.tolist()}, '
                       f'{self.limits.q_max.tolist()}]')
    self.human.reset()
    self._plan = ltp.LongTermPlan.at_rest(q, self.cycle_time, 0.0)
    self._verified = path_lib.Path(0.0, 0.0, 0.0, 0.0)
    self._intended = None
    self._state = self._plan.state(0.0, 0.0, 0.0, 0.0)
    self._goal = None
    self._goal_pending = False
    self._candidate = None       # (plan, start state key) awaiting approval.
    self.time = float(t)
    self._is_safe = not self._gates
    self.intervened = False
    self._first_unsafe_interval = -1
    self._reach_distance = np.inf
    self._reach_arguments = None
    self._pending_check = None   # Mode 'off': the cycle's check, if asked.
    self._previous_q = self._state[0]
    self._lazy = {}

  def new_goal(self, q_goal, plan=None):
    """Plans to rest at q_goal (clamped 0.01 rad inside the limits) from the
    next step on; the new plan is adopted once a step on it verifies.

    plan: the plan to q_goal made already from this shield's command
    (`CollisionPrevention.filter_action` with plan_from=this shield): the
    first candidate where it is the plan the shield would make now (the
    same inputs, bit for bit: `LongTermPlan.made_from`), else ignored.
    """
    self._goal = ltp.clamp_goal(q_goal, self.limits)
    self._goal_pending = True
    self._candidate = None
    if plan is not None:
      s = self._verified.s
      if (self._can_plan_from(self._state)
          and plan.made_from(self._state, self._goal, self.limits,
                             self.cycle_time, s)):
        # What _candidate_plan would make (candidate_from's conditions).
        self._candidate = (plan, (s, self._verified.s_dot))

  def resync(self, q):
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
    """
    q = np.asarray(q, dtype=float)
    if q.shape != (self.dof,) or not np.all(np.isfinite(q)):
      raise ValueError(f'q: expected {self.dof} finite joint positions for '
                       f'{self.description.name}, got {q.tolist()}')
    q = np.clip(q, self.limits.q_min, self.limits.q_max)
    s = self._verified.s
    self._plan = ltp.LongTermPlan.at_rest(q, self.cycle_time, s)
    self._verified = path_lib.Path(s, 0.0, 0.0, 0.0)
    self._intended = None
    self._state = self._plan.state(s, 0.0, 0.0, 0.0)
    self._goal_pending = self._goal is not None
    self._candidate = None
    self._lazy = {}

  @property
  def tracking_tolerance(self):
    """How far (m) the robot may be from its command: the secure radius,
    by which every robot reach capsule is enlarged (docs/safety.md,
    Assumptions: Tracking)."""
    return self.robot.secure_radius

  @property
  def tracking_levers(self):
    """Lever arms (dof,) in m/rad, read-only: sum_i lever_i |q_i - p_i|
    (`tracking_bound`) bounds `tracking_error(q, p)`."""
    return self._levers

  def tracking_bound(self, q, reference=None):
    """A cheap upper bound (m) on `tracking_error(q, reference)`: the joint
    errors times `tracking_levers`."""
    q, reference = self._joint_pair(q, reference)
    return float(np.abs(q - reference) @ self._levers)

  def tracking_error(self, q, reference=None):
    """How far (m) the robot's capsules at joint positions q are from where
    they are at `reference` (None: the command): the largest displacement
    of a capsule axis end. Capsules move rigidly, so no point of a
    capsule moves farther than its farther end. (kernels.tracking_error,
    which tasks/physics_loop.py calls too; tracking_error_reference is
    the NumPy version, equal to round-off.)"""
    q, reference = self._joint_pair(q, reference)
    robot = self.robot
    return float(kernels.tracking_error(q, reference, *robot._kernel_model,
                                        robot._kernel_frames))

  def tracking_error_reference(self, q, reference=None):
    """tracking_error by NumPy (robot capsules by RobotReach.capsules)."""
    q, reference = self._joint_pair(q, reference)
    p1, p2, _ = self.robot.capsules(np.stack([q, reference]))
    moved = np.concatenate([p1[0] - p1[1], p2[0] - p2[1]])
    return float(np.sqrt(np.einsum('ni,ni->n', moved, moved).max()))

  def _joint_pair(self, q, reference):
    reference = self._state[0] if reference is None else reference
    q = np.asarray(q, dtype=float)
    reference = np.asarray(reference, dtype=float)
    if q.shape != (self.dof,) or reference.shape != (self.dof,):
      raise ValueError(f'q, reference: expected {self.dof} joint positions '
                       f'each for {self.description.name}, got shapes '
                       f'{q.shape} and {reference.shape}')
    return q, reference

  @property
  def goal(self):
    """The goal being planned to (None before the first new_goal)."""
    return self._goal

  @property
  def plan(self):
    """The adopted (verified) long-term plan."""
    return self._plan

  @property
  def goal_pending(self):
    """A goal was given whose plan has not been adopted yet."""
    return self._goal_pending

  # ----------------------------------------------------------------- state

  @property
  def q(self):
    return self._state[0]

  @property
  def dq(self):
    return self._state[1]

  @property
  def ddq(self):
    return self._state[2]

  @property
  def dddq(self):
    return self._state[3]

  @property
  def s(self):
    """Position along the adopted plan (plan time, s)."""
    return self._verified.s

  @property
  def s_dot(self):
    return self._verified.s_dot

  def _check_now(self):
    """Mode 'off': runs this cycle's check when a read-out needs it."""
    if self._pending_check is not None:
      arguments, self._pending_check = self._pending_check, None
      self._is_safe = self._verify(*arguments)

  @property
  def is_safe(self):
    """The last cycle's monitored path verified (mode 'off': computed when
    first asked; True before the first step)."""
    self._check_now()
    return self._is_safe

  @property
  def first_unsafe_interval(self):
    """First slice of the last check that was not verified (-1: none)."""
    self._check_now()
    return self._first_unsafe_interval

  @property
  def robot_reach_capsules(self):
    """Robot reach capsules of the last check: c1, c2 (K, L, 3), r (K, L);
    slice 0 is the current step, then the failsafe (None before a check)."""
    self._check_now()
    if 'robot_reach' not in self._lazy:
      if self._reach_arguments is None:
        return None
      _, s_edges, _, q_edges = self._reach_arguments
      self._lazy['robot_reach'] = self.robot.reach_capsules(
          q_edges, np.array(s_edges))
    return self._lazy['robot_reach']

  @property
  def human_reach_capsules(self):
    """Human reach capsules of the last check: c1, c2 (M, K, B, 3), r (M, K,
    B) (None without a measurement or check)."""
    self._check_now()
    if 'human_reach' not in self._lazy:
      if self._reach_arguments is None or self.human.positions is None:
        return None
      self._lazy['human_reach'] = self.human.reach_capsules(
          self.time, np.array(self._reach_arguments[2]))
    return self._lazy['human_reach']

  @property
  def reach_distance(self):
    """Clearance (m) of the last check: verification.ssm_verdict's
    min_distance (inf when nothing was near; a broad phase's lower bound
    when one settled the cycle; -inf when no path could be checked).
    Computed when first asked (the verdict itself stops early)."""
    self._check_now()
    if self._reach_distance is None:
      self._reach_distance = verification.ssm_verdict(
          self.robot_reach_capsules, self.human_reach_capsules,
          compiled=True)[2]
    return self._reach_distance

  @property
  def max_cartesian_speed(self):
    """Largest surface speed of any robot capsule at the command (m/s)."""
    if 'speed' not in self._lazy:
      self._lazy['speed'] = float(self.robot.surface_speeds(
          self._state[0], self._state[1]).max())
    return self._lazy['speed']

  @property
  def min_distance(self):
    """Distance (m) between the robot's real capsules at the command and
    the human's real body capsules at the last measurement (inf without a
    measurement; negative when they overlap)."""
    if 'distance' not in self._lazy:
      if self.human.positions is None:
        self._lazy['distance'] = np.inf
      else:   # The NumPy reference: min_distance_reference.
        human = self.human
        self._lazy['distance'] = float(kernels.capsules_min_distance(
            self._state[0], *self.robot._kernel_model,
            self.robot._kernel_frames, self.robot._kernel_radii,
            np.ascontiguousarray(human.positions, dtype=float),
            human._kernel_ends, human._half_thickness))
    return self._lazy['distance']

  def min_distance_reference(self):
    """min_distance by NumPy (geometry.capsule_distance over all pairs);
    the kernel agrees to round-off (tests/safety/test_shield.py)."""
    if self.human.positions is None:
      return np.inf
    r1, r2, rr = self.robot.capsules(self._state[0])
    h1, h2, hr = self.human.body_capsules(self.human.positions)
    return float(geometry.capsule_distance(
        r1[:, None], r2[:, None], rr[:, None], h1[None], h2[None],
        hr[None]).min())

  # -------------------------------------------------------------- snapshots

  def get_state(self):
    """The shield's state as a flat dict of arrays, strings, numbers and
    booleans (no callables), for np.savez / JSON (after .tolist()).
    `set_state` restores it so that continuing gives identical commands.

    Plans are stored by what defines them (`LongTermPlan.get_state`: a
    Ruckig plan's inputs) and rebuilt; caches (the pending candidate plan,
    PFL speed tables, lazy read-outs) are recomputed from the same inputs.
    In mode 'off' the cycle's check runs first (the read-outs are saved).
    """
    self._check_now()
    plan = self._plan.get_state()
    human = self.human.get_state()
    arguments = self._reach_arguments
    state = {
        'robot': self.description.name, 'mode': self.mode,
        'cycle_time': self.cycle_time, 'time': self.time,
        'command': np.array(self._state), 'previous_q': np.array(
            self._previous_q),
        'verified': _path_array(self._verified),
        'has_intended': self._intended is not None,
        'intended': _path_array(self._intended or path_lib.Path()),
        'has_goal': self._goal is not None,
        'goal': (np.zeros(self.dof) if self._goal is None
                 else np.array(self._goal)),
        'goal_pending': self._goal_pending,
        'is_safe': bool(self._is_safe), 'intervened': bool(self.intervened),
        'first_unsafe_interval': int(self._first_unsafe_interval),
        'reach_distance': float(self.reach_distance),
        'has_reach': arguments is not None,
        's_edges': np.array([] if arguments is None else arguments[1]),
        't_edges': np.array([] if arguments is None else arguments[2]),
        'q_edges': (np.zeros((0, self.dof)) if arguments is None
                    else np.array(arguments[3])),
    }
    state.update({f'plan_{k}': v for k, v in plan.items()})
    state.update({f'human_{k}': v for k, v in human.items()})
    return state

  def set_state(self, state):
    """Restores a `get_state` of a shield of the same robot, mode and cycle
    (arrays may be lists, as after JSON; 0-d arrays as after np.load)."""
    def scalar(name):
      return np.asarray(state[name]).item()
    for name, mine in (('robot', self.description.name), ('mode', self.mode),
                       ('cycle_time', self.cycle_time)):
      if scalar(name) != mine:
        raise ValueError(f'shield state {name}: expected {mine!r}, got '
                         f'{scalar(name)!r}')
    command = np.array(state['command'], dtype=float)
    if command.shape != (5, self.dof):
      raise ValueError(f'shield state command: expected shape (5, '
                       f'{self.dof}), got {command.shape}')
    self._plan = ltp.LongTermPlan.from_state(
        {k[5:]: v for k, v in state.items() if k.startswith('plan_')},
        self.limits)
    self.human.set_state(
        {k[6:]: v for k, v in state.items() if k.startswith('human_')})
    self.time = float(scalar('time'))
    self._state = command
    self._previous_q = np.array(state['previous_q'], dtype=float)
    self._verified = _path_from_array(state['verified'])
    self._intended = (_path_from_array(state['intended'])
                      if scalar('has_intended') else None)
    self._goal = (np.array(state['goal'], dtype=float)
                  if scalar('has_goal') else None)
    self._goal_pending = bool(scalar('goal_pending'))
    self._candidate = None
    self._is_safe = bool(scalar('is_safe'))
    self.intervened = bool(scalar('intervened'))
    self._first_unsafe_interval = int(scalar('first_unsafe_interval'))
    self._reach_distance = float(scalar('reach_distance'))
    self._reach_arguments = None
    if scalar('has_reach'):
      self._reach_arguments = (
          self._plan, np.asarray(state['s_edges'], dtype=float).tolist(),
          np.asarray(state['t_edges'], dtype=float).tolist(),
          np.array(state['q_edges'], dtype=float).reshape(-1, self.dof))
    self._pending_check = None
    self._lazy = {}

  # ------------------------------------------------------------------ step

  def step(self, human_keypoints, t):
    """One cycle at time t: returns the command (q, dq, ddq).

    Call once every cycle_time (the command advances the path by one
    cycle); the robot should reach the command within the cycle.
    human_keypoints: (N_kp, 3) positions measured at t, or None if there is
    no new measurement (the last one then ages; with no measurement ever the
    workcell is taken to be empty).
    """
    t = float(t)
    if human_keypoints is not None:
      self.human.measure(human_keypoints, t)
    self.time = t
    self._pending_check = None
    self._previous_q = self._state[0]
    dt = self.cycle_time

    # Replanning: a candidate plan starts at the current command with path
    # velocity 1 (its first sample is the commanded q, dq, ddq). From rest
    # every path velocity matches the command (the plan starts at rest):
    # a candidate that does not verify at 1 may start at 0 and accelerate
    # along the path as a stopped robot resumes its plan, so a robot
    # stopped next to a person can start again (docs/safety.md,
    # "Starting from rest").
    plan, current = self._plan, self._verified
    candidate = self._candidate_plan()
    starts = (None,)
    if candidate is not None:
      plan = candidate
      starts = (1.0, 0.0) if self._at_rest() else (1.0,)
    nominal = None   # The first start's intended step: what was wanted.
    for start in starts:
      self._lazy = {}   # Read-outs are those of this cycle and start.
      if start is not None:
        current = path_lib.Path(self._verified.s, start, 0.0, 0.0)
      intended, failsafe, s_dot_limit = self._monitored(plan, current,
                                                        candidate)
      nominal = intended if start != 0.0 else nominal
      safe = self._check(plan, current, intended, failsafe, s_dot_limit)
      if safe is not False:
        break
    self._is_safe = safe

    follow = failsafe is not None and (safe or not self._gates)
    if follow:
      if candidate is not None:
        self._adopt(candidate)
      self._verified = failsafe
      self._intended = intended
      state = plan.state(intended.s, intended.s_dot, intended.s_ddot,
                         intended.jerk)
      self.intervened = False
    else:
      self._verified = self._verified.copy()
      self._verified.advance(dt)
      self._intended = None
      v = self._verified
      state = self._plan.state(v.s, v.s_dot, v.s_ddot, v.jerk)
      if nominal is None:
        self.intervened = True
      else:
        wanted = plan.state(nominal.s, nominal.s_dot, nominal.s_ddot,
                            nominal.jerk)
        self.intervened = not (
            np.abs(wanted[0] - state[0]).max() <= _SAME_COMMAND and
            np.abs(wanted[1] - state[1]).max() <= _SAME_COMMAND)
    rates = state[1:4]   # np.clip's max-then-min, without its overhead.
    np.minimum(np.maximum(rates, self._clip_low, out=rates), self._clip,
               out=rates)
    self._state = state
    return state[0], state[1], state[2]

  # -------------------------------------------------------------- internals

  def _at_rest(self):
    """Whether the command is at rest (velocity and acceleration zero)."""
    rates = self._state[1:3]
    return bool((np.abs(rates) <= REST_TOLERANCE).all())

  def _monitored(self, plan, current, candidate):
    """The monitored path from `current` on `plan`: (intended step,
    failsafe, PFL final path velocity); None for what does not exist."""
    dt = self.cycle_time
    max_acc, max_jerk = self._path_limits(self._state[4])
    intended = None
    if candidate is None and self._intended is not None and not (
        self._intended.is_finished() and self._intended.s_dot != 1.0):
      intended = self._intended
    if intended is None:
      intended = path_lib.plan_profile(
          current.s, current.s_dot, current.s_ddot, 1.0, max_acc, max_jerk, dt)
    failsafe, s_dot_limit = None, None
    if intended is not None:
      intended = intended.copy()
      intended.advance(dt)
      s_dot_limit = self._s_dot_limit(plan, intended.s)
      failsafe = path_lib.plan_profile(
          intended.s, intended.s_dot, intended.s_ddot,
          0.0 if s_dot_limit is None else s_dot_limit, max_acc, max_jerk, dt)
    return intended, failsafe, s_dot_limit

  def _check(self, plan, current, intended, failsafe, s_dot_limit):
    """Verifies the monitored path: True, False, or None (mode 'off': the
    check runs when a read-out needs it)."""
    if failsafe is None or intended.s < current.s:
      # No monitored path: keep braking on the verified one.
      self._reach_arguments = None
      self._first_unsafe_interval, self._reach_distance = 0, -np.inf
      return False
    if not self._gates:
      # Unshielded: the check only feeds read-outs; run it when one is
      # read (its inputs do not change until the next step).
      self._reach_arguments = None
      self._pending_check = (plan, current, failsafe, s_dot_limit)
      return None
    return self._verify(plan, current, failsafe, s_dot_limit)

  def _path_limits(self, v_nominal):
    """path.path_limits for this robot with precomputed per-joint terms."""
    dens = [abs(v) + c for v, c in zip(v_nominal.tolist(), self._den_offset)]
    acc = min(n / d for n, d in zip(self._acc_numerator, dens))
    acc = acc if acc > 0.0 else 0.0
    jerk = min((n - c * acc) / d for n, c, d in zip(
        self._jerk_numerator, self._jerk_acc, dens))
    return acc, (jerk if jerk > 0.0 else 0.0)

  def _candidate_plan(self):
    """The plan to the pending goal from the current command, or None."""
    if not self._goal_pending:
      return None
    key = (self._verified.s, self._verified.s_dot)
    if self._candidate is not None and self._candidate[1] == key:
      return self._candidate[0]   # The robot has not moved: still valid.
    self._candidate = (self.candidate_from(self._state, *key)
                       if self._can_plan_from(self._state) else None)
    return None if self._candidate is None else self._candidate[0]

  def _can_plan_from(self, state):
    """Whether a plan may start at command `state` (q, dq, ddq rows first):
    not while braking harder than the planning limits
    (docs/shield_maths.md, 1). The compiled cycles make the same test
    (cycle_kernels.ssm_cycles stops for a candidate only where it holds)."""
    return not (np.abs(state[2]) > self.limits.a_max_ltt).any()

  def candidate_from(self, state, s, s_dot, recent=True):
    """(plan to the pending goal from command `state` (q, dq, ddq rows
    first) at verified path position s and velocity s_dot, its key (s,
    s_dot)), or None where none can be made; the caller has found that a
    plan may start there (`_can_plan_from`). recent: as plan_to_goal's
    (False: a command moved since anyone planned from it)."""
    try:
      plan = ltp.plan_to_goal(state[0], state[1], state[2], self._goal,
                              self.limits, self.cycle_time, s, recent=recent)
    except ltp.PlanningError:
      return None
    return plan, (s, s_dot)

  def _adopt(self, plan):
    self._plan = plan
    self._goal_pending = False
    self._candidate = None

  def _plan_speeds(self, plan):
    """PFL tables of a plan's largest capsule surface speed at nominal path
    speed: over the next PFL_WINDOW samples, and from each sample to the
    end (both (N,), m/s)."""
    # Kept on the plan (for this robot): a candidate's tables stay its
    # own when it is adopted, and a plan shared through long_term_plan's
    # cache of recent plans is not tabled twice.
    cached = plan.__dict__.get('_pfl_tables')
    if cached is None or cached[0] is not self.robot:
      robot = self.robot   # pfl_speed_tables(surface_speeds(q, dq)):
      cached = (robot,) + speed_kernels.plan_speed_tables(
          plan._all(), *robot._kernel_model, robot._kernel_frames,
          robot._kernel_radii, PFL_WINDOW)
      plan._pfl_tables = cached
    return cached[1], cached[2]

  def _s_dot_limit(self, plan, s):
    """PFL: the failsafe's final path velocity (None: brake to rest).

    The robot keeps moving at this path velocity after the failsafe, so the
    bound covers the plan's fastest capsule surface from s to its end.
    """
    allowed = self.speed_limit
    if allowed is None:
      return None
    remaining = self._plan_speeds(plan)[1][plan.sample_index(s)]
    return 1.0 if remaining <= allowed else allowed / remaining

  def _slow_enough(self, plan, current, failsafe, times, s_edges, first,
                   pieces):
    """PFL: the robot's surface speed stays below v_safe from slice `first`
    on (and after the failsafe, coasting at its final path velocity).
    pieces: failsafe.segments()."""
    window, suffix = self._plan_speeds(plan)
    allowed = self.speed_limit * (1.0 + _S_DOT_TOLERANCE)
    for i in range(first, len(times)):
      if i == 0:
        s_dot = max(current.s_dot, failsafe.s_dot)
      else:
        s_dot = failsafe.max_s_dot(times[i - 1], times[i], pieces)
      if window[plan.sample_index(s_edges[i])] * s_dot > allowed:
        return False
    return (suffix[plan.sample_index(s_edges[-1])] * failsafe.final()[1]
            <= allowed)

  def _verify(self, plan, current, failsafe, s_dot_limit):
    """Checks the slice current -> intended step, then the failsafe."""
    dt = self.cycle_time
    end = failsafe.end_time()
    count = max(math.ceil(end / self.interval - 1e-9), 1)
    times = [i * self.interval for i in range(count)] + [end]
    pieces = failsafe.segments()
    s = failsafe.sample(times, pieces)[0]
    s_edges = [current.s] + s
    t_edges = [0.0] + [x + dt for x in times]
    q_edges = np.empty((count + 2, self.dof))
    q_edges[0] = self._previous_q
    plan.positions(s, out=q_edges, first=1)
    self._reach_arguments = (plan, s_edges, t_edges, q_edges)
    end_q = q_edges[-1].tolist()
    if not all(low <= q <= high for low, q, high in zip(
        self._q_min, end_q, self._q_max)):
      self._first_unsafe_interval, self._reach_distance = count, -np.inf
      return False
    human = self.human
    if human.positions is None:
      self._first_unsafe_interval, self._reach_distance = -1, np.inf
      return True
    # Broad phase 1: the human's horizon balls against the robot's whole
    # workspace ball (no kinematics needed).
    age = (self.time - human.last_measurement_time + self._human_delay
           + t_edges[-1])
    centre, radius, gap = kernels.horizon_balls(
        human.positions, human.velocities, self._human_v_max,
        self._body_ends, self._half_thickness, age, self._human_error_pos,
        self._base)
    bound = gap - self._workspace_radius
    if bound > 0.0:
      self._first_unsafe_interval, self._reach_distance = -1, bound
      return True
    # Broad phase 2, bounded from the robot's capsules at q_edges[0] alone
    # (one forward kinematics instead of one per edge; a lower bound of
    # the test below, so it settles only cycles that test settles).
    model = self.robot
    fixed, points = model._kernel_model
    bound = kernels.swept_balls_gap(
        q_edges, np.asarray(s_edges, dtype=float),
        kernels._frames(q_edges[:1], fixed)[0], points,
        model._kernel_frames, model._kernel_alpha, model._kernel_static,
        model._kernel_levers, model._kernel_half_lengths, centre, radius,
        _BROAD_PHASE_SLACK) - _BROAD_PHASE_SLACK
    if bound > 0.0:
      self._first_unsafe_interval, self._reach_distance = -1, bound
      return True
    robot = self.robot_reach_capsules
    # Broad phase 2: the same balls against every robot reach capsule.
    bound = kernels.balls_capsules_distance(centre, radius,
                                            *robot) - _BROAD_PHASE_SLACK
    if bound > 0.0:
      self._first_unsafe_interval, self._reach_distance = -1, bound
      return True
    human = self.human_reach_capsules
    first = kernels.ssm_first_unsafe(
        *robot, *(np.ascontiguousarray(x) for x in human))
    self._first_unsafe_interval, self._reach_distance = first, None
    if first < 0 or s_dot_limit is None:
      return first < 0
    # PFL: contact is possible from slice `first` on; from then on the
    # robot must be slower than v_safe.
    return self._slow_enough(plan, current, failsafe, times, s_edges, first,
                             pieces)

  def _human_horizon_balls(self, horizon):
    """NumPy reference of the first broad phase's balls (the shield runs
    kernels.horizon_balls): one ball per human body containing its
    maximal-velocity (VEL) reachable set over the whole horizon (s after
    this cycle's time):
    the measured body capsule grown by max(v_max, measured speed) of its
    faster end times the measurement's age plus horizon and delay, plus the
    position error. Returns centres (B, 3) and radii (B,)."""
    human, config = self.human, self.human.config
    p1, p2, radius = human.body_capsules(human.positions)
    speeds = np.sqrt(np.einsum('ni,ni->n', human.velocities,
                               human.velocities))
    np.maximum(speeds, config.v_max, out=speeds)
    ends = speeds[self._body_ends]
    age = self.time - human.last_measurement_time + config.delay + horizon
    half = p2 - p1
    grow = (np.maximum(ends[0], ends[1]) * age + radius
            + config.measurement_error_pos)
    grow += 0.5 * np.sqrt(np.einsum('bi,bi->b', half, half))
    return 0.5 * (p1 + p2), grow


def _path_array(path):
  """A `path.Path` as 10 floats: s, s_dot, s_ddot, jerk, phase ends and
  phase jerks."""
  return np.array([path.s, path.s_dot, path.s_ddot, path.jerk]
                  + list(path.phase_ends) + list(path.phase_jerks))


def _path_from_array(values):
  """The `path.Path` of `_path_array` (attributes set as stored)."""
  values = np.asarray(values, dtype=float).ravel().tolist()
  if len(values) != 10:
    raise ValueError(f'path state: expected 10 numbers, got {len(values)}')
  path = path_lib.Path.__new__(path_lib.Path)
  path.s, path.s_dot, path.s_ddot, path.jerk = values[:4]
  path.phase_ends = values[4:7]
  path.phase_jerks = values[7:]
  return path


def pfl_speed_tables(speeds, compiled=True):
  """PFL tables from a plan's capsule surface speeds (N, L) at nominal
  path speed: the largest over the next PFL_WINDOW samples (the last held
  past the end), and from each sample to the end (both (N,)).
  compiled=False runs the NumPy reference."""
  if compiled:
    return kernels.speed_tables(np.ascontiguousarray(speeds, dtype=float),
                                PFL_WINDOW)
  speeds = speeds.max(axis=1)
  padded = np.concatenate([speeds, np.full(PFL_WINDOW, speeds[-1])])
  window = np.lib.stride_tricks.sliding_window_view(
      padded, PFL_WINDOW + 1).max(axis=1)[:len(speeds)]
  suffix = np.maximum.accumulate(speeds[::-1])[::-1]
  return window, suffix


def balls_capsules_distance_reference(centre, radius, capsules):
  """Lower bound of the distance between balls (B,) and capsules (K, L):
  each capsule is bounded by the ball around its midpoint. NumPy reference
  of the second broad phase (the shield runs
  kernels.balls_capsules_distance): centre distances from one matrix
  product (|a|^2 + |b|^2 - 2 a.b); the round-off of either form is far
  below _BROAD_PHASE_SLACK, which is subtracted."""
  c1, c2, r = capsules
  middle = (0.5 * (c1 + c2)).reshape(-1, 3)
  half = (c2 - c1).reshape(-1, 3)
  reach = 0.5 * np.sqrt(np.einsum('ni,ni->n', half, half)) + r.reshape(-1)
  squared = (np.einsum('ni,ni->n', middle, middle)[:, None]
             + np.einsum('bi,bi->b', centre, centre)
             - 2.0 * (middle @ centre.T))
  np.maximum(squared, 0.0, out=squared)
  return float((np.sqrt(squared) - reach[:, None] - radius).min()
               - _BROAD_PHASE_SLACK)
