"""The shared step loop (HrcTask), exercised through the reach task."""

import numpy as np
import pytest

from hrc_suite import layout
from hrc_suite import suite
from hrc_suite.control import ik as ik_lib
from hrc_suite.human import clip as clip_lib
from hrc_suite.tasks.runtime import actions
from hrc_suite.tasks.runtime import contacts
from hrc_suite.tasks.runtime import metrics
from hrc_suite.tasks.runtime import options
from hrc_suite.tasks import reach

import checks    # tests/tasks/checks.py


def _env(seed=0, **task_kwargs):
  task_kwargs.setdefault('time_limit', 1.0)
  return suite.load('reach', task_kwargs.pop('reward', 'dense'),
                    task_kwargs=task_kwargs,
                    environment_kwargs={'random_state': seed})


def _random_actions(env, count, seed=1):
  rs = np.random.RandomState(seed)
  spec = env.action_spec()
  return [rs.uniform(-1.0, 1.0, spec.shape) for _ in range(count)]


# ------------------------------------------------------------------ kwargs


@pytest.mark.parametrize('kwargs, message', [
    ({'robot': 'r2d2'}, 'Unknown robot'),
    ({'action_space': 'polar'}, 'Unknown action_space'),
    ({'shield': 'strong'}, 'Unknown shield'),
    ({'collision_prevention': 'maybe'}, 'Unknown collision_prevention'),
    ({'observations': 'tiny'}, 'Unknown observations preset'),
    ({'observations': ['goal_difference', 'x_ray']}, 'x_ray'),
    ({'control_timestep': 0.05}, 'must equal shield_substeps'),
    ({'shield_substeps': 0}, 'shield_substeps'),
    ({'reward_delay': -1}, 'reward_delay'),
    ({'time_limit': 0.0}, 'time_limit'),
    ({'collision_reward': 5.0}, 'collision_reward'),
    ({'motions': []}, 'motions'),
    ({'observations': 5}, 'observations must be a preset name.*got 5'),
    ({'cameras': 5}, 'cameras must be a camera name or a list.*got 5'),
    ({'cameras': 'top', 'camera_size': 84},
     r'camera_size must be \(height, width\).*got 84'),
    ({'cameras': 'top', 'camera_size': (48, 64.0)}, 'camera_size'),
    # Refused before dm_control allocates a 28 GiB observation buffer.
    ({'cameras': 'top', 'camera_size': (100000, 100000)},
     r'at most the offscreen framebuffer \(960, 1280\).*100000'),
])
def test_bad_kwargs_raise_clearly(kwargs, message):
  with pytest.raises(ValueError, match=message):
    reach.Reach(**kwargs)


def test_error_lists_valid_values():
  with pytest.raises(ValueError, match="'joint', 'cartesian'"):
    reach.Reach(action_space='polar')
  with pytest.raises(ValueError, match="'ssm', 'pfl', 'off'"):
    reach.Reach(shield='strong')


def test_broken_motion_folder_raises(tmp_path):
  (tmp_path / 'broken.json').write_text('{not json')
  with pytest.raises(ValueError):
    reach.Reach(motions=tmp_path)
  with pytest.raises(ValueError, match='not a folder'):
    reach.Reach(motions=tmp_path / 'missing')


def test_substeps_and_timesteps_are_consistent():
  task = reach.Reach(shield_substeps=10, physics_timestep=0.004,
                     control_timestep=0.04)
  assert task.physics_steps_per_control_step == 10
  assert task.horizon == reach.Reach.HORIZON   # 100 RL steps of 0.04 s
  assert task.time_limit == pytest.approx(4.0)


# ----------------------------------------------------------------- actions


@pytest.mark.parametrize('space, size', [('joint', 7), ('cartesian', 3)])
def test_action_spec_is_agent_only_and_bounded(space, size):
  env = _env(action_space=space)
  spec = env.action_spec()
  assert spec.shape == (size,)
  np.testing.assert_array_equal(spec.minimum, -1.0)
  np.testing.assert_array_equal(spec.maximum, 1.0)


@pytest.mark.parametrize('bad', [np.nan, np.inf, -np.inf])
def test_non_finite_actions_raise_naming_entries(bad):
  env = _env()
  env.reset()
  action = np.zeros(7)
  action[[2, 5]] = bad
  with pytest.raises(ValueError, match=r'indices \[2, 5\]'):
    env.step(action)


def test_wrong_action_shape_raises_with_expected_shape():
  env = _env()
  env.reset()
  with pytest.raises(ValueError, match=r'shape \(7,\)'):
    env.step(np.zeros(6))


@pytest.mark.parametrize('bad', ['abc', ['0.1'] * 7, [None] * 7])
def test_non_numeric_actions_raise_naming_the_action(bad):
  env = _env()
  env.reset()
  with pytest.raises(ValueError, match=r'action must be an array of numbers '
                     r'of shape \(7,\).*got'):
    env.step(bad)


def test_out_of_range_actions_are_clipped():
  goals = []
  for scale in (1.0, 7.0):
    env = _env(collision_prevention='off')
    env.reset()
    action = np.zeros(7)
    action[0] = scale
    env.step(action)
    goals.append(env.task.q_goal)
  np.testing.assert_array_equal(goals[0], goals[1])


def test_joint_goal_is_q_plus_step_times_action():
  env = _env(collision_prevention='off')
  env.reset()
  physics, task = env.physics, env.task
  q = task.robot.joint_positions(physics)
  action = np.full(7, 0.5)
  env.step(action)
  expected = np.clip(q + actions.JOINT_STEP * action,
                     task.kinematics.q_min, task.kinematics.q_max)
  np.testing.assert_allclose(task.q_goal, expected)


def test_cartesian_goal_moves_tcp_by_step_inside_box():
  env = _env(action_space='cartesian', collision_prevention='off')
  env.reset()
  task, physics = env.task, env.physics
  q = task.robot.joint_positions(physics)
  tcp = task.kinematics.tcp_pose(q)[:3, 3]
  action = np.array([1.0, 0.0, 0.0])
  env.step(action)
  reached = task.kinematics.tcp_pose(task.q_goal)[:3, 3]
  target = np.clip(tcp + [actions.CARTESIAN_STEP, 0, 0],
                   task._action_space.low, task._action_space.high)
  np.testing.assert_allclose(reached, target, atol=2e-3)
  # The goal keeps the gripper pointing down.
  rotation = task.kinematics.tcp_pose(task.q_goal)[:3, :3]
  assert rotation[2, 2] < -0.99


def test_ik_failure_keeps_goal_and_is_counted():
  env = _env(action_space='cartesian', collision_prevention='off')
  env.reset()
  task = env.task
  space = task._action_space
  # A box far outside the robot's reach: every target is unreachable.
  space.low = np.array([5.0, 5.0, 5.0])
  space.high = np.array([5.1, 5.1, 5.1])
  before = task.q_goal
  env.step(np.zeros(3))
  np.testing.assert_array_equal(task.q_goal, before)
  assert task.step_metrics['ik_failures'] == 1
  assert task.episode_metrics['ik_failures'] == 1


def _near_table_with_downward_action(policy):
  """An env with the TCP 4 cm above the table and the joint action that
  moves it straight down fastest (a goal inside the table)."""
  env = _env(collision_prevention=policy, time_limit=2.0,
             done_at_success=False)
  env.reset()
  task, physics = env.task, env.physics
  model = task.kinematics
  target = np.array([0.5, 0.0, layout.TABLE_TOP_Z + 0.04])
  result = ik_lib.InverseKinematics(model).solve(
      target, task.robot.description.q_home)
  assert result.success
  task.robot.set_joint_positions(physics, result.q)
  task.shield.reset(result.q, task.player.episode_time)
  physics.forward()
  down = -np.sign(model.tcp_jacobian(result.q)[2])
  return env, result.q, down


def test_collision_prevention_replaces_a_goal_into_the_table():
  env, q_low, down = _near_table_with_downward_action('zero')
  env.step(down)
  task = env.task
  assert task.step_metrics['action_replacements'] == 1
  np.testing.assert_allclose(task.q_goal, q_low, atol=1e-3)   # Stays.
  for _ in range(5):
    env.step(down)
  assert task.episode_metrics['contacts_static'] == 0


def test_monitor_sees_static_contacts_without_collision_prevention():
  env, _, down = _near_table_with_downward_action('off')
  for _ in range(5):
    env.step(down)
  task = env.task
  assert task.episode_metrics['contacts_static'] > 0
  assert task.step_metrics['reward'] <= task.collision_reward


# --------------------------------------------------------- determinism etc.


def _rollout(env, actions_):
  observations = []
  for action in actions_:
    observations.append(env.step(action).observation)
  return observations


def _assert_same(first, second):
  assert len(first) == len(second)
  for a, b in zip(first, second):
    assert a.keys() == b.keys()
    for key in a:
      np.testing.assert_array_equal(a[key], b[key], err_msg=key)


@pytest.mark.parametrize('space', ['joint', 'cartesian'])
def test_same_seed_same_observations(space):
  runs = []
  for _ in range(2):
    env = _env(seed=3, action_space=space, observations='full',
               time_limit=10.0)
    first = env.reset().observation
    runs.append([first] + _rollout(env, _random_actions(env, 12)))
  _assert_same(*runs)
  other = _env(seed=4, action_space=space, observations='full')
  different = other.reset().observation
  assert not np.array_equal(different['goal_position'],
                            runs[0][0]['goal_position'])


@pytest.mark.parametrize('space', ['joint', 'cartesian'])
def test_snapshot_restore_is_bit_exact(space):
  env = _env(seed=5, action_space=space, observations='full',
             collision_prevention='resample', time_limit=10.0)
  env.reset()
  _rollout(env, _random_actions(env, 6, seed=2))
  state = env.task.get_state(env.physics)
  replay = _random_actions(env, 10, seed=3)
  first = _rollout(env, replay)
  metrics_first = dict(env.task.episode_metrics)
  # Wander off, then restore and replay.
  _rollout(env, _random_actions(env, 5, seed=4))
  env.task.set_state(env.physics, state)
  second = _rollout(env, replay)
  _assert_same(first, second)
  assert env.task.episode_metrics == metrics_first


def test_snapshot_moves_to_a_fresh_environment():
  env = _env(seed=6, observations='full', time_limit=10.0)
  env.reset()
  _rollout(env, _random_actions(env, 4))
  state = env.task.get_state(env.physics)
  replay = _random_actions(env, 6, seed=9)
  first = _rollout(env, replay)
  fresh = _env(seed=99, observations='full', time_limit=10.0)
  fresh.reset()
  fresh.task.set_state(fresh.physics, state)
  _assert_same(first, _rollout(fresh, replay))


def test_set_state_before_the_first_reset_raises():
  """The environment's first step resets, so a snapshot restored before it
  would be discarded silently."""
  env = _env(seed=6)
  env.reset()
  state = env.task.get_state(env.physics)
  fresh = _env(seed=6)
  with pytest.raises(ValueError, match=r'call env\.reset\(\) before'):
    fresh.task.set_state(fresh.physics, state)


def test_a_snapshot_restored_after_the_last_step_continues():
  env = _env(seed=7, observations='full', time_limit=1.0)
  env.reset()
  _rollout(env, _random_actions(env, 3))
  state = env.task.get_state(env.physics)
  replay = _random_actions(env, 4, seed=5)
  first = _rollout(env, replay)
  timestep = None
  while timestep is None or not timestep.last():
    timestep = env.step(np.zeros(env.action_spec().shape))
  env.task.set_state(env.physics, state)   # No reset in between.
  steps = [env.step(action) for action in replay]
  assert not any(t.first() for t in steps)
  _assert_same(first, [t.observation for t in steps])
  # Without a restore, the step after LAST starts a new episode.
  while not env.step(np.zeros(env.action_spec().shape)).last():
    pass
  assert env.step(np.zeros(env.action_spec().shape)).first()


def test_set_state_rejects_a_foreign_physics_state():
  env = _env()
  env.reset()
  state = env.task.get_state(env.physics)
  state['physics'] = state['physics'][:-3]
  with pytest.raises(ValueError, match='physics state'):
    env.task.set_state(env.physics, state)


# ------------------------------------------------------------------ rewards


def test_reward_delay_shifts_rewards_and_keeps_the_return():
  rewards = {}
  for delay in (0, 3):
    env = _env(seed=2, reward='sparse', reward_delay=delay, time_limit=1.0)
    env.reset()
    rewards[delay] = [env.step(a).reward
                      for a in _random_actions(env, 10, seed=5)]
  assert rewards[3][:3] == [0.0, 0.0, 0.0]
  assert rewards[3][3:9] == rewards[0][:6]
  assert sum(rewards[3]) == pytest.approx(sum(rewards[0]))


# ------------------------------------------------------------------ metrics


def test_metrics_and_observer():
  env = _env(seed=1, time_limit=0.5)
  observer = metrics.EpisodeMetricsObserver()
  rewards = []

  def policy(timestep):
    if timestep.reward is not None:
      rewards.append(timestep.reward)
    return np.zeros(env.action_spec().shape)

  result = metrics.run_episode(env, policy, observer)
  for name in metrics.COUNTERS + ('success', 'return', 'steps'):
    assert name in result
  assert result['steps'] == 5
  assert observer.episodes == [result]
  rewards.append(env.task.step_metrics['reward'])
  assert result['return'] == pytest.approx(sum(rewards))
  assert env.task.step_metrics['shield_interventions'] in (0, 1)
  assert observer.summary()['steps'] == 5.0


# -------------------------------------------------------- contact monitor


def test_monitor_sees_human_contacts_without_shield():
  result = checks.push_towards_human(checks.human_in_robot_env('off'))
  assert result['contacts_human_critical'] > 0
  assert result['max_human_contact_speed'] > contacts.SSM_STOPPED_SPEED


def test_compiled_contact_classification_agrees_with_numpy():
  """Both monitors of the same physics see the same flags at every
  physics step of an unshielded push into the person."""
  env = checks.human_in_robot_env('off')
  env.reset()
  task, physics = env.task, env.physics
  joints = physics.bind(task.robot.joints)
  dofs, qpos = np.array(joints.dofadr), np.array(joints.qposadr)
  monitors = [contacts.ContactMonitor(
      physics, list(task.arena.static_geoms),
      list(task.robot.link_geoms) + list(task.gripper.geoms), [],
      task.human.geoms, robot_dofs=dofs, robot_qpos=qpos,
      compiled=compiled) for compiled in (False, True)]
  seen = np.zeros(len(contacts.CONTACT_TYPES), dtype=int)

  def compare(physics, random_state):
    del random_state
    dq = physics.data.qvel[dofs]
    off_pose = physics.data.qpos[qpos] + 0.01   # judged there if pushed
    for pushed in (None, off_pose):
      expected = monitors[0].update(dq, pushed).copy()
      np.testing.assert_array_equal(monitors[1].update(dq, pushed),
                                    expected)
      seen[:] += expected

  env.add_extra_hook('after_substep', compare)
  action = np.zeros(7)
  action[0] = 1.0     # Base joint turns the arm towards +y (the hand).
  for _ in range(30):
    env.step(action)
  assert seen[contacts.TYPE_INDEX['human_critical']] > 0
  assert (monitors[0].max_human_contact_speed
          == monitors[1].max_human_contact_speed > 0)


def test_shield_prevents_critical_contacts_with_the_same_human():
  result = checks.push_towards_human(checks.human_in_robot_env('ssm'))
  assert result['contacts_human_critical'] == 0
  assert result['shield_interventions'] > 0


def _clips_moved_towards_robot(task, distance):
  """The shipped reach clips with the person `distance` m closer to the
  robot (the station faces the robot's workspace)."""
  _, _, yaw = task.HUMAN_STATION
  c, s = np.cos(yaw), np.sin(yaw)
  rot_t = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
  shift = np.array([0.0, -distance, 0.0]) @ rot_t.T
  return [clip.replace(positions=(clip.positions + shift).astype(np.float32))
          for clip in clip_lib.shipped_library('reach')]


def test_random_actions_near_a_moving_human():
  """The human works 0.45 m closer than usual: unshielded random motion hits
  them at speed; shielded (SSM or PFL), the same seeds make no critical
  contact."""
  clips = _clips_moved_towards_robot(reach.Reach, 0.45)
  totals = {}
  for shield in ('off', 'ssm', 'pfl'):
    for seed in range(3):
      env = _env(seed=seed, shield=shield, motions=clips, time_limit=6.0,
                 done_at_success=False)
      rs = np.random.RandomState(seed)
      result = metrics.run_episode(
          env, lambda ts: rs.uniform(-1.0, 1.0, env.action_spec().shape))
      for name in ('contacts_human_critical', 'shield_interventions',
                   'contacts_static', 'self_collisions'):
        totals[shield, name] = totals.get((shield, name), 0) + result[name]
  assert totals['off', 'contacts_human_critical'] > 0
  assert totals['ssm', 'contacts_human_critical'] == 0
  assert totals['pfl', 'contacts_human_critical'] == 0
  assert totals['ssm', 'shield_interventions'] > 0
  assert totals['ssm', 'contacts_static'] == 0
  assert totals['ssm', 'self_collisions'] == 0


def test_a_person_walking_into_a_still_robot_is_not_critical():
  """The kinematic human shoves the robot (measured link speeds of m/s);
  the robot's own (commanded) speed is zero, so contacts are allowed."""
  clips = _clips_moved_towards_robot(reach.Reach, 0.75)
  env = _env(seed=1, motions=clips, time_limit=8.0, done_at_success=False)
  result = metrics.run_episode(env, lambda ts: np.zeros(7))
  assert result['contacts_human_allowed'] > 0
  assert result['contacts_human_critical'] == 0
  assert result['max_human_contact_speed'] == 0.0


def test_random_actions_with_shield_have_no_critical_contacts():
  for seed in range(3):
    env = _env(seed=seed, time_limit=4.0, done_at_success=False)
    result = metrics.run_episode(
        env, lambda ts, rs=np.random.RandomState(seed): rs.uniform(
            -1.0, 1.0, env.action_spec().shape))
    assert result['contacts_human_critical'] == 0
    assert result['contacts_static'] == 0
    assert result['self_collisions'] == 0


def test_contact_monitor_surface_speed_of_a_turning_link():
  env = _env()
  env.reset()
  physics, task = env.physics, env.task
  monitor = task._stepper.monitor
  dq = np.zeros(7)
  dq[0] = 2.0
  task.robot.set_joint_velocities(physics, dq)
  physics.forward()
  body = physics.bind(task.robot.link_bodies[0]).element_id
  axis_point = physics.bind(task.robot.link_bodies[0]).xpos.copy()
  point = axis_point + np.array([0.3, 0.0, 0.0])
  # A point 0.3 m from the base joint's (vertical) axis turning at 2 rad/s.
  assert monitor.surface_speed(body, point) == pytest.approx(0.6, rel=1e-6)
  assert monitor.commanded_speed(body, point, dq) == pytest.approx(0.6,
                                                                   rel=1e-6)
  # Further out on the arm, measured and commanded speeds agree too.
  dq = np.linspace(-1.0, 1.0, 7)
  task.robot.set_joint_velocities(physics, dq)
  physics.forward()
  body = physics.bind(task.robot.link_bodies[5]).element_id
  point = physics.bind(task.robot.link_bodies[5]).xpos + [0.05, 0.02, 0.0]
  assert monitor.commanded_speed(body, point, dq) == pytest.approx(
      monitor.surface_speed(body, point), rel=1e-9)


def test_contact_monitor_rejects_negative_threshold():
  env = _env()
  env.reset()
  with pytest.raises(ValueError, match='critical_speed'):
    contacts.ContactMonitor(env.physics, [], [], critical_speed=-1.0)


def test_defaults_follow_the_reference():
  task = reach.Reach()
  assert task.shield_mode == 'ssm'
  assert task.horizon == 100
  assert task.physics_steps_per_control_step == options.DEFAULT_SHIELD_SUBSTEPS
  assert task.critical_speed == contacts.SSM_STOPPED_SPEED
  assert reach.Reach(shield='pfl').critical_speed == options.DEFAULT_V_SAFE


def test_batched_human_playback_matches_set_keypoints():
  env = _env(seed=4, time_limit=10.0)
  env.reset()
  for action in _random_actions(env, 3):
    env.step(action)
  physics, task = env.physics, env.task
  # Capsule and keypoint rows side by side: one mocap write per substep.
  assert task._playback._together is not None
  played_pos = physics.data.mocap_pos.copy()
  played_quat = physics.data.mocap_quat.copy()
  # The pose after the step is the player's current pose, as Human puts it.
  task.human.set_keypoints(physics, task.player.positions)
  np.testing.assert_allclose(played_pos, physics.data.mocap_pos, atol=1e-12)
  np.testing.assert_allclose(played_quat, physics.data.mocap_quat,
                             atol=1e-12)
  # The player moved the human during the step.
  assert task.player.episode_time == pytest.approx(0.3)   # 3 RL steps


# ------------------------------------------------------- observation options


def test_observation_noise_is_bounded_and_seeded():
  observed = []
  for noise in (None, {'eef_position': 0.01}, {'eef_position': 0.01}):
    env = _env(seed=2, observations=['eef_position', 'joint_positions'],
               observation_noise=noise)
    steps = [env.reset().observation]
    steps += _rollout(env, _random_actions(env, 3))
    observed.append(steps)
  clean, noisy, again = observed
  for a, b, c in zip(clean, noisy, again):
    difference = b['eef_position'] - a['eef_position']
    assert np.all(np.abs(difference) <= 0.01) and np.any(difference != 0)
    np.testing.assert_array_equal(b['eef_position'], c['eef_position'])
    np.testing.assert_array_equal(b['joint_positions'], a['joint_positions'])


def test_observation_delay_lags_by_the_given_time():
  runs = {}
  for delay in (None, {'joint_positions': 0.1}):
    env = _env(seed=2, observations=['joint_positions'],
               observation_delay=delay)
    env.reset()
    runs[delay is None] = _rollout(env, [np.full(7, 0.5)] * 4)
  undelayed, delayed = runs[True], runs[False]
  for k in range(1, 4):
    np.testing.assert_array_equal(delayed[k]['joint_positions'],
                                  undelayed[k - 1]['joint_positions'])


def test_the_observation_is_the_entities_observables_by_task_names():
  env = _env(observations='full')
  task = env.task
  obs, robot, human = task.task_observables, task.robot, task.human
  # One implementation: what an entity declares, the task enables.
  assert obs['joint_positions'] is robot.observables.joint_positions
  assert obs['joint_velocities'] is robot.observables.joint_velocities
  assert obs['eef_position'] is robot.observables.end_effector_position
  assert obs['eef_quaternion'] is robot.observables.end_effector_quaternion
  assert obs['gripper_aperture'] is task.gripper.observables.aperture
  assert obs['human_keypoints'] is human.observables.keypoint_positions
  assert obs['human_in_eef_frame'] is human.observables.get_observable(
      'keypoints_in_eef_frame')
  # Only the task's names: an entity observable the task does not name
  # stays out of the observation, even enabled.
  task._marker.observables.position.enabled = True
  observation = env.reset().observation
  assert list(observation) == list(task.observation_names)
  assert not any('/' in name for name in env.observation_spec())


@pytest.mark.parametrize('kwargs, message', [
    ({'observation_noise': {'x_ray': 0.1}}, 'unknown observable'),
    ({'observation_noise': {'eef_position': -1.0}}, '>= 0'),
    ({'observation_delay': {'eef_position': 0.005}}, 'multiple'),
    ({'observation_delay': [0.1]}, 'dict'),
])
def test_bad_observation_options_raise(kwargs, message):
  with pytest.raises(ValueError, match=message):
    reach.Reach(**kwargs)


def test_camera_observations_render_the_workcell():
  env = suite.load('reach', 'dense', task_kwargs=dict(
      robot='panda', seed=0, cameras=('front', 'top'), camera_size=(48, 64)))
  spec = env.observation_spec()['camera_front']
  assert spec.shape == (48, 64, 3) and spec.dtype == np.uint8
  timestep = env.step(np.zeros(env.action_spec().shape))
  for name in ('camera_front', 'camera_top'):
    image = timestep.observation[name]
    assert image.shape == (48, 64, 3) and image.std() > 5.0
  assert 'goal_difference' in timestep.observation
  with pytest.raises(ValueError, match="'nope'.*front"):
    suite.load('reach', 'dense', task_kwargs=dict(cameras=('nope',)))
  with pytest.raises(ValueError, match='camera_size'):
    suite.load('reach', 'dense', task_kwargs=dict(cameras='top',
                                                  camera_size=(0, 8)))
