"""A task's facts and defaults, checked in one place.

An `HrcTask` subclass states them as class constants (MOTIONS, HORIZON,
REWARDS, ...; their base values: `TaskConstants`);
`TaskDefaults.of(task_class)` (the class's `defaults()`) gathers them into
one frozen dataclass whose construction checks every one, with an error
naming the class, the constant and what was expected. `suite.register` and
`HrcTask.__init__` build it, so a task class with a bad constant fails
where it is registered (at import), not in an episode (docs/extending.md).
"""

import dataclasses
import math
from typing import Mapping, Optional, Tuple

from hrc_suite import layout
from hrc_suite.entities import gripper as gripper_lib
from hrc_suite.human import clip as clip_lib
from hrc_suite.safety.shield import modes
from hrc_suite.tasks.runtime import actions

# The class constant of each field, in field order.
CONSTANTS = {
    'motions': 'MOTIONS', 'events': 'EVENTS',
    'human_station': 'HUMAN_STATION',
    'table': 'TABLE', 'human_placement_range': 'HUMAN_PLACEMENT_RANGE',
    'shield': 'DEFAULT_SHIELD', 'action_space': 'DEFAULT_ACTION_SPACE',
    'rewards': 'REWARDS', 'reward_delay': 'DEFAULT_REWARD_DELAY',
    'horizon': 'HORIZON', 'has_gripper_action': 'HAS_GRIPPER_ACTION',
    'observation_presets': 'OBSERVATION_PRESETS',
    'extra_counters': 'EXTRA_COUNTERS',
    'fingertip_table_clearance': 'FINGERTIP_TABLE_CLEARANCE',
    'cartesian_yaw': 'CARTESIAN_YAW', 'grip_force': 'GRIP_FORCE',
    'task_state': 'TASK_STATE',
}


def _number(value):
  return (isinstance(value, (int, float)) and not isinstance(value, bool)
          and math.isfinite(value))


def _names(value):
  return isinstance(value, tuple) and all(
      isinstance(v, str) and v for v in value)


@dataclasses.dataclass(frozen=True)
class TaskDefaults:
  """The class constants of a task (CONSTANTS names each field's)."""
  motions: str                      # a shipped motion library
  # The events that end the person's idle phases, in the order the phases
  # occur: the task triggers them (`_human_events`) and its clips must
  # wait for exactly these (`motions.check_motions`). Event names are
  # strings (shipped ones: `clip.Event`), so a task may declare new ones.
  events: Tuple[str, ...]
  human_station: Tuple[float, float, float]   # (x, y, yaw), layout.py
  table: layout.Table
  # Uniform +- (x, y, yaw) about the station.
  human_placement_range: Tuple[float, float, float]
  shield: str                       # a registered shield mode
  action_space: str
  rewards: Tuple[str, ...]          # the first is the default
  reward_delay: int                 # RL steps
  horizon: int                      # RL steps
  has_gripper_action: bool          # the action's last entry: the gripper
  observation_presets: Mapping[str, Tuple[str, ...]]
  extra_counters: Tuple[str, ...]   # the task's episode metrics
  # Collision prevention keeps the tool capsule out of the table (None) or
  # lets it dip in by its radius minus this clearance (m): the fingertips
  # stay this far above the table, low enough to grasp objects lying on
  # it.
  fingertip_table_clearance: Optional[float]
  cartesian_yaw: float              # rad, the gripper yaw of IK goals
  grip_force: float                 # N, the gripper's squeeze
  # Attribute names that hold the task's own episode state (snapshots).
  task_state: Tuple[str, ...]
  owner: str = 'HrcTask'            # the class, for error messages

  def _fail(self, field, expected):
    raise ValueError(f'{self.owner}.{CONSTANTS[field]}: expected '
                     f'{expected}, got {getattr(self, field)!r}')

  def __post_init__(self):
    if self.motions not in clip_lib.MOTION_TASKS:
      self._fail('motions', 'a shipped motion library, one of '
                 + ', '.join(clip_lib.MOTION_TASKS))
    if not (isinstance(self.events, tuple)
            and all(clip_lib.is_event_name(e) for e in self.events)):
      self._fail('events', 'a tuple of event names (identifiers, e.g. '
                 "clip.Event.nail_hammered or 'pose_reached')")
    for field in ('human_station', 'human_placement_range'):
      value = getattr(self, field)
      if not (isinstance(value, tuple) and len(value) == 3
              and all(_number(v) for v in value)):
        self._fail(field, '(x, y, yaw): three finite numbers')
    if any(v < 0 for v in self.human_placement_range):
      self._fail('human_placement_range', 'half-widths >= 0')
    if not isinstance(self.table, layout.Table):
      self._fail('table', 'a layout.Table')
    if self.shield not in modes.names():
      self._fail('shield', 'a shield mode, one of '
                 + ', '.join(modes.names()))
    if self.action_space not in actions.ACTION_SPACES:
      self._fail('action_space', 'one of ' + ', '.join(actions.ACTION_SPACES))
    if not (_names(self.rewards) and self.rewards):
      self._fail('rewards', 'a non-empty tuple of reward names')
    for field, low in (('reward_delay', 0), ('horizon', 1)):
      value = getattr(self, field)
      if not (isinstance(value, int) and not isinstance(value, bool)
              and value >= low):
        self._fail(field, f'an integer >= {low}')
    if not isinstance(self.has_gripper_action, bool):
      self._fail('has_gripper_action', 'True or False')
    presets = self.observation_presets
    if not (isinstance(presets, Mapping) and all(
        isinstance(k, str) and _names(v) for k, v in presets.items())):
      self._fail('observation_presets',
                 'a dict of preset name -> tuple of observable names')
    for field in ('extra_counters', 'task_state'):
      if not _names(getattr(self, field)):
        self._fail(field, 'a tuple of names')
    clearance = self.fingertip_table_clearance
    if clearance is not None and not (_number(clearance) and clearance >= 0):
      self._fail('fingertip_table_clearance', 'None or a distance >= 0 (m)')
    if not _number(self.cartesian_yaw):
      self._fail('cartesian_yaw', 'a finite angle (rad)')
    if not (_number(self.grip_force) and self.grip_force > 0):
      self._fail('grip_force', 'a force > 0 (N)')

  @classmethod
  def of(cls, task_class):
    """The checked defaults of an HrcTask subclass."""
    return cls(owner=task_class.__name__, **{
        field: getattr(task_class, constant)
        for field, constant in CONSTANTS.items()})


class TaskConstants:
  """A task's facts and defaults as class constants (HrcTask has them;
  subclasses override them). Each is documented at its field of
  `TaskDefaults` (CONSTANTS names it), which `defaults()` checks; their
  values come from docs/reference_benchmark.md, Tasks."""
  MOTIONS = 'reach'                          # shipped library name
  EVENTS = ()                                # ends of the idle phases
  HUMAN_STATION = layout.HUMAN_STATION_ACROSS
  TABLE = layout.DEFAULT_TABLE               # layout.Table
  HUMAN_PLACEMENT_RANGE = (0.0, 0.0, 0.0)    # uniform +- (x, y, yaw)
  DEFAULT_SHIELD = 'ssm'
  DEFAULT_ACTION_SPACE = 'cartesian'
  REWARDS = ('sparse',)                      # first is the default
  DEFAULT_REWARD_DELAY = 0                   # RL steps
  HORIZON = 1000                             # RL steps
  HAS_GRIPPER_ACTION = True
  OBSERVATION_PRESETS = {}                   # name -> observable names
  EXTRA_COUNTERS = ()
  FINGERTIP_TABLE_CLEARANCE = None           # m, or None
  CARTESIAN_YAW = actions.GRIPPER_YAW        # rad, gripper yaw of IK goals
  GRIP_FORCE = gripper_lib.GRIP_FORCE        # N, the gripper's squeeze
  TASK_STATE = ()                            # attributes, for snapshots

  @classmethod
  def defaults(cls) -> TaskDefaults:
    """The task's class constants, checked (`TaskDefaults`).

    Returns:
      The task's TaskDefaults.

    Raises:
      ValueError: a class constant of the wrong kind.
    """
    return TaskDefaults.of(cls)
