"""An RL step's physics steps in one compiled call (the fast path).

On the fast path the task runs the L physics steps of an RL step itself
(tasks/runtime/substeps.py). Where nothing in a physics step needs
Python, `CompiledSteps.run` runs a stretch of them in one numba call:
per step the person's mocap rows (HumanPlayback's precomputed arrays),
the shield's precomputed set-point, the controller's torque
(control/controller_kernels.py around mj_mulM), MuJoCo's mj_step2 and
mj_step1 (dm_control's legacy step; libmujoco's own functions, called
by name from compiled code), dm_control's warning check, then the task's
after_substep: the tracking bound (over the tolerance, the exact
distance, TrackingBounds.error's kernel) and the contacts' classification,
robot-human contacts judged by the commanded speed at the contact point
(mj_jac, as tasks/runtime/contacts.py). The arithmetic is the Python loop's,
operation for operation, so both give the same states bit for bit
(tests/tasks/test_fast_path.py). `run` takes its arguments in named
groups (MuJoCo's pointers, the person's mocap rows, the shield's
set-points, the controller's memory and gains, the tracking check, the
contacts' layout and tables, the step record, the task's writes and
hold), which `CompiledSteps` builds once per physics.

The call stops and hands back to Python, which runs the rest exactly as
before, at a step that needs it:

* the person changes clip (the capsules are resized in the model);
* the robot's capsules are farther than the shield's tolerance from
  where the shield put them (a push: rewind and resync, and contacts
  judged at the commanded pose, are Python's);
* a physics step that raised a MuJoCo warning (the task raises
  dm_control's PhysicsError, as the Python loop does);
* a robot-human contact where the contact monitor measures contact
  energies (`ContactTables.human_in_python`; tasks/runtime/contact_energies.py:
  the energy model and the clamping are Python's).

A task that works before every physics step (`_before_physics_step`)
may hand the call what it writes there, computed for the RL step's
physics steps at its start (`SteppedTask._physics_step_writes`,
tasks/runtime/stepped_task.py: the carried plank's pose, the presenting
grip); where it cannot, an entity or an extra substep hook is active, or
the model is not stepped the legacy way, the Python loop runs
(ShieldedStepper.run_physics_steps, tasks/runtime/shielded_stepping.py).
MuJoCo errors (mju_error, e.g. an exhausted arena) cannot pass through
compiled frames as exceptions, so the call also needs the arena's high
water mark below `ARENA_HEADROOM` of its size; above it the Python loop,
whose MuJoCo errors are Python exceptions, takes over.

The number of contacts and their geom pairs are read from MjData's
memory (`ContactMemory`): where they lie follows from the bindings' own
views and mjData's field order (mujoco.introspect), and is checked
against the bindings' views of every MjData bound; where it cannot be
checked (or libmujoco is not found for compiled calls), the Python loop
runs. The mj_* functions are libmujoco's own, the copy the bindings use.
"""

import ctypes
import functools
import os
import typing

from llvmlite import binding as llvm
import mujoco
import numba
from numba.core import types
import numpy as np

from hrc_suite.control import controller_kernels
from hrc_suite.safety import kernels
from hrc_suite.tasks.runtime import contact_kernels
from hrc_suite.tasks.runtime import contacts
from hrc_suite.tasks.runtime import tool_hold_kernels

_jit = numba.njit(cache=True, fastmath=False)

# What `run` reports (with the step it stopped at).
DONE = 0              # every step of the stretch ran
PYTHON_AFTER = 1      # step k's physics ran; its after_substep is Python's
PHYSICS_WARNING = 2   # step k's physics raised a MuJoCo warning counter
# The arena's high-water mark, as a share of its size, up to which the
# compiled call runs (module doc: MuJoCo errors need the Python loop).
ARENA_HEADROOM = 0.5
_ALLOWED = int(contacts.ContactType.human_allowed)
_CRITICAL = int(contacts.ContactType.human_critical)
# Two spheres resting on a plane and touching each other: three contacts,
# to locate mjContact's fields (_contact_fields).
_PROBE_XML = """
<mujoco>
  <worldbody>
    <geom type="plane" size="1 1 0.1"/>
    <body pos="0 0 0.09"><freejoint/><geom type="sphere" size="0.1"/></body>
    <body pos="0.19 0 0.09"><freejoint/><geom type="sphere" size="0.1"/>
    </body>
  </worldbody>
</mujoco>
"""


def _load_library():
  """Makes libmujoco's symbols (the copy the bindings loaded, in the
  mujoco package's folder) known to numba's linker, so compiled code
  calls them by name and caches; False where it is not found."""
  folder = os.path.dirname(mujoco.__file__)
  names = [name for name in os.listdir(folder)
           if name.startswith(('libmujoco', 'mujoco.dll'))]
  for name in names:
    try:
      llvm.load_library_permanently(os.path.join(folder, name))
      return True
    except RuntimeError:
      continue
  return False


_LIBRARY = _load_library()
# MuJoCo's functions with pointers as integers (same registers on the
# platforms MuJoCo's wheels support).
_STEP1 = types.ExternalFunction('mj_step1', types.void(types.uint64,
                                                       types.uint64))
_STEP2 = types.ExternalFunction('mj_step2', types.void(types.uint64,
                                                       types.uint64))
_MUL_M = types.ExternalFunction('mj_mulM', types.void(*[types.uint64] * 4))
_JAC = types.ExternalFunction('mj_jac', types.void(*[types.uint64] * 5,
                                                   types.int32))


def _address(array):
  return int(np.asarray(array).__array_interface__['data'][0])


def _view(ctype, address, count):
  """A NumPy view of `count` values of `ctype` at a raw address."""
  return np.ctypeslib.as_array((ctype * count).from_address(address))


@functools.lru_cache(maxsize=None)
def _pointer_names():
  """mjData's pointer fields from qpos to contact (mujoco.introspect)."""
  from mujoco.introspect import structs   # pylint: disable=g-import-not-at-top
  names = [field.name for field in structs.STRUCTS['mjData'].fields]
  return names[names.index('qpos'):names.index('contact') + 1]


class ContactMemory:
  """Where an MjData keeps ncon and its contacts' geom pairs, as NumPy
  views of its memory: found from the bindings' `timer` and `energy`
  views and mjData's field order (mujoco.introspect: ... timer, ncon, ne,
  nf, nl, nefc, ...; ... energy, buffer, arena, qpos, ..., contact), and
  checked against the bindings' own views."""

  def __init__(self, model, data):
    """Raises ValueError where the layout does not check out."""
    if not _LIBRARY:
      raise ValueError("MuJoCo's library was not found for compiled calls")
    names = _pointer_names()
    counts, pointers = _counts(data), _pointers(data)
    if counts[0] != data.ncon or counts[4] != data.nefc:
      raise ValueError('ncon and nefc are not where expected in mjData')
    checked = 0
    for name, value in zip(names[:-1], pointers[2:]):
      view = getattr(data, name, None)
      if isinstance(view, np.ndarray) and view.size:
        if value != _address(view):
          raise ValueError(f'mjData.{name} is not where expected')
        checked += 1
    if checked < 10:
      raise ValueError("too few of mjData's pointers could be checked")
    self.arena = int(pointers[1])
    self.ncon = counts[:1]
    self.contact_slot = pointers[-1:]   # d->contact (read every step)
    self.arena_ints = _view(ctypes.c_int32, self.arena, model.narena // 4)
    stride, geom, pos = _contact_fields()
    self.stride = stride // 4          # in int32 entries
    self.geom = geom // 4
    self.stride_bytes, self.pos_bytes = stride, pos
    if data.ncon:   # The bindings' geom pairs where this reads them.
      if not np.array_equal(self.geom_pairs(), data.contact.geom):
        raise ValueError('contact geoms are not where expected')

  def layout(self):
    """The `ContactLayout` of `run`."""
    return ContactLayout(self.ncon, self.contact_slot, np.uint64(self.arena),
                         self.arena_ints, self.stride, self.geom,
                         self.stride_bytes, self.pos_bytes)

  def geom_pairs(self):
    """The current contacts' geom pairs (ncon, 2), read as `run` does."""
    start = (int(self.contact_slot[0]) - self.arena) // 4
    rows = start + self.stride * np.arange(int(self.ncon[0]))
    return self.arena_ints[rows[:, None] + self.geom + np.arange(2)]


def _counts(data):
  """ncon, ne, nf, nl, nefc of an MjData: the int32s after its timers."""
  timer = np.asarray(data.timer.duration)   # mjTimerStat[mjNTIMER]
  return _view(ctypes.c_int32,
               _address(timer) + timer.strides[0] * timer.shape[0], 5)


def _pointers(data):
  """buffer, arena, then the pointer fields from qpos to contact of an
  MjData: the words after its `energy`."""
  return _view(ctypes.c_uint64, _address(data.energy) + data.energy.nbytes,
               2 + len(_pointer_names()))


@functools.lru_cache(maxsize=None)
def _contact_fields():
  """(stride, offset of geom, offset of pos) of mjContact in bytes, from
  the bindings' views on a model with contacts, where `_counts` and
  `_pointers` are checked too (with contacts and constraints present)."""
  model = mujoco.MjModel.from_xml_string(_PROBE_XML)
  data = mujoco.MjData(model)
  mujoco.mj_forward(model, data)
  if data.ncon < 2:
    raise ValueError('the probe model has no contacts')
  dist = np.asarray(data.contact.dist)
  counts = _counts(data)
  if (counts[0] != data.ncon or counts[4] != data.nefc
      or _pointers(data)[-1] != _address(dist)):
    raise ValueError('ncon, nefc or contact are not where expected in '
                     'mjData')
  offset = _address(data.contact.geom) - _address(dist)
  pos = _address(data.contact.pos) - _address(dist)
  if dist.strides[0] % 8 or offset % 4 or pos % 8:
    raise ValueError('mjContact is not laid out as expected')
  return dist.strides[0], offset, pos


class Mujoco(typing.NamedTuple):
  """MuJoCo's model and data (their addresses, for libmujoco's functions)
  and data's warning counters."""
  model: int                  # mjModel*
  data: int                   # mjData*
  warnings: np.ndarray        # (mjNWARNING,) int32, MjData.warning.number
  warnings_before: np.ndarray  # (mjNWARNING,) int32, before a step


class PersonMocap(typing.NamedTuple):
  """The person's mocap rows of every physics step of the RL step
  (HumanPlayback.mocap_layout) and where they go in MjData."""
  mocap_pos: np.ndarray    # MjData.mocap_pos
  rows: np.ndarray         # (L, S + K, 3) capsule middles and keypoints
  pos_start: int           # their first mocap_pos row
  mocap_quat: np.ndarray   # MjData.mocap_quat
  quaternions: np.ndarray  # (L, S, 4) capsule orientations
  quat_start: int          # their first mocap_quat row


class ShieldSetpoints(typing.NamedTuple):
  """The shield's set-points from physics step `first` on
  (ShieldedStepper's batch.step_many)."""
  setpoints: np.ndarray    # (n, 3, dof) q, dq, ddq per physics step
  intervened: np.ndarray   # (n,) bool, whether the shield intervened
  first: int               # the physics step of row 0
  expected: np.ndarray     # (n, dof) where each puts the joints after it


class TrackingCheck(typing.NamedTuple):
  """The after-step tracking check (TrackingBounds.bound, then
  TrackingBounds.error over the tolerance; safety/shield/tracking.py)."""
  q_measured: np.ndarray   # (dof,) view of the arm's qpos
  levers: np.ndarray       # (dof,) m/rad
  tolerance: float         # m
  fixed: np.ndarray        # the robot's kinematic chain
  points: np.ndarray       # (robot_reach.RobotReach's kernel model)
  frame_index: np.ndarray


class ContactLayout(typing.NamedTuple):
  """Where MjData keeps ncon and its contacts (`ContactMemory`)."""
  ncon: np.ndarray           # (1,) int32 view of d->ncon
  contact_slot: np.ndarray   # (1,) uint64 view of d->contact
  arena: np.uint64           # the arena's address
  arena_ints: np.ndarray     # the arena as int32
  stride: int                # mjContact's size in int32 entries
  geom: int                  # offset of geom in int32 entries
  stride_bytes: int          # mjContact's size in bytes
  pos_bytes: int             # offset of pos in bytes


class StepRecord(typing.NamedTuple):
  """What the physics steps write for the task: the commanded joint
  velocities, the contact types present per step and over the RL step,
  and the stretch's results."""
  command_dq: np.ndarray              # (dof,) the last step's command
  flags: np.ndarray                   # (types,) bool, one step's
  step_flags: np.ndarray              # (types,) bool, the RL step's
  contact_steps: np.ndarray           # (types,) steps with each type
  largest_tracking_bound: np.ndarray  # (1,) m, updated
  intervened: np.ndarray              # (1,) bool, set if the shield did
  largest_contact_speed: np.ndarray   # (1,) m/s, robot-human, updated


class StepWrites(typing.NamedTuple):
  """A task's writes before each physics step: target[index] = rows[k]
  (SteppedTask._physics_step_writes)."""
  target: np.ndarray   # (n,) float64
  index: np.ndarray    # (m,) int64
  rows: np.ndarray     # (L, m) float64


@_jit
def run(k0, k1, mujoco_, person, shield, memory, gains, tracking, layout,
        tables, record, writes0, writes1, hold):
  """Physics steps k0..k1-1 (module doc); returns (k, status): the step
  it stopped at and why (DONE: k = k1). Every group is the plain tuple of
  its named tuple's fields (kernels.as_fields), named again here.

  Args:
    k0, k1: the stretch of physics steps of the RL step.
    mujoco_: `Mujoco`.
    person: `PersonMocap`.
    shield: `ShieldSetpoints` (covering the stretch).
    memory, gains: the controller's (controller_kernels.ControllerMemory,
      TrackingGains).
    tracking: `TrackingCheck`.
    layout: `ContactLayout`.
    tables: contact_kernels.ContactTables.
    record: `StepRecord`, updated.
    writes0, writes1: `StepWrites`
      (SteppedTask._physics_step_writes; index (0,): none).
    hold: tool_hold_kernels.Hold, a compliant hold's force on its tool
      after the writes (tool_hold_kernels.apply; a hold that is off does
      nothing), or None: no hold (numba compiles the call without it).

  Returns:
    (k, status): DONE, PYTHON_AFTER or PHYSICS_WARNING at step k.
  """
  mujoco_, person, shield = (Mujoco(*mujoco_), PersonMocap(*person),
                             ShieldSetpoints(*shield))
  memory = controller_kernels.ControllerMemory(*memory)
  gains = controller_kernels.TrackingGains(*gains)
  tracking, layout = TrackingCheck(*tracking), ContactLayout(*layout)
  tables = contact_kernels.ContactTables(*tables)
  record = StepRecord(*record)
  writes0, writes1 = StepWrites(*writes0), StepWrites(*writes1)
  model, data = mujoco_.model, mujoco_.data
  warnings, before = mujoco_.warnings, mujoco_.warnings_before
  mocap_pos, mocap_rows = person.mocap_pos, person.rows
  mocap_quat, quaternions = person.mocap_quat, person.quaternions
  pos_start, quat_start = person.pos_start, person.quat_start
  setpoints, expected_rows = shield.setpoints, shield.expected
  ncon, contact_slot, arena_ints = (layout.ncon, layout.contact_slot,
                                    layout.arena_ints)
  stride, geom = layout.stride, layout.geom
  pair_types, jacobian = tables.pair_types, tables.jacobian
  command_dq, flags = record.command_dq, record.flags
  out_bound, out_speed = (record.largest_tracking_bound,
                          record.largest_contact_speed)
  rows, segments = mocap_rows.shape[1], quaternions.shape[1]
  dof = memory.q.shape[0]
  for k in range(k0, k1):
    for r in range(rows):
      for c in range(3):
        mocap_pos[pos_start + r, c] = mocap_rows[k, r, c]
    for r in range(segments):
      for c in range(4):
        mocap_quat[quat_start + r, c] = quaternions[k, r, c]
    i = k - shield.first
    if shield.intervened[i]:
      record.intervened[0] = True
    for d in range(dof):
      command_dq[d] = setpoints[i, 1, d]
    controller_kernels.acceleration(
        setpoints[i, 0], setpoints[i, 1], setpoints[i, 2], memory.q,
        memory.dq, gains.kp, gains.kd, gains.half_step,
        memory.arm_acceleration)
    _MUL_M(model, data, np.uint64(memory.product.ctypes.data),
           np.uint64(memory.acceleration.ctypes.data))
    controller_kernels.torque(
        gains.damping_step, memory.arm_acceleration, memory.arm_product,
        memory.bias, memory.passive, gains.torque_limit, memory.torque,
        memory.ctrl)
    for j in range(writes0.index.shape[0]):
      writes0.target[writes0.index[j]] = writes0.rows[k, j]
    for j in range(writes1.index.shape[0]):
      writes1.target[writes1.index[j]] = writes1.rows[k, j]
    if hold is not None:
      tool_hold_kernels.apply(tool_hold_kernels.named_hold(hold))
    for w in range(warnings.shape[0]):
      before[w] = warnings[w]
    _STEP2(model, data)
    _STEP1(model, data)
    for w in range(warnings.shape[0]):
      if warnings[w] > before[w]:
        return k, PHYSICS_WARNING
    distance = tracking_bound(tracking.q_measured, expected_rows[i],
                              tracking.levers)
    if distance > tracking.tolerance:   # The exact distance decides.
      distance = kernels.tracking_error(
          tracking.q_measured, expected_rows[i], tracking.fixed,
          tracking.points, tracking.frame_index)
      if distance > tracking.tolerance:
        return k, PYTHON_AFTER
    flags[:] = False
    count = ncon[0]
    if count:
      human = False
      start = np.int64(contact_slot[0] - layout.arena) // 4
      for c in range(count):
        row = start + c * stride + geom
        kind = pair_types[arena_ints[row], arena_ints[row + 1]]
        if kind >= 0:
          flags[kind] = True
          human |= kind == _ALLOWED
      if human and tables.human_in_python:   # Measured by energy.
        return k, PYTHON_AFTER
      if human:   # contacts.ContactMonitor.update, the robot tracking
        flags[_ALLOWED] = False
        for c in range(count):
          row = start + c * stride + geom
          first, second = arena_ints[row], arena_ints[row + 1]
          if pair_types[first, second] != _ALLOWED:
            continue
          robot = (first if tables.categories[first] == contacts.ROBOT
                   else second)
          point = contact_slot[0] + np.uint64(c * layout.stride_bytes
                                              + layout.pos_bytes)
          _JAC(model, data, np.uint64(jacobian.ctypes.data), np.uint64(0),
               point, np.int32(tables.geom_body[robot]))
          speed = contact_kernels.commanded_speed(jacobian, tables.dofs,
                                                  command_dq)
          out_speed[0] = max(out_speed[0], speed)
          flags[_CRITICAL if speed > tables.critical_speed
                else _ALLOWED] = True
    if distance > out_bound[0]:
      out_bound[0] = distance
    for t in range(flags.shape[0]):
      if flags[t]:
        record.step_flags[t] = True
        record.contact_steps[t] += 1
  return k1, DONE


@_jit
def tracking_bound(q, expected, levers):
  """sum_j |q_j - expected_j| levers_j in joint order
  (TrackingBounds.bound's value, summed in a fixed order)."""
  total = 0.0
  for j in range(q.shape[0]):
    total += abs(q[j] - expected[j]) * levers[j]
  return total


class CompiledSteps:
  """The arguments of `run` for one compiled physics, and its call."""

  def __init__(self, physics, controller, playback, monitor, tracking_levers,
               tracking_tolerance, q_measured, command_dq, step_flags,
               contact_steps, robot_reach):
    """Raises ValueError where this physics cannot run compiled (MjData's
    layout unchecked, the person's mocap rows not consecutive)."""
    model, data = physics.model.ptr, physics.data.ptr
    memory = ContactMemory(model, data)
    mocap = playback.mocap_layout()
    if mocap is None:
      raise ValueError("the person's mocap rows are not consecutive")
    self._data = data
    self._arena_limit = ARENA_HEADROOM * model.narena
    self._mujoco = Mujoco(
        model._address, data._address, physics.data.warning.number,
        np.zeros(physics.data.warning.number.shape, np.int32))
    fixed, points = robot_reach.kernel_model
    self.record = StepRecord(
        command_dq, np.zeros_like(step_flags), step_flags, contact_steps,
        np.zeros(1), np.zeros(1, dtype=bool), np.zeros(1))
    # `run`'s groups before and after the shield's set-points, as fields.
    self._before_shield = kernels.as_fields((self._mujoco,
                                             PersonMocap(*mocap)))
    self._after_shield = kernels.as_fields((
        controller.memory, controller.gains,
        TrackingCheck(q_measured,
                      np.ascontiguousarray(tracking_levers, dtype=float),
                      float(tracking_tolerance), fixed, points,
                      robot_reach.kernel_frames),
        memory.layout(), monitor.tables, self.record))
    self._no_writes = kernels.as_fields(StepWrites(
        np.zeros(0), np.zeros(0, dtype=np.int64),
        np.zeros((max(len(playback.times), 1), 0))))
    self._no_write_groups = (self._no_writes, self._no_writes)

  def has_headroom(self):
    """Whether MuJoCo's arena is far enough from full (module doc)."""
    return self._data.maxuse_arena <= self._arena_limit

  @property
  def warnings_before(self):
    """The warning counters before the step that raised one."""
    return self._mujoco.warnings_before

  def run(self, k0, k1, setpoints, setpoint_flags, setpoints_from,
          expected_rows, writes=(), hold=None):
    """Physics steps k0..k1-1 (see `run`): (k, status). writes: up to two
    (target, index, rows) groups (SteppedTask._physics_step_writes);
    hold: tool_hold.CompliantHold.kernel_arguments, or None. The stretch's
    results are in `record` (StepRecord)."""
    if writes:
      if len(writes) > 2:
        raise ValueError(f'at most two groups of writes, got {len(writes)}')
      groups = [tuple(StepWrites(*group)) for group in writes]
      groups += [self._no_writes] * (2 - len(groups))
    else:
      groups = self._no_write_groups
    shield = (setpoints, setpoint_flags, setpoints_from,   # ShieldSetpoints
              expected_rows)
    return run(k0, k1, *self._before_shield, shield, *self._after_shield,
               *groups, None if hold is None else kernels.as_fields(hold))
