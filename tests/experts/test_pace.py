"""The pace metrics of expert evaluation (experts/pace.py) against the
shield's read-outs, step by step."""

import math

import numpy as np

from hrc_suite import experts
from hrc_suite import suite
from hrc_suite.experts import pace


def test_pace_metrics_follow_the_shield_read_outs():
  env = suite.load('handover', 'robot_to_human', task_kwargs=dict(
      robot='panda', seed=0, time_limit=25.0))
  policy = experts.make(env)
  observer = pace.PaceObserver()
  timestep = env.reset()
  observer.observe_first(env, timestep)
  speeds, near, first = [], [], math.nan
  while not timestep.last():
    timestep = env.step(policy(timestep))
    observer.observe(env, timestep)
    task = env.task
    speed = task.shield.max_cartesian_speed
    speeds.append(speed)
    if task.step_metrics['min_human_distance'] < pace.NEAR_DISTANCE:
      near.append(speed)
    if math.isnan(first) and task.step_metrics.get('handovers', 0):
      first = task.episode_metrics['steps'] * task.control_timestep
  result = observer.get_metrics()
  assert near, 'the robot never came near the person'
  assert result['robot_speed_mean'] == np.mean(speeds)
  assert result['robot_speed_near_mean'] == np.mean(near)
  assert result['robot_speed_near_max'] == max(near)
  assert result['near_steps'] == len(near)
  assert not math.isnan(first), 'no handover within the time limit'
  assert result['time_to/handovers'] == first
  assert observer.episodes[-1] == result
