"""An RL step's physics steps in one compiled call (the fast path).

On the fast path the task runs the L physics steps of an RL step itself
(tasks/substeps.py). Where nothing in a physics step needs
Python, `CompiledSteps.run` runs a stretch of them in one numba call:
per step the person's mocap rows (HumanPlayback's precomputed arrays),
the shield's precomputed set-point, the controller's torque
(control/controller.py's kernels around mj_mulM), MuJoCo's mj_step2 and
mj_step1 (dm_control's legacy step; libmujoco's own functions, called
by name from compiled code), dm_control's warning check, then the task's
after_substep: the tracking bound (over the tolerance, the exact
distance, Shield.tracking_error's kernel) and the contacts' classification,
robot-human contacts judged by the commanded speed at the contact point
(mj_jac, as tasks/contacts.py). The arithmetic is the Python loop's,
operation for operation, so both give the same states bit for bit
(tests/tasks/test_fast_path.py).

The call stops and hands back to Python, which runs the rest exactly as
before, at a step that needs it:

* the person changes clip (the capsules are resized in the model);
* the robot's capsules are farther than the shield's tolerance from
  where the shield put them (a push: rewind and resync, and contacts
  judged at the commanded pose, are Python's);
* a physics step that raised a MuJoCo warning (the task raises
  dm_control's PhysicsError, as the Python loop does).

A task that works before every physics step (`_before_physics_step`)
may hand the call what it writes there, computed for the RL step's
physics steps at its start (`HrcTask._physics_step_writes`: the carried
plank's pose, the presenting grip); where it cannot, an entity or an
extra substep hook is active, or the model is not stepped the legacy
way, the Python loop runs (ShieldedStepper.run_physics_steps,
tasks/shielded_stepping.py).
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

from llvmlite import binding as llvm
import mujoco
import numba
from numba.core import types
import numpy as np

from hrc_suite.control import controller as controller_lib
from hrc_suite.safety import kernels
from hrc_suite.tasks import contacts
from hrc_suite.tasks import tool_hold_kernels

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


@_jit
def run(k0, k1, model, data, mocap_pos, mocap_rows, pos_start, mocap_quat,
        quaternions, quat_start, setpoints, setpoint_flags, setpoints_from,
        expected_rows, q, dq, bias, passive, ctrl, acceleration,
        arm_acceleration, product, arm_product, kp, kd, half_step,
        damping_step, torque_limit, torque, command_dq, warnings, before,
        q_measured, levers, tolerance, ncon, contact_slot, arena,
        arena_ints, stride, geom, stride_bytes, pos_bytes, pair_types,
        categories, geom_body, dofs, jacobian, critical_speed, flags,
        step_flags, contact_steps, out, fixed, points, frame_index,
        target0, index0, rows0, target1, index1, rows1, hold_params,
        hold_indices, hold_aim, hold_aim_source, hold_history, hold_omega,
        hold_fresh, hold_mocap_pos, hold_mocap_quat, hold_eq_data,
        hold_qpos, hold_qvel, hold_xfrc):
  """Physics steps k0..k1-1 (module doc); returns (k, status): the step
  it stopped at and why (DONE: k = k1). out[0]: the largest tracking
  bound, out[2]: the largest robot-human contact speed (both updated);
  out[1]: set to 1 if a set-point run had the shield intervene. target,
  index, rows (two groups): the task's writes before each physics step,
  target[index] = rows[k] (HrcTask._physics_step_writes). hold_*: a
  compliant hold's force on its tool after them (tool_hold_kernels.apply;
  a hold that is off does nothing)."""
  rows, segments = mocap_rows.shape[1], quaternions.shape[1]
  dof = q.shape[0]
  for k in range(k0, k1):
    for r in range(rows):
      for c in range(3):
        mocap_pos[pos_start + r, c] = mocap_rows[k, r, c]
    for r in range(segments):
      for c in range(4):
        mocap_quat[quat_start + r, c] = quaternions[k, r, c]
    i = k - setpoints_from
    if setpoint_flags[i]:
      out[1] = 1.0
    for d in range(dof):
      command_dq[d] = setpoints[i, 1, d]
    controller_lib._acceleration(setpoints[i, 0], setpoints[i, 1],
                                 setpoints[i, 2], q, dq, kp, kd, half_step,
                                 arm_acceleration)
    _MUL_M(model, data, np.uint64(product.ctypes.data),
           np.uint64(acceleration.ctypes.data))
    controller_lib._torque(damping_step, arm_acceleration, arm_product,
                           bias, passive, torque_limit, torque, ctrl)
    for j in range(index0.shape[0]):
      target0[index0[j]] = rows0[k, j]
    for j in range(index1.shape[0]):
      target1[index1[j]] = rows1[k, j]
    tool_hold_kernels.apply(hold_params, hold_indices, hold_aim,
                            hold_aim_source, hold_history, hold_omega,
                            hold_fresh, hold_mocap_pos, hold_mocap_quat,
                            hold_eq_data, hold_qpos, hold_qvel, hold_xfrc)
    for w in range(warnings.shape[0]):
      before[w] = warnings[w]
    _STEP2(model, data)
    _STEP1(model, data)
    for w in range(warnings.shape[0]):
      if warnings[w] > before[w]:
        return k, PHYSICS_WARNING
    distance = tracking_bound(q_measured, expected_rows[i], levers)
    if distance > tolerance:   # The exact distance decides (after_substep).
      distance = kernels.tracking_error(q_measured, expected_rows[i], fixed,
                                        points, frame_index)
      if distance > tolerance:
        return k, PYTHON_AFTER
    flags[:] = False
    count = ncon[0]
    if count:
      human = False
      start = np.int64(contact_slot[0] - arena) // 4
      for c in range(count):
        row = start + c * stride + geom
        kind = pair_types[arena_ints[row], arena_ints[row + 1]]
        if kind >= 0:
          flags[kind] = True
          human |= kind == _ALLOWED
      if human:   # contacts.ContactMonitor.update, the robot tracking
        flags[_ALLOWED] = False
        for c in range(count):
          row = start + c * stride + geom
          first, second = arena_ints[row], arena_ints[row + 1]
          if pair_types[first, second] != _ALLOWED:
            continue
          robot = first if categories[first] == contacts.ROBOT else second
          point = contact_slot[0] + np.uint64(c * stride_bytes + pos_bytes)
          _JAC(model, data, np.uint64(jacobian.ctypes.data), np.uint64(0),
               point, np.int32(geom_body[robot]))
          speed = contacts.commanded_speed(jacobian, dofs, command_dq)
          out[2] = max(out[2], speed)
          flags[_CRITICAL if speed > critical_speed else _ALLOWED] = True
    if distance > out[0]:
      out[0] = distance
    for t in range(flags.shape[0]):
      if flags[t]:
        step_flags[t] = True
        contact_steps[t] += 1
  return k1, DONE


@_jit
def tracking_bound(q, expected, levers):
  """sum_j |q_j - expected_j| levers_j in joint order
  (Shield.tracking_bound's value, summed in a fixed order)."""
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
    self._flags = np.zeros_like(step_flags)
    self._before = np.zeros(physics.data.warning.number.shape, np.int32)
    self.out = np.zeros(3)
    self._no_writes = (np.zeros(0), np.zeros(0, dtype=np.int64),
                       np.zeros((max(len(playback.times), 1), 0)))
    physics_data = physics.data
    self._no_hold = (   # tool_hold_kernels.apply's arguments, hold off
        np.zeros(tool_hold_kernels.NUM_PARAMS),
        np.zeros(tool_hold_kernels.NUM_INDICES, dtype=np.int64),
        np.zeros(3), np.zeros(0), np.zeros((2, 7)), np.zeros(3),
        np.zeros(1, dtype=np.int64), physics_data.mocap_pos,
        physics_data.mocap_quat, physics.model.eq_data, physics_data.qpos,
        physics_data.qvel, physics_data.xfrc_applied)
    self._head = (model._address, data._address) + mocap
    self._tail = controller.kernel_arguments() + (
        command_dq, physics.data.warning.number, self._before, q_measured,
        np.ascontiguousarray(tracking_levers, dtype=float),
        float(tracking_tolerance), memory.ncon, memory.contact_slot,
        np.uint64(memory.arena), memory.arena_ints, memory.stride,
        memory.geom, memory.stride_bytes, memory.pos_bytes,
        *monitor.kernel_arguments(), self._flags, step_flags,
        contact_steps, self.out, *robot_reach._kernel_model,
        robot_reach._kernel_frames)

  def has_headroom(self):
    """Whether MuJoCo's arena is far enough from full (module doc)."""
    return self._data.maxuse_arena <= self._arena_limit

  @property
  def warnings_before(self):
    """The warning counters before the step that raised one."""
    return self._before

  def run(self, k0, k1, setpoints, setpoint_flags, setpoints_from,
          expected_rows, writes=(), hold=None):
    """Physics steps k0..k1-1 (see `run`): (k, status). writes: up to two
    (target, index, rows) groups (HrcTask._physics_step_writes); hold:
    tool_hold.CompliantHold.kernel_arguments, or None."""
    if len(writes) > 2:
      raise ValueError(f'at most two groups of writes, got {len(writes)}')
    groups = list(writes) + [self._no_writes] * (2 - len(writes))
    return run(k0, k1, *self._head, setpoints, setpoint_flags,
               setpoints_from, expected_rows, *self._tail,
               *groups[0], *groups[1], *(hold or self._no_hold))
