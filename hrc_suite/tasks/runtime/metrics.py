"""Safety and task metrics per RL step and per episode, and an observer.

A task keeps two dicts of plain numbers (`step_metrics`, `episode_metrics`)
that any consumer can read after `env.step` without touching task
internals. `EpisodeMetricsObserver` follows Acme's observer protocol
(`observe_first`, `observe`, `get_metrics`); `run_episode` plays one episode
with a policy and returns the episode's metrics.
"""

import numpy as np

from hrc_suite.tasks.runtime import contact_energies
from hrc_suite.tasks.runtime import contacts

# Counters every task reports; tasks add their own (e.g. handovers).
# * shield_interventions: RL steps in which the shield overrode the intended
#   motion in at least one physics step.
# * contacts_<type>: physics steps with at least one contact of that type
#   (contacts.CONTACT_TYPES; human_pushed: the person had pushed the robot
#   off its command and the command itself was slow enough);
#   self_collisions: RL steps whose final configuration self-collides (robot
#   capsule model).
# * shield_resyncs: physics steps after which the robot was farther from the
#   shield's command than its tracking tolerance (pushed), so the shield
#   restarted from the measured pose (docs/safety.md, "Pushed robots").
# * physics_errors: 1 if a MuJoCo physics error ended the episode (its last
#   RL step; docs/safety.md, "Physics errors").
# * action_replacements: actions replaced by collision prevention.
# * ik_failures: Cartesian actions whose IK failed (the goal was kept).
# * goals_reached: RL steps at which the task's goal was reached.
# * steps_outside_human_model: RL steps in which the person moved faster
#   than the shield's human model (only with outside_human_model='allow':
#   outside the safety guarantee, tasks/runtime/motions.check_motions).
# * contacts_human_critical_outside_model: the contacts_human_critical of
#   RL steps in which the person moved faster than the shield's human
#   model (steps_outside_human_model); the rest happened with the person
#   inside the model, where the shield's guarantee applies
#   (docs/safety.md, "Assumptions"). A contact caused by a faster motion in
#   an earlier RL step counts as inside: the inside count errs high.
# Besides: success (0/1, reached at least once), return, steps,
# min_human_distance (m, robot capsules at the shield's command to the human
# body capsules, the minimum over RL step ends), max_human_contact_speed
# (m/s, the robot's fastest commanded surface point in a human contact) and
# max_tracking_error (m, bound on the robot's distance from where the
# shield's command puts it, the maximum over physics steps).
COUNTERS = (('shield_interventions', 'action_replacements', 'ik_failures',
             'self_collisions', 'goals_reached', 'steps_outside_human_model')
            + tuple(f'contacts_{name}' for name in contacts.CONTACT_TYPES)
            + ('contacts_human_critical_outside_model', 'shield_resyncs',
               'physics_errors'))
# Episode maxima of step maxima.
MAXIMA = ('max_human_contact_speed', 'max_tracking_error')
# Episode maxima of robot-human contact energies, in every shield mode
# (tasks/runtime/contact_energies.py: min(E_j, E_n) of the touching link at the
# commanded joint velocities, against the touched body's limit, clamped or
# transient): max_contact_energy (J) and max_contact_energy_ratio over
# every body, contact_energy/<body> and contact_energy_ratio/<body> per
# human body (0 where untouched). In the episode metrics only (not the
# step metrics).
CONTACT_ENERGY_MAXIMA = (
    ('max_contact_energy', 'max_contact_energy_ratio')
    + tuple(f'contact_energy/{body}' for body in contact_energies.BODIES)
    + tuple(f'contact_energy_ratio/{body}'
            for body in contact_energies.BODIES))


def contact_energy_maxima(energies, ratios):
  """The CONTACT_ENERGY_MAXIMA of per-body maxima.

  Args:
    energies: (bodies,) J, the largest contact energy per body
      (contact_energies.BODIES' order).
    ratios: (bodies,) the largest ratio to the limit per body.

  Returns:
    {name: value} of CONTACT_ENERGY_MAXIMA.
  """
  energies = [float(x) for x in energies]
  ratios = [float(x) for x in ratios]
  if len(energies) != len(contact_energies.BODIES) or len(ratios) != len(
      energies):
    raise ValueError(f'expected {len(contact_energies.BODIES)} energies '
                     f'and ratios, got {len(energies)} and {len(ratios)}')
  values = dict(zip(CONTACT_ENERGY_MAXIMA[2:], energies + ratios))
  values['max_contact_energy'] = max(energies)
  values['max_contact_energy_ratio'] = max(ratios)
  return values


class EpisodeMetrics:
  """Accumulates step metrics into episode metrics."""

  def __init__(self, extra_counters=()):
    self.counters = COUNTERS + tuple(extra_counters)
    self.episode = {}
    self.step = {}
    self.reset()

  def reset(self):
    self.episode = {name: 0 for name in self.counters}
    self.episode.update({'success': 0.0, 'return': 0.0, 'steps': 0,
                         'min_human_distance': float('inf')})
    self.episode.update({name: 0.0 for name in MAXIMA})
    self.episode.update({name: 0.0 for name in CONTACT_ENERGY_MAXIMA})
    self.step = {}

  def record(self, step):
    """Adds one RL step's metrics (a dict of numbers)."""
    self.step = dict(step)
    episode = self.episode
    for name in self.counters:
      episode[name] += step.get(name, 0)
    episode['steps'] += 1
    episode['return'] += float(step.get('reward', 0.0))
    if step.get('success', 0.0):
      episode['success'] = 1.0
    distance = step.get('min_human_distance')
    if distance is not None:
      episode['min_human_distance'] = min(episode['min_human_distance'],
                                          float(distance))
    for name in MAXIMA:
      value = step.get(name)
      if value is not None:
        episode[name] = max(episode[name], float(value))

  def record_episode_maxima(self, values):
    """Raises episode maxima to `values` ({name: number}, e.g.
    contact_energy_maxima's), without adding them to the step metrics."""
    episode = self.episode
    for name, value in values.items():
      episode[name] = max(episode.get(name, 0.0), float(value))

  def state(self):
    return {'episode': dict(self.episode), 'step': dict(self.step)}

  def set_state(self, state):
    """Restores `state()`; metrics a snapshot from an older version lacks
    start from their initial values."""
    self.reset()
    self.episode.update(state['episode'])
    self.step = dict(state['step'])


class EpisodeMetricsObserver:
  """Acme-style observer collecting `env.task.episode_metrics` per episode.

  Use with any loop that calls observe_first after reset and observe after
  each step; `get_metrics` returns the last finished (or current) episode's
  metrics, `episodes` all finished ones.
  """

  def __init__(self):
    self.episodes = []
    self._current = None

  def observe_first(self, env, timestep):
    del timestep
    self._current = dict(env.task.episode_metrics)

  def observe(self, env, timestep, action=None):
    del action
    self._current = dict(env.task.episode_metrics)
    if timestep.last():
      self.episodes.append(self._current)

  def get_metrics(self):
    return dict(self._current or {})

  def summary(self):
    """Mean of every metric over the finished episodes."""
    if not self.episodes:
      return {}
    keys = self.episodes[0].keys()
    return {k: float(np.mean([e[k] for e in self.episodes])) for k in keys}


def run_episode(env, policy, observer=None):
  """Plays one episode; policy(timestep) -> action. Returns its metrics."""
  observer = observer or EpisodeMetricsObserver()
  timestep = env.reset()
  observer.observe_first(env, timestep)
  while not timestep.last():
    action = policy(timestep)
    timestep = env.step(action)
    observer.observe(env, timestep, action)
  return observer.get_metrics()
