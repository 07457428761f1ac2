"""The shield's guarantee, closed loop: the robot follows the shield exactly.

SSM: no robot capsule (description capsules plus a gripper capsule, real
size) ever intersects a human body capsule (real size) while the robot moves
faster than 1 mm/s. PFL: at every contact the robot's surface speed is at
most v_safe. Liveness: a far human never causes an intervention and the goal
is reached on the plan; after the human leaves the robot resumes. Braking:
from full speed the failsafe stops within max_s_stop plus one cycle inside
the acceleration and jerk limits.

Human motions respect the model's assumptions (keypoint speed <= 2 m/s,
acceleration <= a_max) except the real clips, which are used as recorded.
"""

import numpy as np
import pytest

from hrc_suite import robot_description
from hrc_suite.human import keypoints
from hrc_suite.human import bvh_import
from hrc_suite.safety import shield as shield_lib

import shield_harness as harness

ROBOTS = robot_description.ROBOT_NAMES


def _shield(name, mode='ssm', **kwargs):
  description = robot_description.load(name)
  return shield_lib.Shield(description, mode=mode,
                           tool_capsule=harness.tool_capsule(description),
                           **kwargs)


def _attack_on_gripper(shield, **kwargs):
  """A hand thrust at the gripper's home position."""
  _, p2, _ = shield.robot.capsules(shield.description.q_home)
  return harness.hand_attack(p2[-1], **kwargs)


def _assert_no_violation(run, what):
  assert not run.violations, (
      f'{what}: {len(run.violations)} violations, first (time, capsule, body,'
      f' distance, robot speed): {run.violations[:3]}')


def _assert_within_joint_limits(shield, run):
  """Commands stay within position, velocity, acceleration and jerk limits
  (acceleration and jerk by finite differences of the commands), through
  goal changes every 48 ms and interventions."""
  limits, dt = shield.limits, shield.cycle_time
  assert np.all(run.q >= limits.q_min) and np.all(run.q <= limits.q_max)
  assert np.all(np.abs(run.dq) <= limits.v_max * (1 + 1e-9))
  acc = np.diff(run.dq, axis=0) / dt
  assert np.all(np.abs(acc) <= limits.a_max * (1 + 1e-6))
  assert np.all(np.abs(np.diff(acc, axis=0) / dt) <= limits.j_max * (1 + 1e-6))


def test_scenarios_are_adversarial():
  """Without the shield the same runs do hit the human at speed, so the
  property tests below can fail."""
  for make_human in (_attack_on_gripper, lambda s: harness.walk_in()):
    shield = _shield('panda', mode='off')
    human = make_human(shield)
    run = harness.simulate(shield, human, 2.0, check=False,
                           goal=harness.random_goals(
                               shield.description, np.random.RandomState(1)))
    shield.mode = 'ssm'   # Judge the unshielded run by the SSM criterion.
    harness._check_contacts(shield, human, run)
    assert len(run.violations) > 10


@pytest.mark.parametrize('name', ROBOTS)
@pytest.mark.parametrize('scenario', ['hand_attack', 'walk_in'])
def test_ssm_no_contact_while_moving(name, scenario):
  shield = _shield(name)
  human = (_attack_on_gripper(shield) if scenario == 'hand_attack'
           else harness.walk_in())
  run = harness.simulate(shield, human, 1.6, goal=harness.random_goals(
      shield.description, np.random.RandomState(7)))
  _assert_no_violation(run, f'{name} {scenario}')
  assert run.intervened.any()   # The human did get in the way.
  _assert_within_joint_limits(shield, run)


@pytest.mark.parametrize('name', ROBOTS)
def test_pfl_contact_only_below_v_safe(name):
  shield = _shield(name, mode='pfl')
  human = _attack_on_gripper(shield)
  run = harness.simulate(shield, human, 1.6, goal=harness.random_goals(
      shield.description, np.random.RandomState(8)))
  _assert_no_violation(run, f'{name} pfl')
  _assert_within_joint_limits(shield, run)
  # PFL lets the robot keep moving slowly where SSM would stop it.
  speeds = shield.robot.surface_speeds(run.q[-50:], run.dq[-50:]).max(axis=1)
  assert np.all(speeds <= shield.v_safe)


@pytest.mark.parametrize('options', [
    dict(use_kalman_filter=True),
    dict(use_combined_model=False),
    dict(mode='pfl', v_safe=0.1, use_combined_model=False),
])
def test_guarantee_with_other_human_models(options):
  shield = _shield('iiwa', **options)
  for human in (_attack_on_gripper(shield), harness.walk_in(y=0.2)):
    shield.reset(shield.description.q_home)
    run = harness.simulate(shield, human, 1.6, goal=harness.random_goals(
        shield.description, np.random.RandomState(9)))
    _assert_no_violation(run, str(options))


def _clip_runs(motions_dir, per_task, robots, modes, seconds):
  files = []
  for folder in sorted(p for p in motions_dir.iterdir() if p.is_dir()):
    files += sorted(folder.glob('*.bvh'))[:per_task]
  assert files, f'no BVH files under {motions_dir}'
  for path in files:
    clip = bvh_import.import_clip(path)
    for i, name in enumerate(robots):
      for mode in modes:
        shield = _shield(name, mode=mode)
        human = harness.clip_motion(clip.positions, clip.fps)
        run = harness.simulate(
            shield, human, min(clip.duration, seconds),
            goal=harness.random_goals(shield.description,
                                      np.random.RandomState(i)))
        _assert_no_violation(run, f'{path} {name} {mode}')


@pytest.mark.recordings
def test_real_clips(recordings_dir):
  _clip_runs(recordings_dir, 1, ('panda',), ('ssm',), 2.0)


@pytest.mark.slow
@pytest.mark.recordings
def test_real_clips_sweep(recordings_dir):
  _clip_runs(recordings_dir, 2, ROBOTS, ('ssm', 'pfl'), 6.0)


@pytest.mark.slow
@pytest.mark.parametrize('name', ROBOTS)
def test_adversarial_sweep(name):
  rng = np.random.RandomState(11)
  for seed in range(6):
    for mode in ('ssm', 'pfl'):
      shield = _shield(name, mode=mode)
      _, p2, _ = shield.robot.capsules(shield.description.q_home)
      target = p2[rng.randint(len(p2))]
      humans = (
          harness.hand_attack(target, start=rng.uniform(0.1, 0.8)),
          harness.walk_in(y=rng.uniform(-0.5, 0.5),
                          speed=rng.uniform(0.8, 1.6)))
      for human in humans:
        shield.reset(shield.description.q_home)
        run = harness.simulate(shield, human, 3.0, goal=harness.random_goals(
            shield.description, np.random.RandomState(seed)))
        _assert_no_violation(run, f'{name} {mode} seed {seed}')


@pytest.mark.parametrize('name', ROBOTS)
def test_far_human_never_intervenes_and_goal_is_reached(name):
  shield = _shield(name)
  rng = np.random.RandomState(3)
  goal = harness.random_goals(shield.description, rng, spread=0.8)()
  run = harness.simulate(shield, harness.far_away(), 3.0, first_goal=goal)
  assert not run.intervened.any()
  assert run.safe.all()
  assert not shield.goal_pending
  np.testing.assert_allclose(run.q[-1], shield.plan.goal, atol=1e-9)
  np.testing.assert_allclose(shield.plan.goal, np.clip(
      goal, shield.limits.q_min + 0.01, shield.limits.q_max - 0.01))
  # On the plan: every command is the plan's sample at nominal speed.
  plan = shield.plan
  k = np.round((run.times + shield.cycle_time - plan.start_time)
               / shield.cycle_time).astype(int)
  inside = k < plan.num_samples
  np.testing.assert_allclose(run.q[inside], plan.q[k[inside]], atol=1e-9)


def test_robot_resumes_after_the_human_leaves():
  shield = _shield('panda')
  description = shield.description
  goal = description.q_home.copy()
  goal[0] += 1.5   # Sweeps the arm towards the human's side for ~2 s.
  human = harness.walk_in_and_leave(arrive=0.6, stay=0.8, near=0.55)
  run = harness.simulate(shield, human, 6.0, first_goal=goal)
  _assert_no_violation(run, 'walk in and leave')
  stopped = np.abs(run.dq).max(axis=1) < 1e-6
  # It stopped while the human was near, then moved again and arrived.
  near = (run.times > 1.0) & (run.times < 1.3)
  assert stopped[near].any()
  assert (~stopped[run.times > 1.6]).any()
  np.testing.assert_allclose(run.q[-1], shield.plan.goal, atol=1e-6)
  assert not run.intervened[-100:].any()


def _full_speed_then_block(name):
  """Runs a robot to full speed, then puts the human next to it."""
  shield = _shield(name)
  description = shield.description
  goal = description.q_home.copy()
  joint = 0
  goal[joint] = (description.limits.q_max[joint] - 0.05
                 if goal[joint] < 0 else description.limits.q_min[joint] + 0.05)
  shield.new_goal(goal)
  t = 0.0
  far = harness.far_away()(0.0)
  speeds = []
  while True:
    shield.step(far, t)
    t += shield.cycle_time
    speeds.append(np.abs(shield.dq[joint]))
    if speeds[-1] >= description.limits.v_max[joint] - 1e-9:
      break
    assert t < 3.0, 'never reached full speed'
  # The human appears with the torso on the robot's second link, so no
  # motion can be verified any more.
  p1, p2, _ = shield.robot.capsules(shield.q)
  body = harness.place(harness.STANDING, 0.0, 0.0, 0.0)
  torso = keypoints.KEYPOINT_INDEX['torso']
  body += 0.5 * (p1[1] + p2[1]) - body[torso]
  return shield, t, body


@pytest.mark.parametrize('name', ROBOTS)
def test_braking_from_full_speed(name):
  shield, t, body = _full_speed_then_block(name)
  limits = shield.limits
  dt = shield.cycle_time
  q, dq = [shield.q.copy()], [shield.dq.copy()]
  start = t
  while np.abs(shield.dq).max() > 1e-9:
    shield.step(body, t)
    assert not shield.is_safe
    t += dt
    q.append(shield.q.copy())
    dq.append(shield.dq.copy())
    assert t - start < 1.0, 'did not stop'
  stop_time = t - start
  q, dq = np.array(q), np.array(dq)
  # The bound of docs/shield_maths.md, 3: the path may brake at
  # (a_max - a_ltt) / (|v| + a_ltt max_s_stop), i.e. 0.2 s for 1 rad/s
  # joints; UR5e's 3.14 rad/s joints need longer by the same formula.
  v_max = limits.v_max.max()
  brake_bound = max(shield.max_s_stop,
                    ((v_max + limits.a_max_ltt.max() * shield.max_s_stop) /
                     (limits.a_max.min() - limits.a_max_ltt.max())) + 0.03)
  assert stop_time <= brake_bound + dt
  if v_max <= 1.0:
    assert stop_time <= shield.max_s_stop + dt
  # Limits, from the commands by finite differences.
  acc = np.diff(dq, axis=0) / dt
  jerk = np.diff(acc, axis=0) / dt
  assert np.all(np.abs(acc) <= limits.a_max * (1 + 1e-6))
  assert np.all(np.abs(jerk) <= limits.j_max * (1 + 1e-6))
  assert np.all(np.abs(dq) <= limits.v_max * (1 + 1e-9))
  # Path-consistent: the stop lies on the plan's path.
  plan = shield.plan
  np.testing.assert_allclose(q[-1], plan.evaluate(shield.s)[0], atol=1e-12)
  # And it stays stopped while the human stays.
  for _ in range(25):
    shield.step(body, t)
    t += dt
    assert np.abs(shield.dq).max() == 0.0
