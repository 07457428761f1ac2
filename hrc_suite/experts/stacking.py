"""Stacking expert: put the robot's cubes 2 and 4 on the person's 1 and 3.

Every step the expert works out from the observed cubes, slots and stacked
flags which cube is next (cube 2 until it is stacked, then cube 4; cube 3
before cube 4 if the person let it go off the stack and it lies on the
table next to it) and where that cube is, and chooses one aim for the TCP:

* Not holding the cube: fetch it. Rise to the hover height first if low
  and far, hover above its grasp point and descend inside a cone (the
  lower the TCP, the closer above the cube it must be), close the gripper
  once the TCP is on the grasp point (and keep closing while the fingers
  travel). Holding a cube that is not next (cube 4 when cube 3 fell): set
  it down on the table first.
* Holding it: lift it straight up to the carrying height (its bottom
  CARRY_CLEARANCE above the top of the cube below), then, once the cube
  below is stacked and the person's hands are away from the stack, carry it
  over its slot and set it down (a cone again, slowly; cube 2 a little
  towards where the person will put cube 3, SHIFT_FRACTION); otherwise
  park it PARK_BACK towards the robot from the stack. Open the gripper
  once the cube sits in its slot.
* Next to the stack with an empty gripper (just let go): wait until the
  fingers are open, then back off horizontally towards the robot before
  going anywhere else (the open fingers straddle the cube along the
  gripper's closing axis, so they never drag a stacked cube; rising would
  bring the wrist closer to the head of a person leaning over the stack).
* Both cubes stacked: withdraw to a rest point (more than the task's
  WITHDRAWN_DISTANCE from the top slot, so the person goes on) and wait.

Carrying happens low (the wrist of an arm stretched over the stack would
come close to the head of a person leaning over it, and the speed and
separation shield would stop it there) and near the person slowly (the
shield lets a slow robot come closer). The expert keeps no memory (the
gripper's closing hysteresis is read from the observed aperture): it can
take over from any state (snapshots, an agent's states).

Joint space: the same aims, through `steering.Steering` (one gripper-down
IK step at the task's yaw at a time).

An arm that the noisy expert's drift folded into itself while parking a
cube (the Schunk, whose raised base stands 0.35 m from the stack) has
every action replaced by collision prevention; after replan.REPLAN_AFTER
such steps the expert takes a detour that unfolds it (experts/replan.py,
`base.Expert`).
"""

from typing import Mapping

from dm_control import composer
import numpy as np

from hrc_suite import experts
from hrc_suite import layout
from hrc_suite.experts import base
from hrc_suite.experts import steering
from hrc_suite.human import keypoints
from hrc_suite.safety import geometry
from hrc_suite.tasks.runtime import actions
from hrc_suite.tasks import stacking

# TCP above a cube's centre when the fingers grasp it (the pads, 2 cm long
# above the TCP, hold the cube's upper part; collision prevention keeps
# the TCP at least 2.8 cm above the table, 3 mm above a cube's centre).
GRIP_HEIGHT = 0.01           # m
# Fetch: TCP height above the grasp point while travelling, and the cone
# of the descent (height allowed per metre of horizontal error).
HOVER = 0.10                 # m
CONE_SLOPE = 3.0
# Close the gripper when the TCP is this near the grasp point (the 8.5 cm
# opening leaves 1.75 cm either side of a 5 cm cube) ...
GRASP_XY = 0.008             # m
GRASP_Z = 0.008              # m
# ... and keep closing while the fingers travel (aperture between these,
# normalised: a 5 cm cube stops them at 0.59) and the TCP stays near.
CLOSING_APERTURE = (0.4, 0.95)
CLOSING_REACH = 0.02         # m
# Carrying: the cube's bottom this far above the top of the cube below.
CARRY_CLEARANCE = 0.03       # m
# Lift straight up first while the cube is more than LIFT_SLACK below the
# carrying height and farther than LIFT_REACH from its slot sideways.
LIFT_SLACK = 0.02            # m
LIFT_REACH = 0.05            # m
# Let go when the cube is this near its slot (it drops at most that far;
# the task's tolerance is stacking.STACK_TOLERANCE, 2.5 cm).
RELEASE_XY = 0.008           # m
RELEASE_Z = 0.01             # m
# Cube 2 goes on cube 1 shifted towards the stack's planned place (the
# person's target for cube 3: `stack_slots` of a cube not yet in place
# holds it) by SHIFT_FRACTION of the distance, at most SHIFT_MAX (the slot
# tolerance is 2.5 cm). The person's hand puts cube 3 near that target,
# while cube 1 lands 2-4 cm from it; a third of the way balances cube 3 on
# cube 2 against cubes 2 and 3 on cube 1 (both offsets 2/3 of the
# distance). Where cube 3 landed in Panda seeds 0 and 1, this takes its
# offset from cube 2 from 2.3 to 1.5 cm and from 2.1 to 0.5 cm; it does not
# save a cube 3 landing 4 cm from cube 1 (seed 4), which falls off: the
# robot then stacks it itself (DROPPED_RADIUS).
SHIFT_FRACTION = 1.0 / 3.0
SHIFT_MAX = 0.012            # m
# Cube 3 on the table within DROPPED_RADIUS of the stack's axis (its pick
# spots are >= 0.2 m from the stack) was dropped off the stack by the
# person: the robot stacks it then (set down cube 4 first).
DROPPED_RADIUS = 0.15        # m
# Wait with the cube this far from the stack towards the robot base while
# the person places theirs (m, horizontally).
PARK_BACK = 0.25             # m
PARK_BACKS = (PARK_BACK, 0.2, 0.15)   # as REST_BACKS
# The person's hands must be this far from the stack's axis (horizontally)
# before the robot carries a cube over it.
HANDS_CLEAR = 0.3            # m
# After letting go: the gripper is near the stack within NEAR_STACK
# sideways and below RISE_CLEARANCE above the top cube: open the fingers
# to at least OPEN_APERTURE, then back off.
NEAR_STACK = 0.07            # m
RISE_CLEARANCE = 0.05        # m
OPEN_APERTURE = 0.8
# Rest point at the end: this far back from the stack and above its top.
REST_BACK = 0.3              # m
# Where a robot cannot reach (or folds into itself at) a point that far
# back towards its base (the raised Schunk, whose base stands 0.35 m from
# the stack), the nearest of these (m from the stack) it reaches; the last
# keeps the TCP further than stacking.WITHDRAWN_DISTANCE from the stack.
REST_BACKS = (REST_BACK, 0.25, 0.2)
REST_ABOVE = 0.1             # m
# Speed limits, as a fraction of a full Cartesian step (0.1 m per RL step):
# near the stack's slot (precise placing) and near the person. The speed
# and separation shield brakes a robot whose braking distance reaches the
# person's reachable set; a robot it stopped in the middle of a motion
# needs more clearance to start again than a robot that keeps going
# slowly (measured: stuck at 0.30 m after a fast approach, moving freely
# at 0.27 m at 2 cm per step). So the robot slows down with the clearance
# (robot capsules to the person's body capsules), linearly between the
# points NEAR_HUMAN, HUMAN_SPEED.
PLACE_SPEED = 0.25
PLACE_ZONE = 0.05            # m from the aim
NEAR_HUMAN = (0.2, 0.35, 0.65)   # m of clearance ...
HUMAN_SPEED = (0.1, 0.2, 1.0)    # ... and the speed limits there
OPEN, CLOSED = -1.0, 1.0
_HANDS = np.array(keypoints.index(['left_hand', 'right_hand']))


@experts.register('stacking', 'default')
class StackingExpert(base.Expert):
  """Fetches, carries, places cubes 2 and 4 in turn (stacking/default).

  Privileged: none. Besides the observables it uses the task's models
  (not state): the shield's robot capsules at the observed joint positions
  and the person's body capsules at the observed keypoints, for the
  clearance that sets its speed near the person.

  Args:
    env: the environment (hrc_suite.suite.load) whose task it solves.
  """

  OBSERVED = ('eef_position', 'joint_positions', 'gripper_aperture',
              'object_gripped', 'cube_positions', 'stack_slots',
              'cubes_stacked', 'human_keypoints')
  TASKS = (('stacking', 'default'),)

  def __init__(self, env: composer.Environment):
    super().__init__(env)
    self._steer = steering.Steering(self._task)
    self._size = float(self._task.cubes[0].size)
    self._base = np.asarray(self._task.kinematics.base_pose)[:3, 3].copy()
    self._table = layout.TABLE_TOP_Z
    # Above the top of cube 1 on the table (not reaching for a cube there).
    self._above_base = self._table + 1.5 * self._size
    # The TCP's x axis, across the fingers' closing axis (y).
    yaw = float(self._task.CARTESIAN_YAW)
    self._along_fingers = np.array([np.cos(yaw), np.sin(yaw)])
    shield = self._task.shield
    self._robot_capsules = shield.robot.capsules
    self._body_capsules = shield.human.body_capsules
    self.phase = None   # What the last action did (for inspection).

  # ----------------------------------------------------------- state

  def _state(self, obs):
    """The observed state the decisions are made from."""
    tcp = obs['eef_position']
    cubes = obs['cube_positions']
    slots = obs['stack_slots']
    in_slot = (np.linalg.norm(cubes - slots, axis=1)
               < stacking.STACK_TOLERANCE)
    in_slot = np.logical_and.accumulate(in_slot)   # Stacked from cube 1.
    stacked = (obs['cubes_stacked'] > 0.5) & in_slot
    gripped = bool(obs['object_gripped'][0] > 0.5)
    # The gripped cube is the one between the fingers.
    between = np.linalg.norm(cubes - (tcp - [0.0, 0.0, GRIP_HEIGHT]), axis=1)
    held = int(np.argmin(between)) if gripped else None
    if held is not None and between[held] > self._size:
      held = None
    return tcp, cubes, slots, stacked, held

  # ---------------------------------------------------------- actions

  def action(self, observation: Mapping[str, np.ndarray]) -> np.ndarray:
    """The action now.

    Args:
      observation: the OBSERVED observables now (`base.Expert.observe`).

    Returns:
      The action of the phase the observed cubes are in: fetch, carry or
      place the next robot cube, or back away.
    """
    obs = observation
    tcp, cubes, slots, stacked, held = self._state(obs)
    aperture = float(obs['gripper_aperture'][0])
    axis = slots[0, :2]
    top = self._stack_top(cubes, stacked)
    # The robot's cubes, and cube 3 if the person dropped it next to the
    # stack (or the robot holds it), in stacking order.
    third = stacking.HUMAN_CUBES[1]
    ours = held == third or self._dropped(cubes, stacked, axis)
    todo = [i for i in (1, 2, 3) if not (stacked[i] and held != i)
            and (i != third or ours)]
    speed = 1.0
    if held is None and (np.linalg.norm(tcp[:2] - axis) < NEAR_STACK
                         and top + RISE_CLEARANCE > tcp[2] > self._above_base):
      # Just let go on the stack: open fully, then back off towards the
      # robot along the TCP's x axis (the open fingers straddle the cube
      # along y, the closing axis, so this clears it; rising would bring
      # the wrist closer to the head of a person leaning over the stack).
      if aperture < OPEN_APERTURE:
        self.phase, aim = 'open', tcp.copy()
      else:
        self.phase = 'withdraw'
        away = self._along_fingers
        if np.dot(away, self._base[:2] - axis) < 0.0:
          away = -away
        aim = tcp + np.append(2 * NEAR_STACK * away, 0.01)
        if not self._can_reach(aim, obs['joint_positions']):
          # The raised Schunk folds into itself towards its base: rise.
          aim = tcp + [0.0, 0.0, 2 * NEAR_STACK]
      gripper, speed = OPEN, PLACE_SPEED
    elif not todo:
      self.phase, gripper = 'rest', OPEN
      aim = self._back_from_stack(axis, REST_BACKS, slots[3, 2] + REST_ABOVE,
                                  obs['joint_positions'])
    elif held is None:
      aim, gripper = self._fetch(tcp, cubes[todo[0]], aperture,
                                 obs['joint_positions'])
    elif held != todo[0]:
      # Holding a cube that is not next (cube 4 while cube 3 lies on the
      # table): set it down on the table where it is and let go.
      self.phase, gripper = 'set down', CLOSED
      on_table = self._table + self._size / 2
      aim = np.append(tcp[:2], on_table + (tcp[2] - cubes[held, 2]))
      if cubes[held, 2] < on_table + RELEASE_Z:
        aim, gripper = tcp.copy(), OPEN
    else:
      aim, gripper, speed = self._carry(obs, tcp, cubes, slots, stacked,
                                        held)
    speed = min(speed, self._human_speed(obs))
    delta = aim - tcp
    norm = np.linalg.norm(delta)
    limit = speed * actions.CARTESIAN_STEP
    if norm > limit:
      aim = tcp + delta * (limit / norm)
    return self._steer.action(aim, tcp, obs['joint_positions'], gripper)

  def _dropped(self, cubes, stacked, axis):
    """Cube 3 lies on the table next to the stack of cubes 1 and 2 (the
    person let it go off the stack)."""
    i = stacking.HUMAN_CUBES[1]
    cube = cubes[i]
    return bool(stacked[i - 1] and not stacked[i]
                and cube[2] < self._table + self._size / 2 + RELEASE_Z
                and np.linalg.norm(cube[:2] - axis) < DROPPED_RADIUS)

  def _stack_top(self, cubes, stacked):
    """Height of the top of the stacked cubes (the table without any)."""
    if not stacked[0]:
      return cubes[0, 2] + self._size / 2
    count = int(np.argmin(np.append(stacked, False)))
    return float(cubes[count - 1, 2] + self._size / 2)

  def _back_from_stack(self, axis, distances, height, q, offset=None):
    """TCP aim: a point the first of `distances` from the stack's axis
    towards the robot base, at `height`, plus `offset` (the TCP from a held
    cube), that the robot reaches from q (`_can_reach`); else above the
    TCP at HOVER over that height where it reaches that; else the last
    point."""
    direction = self._base[:2] - axis
    direction /= max(np.linalg.norm(direction), 1e-9)
    offset = np.zeros(3) if offset is None else offset
    for distance in distances:
      aim = np.append(axis + distance * direction, height) + offset
      if self._can_reach(aim, q):
        return aim
    up = self._task.kinematics.tcp_pose(q)[:3, 3]
    up[2] = height + offset[2] + HOVER
    return up if self._can_reach(up, q) else aim

  def _fetch(self, tcp, cube, aperture, q):
    """Aim and gripper command to grasp `cube` (centre) from above; q: the
    joint positions."""
    grasp = cube + [0.0, 0.0, GRIP_HEIGHT]
    error = np.linalg.norm(tcp[:2] - grasp[:2])
    height = tcp[2] - grasp[2]
    closing = (CLOSING_APERTURE[0] < aperture < CLOSING_APERTURE[1]
               and np.linalg.norm(tcp - grasp) < CLOSING_REACH)
    if (error < GRASP_XY and abs(height) < GRASP_Z) or closing:
      self.phase = 'grasp'
      return grasp, CLOSED
    self.phase = 'fetch'
    aim = grasp + [0.0, 0.0, min(HOVER, CONE_SLOPE * error)]
    rise = np.append(tcp[:2], grasp[2] + HOVER + LIFT_SLACK)
    if (error > LIFT_REACH and height < HOVER - LIFT_SLACK
        and self._can_reach(rise, q)):
      # Rise first (a little above the hover height: the arm's path may
      # sag on the way across), where the arm can: the Schunk, withdrawn
      # from the stack towards its raised base, folds into itself rising
      # there (stacking, seed 1 on the recordings) and goes across instead.
      aim = rise
      self.phase = 'rise'
    if aperture < CLOSING_APERTURE[1] and height < HOVER / 2:
      aim = tcp.copy()   # A failed grasp: open before moving on.
    return aim, OPEN

  def _can_reach(self, aim, q):
    """The robot reaches `aim` from q and collision prevention lets its
    first step through (`Steering.reaches`)."""
    return self._steer.reaches(aim, q, self._task.collision_checker,
                               first_step=True)

  def _carry(self, obs, tcp, cubes, slots, stacked, held):
    """Aim, gripper command and speed with cube `held` in the gripper."""
    cube, slot = cubes[held], self._target(slots, held)
    offset = tcp - cube   # Where the TCP holds the cube.
    carry_z = slot[2] + CARRY_CLEARANCE
    error = np.linalg.norm(cube[:2] - slot[:2])
    below_ready = bool(stacked[held - 1])
    hands = obs['human_keypoints'][_HANDS]
    clear = np.min(np.linalg.norm(hands[:, :2] - slot[:2], axis=1))
    if error < RELEASE_XY and abs(cube[2] - slot[2]) < RELEASE_Z:
      self.phase = 'release'
      return tcp.copy(), OPEN, PLACE_SPEED
    if cube[2] < carry_z - LIFT_SLACK and error > LIFT_REACH:
      self.phase = 'lift'
      return np.append(tcp[:2], carry_z + offset[2]), CLOSED, 1.0
    if not below_ready or (clear < HANDS_CLEAR and error > LIFT_REACH):
      self.phase = 'park'
      park = self._back_from_stack(slot[:2], PARK_BACKS, carry_z,
                                   obs['joint_positions'], offset)
      return park, CLOSED, 1.0
    self.phase = 'place'
    goal = slot + [0.0, 0.0, min(CARRY_CLEARANCE, CONE_SLOPE * error)]
    speed = PLACE_SPEED if np.linalg.norm(goal - cube) < PLACE_ZONE else 1.0
    return goal + offset, CLOSED, speed

  def clearance(self, obs: Mapping[str, np.ndarray]) -> float:
    """Distance between the robot's and the person's capsules.

    Args:
      obs: the OBSERVED observables now (joint positions, keypoints).

    Returns:
      The smallest capsule distance, m.
    """
    r1, r2, rr = self._robot_capsules(obs['joint_positions'])
    h1, h2, hr = self._body_capsules(obs['human_keypoints'])
    return float(geometry.capsule_distance(
        r1[:, None], r2[:, None], rr[:, None], h1[None], h2[None],
        hr[None]).min())

  @staticmethod
  def _target(slots, i):
    """Where cube i goes: its slot; cube 2's shifted towards the place the
    person will put cube 3 (see SHIFT_FRACTION)."""
    if i != stacking.ROBOT_CUBES[0]:
      return slots[i]
    shift = SHIFT_FRACTION * (slots[3, :2] - slots[i, :2])
    norm = np.linalg.norm(shift)
    if norm > SHIFT_MAX:
      shift *= SHIFT_MAX / norm
    return slots[i] + np.append(shift, 0.0)

  def _human_speed(self, obs):
    """Speed limit from the clearance to the person."""
    return float(np.interp(self.clearance(obs), NEAR_HUMAN, HUMAN_SPEED))
