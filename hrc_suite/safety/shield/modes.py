"""Shield modes: one class per mode, found by name in one registry.

A mode says what the shield does with each cycle's verification
(docs/safety.md, "Modes"; docs/shield_maths.md, 4 and 9):

* `gates`: the verdict decides the command (the robot takes the intended
  step only on a verified monitored path). False runs unshielded: the
  check only feeds read-outs (metrics, overlays) and runs when one is read.
* `speed_limit(v_safe)`: None (SSM: the robot's reachable set must not
  meet the human's), or the surface speed (m/s) the robot must stay under
  wherever it may touch the person (PFL; the shield's speed tables bound
  the plan's capsule surface speeds, `pfl_tables.pfl_speed_tables`).
* `allows_contact`: whether a robot-human contact below v_safe is within
  the mode's rules (tasks then call contacts critical above v_safe
  instead of above the stopped speed; tasks/runtime/contacts.py).

* the verification, readable and compiled: `failsafe_target` (the
  failsafe's final path velocity), `verdict` (the exact check of a
  cycle's slices) and, for the compiled cycles (`batch`,
  `cycle_kernels`), `kernel_parameters` (one named group whose class
  selects the compiled twins of those two, `mode_kernels`) and
  `plan_tables`. The defaults are SSM's, or PFL's where `speed_limit`
  gives a limit.

A mode that only changes the speed limit needs nothing else. A new mode
is a subclass registered by name (docs/extending.md, "A shield mode";
with a check of its own: "A compiled verification"):

  @modes.register
  class SlowPfl(modes.Pfl):
    name = 'pfl_slow'
    def speed_limit(self, v_safe):
      return 0.5 * v_safe

Tasks, rendering, tags and the binaries' flags ask `names()` / `get()`.
"""

from typing import NamedTuple, Optional, Protocol, Tuple, Type, TypeVar

import numpy as np

from hrc_suite import extensions
from hrc_suite.safety import kernels
from hrc_suite.safety import long_term_plan as ltp
from hrc_suite.safety import robot_reach
from hrc_suite.safety.shield import energy_check_kernels
from hrc_suite.safety.shield import energy_setup
from hrc_suite.safety.shield import energy_verification
from hrc_suite.safety.shield import mode_kernels
from hrc_suite.safety.shield import path as path_lib

# PFL: speeds are compared with this fraction of v_safe. Surface speeds are
# taken at the plan's samples; between samples (2 ms either side) they change
# by at most the surface acceleration times 2 ms, a few percent of v_safe at
# the path speeds PFL allows. A design margin of this port.
PFL_SPEED_MARGIN = 0.9
# Relative tolerance on path velocities in the PFL speed test (round-off of
# the path profiles, docs/shield_maths.md, 4).
S_DOT_TOLERANCE = 1e-9

_MODES = {}   # name -> ShieldMode instance, in registration order
_Mode = TypeVar('_Mode', bound='ShieldMode')   # register's class.


class ShieldView(Protocol):
  """What a mode reads of the shield whose cycles it checks: members of
  `shield.Shield` (shield.py imports this module, so the modes name the
  shield by what they read of it; docs/extending.md, "A shield mode")."""

  @property
  def speed_limit(self) -> Optional[float]:
    """The mode's speed limit at the shield's v_safe, m/s (None: no
    contact)."""

  @property
  def interval(self) -> float:
    """The reachability slices' length, s (docs/shield_maths.md, 6)."""

  @property
  def robot(self) -> robot_reach.RobotReach:
    """The robot's capsules and reach capsules."""

  @property
  def energy(self) -> energy_setup.EnergySetup:
    """Energy PFL's inputs: the allowed energies per body, what a body
    can be clamped against and a plan's energy tables."""

  def plan_speeds(self, plan: ltp.LongTermPlan
                  ) -> Tuple[np.ndarray, np.ndarray]:
    """PFL's speed tables of a plan (`Shield.plan_speeds`).

    Args:
      plan: a plan of the shield.
    """


class Slices(NamedTuple):
  """A cycle's check for a mode's readable `verdict`
  (path_check.PathCheck.verify): K slices (the current step, then the
  failsafe's) and their K + 1 edges; the compiled twin is
  mode_kernels.Slices."""
  plan: ltp.LongTermPlan   # The plan the path is on.
  current: path_lib.Path   # The path at the cycle's start.
  failsafe: path_lib.Path  # The failsafe's path.
  times: list        # (K) failsafe times of the edges after the first.
  s_edges: list      # (K + 1) plan times of the edges.
  pieces: list       # failsafe.segments().
  robot: tuple       # Robot reach capsules c1, c2 (K, L, 3), r (K, L).
  human: tuple       # Human reach capsules c1, c2 (M, K, B, 3), r.


class ShieldMode:
  """What the shield does with a cycle's verdict (see the module)."""

  name = None
  gates = True

  def speed_limit(self, v_safe: float) -> Optional[float]:
    """The speed under which the robot may touch the person.

    Args:
      v_safe: the shield's contact speed, m/s.

    Returns:
      The limit, m/s; None: no contact.
    """
    del v_safe
    return None

  @property
  def allows_contact(self) -> bool:
    """Whether a robot-human contact below v_safe is within the mode's
    rules (tasks/runtime/contacts.py)."""
    return self.speed_limit(1.0) is not None

  # The verification: readable (Shield.step) and compiled (mode_kernels),
  # each the other's twin. These implement SSM (speed_limit None) and a
  # speed limit where contact is possible (PFL).

  def failsafe_target(self, shield: ShieldView, plan: ltp.LongTermPlan,
                      s: float) -> Optional[float]:
    """The failsafe's final path velocity. With a speed limit: the largest
    path velocity (1 at most) at which the rest of the plan stays under
    it, since the robot keeps moving after the failsafe.

    Args:
      shield: the shield whose cycle this is.
      plan: the plan the monitored path is on.
      s: the plan time (s) where the intended step ends.

    Returns:
      The path velocity; None: brake to rest.
    """
    allowed = shield.speed_limit
    if allowed is None:
      return None
    remaining = shield.plan_speeds(plan)[1][plan.sample_index(s)]
    return 1.0 if remaining <= allowed else allowed / remaining

  def verdict(self, shield: ShieldView, slices: Slices
              ) -> Tuple[bool, int]:
    """The exact check of a cycle's slices, run when no broad phase settled
    it: SSM's (docs/shield_maths.md, 9.2); with a speed limit also safe
    when from the first slice where contact is possible on the robot
    stays under it (9.3).

    Args:
      shield: the shield whose cycle this is.
      slices: the cycle's slices and reach capsules.

    Returns:
      (safe, the first unsafe slice (-1: none)).
    """
    first = kernels.ssm_first_unsafe(
        *slices.robot, *(np.ascontiguousarray(x) for x in slices.human))
    if first < 0 or shield.speed_limit is None:
      return first < 0, first
    return _slow_enough(shield, slices, first), first

  def kernel_parameters(self, shield: ShieldView) -> tuple:
    """The compiled verification's parameters.

    Args:
      shield: the shield whose cycles run compiled.

    Returns:
      One group: a NamedTuple registered with mode_kernels.register.
    """
    if shield.speed_limit is None:
      return mode_kernels.SsmParameters()
    return mode_kernels.SpeedLimitParameters(float(shield.speed_limit),
                                             S_DOT_TOLERANCE)

  def plan_tables(self, shield: ShieldView, plan: ltp.LongTermPlan
                  ) -> tuple:
    """The compiled verification's tables of a plan.

    Args:
      shield: the shield whose cycles run compiled.
      plan: a plan of the shield.

    Returns:
      One group (a NamedTuple of mode_kernels), the same class for every
      plan of the mode.
    """
    if shield.speed_limit is None:
      return mode_kernels.NoTables()
    return mode_kernels.SpeedTables(*shield.plan_speeds(plan))

  def __repr__(self):
    return f'<shield mode {self.name!r}>'


def _slow_enough(shield, slices, first):
  """PFL: the robot's surface speed stays below the shield's speed limit
  from slice `first` on (and after the failsafe, coasting at its final
  path velocity)."""
  plan, failsafe, times = slices.plan, slices.failsafe, slices.times
  s_edges, pieces = slices.s_edges, slices.pieces
  window, suffix = shield.plan_speeds(plan)
  allowed = shield.speed_limit * (1.0 + S_DOT_TOLERANCE)
  for i in range(first, len(times)):
    if i == 0:
      s_dot = max(slices.current.s_dot, failsafe.s_dot)
    else:
      s_dot = failsafe.max_s_dot(times[i - 1], times[i], pieces)
    if window[plan.sample_index(s_edges[i])] * s_dot > allowed:
      return False
  return (suffix[plan.sample_index(s_edges[-1])] * failsafe.final()[1]
          <= allowed)


def register(cls: Type[_Mode]) -> Type[_Mode]:
  """Class decorator: registers a ShieldMode subclass under `cls.name`.

  Args:
    cls: the subclass; its `name` an identifier not registered yet.

  Returns:
    cls.

  Raises:
    TypeError: cls is not a ShieldMode subclass.
    ValueError: its name is not an identifier or is registered already.
  """
  if not (isinstance(cls, type) and issubclass(cls, ShieldMode)):
    raise TypeError(f'modes.register expects a ShieldMode subclass, got '
                    f'{cls!r}')
  name = cls.name
  if not (isinstance(name, str) and name.isidentifier()):
    raise ValueError(f'{cls.__name__}.name must be an identifier string '
                     f'(e.g. \'pfl_slow\'), got {name!r}')
  if name in _MODES:
    raise ValueError(f'Shield mode {name!r} is already registered '
                     f'({type(_MODES[name]).__name__})')
  _MODES[name] = cls()
  return cls


def unregister(name: str) -> None:
  """Removes a registered mode (e.g. one a test registered).

  Args:
    name: the mode's name.

  Raises:
    ValueError: no mode of that name is registered.
  """
  get(name)
  del _MODES[name]


def names() -> Tuple[str, ...]:
  """Names of the registered modes (shipped first: ssm, pfl, off,
  pfl_energy)."""
  extensions.load()
  return tuple(_MODES)


def get(name: str) -> ShieldMode:
  """The registered mode of a name (extensions loaded first where it is
  not registered yet).

  Args:
    name: the mode's name.

  Returns:
    The mode.

  Raises:
    ValueError: no mode of that name is registered.
  """
  if isinstance(name, str) and name not in _MODES:
    extensions.load()
  if not isinstance(name, str) or name not in _MODES:
    raise ValueError(f'Unknown shield mode {name!r}: expected one of '
                     f'{", ".join(map(repr, _MODES))}')
  return _MODES[name]


@register
class Ssm(ShieldMode):
  """Speed and separation monitoring: the robot's reachable set over the
  failsafe must not meet the person's (docs/shield_maths.md, 9.2)."""
  name = 'ssm'


@register
class Pfl(ShieldMode):
  """Power and force limiting: where contact is possible the robot moves
  slower than PFL_SPEED_MARGIN x v_safe (docs/shield_maths.md, 9.3)."""
  name = 'pfl'

  def speed_limit(self, v_safe: float) -> Optional[float]:
    """PFL_SPEED_MARGIN x v_safe.

    Args:
      v_safe: the shield's contact speed, m/s.

    Returns:
      The limit, m/s.
    """
    return PFL_SPEED_MARGIN * v_safe


@register
class Off(ShieldMode):
  """Unshielded: the robot follows its goals; the check only feeds
  read-outs (minimal distance, overlays)."""
  name = 'off'
  gates = False


@register
class PflEnergy(ShieldMode):
  """Energy-based power and force limiting: where contact is possible
  every possible contact stays within its body region's energy limit,
  clamped or transient, and the robot coasts after the failsafe within
  the smallest clamped limit (docs/shield_maths.md, 9.4; docs/safety.md,
  "Energy limits of body regions"). The shield's energy model, limits,
  clamp geometry and plan tables: its `energy`
  (energy_setup.EnergySetup)."""
  name = 'pfl_energy'

  @property
  def allows_contact(self) -> bool:
    """True: contacts within the energy limits are within the rules."""
    return True

  def failsafe_target(self, shield: ShieldView, plan: ltp.LongTermPlan,
                      s: float) -> Optional[float]:
    """The failsafe's final path velocity: the largest (1 at most) at
    which the rest of the plan stays within the coasting energy
    (energy_verification.coasting_speed).

    Args:
      shield: the shield whose cycle this is.
      plan: the plan the monitored path is on.
      s: the plan time (s) where the intended step ends.

    Returns:
      The path velocity.
    """
    energy = shield.energy
    remaining = energy.plan_energies(plan)[1][plan.sample_index(s)]
    return energy_verification.coasting_speed(remaining, energy.limits)

  def verdict(self, shield: ShieldView, slices: Slices
              ) -> Tuple[bool, int]:
    """The exact check of a cycle's slices: SSM-safe, or from the first
    slice where contact is possible on within the energy limits
    (`_energy_enough`; docs/shield_maths.md, 9.4).

    Args:
      shield: the shield whose cycle this is.
      slices: the cycle's slices and reach capsules.

    Returns:
      (safe, the first SSM-unsafe slice (-1: none)).
    """
    first = kernels.ssm_first_unsafe(
        *slices.robot, *(np.ascontiguousarray(x) for x in slices.human))
    if first < 0:
      return True, first
    return _energy_enough(shield, slices, first), first

  def kernel_parameters(self, shield: ShieldView) -> tuple:
    """The compiled verification's parameters: the shield's energy limits
    and clamp geometry.

    Args:
      shield: the shield whose cycles run compiled.

    Returns:
      A mode_kernels.EnergyParameters.
    """
    limits, clamp = shield.energy.limits, shield.energy.clamp_geometry
    energy_check_kernels.warm_up()   # The readable verdict's kernel.
    return mode_kernels.EnergyParameters(
        transient=np.ascontiguousarray(limits.transient, dtype=float),
        clamped=np.ascontiguousarray(limits.clamped, dtype=float),
        thickness=np.ascontiguousarray(limits.thickness, dtype=float),
        coasting=float(limits.coasting),
        box_min=np.ascontiguousarray(clamp.box_min, dtype=float),
        box_max=np.ascontiguousarray(clamp.box_max, dtype=float),
        clampable=np.ascontiguousarray(clamp.clampable, dtype=np.bool_),
        frame_index=np.ascontiguousarray(shield.robot.frame_index,
                                         dtype=np.int64))

  def plan_tables(self, shield: ShieldView, plan: ltp.LongTermPlan
                  ) -> tuple:
    """The compiled verification's tables of a plan: its energy tables
    (`EnergySetup.plan_energies`).

    Args:
      shield: the shield whose cycles run compiled.
      plan: a plan of the shield.

    Returns:
      A mode_kernels.EnergyTables.
    """
    return mode_kernels.EnergyTables(*shield.energy.plan_energies(plan))


def _energy_enough(shield, slices, first):
  """Energy PFL: from slice `first` on every possible contact within its
  body's limit, each capsule's energy the slice's largest path velocity
  squared times the plan's window table at its link, and coasting after
  the failsafe within the coasting energy (energy_verification.verify)."""
  plan, failsafe, times = slices.plan, slices.failsafe, slices.times
  s_edges, pieces = slices.s_edges, slices.pieces
  energy = shield.energy
  window, suffix = energy.plan_energies(plan)
  s_dot = np.zeros(len(times))
  rows = np.zeros(len(times), dtype=int)
  for i in range(first, len(times)):
    if i == 0:
      s_dot[i] = max(slices.current.s_dot, failsafe.s_dot)
    else:
      s_dot[i] = failsafe.max_s_dot(times[i - 1], times[i], pieces)
    rows[i] = plan.sample_index(s_edges[i])
  energies = energy_verification.slice_energies(
      s_dot, window[rows], shield.robot.frame_index)
  return energy_verification.verify(
      slices.robot, slices.human, energies, energy.limits,
      energy.clamp_geometry, failsafe.final()[1],
      suffix[plan.sample_index(s_edges[-1])], start=first) < 0
