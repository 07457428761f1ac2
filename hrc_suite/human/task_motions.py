"""Per-task motion scripts for the synthetic library (see synthesis.py).

Clip frame: the person's station is the origin, facing +x, z up. For the
tasks across the table (layout.HUMAN_STATION_ACROSS) the table's far edge is
at x = TABLE_EDGE_X and the robot base about 1.45 m ahead; for reach and pick
and place the person works beside the robot (layout.HUMAN_STATION_BESIDE),
where the table edge is at the same x and the robot base at
ROBOT_BASE_BESIDE. Every script draws its variation (targets, hands, timing,
number of repetitions) from the given random_state only.

Idle phases: amplitudes u_i (seconds of clip time) and periods of natural
waiting (a slow sway of a second or so every 12-20 s plus smaller, quicker
shifts), not the reference's values: those add a 0.6-0.7 frame sine at
70-125 Hz whose slope of 2.6-3.1 drives keypoints past 2 m/s (see
docs/motion_library.md). The generator then checks each phase's worst case
and slows it where needed (synthesis.fit_idle_phases).
"""

import math

import numpy as np

from hrc_suite import layout
from hrc_suite.human import clip as clip_lib
from hrc_suite.human import synthesis

# Table edge towards the person and table top height in the clip frame.
TABLE_EDGE_X = layout.HUMAN_STATION_ACROSS[0] - layout.TABLE_X[1]
TABLE_Z = layout.TABLE_TOP_Z
# Robot base in the clip frame of the beside station (yaw -pi/2).
ROBOT_BASE_BESIDE = (layout.HUMAN_STATION_BESIDE[1] - layout.ROBOT_BASE_POS[1],
                     layout.ROBOT_BASE_POS[0] - layout.HUMAN_STATION_BESIDE[0])
# Cubes of the stacking task (edge length, m) and palm height above an
# object's centre when gripping it from above.
CUBE_SIZE = 0.05
GRIP_ABOVE_CENTRE = 0.035
# Hammer: distance from the palm to the striking face along the handle, and
# height of the palm above the face at impact.
HAMMER_REACH = 0.26
HAMMER_FACE_BELOW_PALM = 0.04



def _idle_sines(*sines):
  """(amplitudes u_i in s, slopes S_i) from (amplitude s, period s) pairs.

  u sin(2 pi t / period) has slope S = 2 pi u / period at t = 0.
  """
  amplitudes = [float(u) for u, _ in sines]
  speeds = [round(2 * math.pi * u / period, 3) for u, period in sines]
  return amplitudes, speeds


# Reaching out and waiting for the handover: the arm drifts back by up to a
# second of the reach and out again every ~12 s, with a smaller 5 s shift.
# Slopes sum to 0.8: the hand keeps most of its speed on arriving.
IDLE_HANDOVER_REACH = _idle_sines((1.2, 12.0), (0.15, 5.0))
# Standing and watching the robot (inspection, placing, stacking): slow sway
# over ~0.8 s of the clip, 4 s and 8 s shifts on top.
IDLE_WATCHING = _idle_sines((0.8, 20.0), (0.2, 8.0), (0.06, 4.0))
# Hammering until the nail is in: the blows go on at their own pace
# (slopes sum to 1 at the keyframe), drifting over +-2 s of blows.
IDLE_HAMMERING = _idle_sines((2.0, 16.0), (0.3, 9.0))

IDLE_ROBOT_TO_HUMAN = IDLE_HANDOVER_REACH
IDLE_HUMAN_TO_ROBOT_PRESENT = IDLE_HANDOVER_REACH
IDLE_HUMAN_TO_ROBOT_WAIT = IDLE_WATCHING
IDLE_INSPECTION = IDLE_WATCHING
IDLE_STACKING_SECOND = IDLE_WATCHING
IDLE_STACKING_FOURTH = IDLE_WATCHING

def _warp_reach(amplitudes):
  """Largest |t_A - t_I| (s) of an idle phase: sum u_i x 1.1**3."""
  return sum(amplitudes) * clip_lib.DEFAULT_STD_FACTOR ** 3


def _wait(script, rs, event, idle, sides, after, before=None):
  """An idle phase for `event` amid a still stretch of the clip.

  Hands in `sides` make small gestures meanwhile. The clip stays still for
  the warp's reach after the keyframe plus uniform(*after) s, so a forward
  warp never shows what follows the event. `before` is None (a backward warp
  replays the preceding move), 'still' (the person stands for the warp's
  reach before the keyframe) or 'gestures' (stands, gesturing with `sides`).
  """
  amplitudes, speeds = idle
  reach = _warp_reach(amplitudes)
  if before == 'gestures':
    script.fidget(reach + 0.1, sides)
  elif before == 'still':
    script.hold(reach + 0.1)
  elif before is not None:
    raise ValueError(f"before must be None, 'still' or 'gestures', got "
                     f'{before!r}')
  script.idle(event, amplitudes, speeds)
  script.fidget(reach + rs.uniform(*after), sides)


def _side_sign(side):
  return 1.0 if side == 0 else -1.0


def _hand_name(side):
  return ('left', 'right')[side]


def _choose_hand(rs, right_probability=0.7):
  return 1 if rs.uniform() < right_probability else 0


def _station(rs, spread=0.04):
  return np.array([rs.uniform(-spread, spread), rs.uniform(-spread, spread)])


def _approach(script, rs, distance=(0.8, 1.3), lateral=0.3):
  """Starts back from the station and walks in; hands relaxed."""
  start = np.array([-rs.uniform(*distance), rs.uniform(-lateral, lateral)])
  script.start_at(start, yaw=rs.uniform(-0.15, 0.15))
  script.hold(rs.uniform(0.3, 0.8))
  script.walk(_station(rs), yaw=rs.uniform(-0.05, 0.05))
  script.hold(rs.uniform(0.2, 0.5))


def _retreat(script, rs, distance=(0.6, 1.0)):
  """Turns away from the table and walks off."""
  turn = rs.choice([-1.0, 1.0]) * rs.uniform(2.4, 3.0)
  heading = script.value('yaw') + turn
  d = rs.uniform(*distance)
  xy = script.value('pelvis_xy') + d * np.array(
      [math.cos(heading), math.sin(heading)])
  script.walk(xy, yaw=heading)


def _look_at(script, point, duration, advance=False, start=None):
  """Turns the head towards a clip-frame point (small angles)."""
  local = script.to_local(point)
  neck_height = script.standing_height + script.body.spine
  yaw = math.atan2(local[1], max(local[0], 0.05))
  pitch = math.atan2(neck_height + 0.1 - point[2],
                     max(math.hypot(local[0], local[1]), 0.05))
  script.move(duration, advance=advance, start=start,
              head_yaw=float(np.clip(yaw, -0.8, 0.8)),
              head_pitch=float(np.clip(pitch, -0.3, 0.7)))


def _arm_point(script, rs, side, lean, fraction, elevation, azimuth):
  """A clip-frame point at `fraction` of the arm's reach from the shoulder.

  The shoulder is taken with the torso leaning by `lean`; `elevation` is the
  angle above horizontal, `azimuth` the angle towards the hand's own side.
  People hand things over and strike with the arm almost straight.
  """
  shoulder = script.shoulder_world(side, lean=lean, drop=0.0)
  yaw = script.value('yaw') + _side_sign(side) * azimuth
  direction = np.array([np.cos(elevation) * np.cos(yaw),
                        np.cos(elevation) * np.sin(yaw), np.sin(elevation)])
  return shoulder + fraction * script.body.arm_reach * direction


def _table_point(rs, x, y, height=0.0):
  return np.array([rs.uniform(*x), rs.uniform(*y), TABLE_Z + height])


# ------------------------------------------------------------------ tasks


def _walk_in_beside(script, rs):
  """Walks along the table into the beside station."""
  sign = rs.choice([-1.0, 1.0])
  script.start_at(np.array([rs.uniform(-0.15, 0.0),
                            sign * rs.uniform(0.8, 1.2)]),
                  yaw=-sign * math.pi / 2 * rs.uniform(0.7, 1.0))
  script.hold(rs.uniform(0.2, 0.6))
  script.walk(_station(rs), yaw=rs.uniform(-0.1, 0.1))
  script.metadata['station'] = 'beside'


def _walk_off_beside(script, rs):
  sign = rs.choice([-1.0, 1.0])
  script.walk(np.array([rs.uniform(-0.15, 0.0), sign * rs.uniform(0.7, 1.1)]),
              yaw=sign * math.pi / 2 * rs.uniform(0.7, 1.0))


def reach(script, rs):
  """Working beside the robot: walk in, reach into the shared space, leave."""
  _walk_in_beside(script, rs)
  for i in range(rs.randint(3, 6)):
    side = rs.randint(2)
    target = _table_point(rs, (0.45, 0.72), (-0.35, 0.45),
                          rs.uniform(0.08, 0.4))
    _look_at(script, target, 0.4)
    script.reach(side, target, swivel=rs.uniform(-0.2, 0.4),
                 wrist=rs.uniform(0.1, 0.5), speed_scale=1.05)
    script.targets[f'reach_{i + 1}'] = target
    script.mark()
    script.fidget(rs.uniform(0.2, 0.8), [1 - side])
    if rs.uniform() < 0.5:
      work = _table_point(rs, (0.32, 0.45), (-0.25, 0.25), 0.06)
      script.reach(side, work, wrist=0.6, speed_scale=1.05)
      script.fidget(rs.uniform(0.3, 1.0), [1 - side])
    script.rest(side, lean=0.0, pelvis_drop=0.0, head_pitch=0.0, head_yaw=0.0)
    script.hold(rs.uniform(0.1, 0.5))
  if rs.uniform() < 0.7:
    _walk_off_beside(script, rs)


def pick_place(script, rs):
  """Beside the robot: pick objects from the table and place them elsewhere,
  one after the other without pausing (a brisk work loop)."""
  _walk_in_beside(script, rs)
  side = _choose_hand(rs)
  script.holding_hand = script.placing_hand = _hand_name(side)
  lift_height = GRIP_ABOVE_CENTRE + 0.02
  for i in range(rs.randint(3, 6)):
    pick = _table_point(rs, (0.42, 0.65), (-0.1, 0.45), lift_height)
    place = _table_point(rs, (0.5, 0.75), (-0.4, 0.2), lift_height)
    _look_at(script, pick, 0.4)
    script.reach(side, pick + [0, 0, 0.06], wrist=0.6, speed_scale=1.1)
    script.reach(side, pick, wrist=0.6, duration=rs.uniform(0.25, 0.4))
    script.mark()
    script.hold(rs.uniform(0.1, 0.25))
    lift = 0.5 * (pick + place) + [0, 0, rs.uniform(0.12, 0.25)]
    script.reach(side, lift, wrist=0.4, speed_scale=1.1)
    _look_at(script, place, 0.4)
    script.reach(side, place, wrist=0.6, speed_scale=1.1)
    script.mark()
    script.hold(rs.uniform(0.1, 0.25))
    script.targets[f'pick_{i + 1}'] = pick - [0, 0, GRIP_ABOVE_CENTRE]
    script.targets[f'place_{i + 1}'] = place - [0, 0, GRIP_ABOVE_CENTRE]
    script.reach(side, place + [0, 0, 0.08], duration=rs.uniform(0.3, 0.45))
  script.rest(side, lean=0.0, pelvis_drop=0.0, head_pitch=0.0, head_yaw=0.0)
  script.fidget(rs.uniform(0.5, 1.5), [0, 1])
  if rs.uniform() < 0.7:
    _walk_off_beside(script, rs)


def inspection(script, rs):
  """Approach, wait for the object, inspect it, retreat."""
  _approach(script, rs)
  point = np.array([rs.uniform(0.62, 0.75), rs.uniform(-0.1, 0.1),
                    rs.uniform(1.15, 1.35)])
  script.targets['inspection_point'] = point
  _wait(script, rs, clip_lib.Event.object_presented, IDLE_INSPECTION, [0, 1],
        after=(0.2, 1.0), before='gestures')
  _look_at(script, point, 0.6, advance=True)
  side = _choose_hand(rs, 0.6)
  near = point + [-0.1, -_side_sign(1 - side) * 0.0, -0.06]
  script.reach(side, near, lean=rs.uniform(0.05, 0.2), wrist=0.0)
  other = 1 - side
  for _ in range(rs.randint(4, 8)):
    choice = rs.uniform()
    if choice < 0.5:
      # Shift the stance to look from another side (hand stays on the
      # object's side of the body).
      step = np.array([rs.uniform(-0.05, 0.1), rs.uniform(-0.15, 0.15)])
      script.walk(script.value('pelvis_xy') + step)
    offset = np.array([rs.uniform(-0.08, -0.03), rs.uniform(-0.08, 0.08),
                       rs.uniform(-0.08, 0.02)])
    if choice > 0.7:   # Both hands turn the object over in front.
      script.reach(side, point + offset, lean=script.value('lean'),
                   speed_scale=0.8)
      script.reach(other, point + offset * [1, -1, 1], lean=script.value(
          'lean'), speed_scale=0.8)
      script.hold(rs.uniform(0.2, 0.5))
      script.rest(other)
    else:  # One hand feels around the object while the other idles.
      duration = rs.uniform(0.9, 1.5)
      script.reach(side, point + offset, lean=script.value('lean'),
                   duration=duration, advance=False)
      script.fidget(duration + rs.uniform(0.0, 0.3), [other])
    _look_at(script, point + [0, rs.uniform(-0.08, 0.08), 0], 0.5)
  script.rest(side, lean=0.0, head_pitch=0.0, head_yaw=0.0)
  script.mark()
  script.hold(rs.uniform(0.3, 0.8))
  _retreat(script, rs)


# Where a person carrying one end of the board may walk (clip frame, m,
# relative to where they lifted it: x towards the robot): steps of up to
# 0.25 m would add up to 0.5 m backwards, carrying the robot's end
# (handle) ~0.9 m from the robot's base, beyond every robot's gripper-down
# reach (~0.75-0.8 m, measured with the lifting expert).
LIFT_WALK_RANGE = (np.array([-0.2, -0.2]), np.array([0.05, 0.2]))
# Peak speed of the board while carried (m/s): the robot's end follows in
# steps of at most 3 cm per 0.1 s RL step near the person (the lifting
# expert's measured limit before the shield stalls it); the person's walks
# and hand moves reached 0.35-0.5 m/s and pulled the board out of the
# Schunk's fingers (clip lifting_05).
LIFT_CARRY_SPEED = 0.2


def lifting(script, rs):
  """Grasp the board's end with both hands, lift, carry slowly, put down."""
  script.start_at(_station(rs, 0.06), yaw=rs.uniform(-0.05, 0.05))
  script.channels['pelvis_drop'].value[:] = 0.0
  script.fidget(rs.uniform(0.9, 1.5), [0, 1])
  grasp_x = rs.uniform(TABLE_EDGE_X + 0.18, TABLE_EDGE_X + 0.28)
  half = rs.uniform(0.14, 0.18)
  centre_y = rs.uniform(-0.04, 0.04)
  board_top = TABLE_Z + 0.03
  grasps = [np.array([grasp_x, centre_y + half, board_top + 0.02]),
            np.array([grasp_x, centre_y - half, board_top + 0.02])]
  script.targets['board_grasp_left'] = grasps[0]
  script.targets['board_grasp_right'] = grasps[1]
  script.metadata['board_size'] = [1.0, 0.4, 0.03]
  _look_at(script, 0.5 * (grasps[0] + grasps[1]), 0.6)
  script.reach_both(grasps, left_wrist=0.5, right_wrist=0.5)
  script.mark()
  script.hold(rs.uniform(0.2, 0.5))
  lift = rs.uniform(0.15, 0.3)
  held = [g + [rs.uniform(-0.05, 0.0), 0.0, lift] for g in grasps]
  held[1][0] = held[0][0]
  script.reach_both(held, duration=rs.uniform(1.2, 1.8), lean=0.0,
                    pelvis_drop=0.0, head_pitch=0.2)
  held_local = [script.value('left_hand').copy(),
                script.value('right_hand').copy()]
  script.mark()
  lifted_at = script.value('pelvis_xy').copy()

  def carry_duration(distance, low, high):
    # At least long enough for a peak speed of LIFT_CARRY_SPEED.
    return max(rs.uniform(low, high), synthesis.MIN_JERK_PEAK_RATIO *
               distance / LIFT_CARRY_SPEED)

  for _ in range(rs.randint(4, 8)):
    script.hold(rs.uniform(0.0, 0.3))
    if rs.uniform() < 0.4:
      step = np.array([rs.uniform(-0.25, 0.05), rs.uniform(-0.25, 0.25)])
      # The robot holds the board's other end: the person stays where the
      # robot's end can follow (LIFT_WALK_RANGE about the lifting stance).
      target = np.clip(script.value('pelvis_xy') + step,
                       lifted_at + LIFT_WALK_RANGE[0],
                       lifted_at + LIFT_WALK_RANGE[1])
      distance = np.linalg.norm(target - script.value('pelvis_xy'))
      script.walk(target, duration=carry_duration(distance, 1.8, 2.6))
    else:
      # Around the lifted pose (not cumulative), in the body's frame.
      delta = np.array([rs.uniform(-0.12, 0.08), rs.uniform(-0.15, 0.15),
                        rs.uniform(-0.12, 0.12)])
      targets = [held_local[s] + delta for s in range(2)]
      distance = max(np.linalg.norm(targets[s] - script.value(hand))
                     for s, hand in enumerate(('left_hand', 'right_hand')))
      script.move(carry_duration(distance, 0.9, 1.5), lean=0.0,
                  left_hand=targets[0], right_hand=targets[1])
    script.mark()
  station = _station(rs, 0.02)
  script.walk(station, duration=carry_duration(
      np.linalg.norm(station - script.value('pelvis_xy')), 1.0, 1.0))
  down = [np.array([grasp_x, centre_y + half, board_top + 0.02]),
          np.array([grasp_x, centre_y - half, board_top + 0.02])]
  script.reach_both(down)
  script.mark()
  script.hold(rs.uniform(0.2, 0.5))
  script.rest(0, advance=False, lean=0.0, pelvis_drop=0.0, head_pitch=0.0,
              head_yaw=0.0)
  script.rest(1)
  script.hold(rs.uniform(0.3, 0.8))


def handover_robot_to_human(script, rs):
  """Reach out for the object, wait for it, take it back, retreat."""
  _approach(script, rs)
  side = _choose_hand(rs)
  script.holding_hand = _hand_name(side)
  lean = rs.uniform(0.0, 0.12)
  point = _arm_point(script, rs, side, lean, rs.uniform(0.88, 0.94),
                     rs.uniform(-0.45, -0.15), rs.uniform(-0.15, 0.25))
  script.targets['handover_point'] = point
  _look_at(script, point, 0.6)
  script.reach(side, point, lean=lean, wrist=0.0, pelvis_drop=0.0,
               swivel=rs.uniform(0.0, 0.4))
  script.hold(rs.uniform(0.2, 0.5))
  # A backward warp draws the arm back along the reach and out again.
  _wait(script, rs, clip_lib.Event.object_received, IDLE_ROBOT_TO_HUMAN,
        [1 - side], after=(2.0, 2.8))
  carry = script.to_world(np.array([rs.uniform(0.2, 0.3),
                                    _side_sign(side) * 0.2,
                                    script.standing_height + 0.1]))
  script.reach(side, carry, lean=0.0, wrist=0.3, head_pitch=0.2, head_yaw=0.0,
               pelvis_drop=0.0)
  script.mark()
  script.hold(rs.uniform(0.4, 0.8))
  _retreat(script, rs)


def handover_human_to_robot(script, rs):
  """Pick up the object, present it, wait until it is taken, retreat."""
  _approach(script, rs)
  side = _choose_hand(rs)
  script.holding_hand = _hand_name(side)
  pick = _table_point(rs, (0.38, 0.48), (0.12, 0.32), 0.03)
  pick[1] *= _side_sign(side)
  script.targets['object_pick'] = pick - [0, 0, 0.03]
  _look_at(script, pick, 0.5)
  script.reach(side, pick + [0, 0, 0.06], wrist=0.7)
  script.reach(side, pick, wrist=0.7, duration=rs.uniform(0.4, 0.6))
  script.mark()
  script.hold(rs.uniform(0.3, 0.6))
  lean = rs.uniform(0.0, 0.12)
  point = _arm_point(script, rs, side, lean, rs.uniform(0.88, 0.94),
                     rs.uniform(-0.45, -0.15), rs.uniform(-0.15, 0.2))
  script.targets['handover_point'] = point
  _look_at(script, point, 0.6)
  script.reach(side, point, lean=lean, wrist=0.1, pelvis_drop=0.0)
  _wait(script, rs, clip_lib.Event.object_taken, IDLE_HUMAN_TO_ROBOT_PRESENT,
        [1 - side], after=(2.0, 2.5))
  script.rest(side, lean=0.0, head_pitch=0.3)
  _wait(script, rs, clip_lib.Event.object_placed, IDLE_HUMAN_TO_ROBOT_WAIT,
        [0, 1], after=(1.0, 2.0), before='still')
  script.move(0.6, head_pitch=0.0, head_yaw=0.0)
  _retreat(script, rs)


def hammering(script, rs):
  """Approach holding a hammer, strike the nail until it is in, retreat."""
  side = _choose_hand(rs, 0.8)
  script.holding_hand = _hand_name(side)
  _approach(script, rs)
  lean = rs.uniform(0.05, 0.15)
  contact = _arm_point(script, rs, side, lean, rs.uniform(0.88, 0.94),
                       rs.uniform(-0.35, -0.1), rs.uniform(-0.25, 0.05))
  nail = contact + [HAMMER_REACH * np.cos(script.value('yaw')),
                    HAMMER_REACH * np.sin(script.value('yaw')),
                    -HAMMER_FACE_BELOW_PALM]
  script.targets['nail'] = nail
  script.targets['strike_grip'] = contact
  raised = contact + [-rs.uniform(0.06, 0.1), 0.0, rs.uniform(0.18, 0.26)]
  _look_at(script, nail, 0.6)
  script.reach(side, raised, lean=lean, wrist=0.0)
  script.hold(rs.uniform(0.2, 0.4))
  script.mark()
  amplitudes, speeds = IDLE_HAMMERING
  # The idle phase loops the blows (forwards and backwards) until the nail is
  # in: blows must cover the warp's reach on both sides of the keyframe.
  reach_time = _warp_reach(amplitudes)
  start = script.t
  anchored = False
  while not anchored or script.t < start + 2 * reach_time + 0.5:
    if not anchored and script.t >= start + reach_time:
      script.idle(clip_lib.Event.nail_hammered, amplitudes, speeds)
      anchored = True
    top = raised + rs.uniform(-0.02, 0.02, 3)
    script.strike(side, contact, top, up_time=rs.uniform(0.4, 0.6),
                  down_time=rs.uniform(0.12, 0.16),
                  rest_time=rs.uniform(0.1, 0.3))
  script.mark()
  carry = script.to_world(np.array([0.2, _side_sign(side) * 0.22,
                                    script.standing_height - 0.05]))
  script.reach(side, carry, lean=0.0, head_pitch=0.0, head_yaw=0.0,
               wrist=0.3)
  script.hold(rs.uniform(0.3, 0.6))
  _retreat(script, rs)


# hammering/robot_hammers: the person carries the nail plank in by its
# handle (the holding hand; the other hand steadies the plank's side), sets
# it down with the handle under the holding hand, which rests there, and
# waits for the robot's blows. Palm above the table with the hand on the
# handle (its top 0.10 m up: a 4 cm plank and a 6 cm handle, nail_board.py)
# and the handle's place, clip frame: the reference's recordings set the
# board down 0.56-0.75 m ahead and 0.09-0.29 m to the holding hand's side
# (task_targets, hammering_board).
BOARD_HAND_ABOVE_TABLE = 0.12
BOARD_PLACE_X = (TABLE_EDGE_X + 0.27, TABLE_EDGE_X + 0.42)
BOARD_PLACE_Y = (0.08, 0.25)
# Carrying pose of the holding hand (pelvis heading frame, m) and where the
# other hand steadies the plank from it (along, across, up).
BOARD_CARRY = np.array([0.38, 0.1, 0.1])
BOARD_STEADY = np.array([0.15, -0.12, 0.0])


def hammering_board(script, rs):
  """Carry the nail plank in, set it down, wait (hand resting on it) until
  the robot has driven the nail, take the plank and leave."""
  side = _choose_hand(rs, 0.5)
  script.holding_hand = _hand_name(side)
  sign = _side_sign(side)
  start = np.array([-rs.uniform(0.8, 1.3), rs.uniform(-0.3, 0.3)])
  script.start_at(start, yaw=rs.uniform(-0.15, 0.15))

  def carry_pose(holding):
    local = {side: holding}
    local[1 - side] = holding + BOARD_STEADY * [1.0, sign, 1.0]
    return {HAND: local[s] for s, HAND in enumerate(synthesis.HAND_CHANNELS)}

  carry = np.array([BOARD_CARRY[0], sign * BOARD_CARRY[1],
                    script.standing_height + BOARD_CARRY[2]])
  script.move(rs.uniform(0.6, 0.9), **carry_pose(carry))
  script.hold(rs.uniform(0.2, 0.5))
  script.walk(_station(rs), yaw=rs.uniform(-0.05, 0.05))
  place = _table_point(rs, BOARD_PLACE_X, BOARD_PLACE_Y)
  place[1] *= sign
  script.targets['board_place'] = place
  hand = place + [0.0, 0.0, BOARD_HAND_ABOVE_TABLE]
  steady = hand + BOARD_STEADY * [1.0, sign, 1.0]
  _look_at(script, hand, 0.6)
  both = [hand, steady] if side == 0 else [steady, hand]
  script.reach_both(both, speed_scale=0.7)
  script.mark()                               # set down
  script.hold(rs.uniform(0.2, 0.4))
  script.rest(1 - side, head_pitch=0.4)
  _wait(script, rs, clip_lib.Event.nail_hammered, IDLE_WATCHING, [1 - side],
        after=(1.0, 2.0), before='still')
  script.mark()                               # take back
  script.move(rs.uniform(0.8, 1.1), head_pitch=0.0, head_yaw=0.0,
              **carry_pose(carry), lean=0.0, pelvis_drop=0.0)
  script.hold(rs.uniform(0.2, 0.5))
  _retreat(script, rs)


def stacking(script, rs):
  """Place cube 1, wait for cube 2, place cube 3, wait for cube 4."""
  _approach(script, rs, distance=(0.4, 0.7))
  side = _choose_hand(rs, 0.5)
  script.placing_hand = _hand_name(side)
  base = _table_point(rs, (0.55, 0.65), (-0.08, 0.08))
  script.targets['stack_base'] = base
  script.metadata['cube_size'] = CUBE_SIZE
  second_side = side if rs.uniform() < 0.6 else 1 - side
  events = clip_lib.Event
  for hand, cube, wait, event in (
      (side, 1, IDLE_STACKING_SECOND, events.second_cube_placed),
      (second_side, 3, IDLE_STACKING_FOURTH, events.fourth_cube_placed)):
    pick = _table_point(rs, (0.36, 0.45), (0.2, 0.35), CUBE_SIZE / 2)
    pick[1] *= _side_sign(hand)
    place = base + [0, 0, CUBE_SIZE * (cube - 0.5)]
    script.targets[f'cube_{cube}_pick'] = pick
    script.targets[f'cube_{cube}_place'] = place
    grip = [0, 0, GRIP_ABOVE_CENTRE]
    _look_at(script, pick, 0.5)
    script.reach(hand, pick + grip + [0, 0, 0.06], wrist=0.8)
    script.reach(hand, pick + grip, wrist=0.8, duration=rs.uniform(0.4, 0.6))
    script.hold(rs.uniform(0.2, 0.4))
    _look_at(script, place, 0.5)
    script.reach(hand, place + grip + [0, 0, 0.08], wrist=0.8)
    script.reach(hand, place + grip, wrist=0.8, duration=rs.uniform(0.5, 0.7))
    script.mark()
    script.hold(rs.uniform(0.2, 0.4))
    script.reach(hand, place + grip + [0, 0, 0.1],
                 duration=rs.uniform(0.4, 0.6))
    script.rest(hand, lean=0.0, pelvis_drop=0.0, head_pitch=0.3, head_yaw=0.0)
    _wait(script, rs, event, wait, [0, 1], after=(1.0, 2.0),
          before='gestures')
  _retreat(script, rs, distance=(0.4, 0.8))


TASK_SCRIPTS = {
    'reach': reach,
    'pick_place': pick_place,
    'inspection': inspection,
    'lifting': lifting,
    'handover_robot_to_human': handover_robot_to_human,
    'handover_human_to_robot': handover_human_to_robot,
    'hammering': hammering,
    'stacking': stacking,
    'hammering_board': hammering_board,
}

# Clips per task: the reference's counts (docs/reference_benchmark.md, Tasks).
CLIP_COUNTS = {
    'reach': 12, 'pick_place': 12, 'inspection': 8, 'lifting': 9,
    'handover_robot_to_human': 15, 'handover_human_to_robot': 11,
    'hammering': 11, 'stacking': 8,
    # The reference's hammering recordings (the roles they record).
    'hammering_board': 8,
}
