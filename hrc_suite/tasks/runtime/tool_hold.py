"""A tool held compliantly by the kinematic human's hand.

`Human.hold` welds an object to a hand capsule, a mocap body. MuJoCo gives
mocap bodies no velocity, so a weld's damping acts on the object's absolute
velocity: a weld of time constant tau lags a hand moving at v by about
2 tau v (10 ms, 3 m/s: 6 cm, measured in a hammer swing), and stiff enough
to follow, it presses a blocked tool on with kilonewtons (the hand is
kinematic and never gives way).

`CompliantHold` replaces the weld by what a hand and wrist do: it carries
the tool along the hand's motion (feed-forward: the target's acceleration
and the tool's weight) and corrects deviations through a spring and damper
relative to the hand's motion, of human arm stiffness. Free, the tool
follows the hand within millimetres; blocked (a hammer face on a nail), it
presses with only the spring's force, e.g. ~10 N at 2.5 cm: a blow is an
impulse, not a sustained press. The weld keeps its relative pose (eq_data,
set by `Human.hold`) but is switched off; the hold applies forces through
`xfrc_applied` on the tool's body before every physics step.

The target's velocity and acceleration are finite differences of its poses
at consecutive physics steps; `state()` / `set_state()` carry them through
snapshots. The arithmetic is tasks/runtime/tool_hold_kernels.py's, which the
compiled physics loop calls too (`kernel_arguments`).
"""

import mujoco
import numpy as np

from hrc_suite import rotations
from hrc_suite.tasks.runtime import tool_hold_kernels as kernels

# Hand stiffness of a relaxed human arm: of the order of a few hundred N/m
# (Mussa-Ivaldi, Hogan & Bizzi 1985, J. Neurosci. 5(10): 2732-2743, hand
# stiffness ellipses measured in the horizontal plane). With a 0.58 kg
# hammer this is a time constant sqrt(m / k) of 38 ms.
STIFFNESS = 400.0          # N/m
# Wrist stiffness: of the order of 1-10 N m/rad from relaxed to
# co-contracted (design value within that range: a grip on a tool
# co-contracts).
ROTATIONAL_STIFFNESS = 5.0   # N m/rad
DAMPING_RATIO = 1.0          # critically damped (no rebound of the tool)
# The forces are explicit (computed before each step): about a principal
# axis of small inertia (a handle's own axis) the wrist's stiffness would
# oscillate faster than the step resolves. Each axis' stiffness is capped
# at inertia x MAX_FREQUENCY^2 (omega dt = 0.2 at 4 ms: stable, damped).
MAX_FREQUENCY = 50.0         # rad/s
# Limits of the hand's force and the wrist's torque on the tool. A blow's
# swing accelerates the 0.58 kg hammer at ~75 m/s^2 (0.25 m in 0.14 s,
# minimum jerk: ~50 N with its weight); but their kinematic strikes stop dead at the end point, which a
# hand cannot do to a swung hammer (it decelerates it over centimetres, or
# the nail does): at 80 N a 2 m/s hammer needs ~15 ms and ~1.5 cm to stop,
# so the blow's momentum reaches the nail (measured, Panda seed 1: a 2.3
# m/s blow drives the nail 3.7 mm; capped at 300 N the hold stopped the
# hammer on the head and drove it 0 mm). Design values, bounded by the
# strength of a power grip (~300-500 N) and wrist (~10-15 N m).
MAX_FORCE = 80.0             # N
MAX_TORQUE = 15.0            # N m
# Aiming: the wrist turns the tool about the vertical through the hand by
# at most the wrist's radial deviation (~20 deg; ulnar ~30-35 deg: normal
# ranges of joint motion).
MAX_AIM = np.radians(20.0)   # rad
# ... and the arm reaches up to this much further or shorter (m, design
# value: the synthetic clips' blows scatter +-2.5 cm along the handle, a
# person watching the nail lands them on it). Errors beyond it fade out of
# the correction (zero at twice it: a hammer far from the nail is not
# aimed), so the hold stays continuous.
MAX_REACH = 0.03             # m


_NO_AIM_SOURCE = np.zeros(0)


def _floats(value):
  """A float64 copy of a vector (HoldParameters' arrays)."""
  return np.array(value, dtype=np.float64)


class CompliantHold:
  """Holds one free body at a weld's relative pose to a mocap hand."""

  def __init__(self, physics, body, stiffness=STIFFNESS,
               rotational_stiffness=ROTATIONAL_STIFFNESS,
               damping_ratio=DAMPING_RATIO):
    for name, value in (('stiffness', stiffness),
                        ('rotational_stiffness', rotational_stiffness),
                        ('damping_ratio', damping_ratio)):
      if not np.isfinite(value) or value <= 0.0:
        raise ValueError(f'{name} must be a positive number, got {value!r}')
    model = physics.model
    self._body = int(physics.bind(body).element_id)
    # The free joint sits on the body or, attached with composer's
    # add_free_entity, on its massless attachment frame.
    jointed = self._body
    offset_pos, offset_quat = np.zeros(3), rotations.IDENTITY_QUAT
    while model.body_jntnum[jointed] == 0 and jointed != 0:
      offset_pos = model.body_pos[jointed] + rotations.quat_to_mat(
          model.body_quat[jointed]) @ offset_pos
      offset_quat = rotations.quat_mul(model.body_quat[jointed], offset_quat)
      jointed = int(model.body_parentid[jointed])
    joint = model.body_jntadr[jointed]
    if jointed == 0 or model.body_jntnum[jointed] != 1 or model.jnt_type[
        joint] != mujoco.mjtJoint.mjJNT_FREE or not np.isclose(
            model.body_subtreemass[jointed], model.body_mass[self._body],
            rtol=1e-3):
      raise ValueError(f'{body.full_identifier!r} must be a free body (or '
                       'hang alone from a massless free body)')
    mass = float(model.body_mass[self._body])
    # Centre of mass and principal axes in the free joint's frame (the
    # weld's relative pose is the held body's; offset_* turn it into the
    # free joint's frame).
    com_local = offset_pos + rotations.quat_to_mat(
        offset_quat) @ model.body_ipos[self._body]
    inertia = model.body_inertia[self._body].copy()
    # Per principal axis: stiffness (capped, MAX_FREQUENCY) and damping.
    k_rot = np.minimum(float(rotational_stiffness),
                       inertia * MAX_FREQUENCY ** 2)
    self._params = kernels.HoldParameters(
        mass=mass, dt=float(model.opt.timestep), k=float(stiffness),
        b=float(2.0 * damping_ratio * np.sqrt(stiffness * mass)),
        k_rot=_floats(k_rot),
        b_rot=_floats(2.0 * damping_ratio * np.sqrt(k_rot * inertia)),
        inertia=_floats(inertia), com_local=_floats(com_local),
        inertia_quat=_floats(rotations.quat_mul(
            offset_quat, model.body_iquat[self._body])),
        offset_pos=_floats(offset_pos), offset_quat=_floats(offset_quat),
        gravity=_floats(model.opt.gravity), max_aim=float(MAX_AIM),
        max_reach=float(MAX_REACH), max_force=float(MAX_FORCE),
        max_torque=float(MAX_TORQUE))
    self._addresses = kernels.HoldAddresses(
        body=self._body, qpos=int(model.jnt_qposadr[joint]),
        qvel=int(model.jnt_dofadr[joint]))
    # The hand and weld held by, whether holding and aiming, the aim (the
    # world point the tool's origin heads for), the targets' history
    # (centre of mass and orientation at the last two physics steps), the
    # last target angular velocity and the steps since `start`.
    self._state = kernels.HoldState(
        mocap=np.zeros(1, dtype=np.int64), eq=np.zeros(1, dtype=np.int64),
        holding=np.zeros(1, dtype=np.int64),
        aiming=np.zeros(1, dtype=np.int64), aim=np.zeros(3),
        history=np.zeros((2, 7)), omega=np.zeros(3),
        fresh=np.zeros(1, dtype=np.int64))

  # -------------------------------------------------------------- holding

  def start(self, physics, weld):
    """Holds the body at `weld`'s relative pose (eq_data) to its first body,
    a mocap hand; switches the weld off."""
    model = physics.model
    eq_id = int(physics.bind(weld).element_id)
    if model.eq_obj2id[eq_id] != self._body:
      raise ValueError(f'weld {weld.name!r} does not hold body {self._body}')
    mocap = int(model.body_mocapid[model.eq_obj1id[eq_id]])
    if mocap < 0:
      raise ValueError(f'weld {weld.name!r} does not start at a mocap body')
    physics.data.eq_active[eq_id] = 0
    state = self._state
    state.mocap[0], state.eq[0] = mocap, eq_id
    state.holding[0], state.aiming[0] = 1, 0
    # A new hold aims nowhere until told, and starts as a fresh one would.
    state.fresh[0] = 0
    state.history[:] = 0.0
    state.omega[:] = 0.0
    physics.data.xfrc_applied[self._body] = 0.0

  def stop(self, physics):
    self._state.holding[0] = 0
    physics.data.xfrc_applied[self._body] = 0.0

  @property
  def holding(self):
    return bool(self._state.holding[0])

  def aim(self, point):
    """Turns the held pose about the vertical through the hand (within
    MAX_AIM) so the body's origin lies in the vertical plane through the
    hand and `point` (world), and shifts it along that plane by up to
    MAX_REACH onto `point`'s horizontal distance from the hand, as a person
    aims a hammer at a nail; None holds at the plain relative pose."""
    if point is None:
      self._state.aiming[0] = 0
      return
    point = np.asarray(point, dtype=float)
    if point.shape != (3,) or not np.isfinite(point).all():
      raise ValueError(f'aim point must be a finite (3,) position, got '
                       f'{point!r}')
    self._state.aim[:] = point
    self._state.aiming[0] = 1

  def target(self, physics):
    """(centre of mass (3,), orientation (4,) of the free joint's frame)
    the hand wants the body at (the hold must be on)."""
    if not self.holding:
      raise ValueError('target: the hold is off (start it first)')
    com, quat = np.empty(3), np.empty(4)
    kernels.target(self._params, self._state, self._data(physics), com,
                   quat)
    return com, quat

  def apply(self, physics):
    """Sets the body's applied force and torque for the next physics step
    (call after the hand's mocap pose for that step is set). The body is
    now where the target was a step ago; the feed-forward accelerates it
    onto the new target during this step (semi-implicit Euler), the
    spring and damper correct its deviation from the target of a step
    ago (tool_hold_kernels.apply)."""
    kernels.apply(self.kernel_arguments(physics, None))

  def kernel_arguments(self, physics, aim_source):
    """`tool_hold_kernels.apply`'s argument (a `tool_hold_kernels.Hold`)
    for this physics: as `apply` does, or with aim_source (a (3,) array,
    e.g. a site's xpos row) aimed at before every step as `aim` would."""
    if aim_source is None:
      aim_source = _NO_AIM_SOURCE
    else:
      self._state.aiming[0] = 1
    return kernels.Hold(self._params, self._addresses, self._state,
                        aim_source, self._data(physics))

  @staticmethod
  def _data(physics):
    """The MuJoCo arrays of a hold in this physics."""
    data = physics.data
    return kernels.HoldData(data.mocap_pos, data.mocap_quat,
                            physics.model.eq_data, data.qpos, data.qvel,
                            data.xfrc_applied)

  # ------------------------------------------------------------ snapshots

  def state(self):
    state = self._state
    return {'holding': ([int(state.mocap[0]), int(state.eq[0])]
                        if self.holding else None),
            'aim': state.aim.copy() if state.aiming[0] else None,
            'history': state.history.copy(), 'omega': state.omega.copy(),
            'fresh': int(state.fresh[0])}

  def set_state(self, state):
    hand, own = state['holding'], self._state
    own.holding[0] = hand is not None
    if hand is not None:
      own.mocap[0], own.eq[0] = int(hand[0]), int(hand[1])
    aim = state['aim']
    own.aiming[0] = aim is not None
    if aim is not None:
      own.aim[:] = aim
    own.history[:] = state['history']
    own.omega[:] = state['omega']
    own.fresh[0] = int(state['fresh'])
