"""Pushed robots: the tracking check, the shield's resync and the
`human_pushed` contact type (docs/safety.md, "Pushed robots")."""

import numpy as np
import pytest

from hrc_suite import suite
from hrc_suite.human import clip as clip_lib
from hrc_suite.human import keypoints
from hrc_suite.tasks.runtime import contacts
from hrc_suite.tasks.runtime import metrics
from hrc_suite.tasks import reach

import checks    # tests/tasks/checks.py

PUSHED_LINK = 3      # Panda's elbow capsule.


def _moving_clip(task, start, end, keypoint, seconds, hold=1.0):
  """A still person (the first frame of a shipped reach clip) carried
  rigidly so that `keypoint` goes from `start` to `end` (world) in `seconds`,
  then stays there `hold` s."""
  shipped = clip_lib.shipped_library('reach')[0]
  frame = shipped.positions[0].astype(np.float64)
  x, y, yaw = task.HUMAN_STATION
  c, s = np.cos(yaw), np.sin(yaw)
  rot_t = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
  station = np.array([x, y, 0.0])
  world = frame @ rot_t + station
  alphas = np.concatenate([
      np.linspace(0.0, 1.0, int(round(seconds * shipped.fps)) + 1),
      np.ones(int(round(hold * shipped.fps)))])
  points = np.asarray(start) + alphas[:, None] * (np.asarray(end) - start)
  offsets = points - world[keypoints.KEYPOINT_INDEX[keypoint]]
  positions = (world[None] + offsets[:, None] - station) @ rot_t.T
  return shipped.replace(name='push', positions=positions.astype(np.float32),
                         keyframes=(), idle_phases=(), fast_phases=(),
                         targets={})


def _link_centre(task, link, q=None):
  q = task.robot.description.q_home if q is None else q
  p1, p2, _ = task.shield.robot.capsules(q)
  return 0.5 * (p1[link] + p2[link])


def _push_env(shield='ssm'):
  """The person's torso walks 0.4 m sideways (0.4 m/s) through the Panda's
  elbow at home and stays there."""
  probe = reach.Reach(robot='panda')
  centre = _link_centre(probe, PUSHED_LINK)
  clip = _moving_clip(probe, centre + [0.0, 0.45, 0.0],
                      centre + [0.0, 0.05, 0.0], 'torso', 1.0)
  return suite.load('reach', 'dense', task_kwargs={
      'robot': 'panda', 'shield': shield, 'motions': [clip],
      'action_space': 'joint', 'done_at_success': False, 'time_limit': 3.0,
      'seed': 0})


class _ResyncSpy:
  """Records each resync: the measured pose handed over, the shield's
  command before and after."""

  def __init__(self, shield):
    self.calls = []
    original = shield.resync

    def resync(q):
      before = shield.q.copy()
      measured = np.array(q, copy=True)
      original(q)
      self.calls.append((measured, before, shield.q.copy()))

    shield.resync = resync


@pytest.mark.parametrize('shield', ['ssm', 'pfl'])
def test_a_person_pushing_a_still_robot_makes_pushed_contacts(shield):
  """The person shoves the robot (held at rest by the shield) far off its
  command: the shield's tracking assumption breaks, the contacts are
  human_pushed (not critical), and the shield plans from where the robot
  really is."""
  env = _push_env(shield)
  env.reset()
  task = env.task
  spy = _ResyncSpy(task.shield)
  q_home = task.robot.description.q_home
  rewards = [env.step(np.zeros(7)).reward for _ in range(15)]
  result = task.episode_metrics
  q = task.robot.joint_positions(env.physics)
  # The push broke the tracking assumption: the robot ended more than a
  # radian from where the shield held it, far beyond the secure radius.
  assert np.abs(q - q_home).max() > 1.0
  assert result['max_tracking_error'] > task.shield.tracking_tolerance
  # Counted as pushed contacts: the robot's own command was at rest (PFL:
  # slow, back towards the goal, the pose where the step began).
  assert result['contacts_human_pushed'] > 0
  assert result['contacts_human_critical'] == 0
  assert result['max_human_contact_speed'] <= task.critical_speed
  assert result['shield_resyncs'] == result['contacts_human_pushed'] > 0
  # Each resync took the measured pose, off the command by more than the
  # tolerance, as the shield's new command; now it holds the robot there.
  assert len(spy.calls) == result['shield_resyncs']
  for measured, before, after in spy.calls:
    assert task.shield.tracking_error(measured, before) > (
        task.shield.tracking_tolerance)
    np.testing.assert_array_equal(after, measured)
  assert task.shield.tracking_error(q) < 1e-3
  assert np.abs(task.shield.q - q_home).max() > 1.0
  # The push is not illegal: no collision reward.
  assert min(rewards) > task.collision_reward / 2


def test_contact_observations_read_the_flags_by_name():
  """safe_contact covers allowed and pushed human contacts, critical_contact
  critical ones, static_collision static ones."""
  env = _push_env()
  env.reset()
  task = env.task
  observables = task.task_observables
  expected = {'static': (1.0, 0.0, 0.0), 'human_allowed': (0.0, 1.0, 0.0),
              'human_pushed': (0.0, 1.0, 0.0),
              'human_critical': (0.0, 0.0, 1.0),
              'robot_object': (0.0, 0.0, 0.0)}
  for name, values in expected.items():
    task._stepper.step_flags[:] = False
    task._stepper.step_flags[contacts.TYPE_INDEX[name]] = True
    observed = tuple(
        float(observables[o].observation_callable(env.physics)()[0])
        for o in ('static_collision', 'safe_contact', 'critical_contact'))
    assert observed == values, name


def _posed_contact_env():
  """PFL reach env with the person's right hand (at their side, the body
  away from the robot) touching the Panda's forearm from -y where a push of
  the shoulder (+0.6 rad) put it; returns (env, q_home, q_pushed)."""
  probe = reach.Reach(robot='panda')
  q_home = probe.robot.description.q_home
  q_pushed = q_home.copy()
  q_pushed[1] += 0.6
  hand = _link_centre(probe, PUSHED_LINK, q_pushed) + [0.0, -0.1, 0.0]
  clip = _moving_clip(probe, hand, hand, 'right_hand', 0.5)
  env = suite.load('reach', 'dense', task_kwargs={
      'robot': 'panda', 'shield': 'pfl', 'motions': [clip],
      'action_space': 'joint', 'seed': 0})
  env.reset()
  env.task.robot.set_joint_positions(env.physics, q_pushed)
  env.physics.forward()
  return env, q_home, q_pushed


def _human_contacts(env):
  """[(robot body, point)] of the robot-human contacts now."""
  task, data = env.task, env.physics.data
  robot = set(env.physics.bind(list(task.robot.link_geoms)
                               + list(task.gripper.geoms)).element_id)
  human = set(env.physics.bind(list(task.human.geoms)).element_id)
  found = []
  for i in range(data.ncon):
    g1, g2 = data.contact.geom1[i], data.contact.geom2[i]
    if (g1 in robot and g2 in human) or (g2 in robot and g1 in human):
      geom = g1 if g1 in robot else g2
      found.append((env.physics.model.geom_bodyid[geom],
                    data.contact.pos[i].copy()))
  assert found, 'no robot-human contact'
  return found


def test_pushed_contacts_are_judged_at_the_commanded_pose():
  """The shield commands the base joint to turn slowly at home, but the
  person has pushed the shoulder 0.6 rad forward: the elbow is farther from
  the base axis, so the same command moves it faster there. Judged at the
  pushed pose (the old monitor) the contacts are critical; at the commanded
  pose they are below v_safe: human_pushed."""
  env, q_home, q_pushed = _posed_contact_env()
  monitor = env.task._stepper.monitor
  found = _human_contacts(env)
  dq = np.zeros(7)
  dq[0] = 1.0
  at_pushed = [monitor.commanded_speed(b, p, dq) for b, p in found]
  at_command = [monitor.commanded_speed(b, p, dq, q_home) for b, p in found]
  assert max(at_command) < 0.9 * min(at_pushed)
  v_safe = monitor.critical_speed
  dq[0] = v_safe / np.sqrt(max(at_command) * min(at_pushed))  # In between.
  flags = monitor.update(dq)
  assert flags[contacts.TYPE_INDEX['human_critical']]
  assert not flags[contacts.TYPE_INDEX['human_allowed']]
  flags = monitor.update(dq, q_home)
  assert flags[contacts.TYPE_INDEX['human_pushed']]
  assert not flags[contacts.TYPE_INDEX['human_critical']]
  assert not flags[contacts.TYPE_INDEX['human_allowed']]
  assert monitor.max_human_contact_speed > v_safe   # The first update.
  # The robot's own command too fast at the commanded pose: critical.
  flags = monitor.update(3.0 * dq, q_home)
  assert flags[contacts.TYPE_INDEX['human_critical']]
  # The point rides with its link: judged at q_home it moves as the same
  # link point of a robot standing at q_home.
  body, point = found[0]
  data = env.physics.data
  local = (point - data.xpos[body]) @ data.xmat[body].reshape(3, 3)
  env.task.robot.set_joint_positions(env.physics, q_home)
  env.physics.forward()
  carried = data.xpos[body] + data.xmat[body].reshape(3, 3) @ local
  dq[0] = 1.0
  assert monitor.commanded_speed(body, carried, dq) == pytest.approx(
      at_command[0], rel=1e-9)


def test_the_monitor_needs_qpos_addresses_to_judge_a_command():
  env, q_home, _ = _posed_contact_env()
  task = env.task
  monitor = contacts.ContactMonitor(
      env.physics, [], list(task.robot.link_geoms), (), task.human.geoms)
  with pytest.raises(ValueError, match='robot_qpos'):
    monitor.update(np.zeros(env.physics.model.nv), q_home)
  with pytest.raises(ValueError, match='q_command'):
    task._stepper.monitor.update(np.zeros(7), np.full(7, np.nan))


def test_a_robot_driven_into_a_person_stays_critical_when_blocked():
  """Unshielded, the base joint swings the arm into a still person at
  speed: the person blocks it (the robot is pushed off its command and the
  shield re-synchronised), yet the robot's own command drives into the
  person, so the contacts stay critical, none is counted as pushed."""
  probe = reach.Reach(robot='panda')
  torso = checks.torso_in_base_sweep(probe)
  clip = _moving_clip(probe, torso, torso, 'torso', 0.5, hold=2.0)
  env = suite.load('reach', 'dense', task_kwargs={
      'robot': 'panda', 'shield': 'off', 'motions': [clip],
      'collision_prevention': 'off', 'done_at_success': False,
      'action_space': 'joint', 'time_limit': 3.0, 'seed': 0})
  env.reset()
  judged = []
  monitor = env.task._stepper.monitor
  update = monitor.update

  def spy(dq_command, q_command=None):
    flags = update(dq_command, q_command)
    judged.append((q_command is not None, flags.copy()))
    return flags

  monitor.update = spy
  action = np.zeros(7)
  action[0] = 1.0
  for _ in range(30):
    env.step(action)
  result = env.task.episode_metrics
  assert result['shield_resyncs'] > 0
  assert result['contacts_human_critical'] > 0
  assert result['contacts_human_pushed'] == 0
  critical = contacts.TYPE_INDEX['human_critical']
  assert any(pushed and flags[critical] for pushed, flags in judged)


@pytest.mark.parametrize('robot', ['panda', 'ur5e', 'schunk'])
def test_normal_tracking_stays_far_inside_the_tolerance(robot):
  """Random motion near a working person: the robot tracks the command to
  well under a millimetre; nothing is re-synchronised."""
  for shield in ('ssm', 'pfl'):
    env = suite.load('reach', 'dense', task_kwargs={
        'robot': robot, 'shield': shield, 'time_limit': 4.0,
        'done_at_success': False, 'seed': 1})
    rs = np.random.RandomState(1)
    result = metrics.run_episode(
        env, lambda ts: rs.uniform(-1.0, 1.0, env.action_spec().shape))
    assert result['shield_resyncs'] == 0
    assert result['contacts_human_pushed'] == 0
    assert 0.0 < result['max_tracking_error'] < 1e-3


def test_snapshot_in_the_middle_of_a_push_restores_exactly():
  """Snapshots taken while the person pushes (the shield re-synchronised in
  the last RL steps) replay bit for bit, in this and a fresh environment."""
  env = _push_env('pfl')
  env.reset()
  for _ in range(3):
    env.step(np.zeros(7))
  assert env.task.episode_metrics['shield_resyncs'] > 0
  state = env.task.get_state(env.physics)
  actions = [np.zeros(7)] * 6
  first = checks.rollout(env, actions)
  names = [f'contacts_{n}' for n in contacts.CONTACT_TYPES] + [
      'shield_resyncs', 'max_tracking_error', 'return', 'steps']
  expected = {n: env.task.episode_metrics[n] for n in names}
  assert env.task.step_metrics['shield_resyncs'] > 0
  checks.rollout(env, checks.random_actions(env, 3))
  for target in (env, _push_env('pfl')):
    if target is not env:
      target.reset()
    target.task.set_state(target.physics, state)
    checks.assert_same(first, checks.rollout(target, actions))
    assert {n: target.task.episode_metrics[n] for n in names} == expected


def test_old_snapshots_without_the_pushed_flag_restore():
  """A snapshot from before `human_pushed` existed (one flag and two
  counters fewer) restores; the missing metrics start at zero."""
  env = _push_env()
  env.reset()
  env.step(np.zeros(7))
  state = env.task.get_state(env.physics)
  old = dict(state, task=dict(state['task']))
  old['task']['step_flags'] = state['task']['step_flags'][:5]
  episode = dict(state['task']['metrics']['episode'])
  for name in ('contacts_human_pushed', 'shield_resyncs', 'physics_errors',
               'max_tracking_error'):
    del episode[name]
  old['task']['metrics'] = dict(state['task']['metrics'], episode=episode)
  env.task.set_state(env.physics, old)
  assert env.task.episode_metrics['contacts_human_pushed'] == 0
  env.step(np.zeros(7))
  too_many = dict(state, task=dict(state['task'], step_flags=np.zeros(
      len(contacts.CONTACT_TYPES) + 1, dtype=bool)))
  with pytest.raises(ValueError, match='step_flags'):
    env.task.set_state(env.physics, too_many)
