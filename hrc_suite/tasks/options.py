"""An environment's options (HrcTask's arguments), checked in one place.

`TaskOptions.of(defaults, **arguments)` fills what the arguments leave
None from the task's facts and defaults (`defaults.TaskDefaults`, the
class constants) and checks every value, with an error naming the
argument, the bad value and what was expected. HrcTask builds its scene
from the result, a frozen dataclass (in the spirit of MuJoCo
Playground's task configs). What a module of its own interprets is
checked there: motions (tasks/motions.py), observations and their noise
and delay (tasks/observations.py), cameras (HrcTask._add_cameras).
"""

import dataclasses
import math

from hrc_suite import robot_description
from hrc_suite.entities import workcell as workcell_lib
from hrc_suite.safety import collision_prevention as cp_lib
from hrc_suite.safety import modes as modes_lib
from hrc_suite.tasks import actions
from hrc_suite.tasks import contacts

DEFAULT_SHIELD_SUBSTEPS = 25          # L (docs/reference_benchmark.md, Timing)
DEFAULT_PHYSICS_TIMESTEP = workcell_lib.PHYSICS_TIMESTEP   # 4 ms
DEFAULT_CONTROL_TIMESTEP = 0.1        # s, 10 Hz RL step
COLLISION_PREVENTION_POLICIES = cp_lib.POLICIES + ('off',)
# PFL safe speed: the reference code that produced the paper used 50 mm/s
# (docs/reference_benchmark.md, Safety).
DEFAULT_V_SAFE = 0.05                 # m/s
# Reward of an illegal contact (static, self, critical human): the
# reference's default (its paper runs used 0).
DEFAULT_COLLISION_REWARD = -10.0


def choice(name, value, valid):
  """value if it is one of `valid`, else a ValueError naming `name`."""
  if value not in valid:
    raise ValueError(f'Unknown {name} {value!r}: expected one of '
                     f'{", ".join(map(repr, valid))}')
  return value


def positive(name, value):
  """value as a float if it is a finite number > 0, else a ValueError."""
  if not (isinstance(value, (int, float)) and not isinstance(value, bool)
          and math.isfinite(value) and value > 0):
    raise ValueError(f'{name} must be a positive number, got {value!r}')
  return float(value)


def _flag(name, value):
  if not isinstance(value, bool):
    raise ValueError(f'{name} must be True or False, got {value!r}')
  return value


@dataclasses.dataclass(frozen=True)
class TaskOptions:
  """HrcTask's checked arguments (see HrcTask.__init__ for each)."""
  robot: str                  # a robot name or description path, resolved
  action_space: str
  shield: str                 # a registered shield mode
  shield_substeps: int        # L: physics steps (shield cycles) per RL step
  physics_timestep: float     # s, also the shield's cycle time
  control_timestep: float     # s, L x physics_timestep
  reward: str                 # one of the task's REWARDS
  reward_delay: int           # RL steps
  done_at_success: bool
  collision_prevention: str   # a policy or 'off'
  time_limit: float           # s
  horizon: int                # RL steps of time_limit
  v_safe: float               # m/s, PFL's safe speed
  critical_speed: float       # m/s, a human contact faster is critical
  collision_reward: float     # <= 0
  fast_path: bool

  @classmethod
  def of(cls, defaults, robot='panda', action_space=None, shield=None,
         shield_substeps=DEFAULT_SHIELD_SUBSTEPS,
         physics_timestep=DEFAULT_PHYSICS_TIMESTEP,
         control_timestep=DEFAULT_CONTROL_TIMESTEP, reward=None,
         reward_delay=None, done_at_success=True,
         collision_prevention='zero', time_limit=None, v_safe=DEFAULT_V_SAFE,
         critical_speed=None, collision_reward=DEFAULT_COLLISION_REWARD,
         fast_path=True):
    """The options of a task with `defaults` (TaskDefaults); None takes
    the task's default."""
    robot = robot_description.resolve(robot)   # A name or a .json path.
    action_space = choice('action_space',
                          action_space or defaults.action_space,
                          actions.ACTION_SPACES)
    shield = choice('shield', shield or defaults.shield, modes_lib.names())
    if (not isinstance(shield_substeps, int) or isinstance(
        shield_substeps, bool) or shield_substeps < 1):
      raise ValueError('shield_substeps must be a positive integer, got '
                       f'{shield_substeps!r}')
    physics_timestep = positive('physics_timestep', physics_timestep)
    control_timestep = positive('control_timestep', control_timestep)
    expected = shield_substeps * physics_timestep
    if abs(control_timestep - expected) > 1e-9 * expected:
      raise ValueError(
          f'control_timestep ({control_timestep} s) must equal '
          f'shield_substeps ({shield_substeps}) x physics_timestep '
          f'({physics_timestep} s) = {expected} s: the shield runs once per '
          'physics step, shield_substeps times per RL step')
    reward = choice('reward', reward or defaults.rewards[0], defaults.rewards)
    delay = defaults.reward_delay if reward_delay is None else reward_delay
    if not isinstance(delay, int) or isinstance(delay, bool) or delay < 0:
      raise ValueError(f'reward_delay must be an integer >= 0 (RL steps), '
                       f'got {reward_delay!r}')
    collision_prevention = choice('collision_prevention',
                                  collision_prevention,
                                  COLLISION_PREVENTION_POLICIES)
    if time_limit is None:
      time_limit = defaults.horizon * control_timestep
    time_limit = positive('time_limit', time_limit)
    v_safe = positive('v_safe', v_safe)
    if critical_speed is None:
      critical_speed = v_safe if modes_lib.get(shield).allows_contact else (
          contacts.SSM_STOPPED_SPEED)
    if not (isinstance(collision_reward, (int, float))
            and not isinstance(collision_reward, bool)
            and math.isfinite(collision_reward) and collision_reward <= 0):
      raise ValueError('collision_reward must be a finite number <= 0, got '
                       f'{collision_reward!r}')
    return cls(
        robot=robot, action_space=action_space, shield=shield,
        shield_substeps=shield_substeps, physics_timestep=physics_timestep,
        control_timestep=control_timestep, reward=reward, reward_delay=delay,
        done_at_success=_flag('done_at_success', done_at_success),
        collision_prevention=collision_prevention, time_limit=time_limit,
        horizon=max(1, int(round(time_limit / control_timestep))),
        v_safe=v_safe,
        critical_speed=positive('critical_speed', critical_speed),
        collision_reward=float(collision_reward),
        fast_path=_flag('fast_path', fast_path))
