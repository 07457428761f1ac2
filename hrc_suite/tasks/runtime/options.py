"""An environment's options (HrcTask's arguments), checked in one place.

`TaskOptions.of(defaults, **arguments)` fills what the arguments leave
None from the task's facts and defaults (`defaults.TaskDefaults`, the
class constants) and checks every value, with an error naming the
argument, the bad value and what was expected. HrcTask builds its scene
from the result, a frozen dataclass (in the spirit of MuJoCo
Playground's task configs). What a module of its own interprets is
checked there: motions (tasks/runtime/motions.py), observations and their noise
and delay, cameras (tasks/runtime/observations.py).
"""

import dataclasses
import math
import operator
from typing import Any, Optional, Sequence

from hrc_suite import robot_description
from hrc_suite.entities import workcell as workcell_lib
from hrc_suite.safety import collision_prevention as cp_lib
from hrc_suite.safety.shield import modes as modes_lib
from hrc_suite.tasks.runtime import actions
from hrc_suite.tasks.runtime import contacts
from hrc_suite.tasks.runtime import defaults as defaults_lib

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


def choice(name: str, value: Any, valid: Sequence[Any]) -> Any:
  """value if it is one of `valid`, else a ValueError naming `name`.

  Args:
    name: the argument's name, for the error.
    value: its value.
    valid: the values it may take.

  Returns:
    value.

  Raises:
    ValueError: if value is not one of `valid`.
  """
  if value not in valid:
    raise ValueError(f'Unknown {name} {value!r}: expected one of '
                     f'{", ".join(map(repr, valid))}')
  return value


def positive(name: str, value: Any) -> float:
  """value as a float if it is a finite number > 0, else a ValueError.

  Args:
    name: the argument's name, for the error.
    value: its value.

  Returns:
    float(value).

  Raises:
    ValueError: if value is not a finite number > 0 (bools are not).
  """
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
  """HrcTask's checked arguments (docs/tasks.md, "Task kwargs"). A field
  that is None as an argument takes the task's default (the class
  constants, `defaults.TaskDefaults`).

  HrcTask's other arguments are checked by the modules that interpret
  them:

  * motions: None (the task's shipped clips), a folder of clips, a list
    of `clip.Clip`s, or one side of a train/test split
    (`motions.MotionSplit` or {'split': 'train'|'test', 'test_clips': n,
    'split_seed': k}). A folder may hold BVH recordings or the
    reference's layout (`human.recording_cache`).
  * outside_human_model: 'refuse' (a clip whose person moves faster than
    the shield's human model raises ClipError at construction) or
    'allow' (play it; the metric 'steps_outside_human_model' counts the
    RL steps outside the guarantee; `motions.check_motions`).
  * observations: a preset name ('paper', 'full', ...) or a list of
    observable names (`observations.select`).
  * observation_noise: None or {observable name: bound}: uniform noise in
    [-bound, bound] (drawn from the environment's random_state, so
    snapshots restore the noise-free state, not the noise stream).
  * observation_delay: None or {observable name: seconds}, a multiple of
    physics_timestep.
  * cameras: names of workcell cameras ('front', 'side', 'top',
    'human_view') whose RGB images join the observation as
    'camera_<name>' (uint8, camera_size; `observations.add_cameras`).
  * camera_size: (height, width) of camera observations in pixels, at
    most the workcell's offscreen framebuffer (960, 1280).
  * cost: None (no cost signal), True (the default `cost.CostSpec`), a
    CostSpec or a dict of its fields: every RL step's step metrics then
    hold the safety cost's components and scalar (tasks/runtime/cost.py), and
    the observables 'cost' and 'cost_components' exist (enabled by the
    'safe_rl' observations preset, which implies cost=True).
  """
  # A robot name (`robot_description.names()`: the description files of
  # hrc_suite/assets/robots and those registered) or the path of a .json
  # description file (registered under its name), resolved to a name.
  robot: str
  # 'joint' or 'cartesian' (tasks/runtime/actions.py).
  action_space: str
  # A shield mode of safety/shield/modes.py ('ssm', 'pfl', 'off' or one
  # registered elsewhere).
  shield: str
  # L: physics steps (= shield cycles) per RL step.
  shield_substeps: int
  # s, also the shield's cycle time.
  physics_timestep: float
  # s, must equal shield_substeps x physics_timestep.
  control_timestep: float
  # One of the task's REWARDS (default: its first).
  reward: str
  # RL steps by which task rewards are paid late; what is still owed is
  # paid at the episode's end.
  reward_delay: int
  # End the episode (discount 0) at success.
  done_at_success: bool
  # A collision prevention policy ('zero', 'resample', 'closest') or 'off'.
  collision_prevention: str
  # s, the episode's length (default: the task's HORIZON RL steps).
  time_limit: float
  # RL steps of time_limit (derived).
  horizon: int
  # m/s, PFL's safe robot speed at a human contact.
  v_safe: float
  # m/s, robot speed above which a human contact is critical (default:
  # v_safe in modes that allow contact, such as PFL;
  # contacts.SSM_STOPPED_SPEED else).
  critical_speed: float
  # <= 0, added at RL steps with a static, self or critical human contact.
  collision_reward: float
  # Run an RL step's shield cycles at its start in one call
  # (`safety.shield.batch.step_many`, compiled where it can) and hand the
  # controller the verified set-points, check new goals with compiled
  # capsule tests (`safety.collision_prevention.kernels`), compute the
  # controller's torques, the contact classification, the person's capsule
  # frames and the self-collision check in compiled kernels (the same bit
  # for bit) and, in environments of `suite.load`, run the RL step's
  # physics steps in one composer substep (`substeps`); False runs
  # `Shield.step` every physics step, NumPy collision checks, controller,
  # contact classification and capsule frames and composer's substeps
  # (the readable reference; the two agree, tests/tasks/test_fast_path.py).
  fast_path: bool

  @classmethod
  def of(cls, defaults: defaults_lib.TaskDefaults, robot: str = 'panda',
         action_space: Optional[str] = None, shield: Optional[str] = None,
         shield_substeps: int = DEFAULT_SHIELD_SUBSTEPS,
         physics_timestep: float = DEFAULT_PHYSICS_TIMESTEP,
         control_timestep: float = DEFAULT_CONTROL_TIMESTEP,
         reward: Optional[str] = None, reward_delay: Optional[int] = None,
         done_at_success: bool = True, collision_prevention: str = 'zero',
         time_limit: Optional[float] = None, v_safe: float = DEFAULT_V_SAFE,
         critical_speed: Optional[float] = None,
         collision_reward: float = DEFAULT_COLLISION_REWARD,
         fast_path: bool = True) -> 'TaskOptions':
    """The checked options of a task; None takes the task's default.

    Each argument is the field of the same name (its comment there).

    Args:
      defaults: the task's facts and defaults (its class constants).
      robot: a robot name or a description file's path (default 'panda').
      action_space: 'joint' or 'cartesian' (default: the task's).
      shield: a shield mode's name (default: the task's).
      shield_substeps: L, an integer >= 1 (default 25).
      physics_timestep: s, > 0 (default 0.004).
      control_timestep: s, L x physics_timestep (default 0.1).
      reward: one of the task's rewards (default: its first).
      reward_delay: RL steps, an integer >= 0 (default: the task's).
      done_at_success: whether success ends the episode (default True).
      collision_prevention: 'zero', 'resample', 'closest' or 'off'
        (default 'zero').
      time_limit: s, > 0 (default: the task's horizon x control_timestep).
      v_safe: m/s, > 0 (default 0.05).
      critical_speed: m/s, > 0 (default: v_safe in modes that allow
        contact, contacts.SSM_STOPPED_SPEED else).
      collision_reward: a finite number <= 0 (default -10).
      fast_path: whether the fast path runs (default True).

    Returns:
      The options.

    Raises:
      ValueError: naming the argument, the bad value and what was expected.
    """
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


def _option(name, doc):
  """A read-only property: the option `name` of `self.options`."""
  return property(operator.attrgetter(f'options.{name}'), doc=doc)


class OptionNames:
  """The options of `self.options` (a TaskOptions) by the names tasks and
  users read, read-only (HrcTask has them)."""
  reward_kind = _option('reward', 'The reward, one of REWARDS.')
  reward_delay = _option('reward_delay', 'RL steps task rewards are late.')
  done_at_success = _option('done_at_success', 'Success ends the episode.')
  collision_prevention_policy = _option(
      'collision_prevention', "A collision prevention policy or 'off'.")
  time_limit = _option('time_limit', 's, the episode length.')
  horizon = _option('horizon', 'RL steps of time_limit.')
  collision_reward = _option('collision_reward', '<= 0, of illegal contacts.')
  fast_path = _option('fast_path', 'Whether the fast path runs.')
  shield_mode = _option('shield',
                        'The shield mode (safety/shield/modes.py).')
  shield_substeps = _option('shield_substeps', 'Physics steps per RL step.')
  critical_speed = _option('critical_speed',
                           'm/s, human contacts faster are critical.')
