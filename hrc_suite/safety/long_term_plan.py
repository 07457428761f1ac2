"""The long-term plan: a jerk-limited joint trajectory to rest at a goal.

A `LongTermPlan` stores joint samples (q, dq, ddq, dddq) one cycle apart,
starting at plan time `start_time`. The shield moves along it with a path
parameter s (plan time) and path velocity s_dot (docs/shield_maths.md, 2):
the plan is evaluated by a Taylor expansion from the sample at or before s
and the chain rule. The sample index is floor((s - start_time) / cycle_time): the
plan's own start is subtracted exactly once (the original subtracted its
starting index twice after the first re-planning, so every look-ahead
collapsed onto the current sample: defect B1, docs/shield_maths.md, 10).

`plan_to_goal` computes the time-optimal, jerk-limited, synchronised motion
from the current joint state to rest at a goal with Ruckig, using the
long-term-planning limits (a_max_ltt, j_max_ltt, v_max; docs/shield_maths.md,
1), and samples it exactly (piecewise constant jerk) every cycle.
"""

import collections
import math

import numpy as np
import ruckig

from hrc_suite.safety import kernels
from hrc_suite.safety import plan_kernels

# Goals are kept this far inside the joint limits (rad; docs/shield_maths.md,
# 1: the original's planning tolerance).
GOAL_LIMIT_MARGIN = 0.01
# Plan samples computed at once when more are needed (~0.26 s at 4 ms: a
# failsafe's horizon).
_SAMPLE_CHUNK = 64
# Slack for float round-off when checking the start state against limits.
_LIMIT_SLACK = 1e-9


class PlanningError(ValueError):
  """No plan can be made from this state to this goal."""


class LongTermPlan:
  """Joint samples every `cycle_time` seconds from plan time `start_time`."""

  def __init__(self, q, dq, ddq, dddq, cycle_time, start_time=0.0):
    arrays = [np.array(x, dtype=float) for x in (q, dq, ddq, dddq)]
    shape = arrays[0].shape
    if len(shape) != 2 or shape[0] < 1:
      raise ValueError('Plan samples must have shape (num_samples >= 1, dof), '
                       f'got q of shape {shape}')
    for name, array in zip(('dq', 'ddq', 'dddq'), arrays[1:]):
      if array.shape != shape:
        raise ValueError(f'Plan {name} has shape {array.shape}, expected '
                         f'{shape} like q')
    if not all(np.all(np.isfinite(a)) for a in arrays):
      raise ValueError('Plan samples must be finite')
    if not cycle_time > 0:
      raise ValueError(f'cycle_time must be positive, got {cycle_time}')
    # (num_samples, 4, dof): q and its derivatives, for one gather per query.
    coefficients = np.stack(arrays, axis=1)
    coefficients.flags.writeable = False
    self._init(coefficients, shape[0], cycle_time, start_time, None)

  def _init(self, coefficients, filled, cycle_time, start_time, sampler,
            made_by=None):
    self._coefficients = coefficients
    self._filled = filled          # Samples [0, filled) are computed.
    self._sampler = sampler        # Computes samples [a, b) on demand.
    self.cycle_time = float(cycle_time)
    self.start_time = float(start_time)
    self._inverse_cycle = 1.0 / self.cycle_time
    self._last = coefficients.shape[0] - 1
    # plan_to_goal's (pieces (the sampler's arguments), goal (dof,), inputs
    # (q0, dq0, ddq0, goal) (4, dof), limits), or None.
    made_by = made_by or (None, None, None, None)
    self._pieces, self._goal, self._inputs, self._limits = made_by
    self._derived = {}   # name -> (owner, value): `derived`.

  @classmethod
  def _lazy(cls, num_samples, dof, sampler, cycle_time, start_time,
            made_by=None):
    """A plan whose `sampler(a, b, out)` computes samples a..b - 1 into
    out[a:b] (its samples (num_samples, 4, dof)) when first needed (most
    of a plan is replaced before it is used); made_by: `_init`'s."""
    plan = cls.__new__(cls)
    plan._init(np.empty((num_samples, 4, dof)), 0, cycle_time, start_time,
               sampler, made_by)
    return plan

  def _fill(self, k):
    """Computes the samples up to index k (and a chunk beyond)."""
    stop = min(max(k + 1, self._filled + _SAMPLE_CHUNK), self._last + 1)
    self._sampler(self._filled, stop, self._coefficients)
    self._filled = stop

  def _all(self):
    if self._filled <= self._last:
      self._fill(self._last)
    return self._coefficients

  @property
  def filled(self):
    """How many samples, from the first, are computed."""
    return self._filled

  @property
  def fully_sampled(self):
    """Whether every sample is computed."""
    return self._filled > self._last

  def samples(self):
    """All samples (num_samples, 4, dof): q, dq, ddq, dddq (computed now
    where not yet; read-only once complete for plans made from samples)."""
    return self._all()

  def samples_through(self, k):
    """The samples array (num_samples, 4, dof) with at least samples
    0..k computed (k clamped to the last); later rows may not be."""
    if k >= self._filled and self._filled <= self._last:
      self._fill(min(k, self._last))
    return self._coefficients

  def derived(self, name, owner, compute):
    """A value derived from this plan for `owner` (compared by identity):
    compute() the first time, then the kept value (one per name; a plan
    kept in long_term_plan's recent plans may serve several shields)."""
    kept = self._derived.get(name)
    if kept is None or kept[0] is not owner:
      kept = (owner, compute())
      self._derived[name] = kept
    return kept[1]

  @property
  def q(self):
    """Joint positions of all samples (num_samples, dof), read-only view."""
    view = self._all()[:, 0]
    view.flags.writeable = False
    return view

  @property
  def dq(self):
    view = self._all()[:, 1]
    view.flags.writeable = False
    return view

  @property
  def ddq(self):
    view = self._all()[:, 2]
    view.flags.writeable = False
    return view

  @property
  def dddq(self):
    view = self._all()[:, 3]
    view.flags.writeable = False
    return view

  def get_state(self):
    """What defines the plan, as arrays and scalars (no callables): a
    `plan_to_goal` plan's inputs (q0, dq0, ddq0, goal) (4, dof), or the
    samples (N, 4, dof) of a plan made from samples. `from_state` rebuilds
    it bit for bit (Ruckig is deterministic)."""
    dof = self._coefficients.shape[2]
    ruckig_plan = self._inputs is not None
    return {
        'kind': 'ruckig' if ruckig_plan else 'samples',
        'inputs': (self._inputs.copy() if ruckig_plan
                   else np.zeros((4, dof))),
        'samples': (np.zeros((0, 4, dof)) if ruckig_plan
                    else np.array(self._coefficients)),
        'cycle_time': self.cycle_time,
        'start_time': self.start_time,
    }

  @classmethod
  def from_state(cls, state, limits):
    """The plan of `get_state` (arrays may be lists, as after JSON);
    limits: the `JointLimits` a Ruckig plan was made with."""
    kind = str(np.asarray(state['kind']))
    cycle_time = float(state['cycle_time'])
    start_time = float(state['start_time'])
    if kind == 'ruckig':
      q0, dq0, ddq0, goal = np.asarray(state['inputs'], dtype=float)
      return plan_to_goal(q0, dq0, ddq0, goal, limits, cycle_time, start_time)
    if kind == 'samples':
      samples = np.asarray(state['samples'], dtype=float)
      if samples.ndim != 3 or samples.shape[1] != 4:
        raise ValueError('plan samples: expected shape (N, 4, dof), got '
                         f'{samples.shape}')
      return cls(samples[:, 0], samples[:, 1], samples[:, 2], samples[:, 3],
                 cycle_time, start_time)
    raise ValueError(f"plan kind: expected 'ruckig' or 'samples', got "
                     f'{kind!r}')

  @classmethod
  def at_rest(cls, q, cycle_time, start_time=0.0):
    """A one-sample plan: stand still at q."""
    q = np.asarray(q, dtype=float)[None]
    zeros = np.zeros_like(q)
    return cls(q, zeros, zeros, zeros, cycle_time, start_time)

  @property
  def num_samples(self):
    return self._last + 1

  @property
  def dof(self):
    return self.q.shape[1]

  def made_from(self, state, goal, limits, cycle_time, start_time):
    """Whether this is `plan_to_goal`'s plan from state (rows q0, dq0,
    ddq0 first; C-contiguous float64), to the clamped goal (dof,) with
    limits (the same object), cycle_time and start_time: the same inputs
    bit for bit, so the same plan (Ruckig is deterministic)."""
    inputs = self._inputs
    return (inputs is not None and self._limits is limits
            and self.cycle_time == cycle_time
            and self.start_time == start_time
            and inputs[:3].tobytes() == state[:3].tobytes()
            and inputs[3].tobytes() == goal.tobytes())

  @property
  def end_time(self):
    """Plan time of the last sample (the goal, at rest)."""
    return self.start_time + self._last * self.cycle_time

  @property
  def goal(self):
    if self._sampler is not None:
      return self._goal
    return self._coefficients[-1, 0]

  def index(self, s):
    """Sample index at or before plan time s (array or scalar), clamped."""
    k = np.floor((np.asarray(s, dtype=float) - self.start_time)
                 * self._inverse_cycle)
    return np.clip(k, 0, self._last).astype(int)

  def sample_index(self, s):
    """index(s) for one plan time s (Python float arithmetic)."""
    k = int((s - self.start_time) * self._inverse_cycle // 1.0)
    return 0 if k < 0 else (self._last if k > self._last else k)

  def nominal(self, s):
    """Joint state at nominal speed at plan times s (K,).

    Returns (q, v, a, j), each (K, dof): position and its first three
    derivatives with respect to plan time, by Taylor expansion from the
    sample at or before s. Past the end the last sample (at rest) is held.
    """
    s = np.atleast_1d(np.asarray(s, dtype=float))
    k = self.index(s)
    if k.max() >= self._filled:
      self._fill(int(k.max()))
    tau = (s - self.start_time - k * self.cycle_time)[:, None]
    c = self._coefficients[k]
    j = c[:, 3]
    a = c[:, 2] + tau * j
    v = c[:, 1] + tau * (c[:, 2] + 0.5 * tau * j)
    q = c[:, 0] + tau * (c[:, 1] + tau * (0.5 * c[:, 2] + tau * j / 6.0))
    return q, v, a, j

  def positions(self, s, out=None, first=0):
    """Joint positions (K, dof) at plan times s (K values); the fast path
    for the few edges of a failsafe (a compiled kernel). With `out`, they
    are written to out[first:first + K] (C-contiguous float64) instead."""
    s = np.ascontiguousarray(s, dtype=float)
    if out is None:
      out = np.empty((s.shape[0], self._coefficients.shape[2]))
      first = 0
    if s.shape[0]:
      top = int((float(s.max()) - self.start_time) * self._inverse_cycle
                // 1.0)
      top = 0 if top < 0 else (self._last if top > self._last else top)
      if top >= self._filled:
        self._fill(top)
      kernels.plan_positions(self._coefficients, self.start_time,
                             self._inverse_cycle, self.cycle_time, s, out,
                             first)
    return out[first:first + s.shape[0]]

  def state(self, s, s_dot=1.0, s_ddot=0.0, jerk=0.0):
    """One path state (scalars) -> (5, dof): q, dq, ddq, dddq, v_nominal
    (computed by a compiled kernel that the compiled shield cycles share:
    plan_kernels.plan_state; its NumPy reference is in
    tests/safety/safety_references.py)."""
    k = int((s - self.start_time) * self._inverse_cycle // 1.0)
    k = 0 if k < 0 else (self._last if k > self._last else k)
    if k >= self._filled:
      self._fill(k)
    return plan_kernels.plan_state(
        self._coefficients, self.start_time, self._inverse_cycle,
        self.cycle_time, float(s), float(s_dot), float(s_ddot), float(jerk),
        np.empty((5, self._coefficients.shape[2])))

  def evaluate(self, s, s_dot=1.0, s_ddot=0.0, jerk=0.0):
    """Joint (q, dq, ddq, dddq) on the path state (s, s_dot, s_ddot, jerk).

    Scalars give (dof,) arrays; (K,) arrays give (K, dof) arrays.
    """
    if np.ndim(s) == 0:
      out = self.state(float(s), float(s_dot), float(s_ddot), float(jerk))
      return out[0], out[1], out[2], out[3]
    q, v, a, j = self.nominal(s)
    s_dot, s_ddot, jerk = (np.asarray(x, dtype=float)[:, None]
                           for x in (s_dot, s_ddot, jerk))
    dq = v * s_dot
    ddq = v * s_ddot + a * (s_dot * s_dot)
    dddq = j * (s_dot * s_dot * s_dot) + 3.0 * a * (s_ddot * s_dot) + v * jerk
    return q, dq, ddq, dddq


def _check_vector(name, value, dof):
  array = np.asarray(value, dtype=float)
  if array.shape != (dof,):
    raise ValueError(f'{name} must have shape ({dof},), got {array.shape}')
  if not np.isfinite(array).all():
    raise ValueError(f'{name} must be finite, got {array.tolist()}')
  return array


def clamp_goal(q_goal, limits):
  """The goal moved GOAL_LIMIT_MARGIN inside the joint limits
  (docs/shield_maths.md, 1)."""
  dof = len(limits.q_min)
  if _is_float_vector(q_goal) and q_goal.shape[0] == dof:   # Compiled.
    goal = np.empty(dof)
    if plan_kernels.clamped_goal(q_goal, limits.q_min, limits.q_max,
                                 GOAL_LIMIT_MARGIN, goal):
      return goal
  q_goal = _check_vector('q_goal', q_goal, dof)
  # np.clip's values, cheaper.
  return np.minimum(np.maximum(q_goal, limits.q_min + GOAL_LIMIT_MARGIN),
                    limits.q_max - GOAL_LIMIT_MARGIN)


def check_start_state(q0, dq0, ddq0, limits):
  """Raises PlanningError if the plan cannot start here
  (docs/shield_maths.md, 1)."""
  v_max, a_max, j_max = limits.v_max, limits.a_max_ltt, limits.j_max_ltt
  if plan_kernels.start_state_ok(q0, dq0, ddq0, limits.q_min, limits.q_max,
                                 v_max, a_max, j_max, _LIMIT_SLACK):
    return
  ramped = np.abs(dq0 + ddq0 * np.abs(ddq0) / (2.0 * j_max))
  checks = (
      ('q0 below q_min', q0 < limits.q_min - _LIMIT_SLACK),
      ('q0 above q_max', q0 > limits.q_max + _LIMIT_SLACK),
      ('|dq0| above v_max', np.abs(dq0) > v_max + _LIMIT_SLACK),
      ('|ddq0| above a_max_ltt', np.abs(ddq0) > a_max + _LIMIT_SLACK),
      ('velocity after ramping ddq0 to zero above v_max',
       ramped > v_max + _LIMIT_SLACK),
  )
  for what, bad in checks:
    if np.any(bad):
      joints = np.nonzero(bad)[0].tolist()
      raise PlanningError(f'Cannot plan from this state: {what} for joints '
                          f'{joints} (q0={q0.tolist()}, dq0={dq0.tolist()}, '
                          f'ddq0={ddq0.tolist()})')


class _Solver:
  """One reusable Ruckig instance per number of joints (creating one costs
  more than a whole calculation)."""

  _by_dof = {}
  # dof -> (the limits last written into its request, their joint ranges
  # with _LIMIT_SLACK as lists: the check of Ruckig's position extrema).
  _limits = {}

  @classmethod
  def get(cls, dof, limits):
    """(Ruckig, its request with `limits` and rest at the target, a
    trajectory, lowest and highest admissible positions (lists)) for dof
    joints."""
    if dof not in cls._by_dof:
      request = ruckig.InputParameter(dof)
      request.target_velocity = [0.0] * dof
      request.target_acceleration = [0.0] * dof
      cls._by_dof[dof] = (ruckig.Ruckig(dof), request, ruckig.Trajectory(dof))
    solver = cls._by_dof[dof]
    last = cls._limits.get(dof)
    if last is None or last[0] is not limits:   # Read-only: by identity.
      request = solver[1]
      request.max_velocity = limits.v_max.tolist()
      request.max_acceleration = limits.a_max_ltt.tolist()
      request.max_jerk = limits.j_max_ltt.tolist()
      last = (limits, (limits.q_min - _LIMIT_SLACK).tolist(),
              (limits.q_max + _LIMIT_SLACK).tolist())
      cls._limits[dof] = last
    return solver + last[1:]


# No brake pre-profile (plan_kernels.piece_table).
_NO_BRAKES = np.zeros((0, 5, 2))

# Ruckig >= 0.13 raises RuckigError (an Exception, not a RuntimeError).
_RUCKIG_ERRORS = (RuntimeError, getattr(ruckig, 'RuckigError', RuntimeError))
# Ruckig's results of a calculation that made a trajectory (a set: a
# tuple's `in` compares Python enums by their slow __eq__).
_PLANNED = frozenset((ruckig.Result.Working, ruckig.Result.Finished))


class _RecentPlans:
  """The last few plans by their inputs: a goal's plan from the shield's
  command is made more than once where the goal is checked before it is
  given (an expert's `CollisionPrevention.planned_paths_free`, then the
  task's collision prevention); Ruckig is deterministic, so a plan from
  the same inputs is the same plan (plans are read-only once sampled).
  The shield itself is handed collision prevention's plan
  (`Shield.new_goal`)."""

  SIZE = 32

  def __init__(self):
    self._plans = collections.OrderedDict()
    self._limits = (None, b'')   # The last limits and their bytes.

  def key(self, arrays, limits, cycle_time, start_time):
    """The plan's inputs as one hashable value. The limits' bytes are
    kept for the last limits object (JointLimits' arrays are read-only)."""
    if self._limits[0] is not limits:
      self._limits = (limits, b''.join(
          np.ascontiguousarray(a, dtype=float).tobytes() for a in (
              limits.v_max, limits.a_max_ltt, limits.j_max_ltt,
              limits.q_min, limits.q_max)))
    return (np.concatenate(arrays).tobytes() + self._limits[1],
            float(cycle_time), float(start_time))

  def get(self, key):
    plan = self._plans.get(key)
    if plan is not None:
      self._plans.move_to_end(key)
    return plan

  def put(self, key, plan):
    self._plans[key] = plan
    if len(self._plans) > self.SIZE:
      self._plans.popitem(last=False)


_RECENT = _RecentPlans()


_FLOAT64 = np.dtype(np.float64)
_UNIT_STRIDE = (_FLOAT64.itemsize,)


def _is_float_vector(x):
  """Whether x is a contiguous float64 vector (the kernels' argument
  type; anything else is converted first)."""
  return (type(x) is np.ndarray and x.dtype is _FLOAT64
          and x.strides == _UNIT_STRIDE)


def plan_to_goal(q0, dq0, ddq0, q_goal, limits, cycle_time, start_time=0.0,
                 recent=True):
  """Time-optimal jerk-limited synchronised plan to rest at q_goal.

  Args:
    q0, dq0, ddq0: the current joint state (dof,).
    q_goal: the goal; clamped GOAL_LIMIT_MARGIN inside the joint limits.
    limits: `robot_description.JointLimits` (v_max, a_max_ltt, j_max_ltt).
    cycle_time: sample spacing (s).
    start_time: plan time of the first sample (the current state).
    recent: look the plan up among the last plans made and keep it there
      (a goal checked before it is given is planned again by collision
      prevention); False for a state nobody planned from before (the
      shield's re-plans from a braking command), which only skips the
      look-up (Ruckig is deterministic: the same plan either way).

  Returns:
    A `LongTermPlan` whose first sample is the current state and whose last
    is the goal at rest.

  Raises:
    PlanningError: the start state violates the checks of docs/shield_maths.md,
      1, or the motion would leave the joint limits on the way.
  """
  dof = len(limits.q_min)
  inputs = (q0, dq0, ddq0, q_goal)
  if not all(_is_float_vector(x) for x in inputs):
    inputs = [np.ascontiguousarray(x, dtype=float) for x in inputs]
  goal = np.empty(dof)
  if (inputs[0].shape == inputs[1].shape == inputs[2].shape
      == inputs[3].shape == (dof,)) and plan_kernels.plan_inputs_ok(
          *inputs, limits.q_min, limits.q_max, limits.v_max,
          limits.a_max_ltt, limits.j_max_ltt, _LIMIT_SLACK,
          GOAL_LIMIT_MARGIN, goal):
    q0, dq0, ddq0 = inputs[:3]
  else:   # The checks one by one, raising the first failure's error.
    q0 = _check_vector('q0', q0, dof)
    dq0 = _check_vector('dq0', dq0, dof)
    ddq0 = _check_vector('ddq0', ddq0, dof)
    goal = clamp_goal(q_goal, limits)
    check_start_state(q0, dq0, ddq0, limits)
  if not cycle_time > 0:
    raise ValueError(f'cycle_time must be positive, got {cycle_time}')
  if not recent:
    return _ruckig_plan(q0, dq0, ddq0, goal, limits, cycle_time, start_time)
  key = _RECENT.key((q0, dq0, ddq0, goal), limits, cycle_time, start_time)
  plan = _RECENT.get(key)
  if plan is None:
    plan = _ruckig_plan(q0, dq0, ddq0, goal, limits, cycle_time, start_time)
    _RECENT.put(key, plan)
  return plan


def _ruckig_plan(q0, dq0, ddq0, goal, limits, cycle_time, start_time):
  """plan_to_goal's plan, computed (arguments checked, goal clamped)."""
  dof = len(limits.q_min)

  otg, request, trajectory, low, high = _Solver.get(dof, limits)
  request.current_position = q0.tolist()
  request.current_velocity = dq0.tolist()
  request.current_acceleration = ddq0.tolist()
  request.target_position = goal.tolist()
  try:
    result = otg.calculate(request, trajectory)
  except _RUCKIG_ERRORS as e:
    # Invalid input, and (rarely) valid input where Ruckig's time
    # synchronisation fails numerically ("error in step 2 ... for t sync").
    raise PlanningError(f'Ruckig failed: {e}') from None
  if result not in _PLANNED:
    raise PlanningError(f'Ruckig failed with {result}')

  # Pieces of constant jerk of all joints, (dof * P, 5) rows, padded to P
  # per joint with pieces that start after the end. Shifting joint i's
  # times by i * span makes one sorted array for one searchsorted.
  numbers = []
  brakes = _NO_BRAKES
  for i, profile in enumerate(trajectory.profiles[0]):
    if profile.accel.duration > 0.0:
      raise PlanningError('Ruckig returned a pre-acceleration phase; the '
                          'start state is outside the planning limits')
    # Each attribute access converts a whole C++ array: read them once.
    numbers += profile.t
    numbers += profile.p
    numbers += profile.v
    numbers += profile.a
    numbers += profile.j
    brake = profile.brake
    if brake.duration > 0.0:
      if not brakes.shape[0]:
        brakes = np.zeros((dof, 5, 2))
      brakes[i] = (brake.t, brake.p, brake.v, brake.a, brake.j)
  if len(numbers) != dof * plan_kernels.PROFILE_SIZE:
    raise RuntimeError(f'Ruckig profiles: expected {plan_kernels.PROFILE_SIZE}'
                       f' numbers per joint, got {len(numbers) / dof}')
  duration = trajectory.duration
  table, starts, joint_shift = plan_kernels.piece_table(
      np.fromiter(numbers, float, len(numbers)).reshape(dof, -1), brakes,
      duration)
  num = math.ceil(duration / cycle_time - 1e-9) + 1
  # Whole-motion joint extremes (exact, from Ruckig) for the limit check.
  outside = [i for i, e in enumerate(trajectory.position_extrema)
             if e.min < low[i] or e.max > high[i]]
  if outside:
    raise PlanningError(f'The motion to {goal.tolist()} would leave the joint '
                        f'limits on joints {outside}')

  pieces = (table, starts, joint_shift, goal, float(cycle_time),
            float(duration))

  def sampler(first, stop, out):
    plan_kernels.sample_pieces(*pieces, first, stop, out)

  return LongTermPlan._lazy(
      num, dof, sampler, cycle_time, start_time,
      made_by=(pieces, goal, np.array((q0, dq0, ddq0, goal)), limits))
