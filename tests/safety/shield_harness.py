"""Closed-loop harness for the shield's tests (imported by test modules).

The robot follows the shield's command exactly; the human is a keypoint
trajectory (synthetic adversarial motions, or real clips). After a run the
robot's real capsules (description capsules plus the tool) are checked
against the human's real body capsules at the command's cycle time, half a
cycle later and one cycle later.
"""

import dataclasses
import math

import numpy as np

from hrc_suite import layout
from hrc_suite.human import keypoints as keypoint_set
from hrc_suite.safety import geometry

CYCLE = 0.004
# Robot speed (m/s) above which a contact in SSM counts as a violation.
MOVING_SPEED = 1e-3

# A standing person at the origin facing +x (metres, z up): a plain template
# with roughly 50th-percentile male proportions (DIN 33402-2 stature 1.75 m).
_TEMPLATE = {
    'pelvis': (0.0, 0.0, 0.95), 'torso': (0.0, 0.0, 1.12),
    'chest': (0.0, 0.0, 1.30), 'neck': (0.0, 0.0, 1.48),
    'head': (0.0, 0.0, 1.62),
    'left_shoulder': (0.0, 0.19, 1.43), 'left_elbow': (0.02, 0.21, 1.13),
    'left_wrist': (0.05, 0.22, 0.88), 'left_hand': (0.06, 0.22, 0.79),
    'left_hip': (0.0, 0.09, 0.92), 'left_knee': (0.02, 0.09, 0.50),
    'left_ankle': (0.0, 0.09, 0.08),
}
for _name, (_x, _y, _z) in list(_TEMPLATE.items()):
  if _name.startswith('left_'):
    _TEMPLATE['right_' + _name[5:]] = (_x, -_y, _z)
STANDING = np.array([_TEMPLATE[n] for n in keypoint_set.KEYPOINT_NAMES])
RIGHT_ARM = keypoint_set.index(['right_elbow', 'right_wrist', 'right_hand'])


def place(points, x, y, yaw):
  """Keypoints of a clip-frame pose placed at (x, y) turned by yaw."""
  c, s = math.cos(yaw), math.sin(yaw)
  rotation = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
  return points @ rotation.T + np.array([x, y, 0.0])


def ramped_distance(t, start, speed, accel):
  """Distance travelled by t when accelerating at accel up to speed."""
  t = max(t - start, 0.0)
  ramp = speed / accel
  if t < ramp:
    return 0.5 * accel * t * t
  return 0.5 * accel * ramp * ramp + speed * (t - ramp)


def hand_attack(target, start=0.3, speed=2.0, accel=40.0, station=None,
                overshoot=0.5):
  """The right forearm and hand thrust straight at `target` at `speed`
  (m/s, reached at accel m/s^2 within the arm joints' a_max of 50), from a
  person standing across the table, and on through it for `overshoot` m
  (0: the hand stays at the target)."""
  x, y, yaw = station or (1.3, 0.0, math.pi)
  body = place(STANDING, x, y, yaw)
  hand = body[keypoint_set.KEYPOINT_INDEX['right_hand']]
  direction = np.asarray(target, dtype=float) - hand
  reach = np.linalg.norm(direction) + overshoot
  direction /= np.linalg.norm(direction)

  def keypoints(t):
    out = body.copy()
    out[RIGHT_ARM] += min(ramped_distance(t, start, speed, accel),
                          reach) * direction
    return out
  return keypoints


def walk_in(start=0.2, speed=1.2, accel=10.0, y=0.0, stop_x=0.35,
            from_x=2.6, swing=0.1):
  """A person walking from from_x straight at the robot along -x at speed
  (m/s) with arms swinging (amplitude `swing` m at 1 Hz), stopping at
  stop_x. Every keypoint stays below 2 m/s and its a_max."""
  body = place(STANDING, 0.0, y, math.pi)
  hands = keypoint_set.index(['left_wrist', 'left_hand', 'right_wrist',
                              'right_hand'])
  signs = np.array([1.0, 1.0, -1.0, -1.0])[:, None]

  def keypoints(t):
    x = max(from_x - ramped_distance(t, start, speed, accel), stop_x)
    out = body + np.array([x, 0.0, 0.0])
    out[hands, 0] += swing * math.sin(2 * math.pi * t) * signs[:, 0]
    return out
  return keypoints


def walk_in_and_leave(arrive=1.0, stay=0.6, speed=1.2, accel=10.0, near=0.6,
                      far=3.0):
  """Walks from far to near, stays, walks back to far."""
  body = place(STANDING, 0.0, 0.0, math.pi)
  travel = far - near
  duration = speed / accel + travel / speed   # Time to cover `travel`.
  start_in = arrive - duration
  start_out = arrive + stay

  def keypoints(t):
    if t < start_out:
      x = far - min(ramped_distance(t, start_in, speed, accel), travel)
    else:
      x = near + min(ramped_distance(t, start_out, speed, accel), travel)
    return body + np.array([x, 0.0, 0.0])
  return keypoints


def far_away():
  body = place(STANDING, 3.5, 0.0, math.pi)
  return lambda t: body


def clip_motion(positions, fps, station=layout.HUMAN_STATION_ACROSS):
  """Keypoints of a real clip (T, N, 3) at fps, placed at a station and
  interpolated linearly between frames."""
  placed = place(np.asarray(positions, dtype=float), *station)

  def keypoints(t):
    f = min(t * fps, len(placed) - 1.0)
    i = min(int(f), len(placed) - 2)
    w = f - i
    return (1 - w) * placed[i] + w * placed[i + 1]
  return keypoints


def tool_capsule(description, length=0.12, radius=0.045):
  """A gripper-sized capsule along the flange z axis (last link frame)."""
  p1 = description.flange_translation
  p2 = p1 + description.flange_rotation @ np.array([0.0, 0.0, length])
  return (p1, p2, radius)


def random_goals(description, random_state, spread=1.2):
  """Goals around the home pose, inside the joint limits."""
  limits = description.limits
  def goal():
    return np.clip(description.q_home + random_state.uniform(
        -spread, spread, description.dof), limits.q_min, limits.q_max)
  return goal


@dataclasses.dataclass
class Run:
  """What happened in a closed-loop run."""
  q: np.ndarray           # (T, dof) commands.
  dq: np.ndarray
  ddq: np.ndarray
  times: np.ndarray       # (T,) cycle times.
  safe: np.ndarray        # (T,) verdicts.
  intervened: np.ndarray
  min_clearance: float    # Smallest real robot-human distance seen (m).
  violations: list        # (time, capsule, body, distance, speed) tuples.


def simulate(shield, human, duration, goal=None, goal_every=12,
             first_goal=None, check=True):
  """Runs the shield for `duration` s; returns a `Run`.

  human(t) -> keypoints or None; goal() -> a new goal every goal_every
  cycles (the 20 Hz policy of the reference at a 4 ms cycle), or only
  first_goal once.
  """
  steps = int(round(duration / shield.cycle_time))
  dof = shield.dof
  q, dq, ddq = np.empty((steps, dof)), np.empty((steps, dof)), np.empty(
      (steps, dof))
  times = np.arange(steps) * shield.cycle_time
  safe = np.empty(steps, dtype=bool)
  intervened = np.empty(steps, dtype=bool)
  if first_goal is not None:
    shield.new_goal(first_goal)
  for i in range(steps):
    if goal is not None and i % goal_every == 0:
      shield.new_goal(goal())
    q[i], dq[i], ddq[i] = shield.step(human(times[i]), times[i])
    safe[i] = shield.is_safe
    intervened[i] = shield.intervened
  run = Run(q, dq, ddq, times, safe, intervened, np.inf, [])
  if check:
    _check_contacts(shield, human, run)
  return run


def _check_contacts(shield, human, run):
  """Fills run.min_clearance and run.violations (mode-dependent).

  Pairs checked: the command at t with the human at t, t + dt/2 and t + dt
  (the robot reaches the command within the cycle), and the midpoint of
  consecutive commands with the human at t.
  """
  robot = shield.robot
  limit = MOVING_SPEED if shield.mode == 'ssm' else shield.v_safe
  dt = shield.cycle_time
  middle = np.concatenate([run.q[:1], 0.5 * (run.q[1:] + run.q[:-1])])
  cases = ((run.q, 0.0), (run.q, 0.5), (run.q, 1.0), (middle, 0.0))
  for q, offset in cases:
    r1, r2, rr = robot.capsules(q)                     # (T, L, 3)
    speeds = robot.surface_speeds(q, run.dq)           # (T, L)
    points = np.array([human(t + offset * dt) for t in run.times])
    h1, h2, hr = shield.human.body_capsules(points)    # (T, B, 3)
    distance = geometry.capsule_distance(
        r1[:, :, None], r2[:, :, None], rr[None, :, None],
        h1[:, None], h2[:, None], hr[None, None])      # (T, L, B)
    run.min_clearance = min(run.min_clearance, float(distance.min()))
    t_idx, link, body = np.nonzero(distance < 0.0)
    fast = speeds.max(axis=1)[t_idx] > limit
    for i in np.nonzero(fast)[0]:
      run.violations.append((float(run.times[t_idx[i]]), int(link[i]),
                             shield.human.body_names[body[i]],
                             float(distance[t_idx[i], link[i], body[i]]),
                             float(speeds[t_idx[i]].max())))
