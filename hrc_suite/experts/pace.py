"""How fast a policy's robot works near the person: episode metrics beside
the task's own, for comparing shield modes (docs/results/pfl_energy.md).

`PaceObserver` adds to an episode's metrics (tasks/runtime/metrics.py):

* robot_speed_mean: m/s, the mean over RL steps of the robot's largest
  capsule surface speed at the shield's command at the step's end
  (`Shield.max_cartesian_speed`);
* robot_speed_near_mean, robot_speed_near_max: m/s, the same over the RL
  steps whose robot-human distance at the command (the step metric
  min_human_distance) is below NEAR_DISTANCE (0 where there is none);
* near_steps: the number of those RL steps;
* time_to/<counter>: s, the time of the first RL step at which one of the
  task's own counters (EXTRA_COUNTERS, e.g. handovers, nail_blows) counts,
  NaN where it never does.

Reading these changes no episode: the shield's read-outs are computed
lazily from its state.
"""

import math
from typing import Optional

from dm_control import composer
import dm_env
import numpy as np

from hrc_suite.tasks.runtime import metrics as metrics_lib

# m: robot and person capsules closer than this count as near (design
# value: the length of a forearm with the hand, the distance one reach of
# the person closes).
NEAR_DISTANCE = 0.4


class PaceObserver(metrics_lib.EpisodeMetricsObserver):
  """EpisodeMetricsObserver with the pace metrics of the module."""

  def observe_first(self, env: composer.Environment,
                    timestep: dm_env.TimeStep) -> None:
    """Starts an episode's metrics.

    Args:
      env: the environment.
      timestep: its first timestep.
    """
    super().observe_first(env, timestep)
    self._speeds, self._near = [], []
    self._counters = tuple(env.task.defaults().extra_counters)
    self._first = {name: math.nan for name in self._counters}
    self._add(env)

  def observe(self, env: composer.Environment, timestep: dm_env.TimeStep,
              action: Optional[np.ndarray] = None) -> None:
    """Adds an RL step to the episode's metrics.

    Args:
      env: the environment.
      timestep: the timestep the step led to.
      action: the action taken (unused).
    """
    step = env.task.step_metrics
    speed = float(env.task.shield.max_cartesian_speed)
    self._speeds.append(speed)
    if step.get('min_human_distance', math.inf) < NEAR_DISTANCE:
      self._near.append(speed)
    seconds = env.task.episode_metrics['steps'] * env.task.control_timestep
    for name in self._counters:
      if math.isnan(self._first[name]) and step.get(name, 0):
        self._first[name] = seconds
    super().observe(env, timestep, action)
    self._add(env)
    if timestep.last():
      self.episodes[-1] = self._current

  def _add(self, env):
    del env
    near = self._near
    self._current.update(
        robot_speed_mean=float(np.mean(self._speeds)) if self._speeds
        else 0.0,
        robot_speed_near_mean=float(np.mean(near)) if near else 0.0,
        robot_speed_near_max=float(max(near)) if near else 0.0,
        near_steps=float(len(near)))
    for name, value in self._first.items():
      self._current[f'time_to/{name}'] = value
