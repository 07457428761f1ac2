"""Contact monitor: classifies MuJoCo contacts every physics step.

Every geom of the model gets a category once (static, robot, object, human,
other); each physics step the active contacts are classified by the pair of
categories, vectorised over `physics.data.contact`:

* robot-static: a static collision (table, pedestal, floor);
* robot-human: allowed or critical by the robot's own speed at the contact
  point: the surface velocity the commanded joint velocities give that
  point (`mujoco.mj_jac` of the contacting robot body at the point times
  the shield's dq command): critical above `critical_speed` (PFL: the
  shield's v_safe; SSM: SSM_STOPPED_SPEED, the robot is not stopped);
  pushed (`human_pushed`) instead of allowed when the person has pushed the
  robot off its command (below); with `energies`
  (tasks/runtime/contact_energies.py) each such contact's energy is measured
  too, and under `critical_by_energy` (shield mode 'pfl_energy') the contact is
  critical when its energy exceeds its body's limit instead;
* robot-object, human-object, object-object, object-static: normal.

Why the commanded and not the measured velocity: the human is kinematic
(mocap capsules of unbounded mass), so a person walking into a robot that
holds still shoves it: measured link speeds of 0.2-6 m/s were seen with the
robot commanded to rest (random human clips walking into a Panda at home).
Judged by measured speed, every such push would be "critical", although no
robot controller can prevent it and SSM's guarantee (the robot is at rest at
contact) holds. The command is what the robot does of its own accord; the
tracking controller follows it to ~3e-5 rad when nothing pushes.
`surface_speed` gives the measured speed (mj_objectVelocity) for
diagnostics.

Pushed robots: a person can shove the robot far from its command (0-3 cm
inside a link, joints 0.29-2.9 rad off, seen with real recordings). The
Jacobian at the pushed pose times the command then judges the command
where the robot never meant to be. So when the task finds the robot
farther from the command than the shield's tracking tolerance (HrcTask,
docs/safety.md "Pushed robots"), it passes the commanded configuration:
each robot-human contact point is carried rigidly with its link to the
link's commanded pose and judged there; at or below `critical_speed` the
contact is `human_pushed` (the person moved the robot; not illegal), above
it stays `human_critical` (the robot's own motion was too fast).

Robot geoms never collide with each other in MuJoCo (collision_groups), so
self-collision is judged geometrically by the task from the robot's capsule
model (the one collision prevention uses), once per RL step.

compiled=True (the default) classifies the contacts' geom pairs in one
numba call over a table of every pair's type (tasks/runtime/contact_kernels.py)
instead of a dozen NumPy calls; compiled=False runs the NumPy calls, the
readable reference. Robot-human contacts are then judged as above (the
same flags, tests/tasks/test_base.py).
"""

import enum

import mujoco
import numpy as np

from hrc_suite.tasks.runtime import contact_kernels

# Geom categories (what a geom belongs to; not contact types).
NONE, STATIC, ROBOT, OBJECT, HUMAN = range(5)


class ContactType(enum.IntEnum):
  """Contact types: each is its position among the monitor's flags. New
  types go last, so flags stored in older snapshots keep their positions."""
  static = 0
  human_allowed = 1
  human_critical = 2
  robot_object = 3
  human_object = 4
  human_pushed = 5


CONTACT_TYPES = tuple(kind.name for kind in ContactType)
TYPE_INDEX = {kind.name: int(kind) for kind in ContactType}
# Contacts that cost the task's collision reward (with self-collisions).
ILLEGAL_TYPES = (ContactType.static, ContactType.human_critical)
# Types decided by the pair of geom categories; robot-human contacts are
# then split by speed (and push) into allowed, critical and pushed.
_PAIR_TYPES = (((ROBOT, STATIC), 'static'), ((ROBOT, HUMAN), 'human_allowed'),
               ((ROBOT, OBJECT), 'robot_object'),
               ((HUMAN, OBJECT), 'human_object'))
_ALLOWED = int(ContactType.human_allowed)
_CRITICAL = int(ContactType.human_critical)
_PUSHED = int(ContactType.human_pushed)
# SSM: the shield stops the robot before any contact, so a contact with the
# robot moving is a violation. The reference's threshold (1 mm/s) is kept:
# judged on the commanded velocity, which is exactly zero once the shield's
# failsafe has braked to rest, it has no noise to tolerate.
SSM_STOPPED_SPEED = 0.001   # m/s


class ContactMonitor:
  """Counts contacts by type for one compiled physics."""

  def __init__(self, physics, static_geoms, robot_geoms, object_geoms=(),
               human_geoms=(), critical_speed=SSM_STOPPED_SPEED,
               robot_dofs=None, robot_qpos=None, compiled=True,
               energies=None, critical_by_energy=False):
    """robot_dofs, robot_qpos: the robot's joints' dof and qpos addresses
    (the order of dq and q commands); robot_dofs None: every dof. Judging
    at a commanded configuration needs robot_qpos. compiled: classify
    with the numba kernel (module doc). energies: a
    contact_energies.ContactEnergies measuring every robot-human contact
    (needs robot_qpos), or None; critical_by_energy: robot-human contacts
    are critical above their energy limit instead of critical_speed
    (shield mode 'pfl_energy'; needs energies)."""
    if critical_by_energy and energies is None:
      raise ValueError('critical_by_energy needs energies '
                       '(contact_energies.ContactEnergies)')
    if energies is not None and robot_qpos is None:
      raise ValueError("measuring contact energies needs the robot's qpos "
                       'addresses (robot_qpos)')
    if not critical_speed >= 0:
      raise ValueError(f'critical_speed must be >= 0 m/s, got '
                       f'{critical_speed!r}')
    self.critical_speed = float(critical_speed)
    model = physics.model
    categories = np.full(model.ngeom, NONE, dtype=np.int8)
    for category, geoms in ((STATIC, static_geoms), (ROBOT, robot_geoms),
                            (OBJECT, object_geoms), (HUMAN, human_geoms)):
      if len(geoms):
        categories[physics.bind(list(geoms)).element_id] = category
    self._categories = categories
    # Pair code = 5 * category1 + category2, made symmetric.
    codes = np.full(25, -1, dtype=np.int8)
    for (a, b), name in _PAIR_TYPES:
      codes[5 * a + b] = codes[5 * b + a] = TYPE_INDEX[name]
    self._codes = codes
    self._compiled = bool(compiled)
    # Type of every geom pair (-1: none), for the compiled classification.
    self._pair_types = codes[5 * categories[:, None] + categories[None, :]]
    self._model, self._data = model.ptr, physics.data.ptr
    self._geom_body = model.geom_bodyid.copy()
    self._velocity = np.zeros(6)
    self._jacobian = np.zeros((3, model.nv))
    self._dofs = (np.arange(model.nv) if robot_dofs is None
                  else np.asarray(robot_dofs, dtype=np.int64))
    self._qpos = (None if robot_qpos is None
                  else np.asarray(robot_qpos, dtype=int))
    if self._qpos is not None and self._qpos.shape != self._dofs.shape:
      raise ValueError(f'robot_qpos ({self._qpos.size} addresses) and '
                       f'robot_dofs ({self._dofs.size}) must match')
    self._commanded = None   # MjData posed at a commanded configuration.
    self._flags = np.zeros(len(CONTACT_TYPES), dtype=bool)
    self.max_human_contact_speed = 0.0
    self.energies = energies
    self.critical_by_energy = bool(critical_by_energy)
    # What tasks/runtime/physics_loop.run judges contacts with; robot-human
    # contacts measured by energy are judged here (human_in_python).
    self.tables = contact_kernels.ContactTables(
        self._pair_types, self._categories, self._geom_body, self._dofs,
        self._jacobian, self.critical_speed, energies is not None)

  def reset(self):
    """Starts a new interval for `max_human_contact_speed` and the
    energies' maxima."""
    self.max_human_contact_speed = 0.0
    if self.energies is not None:
      self.energies.reset()

  def commanded_speed(self, body, point, dq_command, q_command=None):
    """Speed (m/s) of the point (world) rigidly attached to `body` when the
    robot's joints move at dq_command (one entry per robot dof).

    q_command: None to judge the robot where it is; else joint positions
    (robot_qpos order) at which to judge it: the point is carried with
    `body` from its measured pose to its pose at q_command (the rest of
    the model as measured).
    """
    posed = None if q_command is None else self._posed(q_command)
    return self._speed(int(body), np.asarray(point, dtype=np.float64),
                       dq_command, posed)

  def _speed(self, body, point, dq_command, posed):
    """commanded_speed with the posed MjData (None: the measured one)."""
    data = self._data
    if posed is not None:
      local = (point - data.xpos[body]) @ data.xmat[body].reshape(3, 3)
      point = posed.xpos[body] + posed.xmat[body].reshape(3, 3) @ local
      data = posed
    mujoco.mj_jac(self._model, data, self._jacobian, None, point, body)
    return float(contact_kernels.commanded_speed(
        self._jacobian, self._dofs, np.asarray(dq_command,
                                               dtype=np.float64)))

  def _posed(self, q_command):
    """A scratch MjData with the measured state and the robot at q_command
    (kinematics and the Jacobians' inputs computed)."""
    if self._qpos is None:
      raise ValueError('judging at a commanded configuration needs the '
                       "robot's qpos addresses (robot_qpos)")
    q_command = np.asarray(q_command, dtype=np.float64)
    if q_command.shape != self._qpos.shape or not np.all(
        np.isfinite(q_command)):
      raise ValueError(f'q_command: expected {self._qpos.size} finite joint '
                       f'positions, got {q_command.tolist()}')
    if self._commanded is None:
      self._commanded = mujoco.MjData(self._model)
    posed = self._commanded
    posed.qpos[:] = self._data.qpos
    posed.qpos[self._qpos] = q_command
    posed.mocap_pos[:] = self._data.mocap_pos
    posed.mocap_quat[:] = self._data.mocap_quat
    mujoco.mj_kinematics(self._model, posed)
    mujoco.mj_comPos(self._model, posed)
    return posed

  def surface_speed(self, body, point):
    """Measured speed (m/s) of the point (world) rigidly attached to
    `body`."""
    data = self._data
    mujoco.mj_objectVelocity(self._model, data, mujoco.mjtObj.mjOBJ_XBODY,
                             int(body), self._velocity, 0)
    angular, linear = self._velocity[:3], self._velocity[3:]
    offset = point - data.xpos[body]
    return float(np.linalg.norm(linear + np.cross(angular, offset)))

  def update(self, dq_command, q_command=None):
    """Classifies the current contacts, the robot's joints commanded at
    dq_command; returns flags (len(CONTACT_TYPES),) of the types present
    now (an array reused by the next call).

    q_command: None while the robot tracks its command; else the
    configuration the command puts the robot in, the person having pushed
    it away: robot-human contacts are judged there and are `human_pushed`
    at or below critical_speed, `human_critical` above.
    """
    data = self._data
    flags = self._flags
    flags[:] = False
    ncon = data.ncon
    if ncon == 0:
      return flags
    contact = data.contact
    if self._compiled and not contact_kernels.classify(
        contact.geom, self._pair_types, flags):
      return flags   # No robot-human contact to judge by speed.
    geom1, geom2 = contact.geom1[:ncon], contact.geom2[:ncon]
    cat1, cat2 = self._categories[geom1], self._categories[geom2]
    codes = self._codes[5 * cat1 + cat2]
    present = codes >= 0
    if not present.any():
      return flags
    flags[codes[present]] = True
    human = np.flatnonzero(codes == _ALLOWED)
    if human.size:
      flags[_ALLOWED] = False
      slow, posed = _ALLOWED, None
      if q_command is not None:
        slow, posed = _PUSHED, self._posed(q_command)
      energies = self.energies
      if energies is not None:
        clamped = energies.clamped(geom1, geom2)
        q = (self._data.qpos[self._qpos] if q_command is None
             else np.asarray(q_command, dtype=np.float64))
        dq = np.asarray(dq_command, dtype=np.float64)
      for i in human:
        robot, person = ((geom1[i], geom2[i]) if cat1[i] == ROBOT
                         else (geom2[i], geom1[i]))
        speed = self._speed(int(self._geom_body[robot]), contact.pos[i],
                            dq_command, posed)
        self.max_human_contact_speed = max(self.max_human_contact_speed,
                                           speed)
        critical = speed > self.critical_speed
        if energies is not None:
          ratio = energies.measure(q, dq, int(robot), int(person),
                                   int(person) in clamped).ratio
          if self.critical_by_energy:
            critical = ratio > 1.0
        flags[_CRITICAL if critical else slow] = True
    return flags
