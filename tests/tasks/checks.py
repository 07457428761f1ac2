"""Checks every task's tests share: random rollouts, rewards in range,
same seed same episode, snapshot/restore bit-exactness, a person in the
robot's path."""

import numpy as np

from hrc_suite import suite
from hrc_suite.human import clip as clip_lib
from hrc_suite.human import keypoints
from hrc_suite.tasks import reach


def random_actions(env, count, seed=1, scale=1.0, gripper=None):
  """`count` uniform actions in [-scale, scale] from their own seed; the
  last entry fixed to `gripper` if given."""
  rs = np.random.RandomState(seed)
  shape = env.action_spec().shape
  out = [scale * rs.uniform(-1.0, 1.0, shape) for _ in range(count)]
  if gripper is not None:
    for action in out:
      action[-1] = gripper
  return out


def rollout(env, actions):
  """(reward, discount, observation copy) of each step of `actions`."""
  out = []
  for action in actions:
    timestep = env.step(action)
    out.append((timestep.reward, timestep.discount,
                {name: np.array(value, copy=True)
                 for name, value in timestep.observation.items()}))
  return out


def assert_same(first, second):
  """Two rollouts have the same rewards, discounts and observations, bit
  for bit."""
  assert len(first) == len(second)
  for k, ((r1, d1, o1), (r2, d2, o2)) in enumerate(zip(first, second)):
    assert r1 == r2, f'step {k}: reward {r1} != {r2}'
    assert d1 == d2, f'step {k}: discount {d1} != {d2}'
    assert sorted(o1) == sorted(o2)
    for name in o1:
      np.testing.assert_array_equal(o1[name], o2[name],
                                    err_msg=f'step {k}: {name}')


def run_random_episode(env, timestep=None, seed=0, max_steps=None):
  """Steps random actions from `timestep` (None: a reset) to the episode's
  end, checking each reward against task.reward_range and every
  observation for finiteness. Returns the rewards, one per step."""
  if timestep is None:
    timestep = env.reset()
  low, high = env.task.reward_range
  for name, value in timestep.observation.items():
    assert np.all(np.isfinite(value)), name
  rs = np.random.RandomState(seed)
  shape = env.action_spec().shape
  rewards = []
  while not timestep.last():
    timestep = env.step(rs.uniform(-1.0, 1.0, shape))
    rewards.append(timestep.reward)
    assert low <= timestep.reward <= high, (timestep.reward, low, high)
    for name, value in timestep.observation.items():
      assert np.all(np.isfinite(value)), name
    if max_steps is not None:
      assert len(rewards) <= max_steps
  return rewards


def assert_same_seed_same_episode(make_env, steps=8, **action_kwargs):
  """Two environments from `make_env()` (same seed) give the same episode
  under the same random actions (`random_actions` kwargs)."""
  runs = []
  for _ in range(2):
    env = make_env()
    first = env.reset().observation
    runs.append([(None, None, {k: np.array(v, copy=True) for k, v in
                               first.items()})]
                + rollout(env, random_actions(env, steps, **action_kwargs)))
  assert_same(*runs)


def assert_snapshot_restores(env, make_fresh=None, replay=6, diverge=4,
                             **action_kwargs):
  """Snapshot `env` where it is, replay `replay` random actions, diverge,
  restore: the replay repeats bit for bit, metrics included; likewise in
  `make_fresh()`'s environment (reset first, e.g. with another seed: other
  clip, other objects) when given. `action_kwargs` go to random_actions.
  Returns the snapshot."""
  state = env.task.get_state(env.physics)
  actions = random_actions(env, replay, seed=3, **action_kwargs)
  first = rollout(env, actions)
  metrics = dict(env.task.episode_metrics)
  rollout(env, random_actions(env, diverge, seed=4, **action_kwargs))
  env.task.set_state(env.physics, state)
  assert_same(first, rollout(env, actions))
  assert env.task.episode_metrics == metrics
  if make_fresh is not None:
    fresh = make_fresh()
    fresh.reset()
    fresh.task.set_state(fresh.physics, state)
    assert_same(first, rollout(fresh, actions))
  return state


def torso_in_base_sweep(task):
  """A torso position on the circle the TCP sweeps when the base joint
  turns from home towards +y, 90 degrees on: a robot turning its base runs
  into a person standing there."""
  q_home = task.robot.description.q_home
  tcp = task.kinematics.tcp_pose(q_home)[:3, 3]
  radius = np.linalg.norm(tcp[:2])
  angle = np.arctan2(tcp[1], tcp[0]) + np.pi / 2
  return np.array([radius * np.cos(angle), radius * np.sin(angle), tcp[2]])


def clip_with_keypoint_at(task, point, keypoint):
  """A still human whose `keypoint` sits at `point` (world)."""
  shipped = clip_lib.shipped_library('reach')[0]
  frame = shipped.positions[:1].astype(np.float64)
  x, y, yaw = task.HUMAN_STATION
  c, s = np.cos(yaw), np.sin(yaw)
  rot_t = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
  world = frame[0] @ rot_t + np.array([x, y, 0.0])
  offset = np.asarray(point) - world[keypoints.KEYPOINT_INDEX[keypoint]]
  shift = offset @ rot_t.T
  positions = np.repeat(frame + shift, 50, axis=0)
  return shipped.replace(name='person_in_robot_path', positions=positions,
                         keyframes=(), idle_phases=(), fast_phases=(),
                         targets={})


def human_in_robot_env(shield, seed=0, fast_path=True, keypoint='torso',
                       robot='panda'):
  """Reach with `robot` and a still person whose `keypoint` lies where the
  arm sweeps when its base turns (`push_towards_human`), collision
  prevention off."""
  probe = reach.Reach(robot=robot)
  point = torso_in_base_sweep(probe)   # the robot sweeps into it
  clip = clip_with_keypoint_at(probe, point, keypoint)
  return suite.load('reach', 'dense', task_kwargs={
      'robot': robot, 'shield': shield, 'motions': [clip],
      'collision_prevention': 'off', 'done_at_success': False,
      'time_limit': 3.0, 'fast_path': fast_path},
                    environment_kwargs={'random_state': seed})


def push_towards_human(env, steps=30):
  """Turns the base joint of `human_in_robot_env`'s robot into the person
  for `steps` RL steps; returns the episode metrics."""
  env.reset()
  assert env.physics.data.ncon == 0   # Not touching at the start.
  action = np.zeros(env.action_spec().shape)
  action[0] = 1.0     # Base joint turns the arm towards +y (the hand).
  for _ in range(steps):
    env.step(action)
  return env.task.episode_metrics
