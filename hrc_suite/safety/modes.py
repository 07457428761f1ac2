"""Shield modes: one class per mode, found by name in one registry.

A mode says what the shield does with each cycle's verification
(docs/safety.md, "Modes"; docs/shield_maths.md, 4 and 9):

* `gates`: the verdict decides the command (the robot takes the intended
  step only on a verified monitored path). False runs unshielded: the
  check only feeds read-outs (metrics, overlays) and runs when one is read.
* `speed_limit(v_safe)`: None (SSM: the robot's reachable set must not
  meet the human's), or the surface speed (m/s) the robot must stay under
  wherever it may touch the person (PFL; the shield's speed tables bound
  the plan's capsule surface speeds, `shield.pfl_speed_tables`).
* `allows_contact`: whether a robot-human contact below v_safe is within
  the mode's rules (tasks then call contacts critical above v_safe
  instead of above the stopped speed; tasks/contacts.py).

Both the readable shield and its compiled twin (`batch`,
`cycle_kernels`) run every mode expressed through these. A new mode is
a subclass registered by name (docs/extending.md, "A shield mode"):

  @modes.register
  class SlowPfl(modes.Pfl):
    name = 'pfl_slow'
    def speed_limit(self, v_safe):
      return 0.5 * v_safe

Tasks, rendering, tags and the binaries' flags ask `names()` / `get()`.
"""

from hrc_suite import extensions

# PFL: speeds are compared with this fraction of v_safe. Surface speeds are
# taken at the plan's samples; between samples (2 ms either side) they change
# by at most the surface acceleration times 2 ms, a few percent of v_safe at
# the path speeds PFL allows. A design margin of this port.
PFL_SPEED_MARGIN = 0.9

_MODES = {}   # name -> ShieldMode instance, in registration order


class ShieldMode:
  """What the shield does with a cycle's verdict (see the module)."""

  name = None
  gates = True

  def speed_limit(self, v_safe):
    """m/s under which the robot may touch the person; None: no contact."""
    del v_safe
    return None

  @property
  def allows_contact(self):
    return self.speed_limit(1.0) is not None

  def __repr__(self):
    return f'<shield mode {self.name!r}>'


def register(cls):
  """Class decorator: registers a ShieldMode subclass under `cls.name`."""
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


def unregister(name):
  """Removes a registered mode (e.g. one a test registered)."""
  get(name)
  del _MODES[name]


def names():
  """Names of the registered modes (shipped first: ssm, pfl, off)."""
  extensions.load()
  return tuple(_MODES)


def get(name):
  """The registered ShieldMode called `name`."""
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

  def speed_limit(self, v_safe):
    return PFL_SPEED_MARGIN * v_safe


@register
class Off(ShieldMode):
  """Unshielded: the robot follows its goals; the check only feeds
  read-outs (minimal distance, overlays)."""
  name = 'off'
  gates = False
