"""Observables every task shares, and selection by preset or by name.

Shared (docs/reference_benchmark.md, Observations): joint angles and
velocities, gripper aperture, end-effector (TCP) pose, human keypoints in
the world, head and hands in the TCP frame and their distances, safe and
critical human contact and static collision flags of the last RL step.
Tasks add goals and objects. The quantities of one entity are that
entity's observables, named here as the observation names them. Cameras
of the workcell join as RGB images (`add_cameras`).
"""

import collections

from dm_control.composer.observation import observable
import numpy as np

from hrc_suite.tasks.runtime import contacts
from hrc_suite.tasks.runtime import cost as cost_lib

# Human keypoints observed relative to the end effector: head and hands
# (docs/reference_benchmark.md, Observations).
OBSERVED_HUMAN_KEYPOINTS = ('head', 'left_hand', 'right_hand')
# The observations preset of HrcTask's default, and the safe-RL preset: it
# adds the cost observables (which exist only in tasks with a cost).
DEFAULT_PRESET = 'paper'
SAFE_RL = 'safe_rl'
COST_OBSERVABLES = ('cost', 'cost_components')
DEFAULT_CAMERA_SIZE = (84, 84)        # pixels (height, width), as in DMC


def _flag(contact_flags, *names):
  """Observable callable: (1,) float, 1 if any of the contact types `names`
  occurred in the last RL step."""
  indices = np.array([contacts.TYPE_INDEX[name] for name in names])
  return lambda physics: np.array([float(contact_flags[indices].any())])


def shared_observables(robot, gripper, human, contact_flags):
  """name -> observable; contact_flags: the task's flags of the last RL
  step, one per contacts.CONTACT_TYPES (an array it updates)."""
  in_eef, distances = human.add_relative_observables(
      robot.tcp_site, OBSERVED_HUMAN_KEYPOINTS, name='eef')
  obs = collections.OrderedDict()
  obs['joint_positions'] = robot.observables.joint_positions
  obs['joint_velocities'] = robot.observables.joint_velocities
  obs['gripper_aperture'] = gripper.observables.aperture
  obs['eef_position'] = robot.observables.end_effector_position
  obs['eef_quaternion'] = robot.observables.end_effector_quaternion
  obs['human_keypoints'] = human.observables.keypoint_positions
  obs['human_in_eef_frame'] = in_eef
  obs['human_distances'] = distances
  obs['static_collision'] = observable.Generic(
      _flag(contact_flags, 'static'))
  # Safe: the robot's own motion was slow, whether or not the person had
  # pushed it (human_pushed; contacts.py).
  obs['safe_contact'] = observable.Generic(
      _flag(contact_flags, 'human_allowed', 'human_pushed'))
  obs['critical_contact'] = observable.Generic(
      _flag(contact_flags, 'human_critical'))
  return obs


def cost_observables(metrics):
  """name -> observable of the last RL step's cost (1,) and its
  components (len(cost.COMPONENTS),), read from the task's EpisodeMetrics
  (zeros before the first step)."""
  names = cost_lib.metric_names()
  obs = collections.OrderedDict()
  obs['cost'] = observable.Generic(lambda physics: np.array(
      [float(metrics.step.get(cost_lib.COST, 0.0))]))
  obs['cost_components'] = observable.Generic(lambda physics: np.array(
      [float(metrics.step.get(name, 0.0)) for name in names[:-1]]))
  return obs


def safe_rl_preset(observables, presets):
  """The 'safe_rl' preset: the default preset (every observable but the
  cost ones where a task has none) and the cost observables."""
  base = presets.get(DEFAULT_PRESET)
  if base is None:
    base = tuple(n for n in observables if n not in COST_OBSERVABLES)
  return tuple(base) + COST_OBSERVABLES


def select(observables, presets, selection):
  """Enables the observables named by a preset or a list; returns the
  enabled names in order. 'full' (every observable) is always a preset."""
  presets = dict(presets)
  presets['full'] = tuple(observables)
  if isinstance(selection, str):
    names = presets.get(selection)
    if names is None:
      raise ValueError(f'Unknown observations preset {selection!r}: '
                       f'expected one of {", ".join(sorted(presets))} or a '
                       'list of observable names')
  else:
    if not (isinstance(selection, (list, tuple))
            and all(isinstance(name, str) for name in selection)):
      raise ValueError('observations must be a preset name ('
                       f'{", ".join(sorted(presets))}) or a list of '
                       f'observable names, got {selection!r:.80}')
    names = list(selection)
    unknown = [n for n in names if n not in observables]
    if unknown or not names:
      raise ValueError(f'Unknown observables {unknown}: expected a non-empty '
                       f'list from {", ".join(observables)}')
  for name, value in observables.items():
    value.enabled = name in names
  return tuple(n for n in observables if n in names)


def task_observables(robot, gripper, human, contact_flags, own, presets,
                     metrics, selection):
  """A task's observables and the names `selection` enables.

  Args:
    robot, gripper, human: the task's entities (`shared_observables`).
    contact_flags: the task's contact flags of the last RL step.
    own: a callable returning the task's own observables (name ->
      observable), called after the shared ones are made.
    presets: the task's presets (name -> observable names).
    metrics: the task's EpisodeMetrics where it has a cost (the cost
      observables and the 'safe_rl' preset join), else None.
    selection: a preset name or a list of observable names (`select`).

  Returns:
    (name -> observable, the enabled names in order).
  """
  obs = shared_observables(robot, gripper, human, contact_flags)
  obs.update(own())
  presets = dict(presets)
  if metrics is not None:
    obs.update(cost_observables(metrics))
    presets[SAFE_RL] = safe_rl_preset(obs, presets)
  return obs, select(obs, presets, selection)


def _is_integer(value):
  return isinstance(value, (int, np.integer)) and not isinstance(value, bool)


def add_cameras(observables, names, mjcf_model, cameras, camera_size):
  """Adds enabled RGB observables 'camera_<name>' of named cameras.

  Args:
    observables: name -> observable, to which the cameras are added.
    names: the enabled observable names so far.
    mjcf_model: the workcell's model (its cameras and offscreen
      framebuffer, into which cameras render; workcell.py).
    cameras: a camera name or a list of names.
    camera_size: (height, width) in pixels, at most the framebuffer's.

  Returns:
    `names` followed by the cameras' observable names.
  """
  if isinstance(cameras, str):
    cameras = (cameras,)
  if not (isinstance(cameras, (list, tuple))
          and all(isinstance(name, str) for name in cameras)):
    raise ValueError('cameras must be a camera name or a list of names, '
                     f'got {cameras!r}')
  frame = getattr(mjcf_model.visual, 'global')
  largest = (frame.offheight, frame.offwidth)
  if not (isinstance(camera_size, (list, tuple)) and len(camera_size) == 2
          and all(_is_integer(v) and 0 < v <= top
                  for v, top in zip(camera_size, largest))):
    raise ValueError('camera_size must be (height, width) in pixels, at '
                     f'most the offscreen framebuffer {largest}, got '
                     f'{camera_size!r}')
  available = {c.name: c for c in mjcf_model.find_all('camera')}
  names = tuple(names)
  for name in cameras:
    if name not in available:
      raise ValueError(f'Unknown camera {name!r}: expected some of '
                       f'{", ".join(sorted(available))}')
    camera = observable.MJCFCamera(available[name],
                                   height=int(camera_size[0]),
                                   width=int(camera_size[1]))
    camera.enabled = True
    observables[f'camera_{name}'] = camera
    names += (f'camera_{name}',)
  return names


def _uniform_noise(bound):
  def corrupt(value, random_state):
    value = np.asarray(value, dtype=np.float64)
    return value + random_state.uniform(-bound, bound, value.shape)
  return corrupt


def configure_noise_and_delay(observables, noise, delay, physics_timestep):
  """Bounded uniform noise and delays on selected observables.

  noise: None or {name: bound}: uniform in [-bound, bound] added to every
  entry (drawn from the environment's random_state). delay: None or
  {name: seconds}, a multiple of the physics timestep.
  """
  for what, settings in (('observation_noise', noise),
                         ('observation_delay', delay)):
    if settings is None:
      continue
    if not isinstance(settings, dict):
      raise ValueError(f'{what} must be None or a dict of observable name ->'
                       f' number, got {settings!r}')
    for name, value in settings.items():
      if name not in observables:
        raise ValueError(f'{what}: unknown observable {name!r}, expected one'
                         f' of {", ".join(observables)}')
      if not (isinstance(value, (int, float)) and np.isfinite(value)
              and value >= 0):
        raise ValueError(f'{what}[{name!r}] must be a finite number >= 0, '
                         f'got {value!r}')
      if what == 'observation_noise':
        observables[name].corruptor = _uniform_noise(float(value))
      else:
        steps = value / physics_timestep
        if abs(steps - round(steps)) > 1e-6:
          raise ValueError(f'{what}[{name!r}] = {value} s is not a multiple '
                           f'of the physics timestep {physics_timestep} s')
        observables[name].delay = int(round(steps))
