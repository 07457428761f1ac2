"""Collaborative stacking: four cubes stacked in turns, human 1, robot 2,
human 3, robot 4 (docs/reference_benchmark.md, Tasks).

* Scene: four 5 cm cubes (`props.make_stacking_cubes`) on a shallower
  table than the other tasks' (layout.STACKING_TABLE). Cubes 1 and 3
  start at the clip's 'cube_1_pick' / 'cube_3_pick' targets; the human
  holds each (`Human.hold`, a weld to the nearer hand) once that hand
  reaches it (one cube at a time: cube 3 after cube 1 is down) and
  releases it on the clip's 'cube_i_place' target, setting it down
  upright and at rest. Cubes 2 and 4 start on the robot's side of the
  table (x ROBOT_CUBE_X, |y| ROBOT_CUBE_Y, on a random side each, clear of
  the clip's stack), where every robot reaches them gripper-down.
* Slots: cube 1's is the clip's 'stack_base' + half a cube, moved sideways
  to where the human let it go (the clips' hands land 2-4 cm from their
  place targets, short of full reach); cube i's is one cube size above
  cube i-1 once that one is in its slot. A cube is in place within
  STACK_TOLERANCE of its slot and stacked once in place and nobody holds
  it. The human waits for 'second_cube_placed' and
  'fourth_cube_placed' (Stacking.EVENTS): the robot's cube in its slot,
  released, the TCP WITHDRAWN_DISTANCE away from it.
* Station: across the table at layout.HUMAN_STATION_STACKING (x 1.10 m,
  the pelvis 0.18 m from the table's edge), placement +-(0.02 m, 0.1 m,
  0.1 rad), so the person-robot distance is about the reference's (its
  stacking table is centred on its robot). People put the stack 0.40-0.65
  m ahead of their pelvis: it lands at world x 0.45-0.67 m, where every
  robot on its mount reaches the top cube's place gripper-down
  (docs/tasks.md). Across the other tasks' 1 m table it would lie
  0.71-0.94 m away, beyond the Cartesian action box (x <= 0.8 m) and most
  robots' reach.
* Success (delayed by the retreat, reference): all four cubes stacked when
  the human's clip ends (the clips go on ~5 s after the last event; the
  base's `clip_ended`). Rewards (sparse): +2 success, -10 and termination
  if a stacked cube (not held) moves by more than TOPPLE_DISTANCE from
  where it was stacked (the stack toppled), +1 with the fourth cube in its
  slot (held or not, before the clip ends), +0.75 while the robot grips a
  cube, -1 otherwise; no extra reward delay.
* Observations: 'paper' = object gripped, TCP->each cube, gripper aperture,
  distances to the human's head and hands; 'full' adds cube positions,
  quaternions, slots and stacked flags.
"""

import math

from dm_control.composer.observation import observable
import numpy as np

from hrc_suite import layout
from hrc_suite import rotations
from hrc_suite import suite
from hrc_suite.entities import element_ids
from hrc_suite.entities import human as human_lib
from hrc_suite.entities import props
from hrc_suite.human import clip as clip_lib
from hrc_suite.human import keypoints
from hrc_suite.human import task_motions
from hrc_suite.tasks import base
from hrc_suite.tasks.runtime import robot_payload

STACK_TOLERANCE = 0.025        # m (reference)
TOPPLE_DISTANCE = 2 * STACK_TOLERANCE   # m a stacked cube moved: fallen
REWARD_SUCCESS = 2.0           # reference values
REWARD_TOPPLED = -10.0
REWARD_FOURTH_PLACED = 1.0
REWARD_GRIPPING = 0.75
REWARD_OTHERWISE = -1.0
# Robot cubes: on the robot's half of the table, to the sides (world, m),
# where every robot on its mount reaches them gripper-down
# (layout.STACKING_TABLE's note; docs/tasks.md), each at least
# STACK_CLEARANCE (horizontally) from the clip's stack, whose place the
# clip knows at reset (recorded people put it up to 0.33 m to a side), and
# CUBE_SPACING from the other: drawn on a random side, the other side
# where that side has no room (ROBOT_CUBE_DRAWS tries).
ROBOT_CUBE_X = (0.40, 0.55)    # m, world
ROBOT_CUBE_Y = (0.22, 0.36)    # m to either side of the centre line
STACK_CLEARANCE = 0.15         # m: fingers and the person's hands
CUBE_SPACING = 0.1             # m
ROBOT_CUBE_DRAWS = 200
# The human's palm within this of a cube's grip point grabs it (the clips'
# hands stop up to ~2.5 cm short of a pick at full reach).
HAND_TOLERANCE = 0.035         # m
# The human lets a cube go once it is down on its place: centre within
# RELEASE_HEIGHT of the place's height and RELEASE_REACH of it sideways
# (the clips' hands land 2-4 cm from their targets).
RELEASE_HEIGHT = 0.01          # m
RELEASE_REACH = 0.06           # m
# ... or, where the hand stops short of the place (full reach), as soon as
# it starts to rise with the cube at most this high above its place.
RELEASE_DROP = 0.03            # m
# The human goes on once the robot's cube is in its slot and the TCP is
# this far from it (the robot has let go and withdrawn).
WITHDRAWN_DISTANCE = 0.15      # m
# Fingertips' clearance above the table that collision prevention keeps
# (pick_place's value: the TCP may go down to 2.8 cm above the table).
TABLE_CLEARANCE = 0.018        # m
HUMAN_CUBES = (0, 2)           # cubes 1 and 3
ROBOT_CUBES = (1, 3)           # cubes 2 and 4
_GRIP = np.array([0.0, 0.0, task_motions.GRIP_ABOVE_CENTRE])
_HAND_KEYPOINTS = np.array(keypoints.index(
    [f'{hand}_hand' for hand in human_lib.HANDS]))
_SEGMENT_NAMES = [s[0] for s in human_lib.SEGMENTS]
_ARM_SEGMENTS = tuple(f'{hand}_{part}' for hand in human_lib.HANDS
                      for part in ('hand', 'forearm'))
# Cube states of the human's cubes.
ON_TABLE, HELD, RELEASED = 0, 1, 2


def _distance(a, b):
  """Euclidean distance between two points given as sequences of floats
  (the squares summed in order, as NumPy's norm along an axis)."""
  total = 0.0
  for x, y in zip(a, b):
    d = x - y
    total += d * d
  return math.sqrt(total)


@suite.register('stacking', 'default',
                tags=('assembly', 'sparse', 'delayed', 'ssm'))
class Stacking(robot_payload.CarriesPayload, base.HrcTask):
  """Stack cubes 2 and 4 on the human's cubes 1 and 3."""

  MOTIONS = 'stacking'
  # The person waits for the robot's cube in slot two, then in slot four.
  EVENTS = (clip_lib.Event.second_cube_placed,
            clip_lib.Event.fourth_cube_placed)
  HUMAN_STATION = layout.HUMAN_STATION_STACKING
  TABLE = layout.STACKING_TABLE
  HUMAN_PLACEMENT_RANGE = (0.02, 0.1, 0.1)   # reference
  DEFAULT_SHIELD = 'ssm'
  DEFAULT_ACTION_SPACE = 'cartesian'
  REWARDS = ('sparse',)
  DEFAULT_REWARD_DELAY = 0     # the retreat delays success itself
  HORIZON = 3000
  HAS_GRIPPER_ACTION = True
  OBSERVATION_PRESETS = {'paper': (
      'object_gripped', 'eef_to_cubes', 'gripper_aperture',
      'human_distances')}
  EXTRA_COUNTERS = ('cubes_placed',)
  # The fingers go down around a cube on the table (as pick and place).
  FINGERTIP_TABLE_CLEARANCE = TABLE_CLEARANCE
  TASK_STATE = ('_slots', '_picks', '_places', '_human_state',
                '_holding_hand', '_held_height', '_stacked', '_stacked_at',
                '_in_slot', '_gripped', '_complete', '_success',
                '_toppled')

  def _build_task(self):
    self._cubes = props.make_stacking_cubes()
    self._cube_bodies = [c.body for c in self._cubes]
    self._cube_ids = element_ids.ElementIds(self._cube_bodies)
    self._size = self._cubes[0].size
    self._welds = {}
    for i, cube in enumerate(self._cubes):
      self._arena.add_free_entity(cube)
      self._object_geoms.extend(cube.geoms)
      if i in HUMAN_CUBES:
        self._welds[i] = self._grips.add(cube.body)
        # The hand capsule encloses the top of a cube it holds, and the
        # kinematic forearms (which cannot give way) sweep over the cubes
        # the person handles: no contacts between those and these cubes.
        for segment in _ARM_SEGMENTS:
          self._arena.mjcf_model.contact.add(
              'exclude', name=f'{segment}_{cube.mjcf_model.model}',
              body1=self._human.segment_bodies[_SEGMENT_NAMES.index(
                  segment)], body2=cube.body)
    # The clips may put cube 3's pick within a cube size of cube 1's (same
    # hand, same side): the two never touch in a stack (cube 2 is between),
    # so they do not collide, and neither overlaps nor bumps the other.
    first, third = (self._cubes[i] for i in HUMAN_CUBES)
    self._arena.mjcf_model.contact.add(
        'exclude', name='human_cubes', body1=first.body, body2=third.body)
    self._slots = np.zeros((4, 3))
    self._picks = np.zeros((4, 3))
    self._places = np.zeros((4, 3))
    self._reset_progress()

  def _reset_progress(self):
    self._human_state = [ON_TABLE] * 4
    self._holding_hand = [None] * 4
    self._held_height = np.full(4, np.inf)
    self._stacked = np.zeros(4, dtype=bool)
    self._stacked_at = np.zeros((4, 3))
    self._in_slot = np.zeros(4, dtype=bool)
    self._gripped = np.zeros(4, dtype=bool)
    self._complete = False   # all four stacked, nobody holds them
    self._success = False
    self._toppled = False

  @property
  def cubes(self) -> tuple[props.Cube, ...]:
    """The cubes to stack, in stacking order."""
    return self._cubes

  @property
  def slots(self) -> np.ndarray:
    """(4, 3) world positions of the cubes' places in the stack."""
    return self._slots.copy()

  @property
  def stacked(self) -> np.ndarray:
    """(4,) bools: which cubes lie in their place in the stack."""
    return self._stacked.copy()

  # ------------------------------------------------------------- episode

  def _initialize_task(self, physics, random_state):
    self._reset_progress()
    targets = self._player.targets_world
    base_point = np.asarray(targets['stack_base'], float)
    for i in range(4):
      self._slots[i] = base_point + [0.0, 0.0, self._size * (i + 0.5)]
    self._places = self._slots.copy()
    for i in HUMAN_CUBES:
      self._picks[i] = targets[f'cube_{i + 1}_pick']
      self._places[i] = targets[f'cube_{i + 1}_place']
    side = random_state.choice([-1.0, 1.0])
    taken = [base_point[:2]]
    for k, i in enumerate(ROBOT_CUBES):
      self._picks[i] = self._robot_cube_spot(
          random_state, side if k == 0 else -side, taken)
      taken.append(self._picks[i, :2])
    identity = np.array([1.0, 0.0, 0.0, 0.0])
    for i, cube in enumerate(self._cubes):
      cube.set_pose(physics, self._picks[i], identity)
      cube.set_velocity(physics, np.zeros(3), np.zeros(3))
    self._start_in_hand(physics)

  def _robot_cube_spot(self, random_state, side, taken):
    """Where a robot cube starts: uniform in the region on `side` (+-1),
    else the other side, clear of the `taken` points (the stack first)."""
    for sign in (side, -side):
      for _ in range(ROBOT_CUBE_DRAWS):
        spot = np.array([random_state.uniform(*ROBOT_CUBE_X),
                         sign * random_state.uniform(*ROBOT_CUBE_Y)])
        gaps = np.linalg.norm(np.asarray(taken) - spot, axis=1)
        if gaps[0] >= STACK_CLEARANCE and np.all(gaps[1:] >= CUBE_SPACING):
          return np.append(spot, layout.TABLE_TOP_Z + self._size / 2)
    raise ValueError(
        f'stacking: no room for a robot cube in x {ROBOT_CUBE_X}, |y| '
        f'{ROBOT_CUBE_Y} m at least {STACK_CLEARANCE} m from the stack at '
        f'{np.round(taken[0], 3).tolist()} m (the clip\'s stack_base)')

  def _start_in_hand(self, physics):
    """A human cube whose pick is where a hand holds it at the clip's start
    (recordings: the person carries both cubes in, human/task_targets.py)
    starts in that hand."""
    physics.forward()
    hands = self._human.keypoint_positions(physics)[_HAND_KEYPOINTS]
    for i in HUMAN_CUBES:
      distances = np.linalg.norm(hands - (self._picks[i] + _GRIP), axis=1)
      hand = int(np.argmin(distances))
      if distances[hand] < HAND_TOLERANCE:
        self._grab(physics, i, hand, hands[hand])
    physics.forward()

  # ------------------------------------------------------------ progress

  def _move_human_cubes(self, physics):
    """The human grabs a cube the hand reaches and lets go on its place.
    Returns whether anything was grabbed or let go."""
    changed = False
    hands = self._human.keypoint_positions(physics)[_HAND_KEYPOINTS].tolist()
    for i in HUMAN_CUBES:
      state = self._human_state[i]
      if state == ON_TABLE and any(self._human_state[j] != RELEASED
                                   for j in HUMAN_CUBES if j < i):
        continue   # One cube at a time: cube 3 only after cube 1 is down.
      if state == ON_TABLE:
        grip = (self._cube_positions(physics)[i] + _GRIP).tolist()
        distances = [_distance(hand, grip) for hand in hands]
        hand = 0 if distances[0] <= distances[1] else 1   # np.argmin's
        if distances[hand] < HAND_TOLERANCE:
          self._grab(physics, i, hand, np.array(hands[hand]))
          changed = True
      elif state == HELD:
        centre = self._cube_positions(physics)[i]
        x, y, z = centre.tolist()
        place = self._places[i].tolist()
        # Where the cube comes to rest: its place, or the surface under it
        # where that is higher (a recording's place may lie in our table).
        drop = abs(z - max(place[2], float(self._support(i, centre)[2])))
        rising = z > self._held_height[i]
        self._held_height[i] = z
        if (_distance((x, y), place[:2]) < RELEASE_REACH
            and (drop < RELEASE_HEIGHT
                 or (rising and drop < RELEASE_DROP))):
          self._grips.release(physics, self._cubes[i].body)
          self._set_down(physics, i, centre)
          self._human_state[i], self._holding_hand[i] = RELEASED, None
          changed = True
    return changed

  def _support(self, i, centre):
    """Where cube i rests when the person sets it down: cube 1 on the table
    under it; cube 3 on top of the robot's cube 2 once that is in its slot
    (as the reference: the recorded hands hold cube 3 0.1-0.3 m beside the
    stack, docs/tasks.md), else on the table."""
    if i == HUMAN_CUBES[1] and self._in_slot[ROBOT_CUBES[0]]:
      return self._slots[i].copy()
    return np.array([centre[0], centre[1], layout.TABLE_TOP_Z
                     + self._size / 2])

  def _set_down(self, physics, i, centre):
    """The person sets cube i down on its support (`_support`) upright and
    at rest (the welded cube turns with the hand's wrist, up to ~13
    degrees, and one let go tilted and moving tipped cube 3 off the stack:
    Panda seeds 0, 7, 9 of 10, without the robot touching anything)."""
    rest = self._support(i, centre)
    yaw = rotations.quat_yaw(physics.bind(self._cubes[i].body).xquat)
    self._cubes[i].set_pose(physics, rest, rotations.yaw_to_quat(yaw))
    self._cubes[i].set_velocity(physics, np.zeros(3), np.zeros(3))
    if i == HUMAN_CUBES[0]:   # The stack stands where the base cube is.
      self._slots[0] = rest

  def _grab(self, physics, i, hand, palm):
    """Welds cube i to `hand` with its centre GRIP_ABOVE_CENTRE under the
    palm (where the clip puts it), whatever the palm's residual offset."""
    body = self._cubes[i].body
    hand_name = human_lib.HANDS[hand]
    position, quaternion = self._human.relative_pose(physics, body, hand_name)
    hand_body = physics.bind(self._human.segment_bodies[
        _SEGMENT_NAMES.index(f'{hand_name}_hand')])
    shift = (palm - _GRIP) - physics.bind(body).xpos
    position = position + hand_body.xmat.reshape(3, 3).T @ shift
    self._grips.hold(physics, body, hand_name, (position, quaternion))
    self._human_state[i], self._holding_hand[i] = HELD, hand

  def _update_task(self, physics):
    # A grab or release changes the model: the base then calls
    # physics.forward() after the step (as restoring a snapshot does).
    # The four cubes' logic runs on Python floats: on NumPy 3-vectors it
    # costs about 120 us per RL step (docs/benchmarks.md, "Task code per RL
    # step").
    self._move_human_cubes(physics)
    positions = self._cube_positions(physics).tolist()
    self._gripped[:] = self._gripper.grasping(physics, self._cube_bodies)
    free = [not (state == HELD or gripped) for state, gripped in zip(
        self._human_state, self._gripped.tolist())]
    # The stack grows from where the human put cube 1: each slot is one
    # cube size above the cube below, once that one is in its own slot.
    below = True
    for i, position in enumerate(positions):
      if i > 0 and below:
        x, y, z = positions[i - 1]
        self._slots[i] = (x, y, z + self._size)
      below = below and (_distance(position, self._slots[i].tolist())
                         < STACK_TOLERANCE)
      self._in_slot[i] = below
    in_slot = self._in_slot.tolist()
    placed = [in_slot[i] and free[i] for i in range(4)]
    newly = 0
    for i in range(4):
      if placed[i] and not self._stacked[i]:
        self._stacked[i] = True
        self._stacked_at[i] = positions[i]
        newly += 1
    self._toppled = any(
        self._stacked[i] and free[i] and _distance(
            positions[i], self._stacked_at[i].tolist()) > TOPPLE_DISTANCE
        for i in range(4))
    self._complete = all(placed) and not self._toppled
    self._success = self._complete and self.clip_ended
    return {'success': float(self._success),
            'cubes_placed': newly,
            'stack_height': sum(placed),
            'object_gripped': float(self._gripped.any())}

  def _held_bodies(self):
    return tuple(body for body, gripped in zip(self._cube_bodies,
                                               self._gripped) if gripped)

  def _human_events(self, physics):
    # The robot has put its cube down and withdrawn its gripper.
    tcp = self._robot.tcp_frame(physics)[0].tolist()

    def free(i):
      return (self._in_slot[i] and not self._gripped[i] and _distance(
          self._slots[i].tolist(), tcp) > WITHDRAWN_DISTANCE)

    events = []
    if self._in_slot[0] and free(1):
      events.append(clip_lib.Event.second_cube_placed)
    if self._in_slot[:3].all() and free(3):
      events.append(clip_lib.Event.fourth_cube_placed)
    return events

  def _failed(self, physics):
    del physics
    return self._toppled

  def _task_reward(self, physics):
    del physics
    if self._toppled:
      return REWARD_TOPPLED
    if self._success:
      return REWARD_SUCCESS
    if self._in_slot[3]:
      return REWARD_FOURTH_PLACED
    if self._gripped.any():
      return REWARD_GRIPPING
    return REWARD_OTHERWISE

  def _task_reward_range(self):
    return (REWARD_TOPPLED, REWARD_SUCCESS)

  def _task_failure_reward(self):
    return (REWARD_TOPPLED, REWARD_OTHERWISE)

  # -------------------------------------------------------- observables

  def _cube_positions(self, physics):
    """(4, 3) world positions of the cubes (a copy)."""
    return element_ids.synced_data(physics).xpos[self._cube_ids(physics)]

  def _task_observables(self):
    return {
        # The flag the reward used (as the pick-and-place family's): the
        # robot holds no cube at reset (they start on the table).
        'object_gripped': observable.Generic(
            lambda physics: np.array([float(self._gripped.any())])),
        'eef_to_cubes': observable.Generic(
            lambda physics: self._cube_positions(physics)
            - self._robot.tcp_frame(physics)[0]),
        'cube_positions': observable.Generic(self._cube_positions),
        'cube_quaternions': observable.Generic(
            lambda physics: element_ids.synced_data(physics).xquat[
                self._cube_ids(physics)]),
        'stack_slots': observable.Generic(lambda physics: self._slots.copy()),
        'cubes_stacked': observable.Generic(
            lambda physics: self._stacked.astype(np.float64)),
    }
