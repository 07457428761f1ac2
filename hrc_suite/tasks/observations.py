"""Observables every task shares, and selection by preset or by name.

Shared (docs/reference_benchmark.md, Observations): joint angles and
velocities, gripper aperture, end-effector (TCP) pose, human keypoints in
the world, head and hands in the TCP frame and their distances, safe and
critical human contact and static collision flags of the last RL step.
Tasks add goals and objects.
"""

import collections

from dm_control.composer.observation import observable
import numpy as np

from hrc_suite.human import keypoints
from hrc_suite.tasks import contacts

# Human keypoints observed relative to the end effector: head and hands
# (docs/reference_benchmark.md, Observations).
OBSERVED_HUMAN_KEYPOINTS = ('head', 'left_hand', 'right_hand')


def in_frame(physics, site, points):
  """Points (N, 3) in the frame of `site`."""
  frame = physics.bind(site)
  return (points - frame.xpos) @ frame.xmat.reshape(3, 3)


def _flag(contact_flags, *names):
  """Observable callable: (1,) float, 1 if any of the contact types `names`
  occurred in the last RL step."""
  indices = np.array([contacts.TYPE_INDEX[name] for name in names])
  return lambda physics: np.array([float(contact_flags[indices].any())])


def shared_observables(robot, gripper, human, contact_flags):
  """name -> observable; contact_flags: the task's flags of the last RL
  step, one per contacts.CONTACT_TYPES (an array it updates)."""
  tcp = robot.tcp_site
  observed = np.array(keypoints.index(OBSERVED_HUMAN_KEYPOINTS))

  def human_in_eef(physics):
    return in_frame(physics, tcp, human.keypoint_positions(physics)[observed])

  obs = collections.OrderedDict()
  obs['joint_positions'] = observable.MJCFFeature('qpos', robot.joints)
  obs['joint_velocities'] = observable.MJCFFeature('qvel', robot.joints)
  obs['gripper_aperture'] = observable.Generic(
      lambda physics: np.array([gripper.aperture(physics)]))
  obs['eef_position'] = observable.MJCFFeature('xpos', tcp)
  obs['eef_quaternion'] = observable.Generic(
      lambda physics: robot.tcp_pose(physics)[1])
  obs['human_keypoints'] = observable.Generic(human.keypoint_positions)
  obs['human_in_eef_frame'] = observable.Generic(human_in_eef)
  obs['human_distances'] = observable.Generic(
      lambda physics: np.linalg.norm(human_in_eef(physics), axis=-1))
  obs['static_collision'] = observable.Generic(
      _flag(contact_flags, 'static'))
  # Safe: the robot's own motion was slow, whether or not the person had
  # pushed it (human_pushed; contacts.py).
  obs['safe_contact'] = observable.Generic(
      _flag(contact_flags, 'human_allowed', 'human_pushed'))
  obs['critical_contact'] = observable.Generic(
      _flag(contact_flags, 'human_critical'))
  return obs


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
