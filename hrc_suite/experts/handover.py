"""Experts of the two hammer handovers (docs/tasks.md).

Robot to human (`RobotToHumanExpert`): keep the gripper closed and bring the
end of the handle (where a person holds a hammer) to the palm of the
person's holding hand; when the person holds the hammer, open and, once the
fingers are clear, go back home. Cartesian: the TCP moves by the palm-to-
handle-end difference (gripper down); joint space: the same aim through one
gripper-down IK step (or a shorter one). A palm beyond the gripper-down
reach: the aim moves back along the handle to the nearest point IK
reaches, so the handle still points along the palm's line and reaches as
far towards it as the arm can, and the arm waits there (the person's hand
sways while they wait and comes to the handle). The palm aimed at is the
one nearest the robot seen so far (the person's reach loop returns there;
chasing the current palm at the PFL shield's v_safe, the handle misses
it for 1000 RL steps), the current one for a while after the
TCP stood still for STALL_STEPS.

Human to robot (`HumanToRobotExpert`): wait near where the person will
present the hammer, and once it is presented (held, on its side, above the
table, still; held low, still for a second) come down on the handle inside
a cone (the reference's pick-and-place approach), slide the open pads
along it to the grip point and close once the handle lies across the pads
(MIN_GRASP_ANGLE; a hand that sways in and out of the gripper-down reach
is approached, the arm waiting at the edge of its reach; one held beyond
it by more than SWAY_MARGIN is waited for at the ready point, one held
above the Cartesian box all along its sway at home); once the person
lets go, carry it
over the table target, lower it to RELEASE_HEIGHT and open: it drops the
last centimetres. Then go home. A hammer lying on the table (before the
person's pick, placed, or dropped) is left alone.

Both derive their phase from the observed state every step (which hand
holds the hammer, gripper aperture, where the hammer is). The human-to-robot
expert also remembers the previous grip point (the hammer's speed), for
how long it has been held still, the last presented one (where to wait
while the person sways back), whether the sway of the presentation held
still now has brought it within the Cartesian box's reach, and its last
gripper command; all are forgotten at reset, so it can take over from
any state.
"""

from typing import Mapping

from dm_control import composer
import numpy as np

from hrc_suite import experts
from hrc_suite import layout
from hrc_suite import rotations
from hrc_suite.entities import props
from hrc_suite.experts import base
from hrc_suite.experts import steering
from hrc_suite.tasks.runtime import actions
from hrc_suite.tasks import handover

# Distance along the handle (body -x) from the robot's grip point to where
# a person holds it (props.Hammer: grip_site at the centre of mass,
# human_grip_site HAMMER_HUMAN_GRIP from the head's axis).
_COM_X = (-props.HAMMER_HANDLE_LENGTH / 2 * props.HAMMER_HANDLE_MASS
          / (props.HAMMER_HANDLE_MASS + props.HAMMER_HEAD_MASS))
GRIP_TO_HANDLE_END = props.HAMMER_HUMAN_GRIP + _COM_X      # m, ~0.226
# The handle is "in the hand": grip point this close to the TCP with the
# pads this close together (gripper_aperture is normalised by the 0.085 m
# stroke; the handle, 2 x 0.011 m deep, holds them at ~0.25).
IN_HAND_DISTANCE = 0.03                  # m
IN_HAND_APERTURE = 0.4                   # normalised
# Approach (reference pick and place: hover above, descend in a cone):
# the TCP may be at most CONE_SLOPE x (horizontal error) above the grip
# point, and at most HOVER_HEIGHT.
HOVER_HEIGHT = 0.08                      # m
CONE_SLOPE = 3.0
# A hammer presented high (shoulder height, recordings' advanced people)
# can lie where gripper-down IK reaches the grip point but not HOVER_HEIGHT
# above it: the approach then hovers as high as IK reaches, found to
# REACH_TOLERANCE, but not lower than this (m): the fingertips, 0.01 m
# below the TCP, stay clear of the 0.022 m deep handle.
MIN_HOVER_HEIGHT = 0.025                 # m
# A presentation counts as within reach when the grip point moved this
# far towards the base is: people waiting with the hammer held high sway
# it 0.05 m along the handle (recording advanced_0 of
# HumanRobotHandover: the grip point 0.62-0.67 m from the Panda's base,
# gripper-down IK reaching it at 0.64 m); the arm approaches and closes
# when the sway brings the grip point between its pads.
SWAY_MARGIN = 0.05                       # m
# The TCP's highest target is the top of the Cartesian box: the pads close
# on a grip point at most GRASP_Z above it. A presentation whose sway
# keeps the grip point higher (recording advanced_1 of HumanRobotHandover:
# 1.40-1.42 m, the Schunk's box ending at 1.33 m) is waited for at home:
# at the ready point, under the hammer, and pushing its pads against the
# hammer's head, the arm was hit by the hammer at every sway (shield
# resyncs). One whose sway brings it within the box (advanced_0: 1.31-1.35
# m on the Schunk) is approached while the person holds it still: the
# pads close when the sway brings the handle between them.
# Close when the grip point is between the pads: TCP offset from it along
# the handle (towards its end; the head is 0.034 m the other way, the pads
# 0.01 m wide), across it (the pads open 0.085 m around the 0.022 m deep
# handle) and vertically within these; keep closing while within
# KEEP_CLOSING of it. The approach aims at the grip point itself, so the
# tolerances matter where the gripper-down reach ends short of it. Along
# the handle the grip point is the centre of mass: 3 cm off it, the head's
# weight turned the hammer in the pads until the head wedged them open and
# it fell (Panda, noisy, seed 6).
GRASP_ALONG = (-0.008, 0.012)            # m
# The cone's apex is the stretch of handle between the head and the hand
# holding it (COM 0.18 m from the person's grip, hand radius 0.045 m): the
# open pads may come down over it anywhere there and then slide along it
# to the grip point. A person's hand that drifts along the handle's line
# (a recording's wait replays the reach, 1-13 mm per RL step) outruns a
# robot slowed near them, which then hung in the cone above the hammer.
DESCEND_ALONG = (-0.02, 0.08)            # m
GRASP_ACROSS = 0.015                     # m
# The pads close only on a handle lying across them: at least this angle
# (rad) between the handle and the pads' closing axis (TCP y). The open pads
# stand 0.085 m apart; a handle closer to the closing axis spans them
# diagonally and jams them open on its edges: the hammer is carried with
# the pads at full aperture and stays between them when they open over the
# target (HumanRobotHandover_4 on the Schunk: the wrist, turned on its way
# at the edge of the reach, closed 34 deg from the closing axis).
MIN_GRASP_ANGLE = np.radians(60.0)
GRASP_Z = 0.008                          # m
KEEP_CLOSING = 0.035                     # m
# Presented: held by the person, on its side (body y this close to up),
# grip point this high above the table top and moving this little per RL
# step (the person waits, the idle motion sways the hand slowly).
PRESENTED_UPRIGHT = 0.8                  # cosine of body y to world z
PRESENTED_HEIGHT = 0.12                  # m above the table top
PRESENTED_SPEED = 0.02                   # m per RL step
# Presented low (recordings: palms 0.05 m above the table; the task lets
# the fingertips down to handover.TABLE_CLEARANCE): at least this high and
# held still this many RL steps (a person who has just picked the hammer
# up holds it 0.3-0.6 s before lifting it: task_motions).
LOW_PRESENTED_HEIGHT = 0.03              # m above the table top
PRESENTED_DWELL = 10                     # RL steps
# Carry: the grip point this high above the table target while moving to
# it, then lowered to RELEASE_HEIGHT above it and let go (the hammer drops
# the rest).
CARRY_HEIGHT = 0.15                      # m
# At most this far per RL step while carrying (0.5 m/s): full 0.1 m steps
# pried a grasp near the end of the Schunk's reach open (joint seed 6).
CARRY_STEP = 0.05                        # m
RELEASE_HEIGHT = 0.08                    # m
RELEASE_BELOW = 0.1                      # m: open once the grip is lower
OVER_TARGET = 0.02                       # m, horizontal: lower the hammer
# Robot to human: the handle's end is not taken lower than this above the
# table top (a palm swaying low would pull the hammer into the table).
MIN_HANDLE_END_HEIGHT = 0.05             # m
# Robot to human: the handle waits at the nearest palm seen; a TCP that
# moved less than STALL_MOTION in each of STALL_STEPS RL steps chases the
# current palm for CHASE_STEPS RL steps (RobotToHumanExpert._palm_aim).
STALL_MOTION = 0.001                     # m
STALL_STEPS = 20
CHASE_STEPS = 50
# Fingers clear of the handle before moving away: aperture at least; then
# up and back until the grip point is this far from the TCP (a joint path
# home from a stretched arm swept the open fingers along the handle).
RELEASED_APERTURE = 0.6                  # normalised
CLEAR_DISTANCE = 0.06                    # m
# Closing has begun: aperture below this (normalised).
CLOSING_APERTURE = 0.9
# Human to robot, waiting for the presentation: ready point this high above
# the last presented grip point (or, before one was seen, READY_HEIGHT above
# the table top, at most READY_AHEAD in front of the home TCP towards the
# hammer and READY_SIDE to its side).
READY_ABOVE = 0.1                        # m
READY_HEIGHT = 0.42                      # m
READY_AHEAD = 0.12                       # m
READY_SIDE = 0.25                        # m
# At the edge of the gripper-down reach: steps tried (from the TCP towards
# the aim, at most CARTESIAN_STEP) until gripper-down IK solves one: the
# step, half, a quarter and, when sliding, straight up or down and half of
# it plus a retraction of RETRACT towards the base (a stretched arm slides
# along its reach limit towards a hammer presented beyond it). Where none
# solves, the arm holds still. The robot-to-human presentation does not
# slide: following a palm swaying beyond the reach took the Panda into the
# person's path (shoved, hammer dropped, critical contacts; seeds 0, 5);
# holding at the limit, the swaying palm comes to the handle.
STEP_FRACTIONS = (1.0, 0.5, 0.25)
RETRACT = 0.03                           # m
# Robot to human, a palm beyond the reach: aim at the nearest reachable
# point at most PULL_BACK back along the handle from the aim (the handle
# stays on the palm's line and reaches along it), found to REACH_TOLERANCE.
PULL_BACK = 0.3                          # m
REACH_TOLERANCE = 0.005                  # m


class _HammerExpert(base.Expert):
  """Steering, home pose and the hammer's geometry shared by both."""

  OBSERVED = ('eef_position', 'joint_positions', 'gripper_aperture',
              'object_position', 'object_quaternion', 'object_gripped',
              'object_held_by_human', 'target_position')

  def __init__(self, env: composer.Environment):
    """The expert of `env`'s task.

    Args:
      env: the environment (hrc_suite.suite.load) whose task it solves.
    """
    super().__init__(env)
    self._last_close = None    # the last gripper command closed (memory)
    self._steer = steering.Steering(self._task)
    self._kinematics = self._task.kinematics
    self._q_home = np.asarray(self._kinematics.description.q_home, float)
    self._home = self._kinematics.tcp_pose(self._q_home)[:3, 3].copy()
    # The Cartesian action space's box of TCP targets.
    self._box = actions.workspace_box(self._kinematics)

  def _in_hand(self, obs):
    """The robot holds the hammer (grip point at the TCP, pads closed)."""
    near = np.linalg.norm(obs['object_position'] - obs['eef_position'])
    return bool(obs['object_gripped'][0] > 0.5 or (
        near < IN_HAND_DISTANCE
        and obs['gripper_aperture'][0] < IN_HAND_APERTURE))

  def _go_home(self, obs, gripper):
    """Up to the home height first, then home (the TCP never dives)."""
    tcp = obs['eef_position']
    if self._steer.space == 'joint' and tcp[2] >= self._home[2] - 0.03:
      return self._steer.joint_goal_action(self._q_home,
                                           obs['joint_positions'], tcp,
                                           gripper)
    aim = self._home.copy()
    if tcp[2] < self._home[2] - 0.03:
      aim[:2] = tcp[:2]
    return self._steer.action(aim, tcp, obs['joint_positions'], gripper)

  def _hold_still(self, obs, gripper):
    tcp = obs['eef_position']
    if self._steer.space == 'joint':
      return self._steer.joint_goal_action(
          obs['joint_positions'], obs['joint_positions'], tcp, gripper)
    return self._steer.action(tcp, tcp, obs['joint_positions'], gripper)

  def _step(self, obs, shift, gripper, slide=True):
    """Moves the TCP by `shift` (cut to one CARTESIAN_STEP) or the longest
    of a few steps gripper-down IK reaches at the current gripper yaw
    branch (slide: also straight up or down, and half the step plus a
    retraction towards the base); holds still if none."""
    tcp, q = obs['eef_position'], obs['joint_positions']
    norm = np.linalg.norm(shift)
    if norm > actions.CARTESIAN_STEP:
      shift = shift * (actions.CARTESIAN_STEP / norm)
    inward = self._kinematics.base_pose[:3, 3] - tcp
    inward[2] = 0.0
    inward *= RETRACT / max(np.linalg.norm(inward), 1e-9)
    vertical = shift * (0.0, 0.0, 1.0)
    steps = [f * shift for f in STEP_FRACTIONS]
    if slide:
      steps += [vertical, 0.5 * shift + inward]
    rotation = self._kinematics.tcp_pose(q)[:3, :3]
    yaw_now = rotations.mat_yaw(rotation)
    for step in steps:
      target = np.clip(tcp + step, self._box[0], self._box[1])
      result = self._steer.ik.solve(target, q, self._steer.yaw)
      # Not through the other gripper yaw (the IK's yaw + pi fallback):
      # that half turn of the wrist swings the hammer about.
      turn = rotations.wrap_angle(result.yaw - yaw_now)
      if result.success and abs(turn) < np.pi / 2:
        if self._steer.space == 'cartesian':
          return self._steer.action(target, tcp, q, gripper)
        return self._steer.joint_goal_action(result.q, q, tcp, gripper)
    return self._hold_still(obs, gripper)

  def _reachable(self, target, q):
    """Gripper-down IK reaches `target` from q at the current yaw."""
    result = self._steer.ik.solve(target, q, self._steer.yaw)
    rotation = self._kinematics.tcp_pose(q)[:3, :3]
    yaw_now = rotations.mat_yaw(rotation)
    turn = rotations.wrap_angle(result.yaw - yaw_now)
    return bool(result.success and abs(turn) < np.pi / 2)

  def _hover_height(self, grip, q):
    """HOVER_HEIGHT, or the highest point above `grip` gripper-down IK
    reaches (to REACH_TOLERANCE), at least MIN_HOVER_HEIGHT."""
    up = np.array([0.0, 0.0, 1.0])
    if self._reachable(np.clip(grip + HOVER_HEIGHT * up, self._box[0],
                               self._box[1]), q):
      return HOVER_HEIGHT
    low, high = MIN_HOVER_HEIGHT, HOVER_HEIGHT   # reachable?, not
    while high - low > REACH_TOLERANCE:
      middle = 0.5 * (low + high)
      if self._reachable(np.clip(grip + middle * up, self._box[0],
                                 self._box[1]), q):
        low = middle
      else:
        high = middle
    return low

  def _grasp(self, obs):
    """Cone approach to the grip point and close when it is between the
    pads (within the handle-frame tolerances)."""
    tcp, grip = obs['eef_position'], obs['object_position']
    offset = tcp - grip
    # Handle frame: along the handle towards its end (away from the head),
    # across it (horizontal), up.
    along_axis = -rotations.quat_to_mat(obs['object_quaternion'])[:, 0]
    along_axis[2] = 0.0
    along_axis /= max(np.linalg.norm(along_axis), 1e-9)
    across_axis = np.array([-along_axis[1], along_axis[0], 0.0])
    along, across = offset @ along_axis, offset @ across_axis
    def excess(bounds):
      return np.hypot(max(along - bounds[1], bounds[0] - along, 0.0),
                      max(abs(across) - GRASP_ACROSS, 0.0))
    height = min(self._hover_height(grip, obs['joint_positions']),
                 CONE_SLOPE * excess(DESCEND_ALONG))
    closing_axis = self._kinematics.tcp_pose(obs['joint_positions'])[:3, 1]
    handle_axis = rotations.quat_to_mat(obs['object_quaternion'])[:, 0]
    across_pads = abs(closing_axis @ handle_axis) < np.cos(MIN_GRASP_ANGLE)
    close = (excess(GRASP_ALONG) == 0.0 and abs(offset[2]) < GRASP_Z
             and across_pads)
    # Closing: the aperture dropped after a close command (the last one,
    # where known: open pads pushed in by the person's hand are not).
    closing = (obs['gripper_aperture'][0] < CLOSING_APERTURE
               and self._last_close is not False)
    if closing and np.linalg.norm(offset) < KEEP_CLOSING:
      close = True
    return self._step(obs, grip + (0.0, 0.0, height) - tcp,
                      1.0 if close else -1.0)


@experts.register('handover', 'robot_to_human')
class RobotToHumanExpert(_HammerExpert):
  """Presents the handle's end at the person's palm, lets go when held.

  Observed: target_position is the palm of the clip's holding hand.
  """

  TASKS = (('handover', 'robot_to_human'),)

  def __init__(self, env: composer.Environment):
    """The expert of `env`'s task.

    Args:
      env: the environment (hrc_suite.suite.load) whose task it solves.
    """
    super().__init__(env)
    self.reset()

  def reset(self) -> None:
    """Forgets the palm aimed at and the stall count."""
    self._nearest_palm = None
    self._last_tcp = None
    self._stalled = 0        # RL steps the TCP has not moved
    self._chase = 0          # RL steps left chasing the current palm

  def _palm_aim(self, palm, tcp):
    """The palm position nearest the robot's base (horizontally) seen
    this episode: the person's reach loop brings the hand back there, so
    the handle waits where the hand comes closest instead of chasing it
    (the PFL shield slows the arm to v_safe near the person). A TCP still
    for STALL_STEPS (waiting in vain, or stalled: the Schunk's Cartesian
    IK failed at every step towards a fixed aim at the edge of its reach,
    seeds 15, 21, 32, 34) chases the current palm for CHASE_STEPS, as
    before the memory."""
    base = self._kinematics.base_pose[:3, 3]
    if self._nearest_palm is None or (
        np.linalg.norm((palm - base)[:2])
        < np.linalg.norm((self._nearest_palm - base)[:2])):
      self._nearest_palm = palm.copy()
    moved = (self._last_tcp is None
             or np.linalg.norm(tcp - self._last_tcp) > STALL_MOTION)
    self._last_tcp = tcp.copy()
    self._stalled = 0 if moved else self._stalled + 1
    if self._stalled >= STALL_STEPS:
      self._chase, self._stalled = CHASE_STEPS, 0
    if self._chase > 0:
      self._chase -= 1
      return palm.copy()
    return self._nearest_palm.copy()

  def action(self, obs: Mapping[str, np.ndarray]) -> np.ndarray:
    """The action now.

    Args:
      obs: the OBSERVED observables now (`base.Expert.observe`).

    Returns:
      The action: the handle's end towards the person's palm, gripper
      closed; once the person holds the hammer: open, clear the handle
      and go home.
    """
    tcp = obs['eef_position']
    held = obs['object_held_by_human'][0] > 0.5
    if held:
      if obs['gripper_aperture'][0] < RELEASED_APERTURE:
        return self._hold_still(obs, -1.0)
      if np.linalg.norm(obs['object_position'] - tcp) < CLEAR_DISTANCE:
        # Lift the open fingers off the handle (up and back) before
        # heading home.
        back = self._kinematics.base_pose[:3, 3] - tcp
        back[2] = 0.0
        back *= CLEAR_DISTANCE / max(np.linalg.norm(back), 1e-9)
        return self._step(obs, back + (0.0, 0.0, CLEAR_DISTANCE), -1.0)
      return self._go_home(obs, -1.0)
    if not self._in_hand(obs):
      # Dropped: the tool may not reach into the table to pick it up.
      return self._go_home(obs, -1.0)
    rotation = rotations.quat_to_mat(obs['object_quaternion'])
    end = obs['object_position'] - GRIP_TO_HANDLE_END * rotation[:, 0]
    palm = self._palm_aim(obs['target_position'], tcp)
    palm[2] = max(palm[2], layout.TABLE_TOP_Z + MIN_HANDLE_END_HEIGHT)
    # Beyond the reach: the reachable aim nearest along the handle; at
    # the reach's edge already (no nearer point), hold still.
    target = tcp + palm - end
    aim = self._within_reach(target, -rotation[:, 0],
                             obs['joint_positions'])
    if aim is None or (np.linalg.norm(aim - target) > np.linalg.norm(
        tcp - target) - REACH_TOLERANCE):
      return self._hold_still(obs, 1.0)
    if self._steer.space == 'cartesian':
      return self._steer.action(aim, tcp, obs['joint_positions'], 1.0)
    return self._step(obs, aim - tcp, 1.0, slide=False)

  def _within_reach(self, aim, towards_end, q):
    """`aim` if reachable, else the nearest reachable point on the line
    back from it along the handle (the handle then still reaches along
    the palm's line; a palm beyond the reach sways or waits there), at
    most PULL_BACK back (to REACH_TOLERANCE); None if none is."""
    aim = np.clip(aim, self._box[0], self._box[1])
    if self._reachable(aim, q):
      return aim
    back = -np.asarray(towards_end, float) * (1.0, 1.0, 0.0)
    back /= max(np.linalg.norm(back), 1e-9)
    near, far = PULL_BACK, 0.0     # reachable, not reachable
    if not self._reachable(aim + near * back, q):
      return None
    while near - far > REACH_TOLERANCE:
      middle = 0.5 * (near + far)
      if self._reachable(aim + middle * back, q):
        near = middle
      else:
        far = middle
    return aim + near * back

@experts.register('handover', 'human_to_robot')
class HumanToRobotExpert(_HammerExpert):
  """Takes the presented hammer and places it on the table target.

  Memory: the previous grip point (the hammer's speed) and for how many
  steps it has been held still, the last grip point seen presented (where
  to wait when the person sways it back), whether the sway of the
  presentation held still now has brought the grip point within the
  Cartesian box's reach and whether the last gripper command closed
  (`_grasp`).
  """

  TASKS = (('handover', 'human_to_robot'),)

  def __init__(self, env: composer.Environment):
    """The expert of `env`'s task.

    Args:
      env: the environment (hrc_suite.suite.load) whose task it solves.
    """
    super().__init__(env)
    self.reset()

  def reset(self) -> None:
    """Forgets the grip points seen, the still count and the last gripper
    command."""
    self._previous_grip = None
    self._last_presented = None
    self._last_close = None
    self._still_steps = 0
    self._sway_within_box = False

  def action(self, obs: Mapping[str, np.ndarray]) -> np.ndarray:
    """The action now; notes whether its gripper command closes.

    Args:
      obs: the OBSERVED observables now (`base.Expert.observe`).

    Returns:
      The action: take the presented hammer, carry it to the table target
      and let go there.
    """
    action = self._action(obs)
    self._last_close = bool(action[-1] > 0.0)
    return action

  def _placed(self, obs):
    offset = obs['object_position'] - obs['target_position']
    return bool(np.linalg.norm(offset) <= handover.SUCCESS_DISTANCE)

  def _presented(self, obs):
    """Held by the person on its side, high above the table; or low above
    it, held there PRESENTED_DWELL steps, by a person who has not presented
    it high (one who has is lowering it while swaying back)."""
    rotation = rotations.quat_to_mat(obs['object_quaternion'])
    height = obs['object_position'][2] - layout.TABLE_TOP_Z
    presented_low = self._last_presented is None or (
        self._last_presented[2] - layout.TABLE_TOP_Z <= PRESENTED_HEIGHT)
    return bool(obs['object_held_by_human'][0] > 0.5
                and rotation[2, 1] > PRESENTED_UPRIGHT
                and (height > PRESENTED_HEIGHT or (
                    height > LOW_PRESENTED_HEIGHT and presented_low
                    and self._still_steps >= PRESENTED_DWELL)))

  def _graspable(self, grip, q):
    """Gripper-down IK reaches MIN_HOVER_HEIGHT above the grip point
    moved SWAY_MARGIN towards the base: a hand that sways in and out of
    the reach is approached (the arm waits at the edge of its reach), one
    held beyond it is not."""
    inward = self._kinematics.base_pose[:3, 3] - grip
    inward[2] = 0.0
    inward *= SWAY_MARGIN / max(np.linalg.norm(inward), 1e-9)
    return self._reachable(np.clip(grip + inward + (0.0, 0.0,
                                                    MIN_HOVER_HEIGHT),
                                   self._box[0], self._box[1]), q)

  def _ready_point(self, grip):
    """Where to wait for the presentation."""
    if self._last_presented is not None:
      return self._last_presented + (0.0, 0.0, READY_ABOVE)
    home = self._home
    return np.array([
        home[0] + np.clip(grip[0] - home[0], 0.0, READY_AHEAD),
        home[1] + np.clip(grip[1] - home[1], -READY_SIDE, READY_SIDE),
        max(home[2], layout.TABLE_TOP_Z + READY_HEIGHT)])

  def _carry(self, obs):
    tcp, grip = obs['eef_position'], obs['object_position']
    target = obs['target_position']
    horizontal = np.linalg.norm((target - grip)[:2])
    if horizontal > OVER_TARGET:
      aim_grip = target + (0.0, 0.0, CARRY_HEIGHT)
      # Lift before crossing: not below the carry height while far.
      if grip[2] < aim_grip[2] - 0.03 and horizontal > 0.1:
        aim_grip = np.array([grip[0], grip[1], aim_grip[2]])
    else:
      aim_grip = target + (0.0, 0.0, RELEASE_HEIGHT)
    low = grip[2] - target[2] < RELEASE_BELOW
    gripper = -1.0 if (low and horizontal < OVER_TARGET + 0.01) else 1.0
    shift = aim_grip - grip
    norm = np.linalg.norm(shift)
    if norm > CARRY_STEP:
      shift *= CARRY_STEP / norm
    return self._step(obs, shift, gripper, slide=False)

  def _action(self, obs):
    grip = obs['object_position']
    speed = (0.0 if self._previous_grip is None
             else float(np.linalg.norm(grip - self._previous_grip)))
    self._previous_grip = grip.copy()
    held = obs['object_held_by_human'][0] > 0.5
    still = held and speed < PRESENTED_SPEED
    self._still_steps = self._still_steps + 1 if still else 0
    if held and obs['object_gripped'][0] > 0.5:
      # Both fingers on it and the person still holds it: they are not
      # waiting to let go yet (they let go of a grasp at once when they
      # are). Open and back off above it.
      return self._hover(obs, grip + (0.0, 0.0, HOVER_HEIGHT))
    if self._in_hand(obs) and not held:
      return self._carry(obs)
    presented = self._presented(obs)
    if not presented or speed >= PRESENTED_SPEED:
      self._sway_within_box = False
    elif grip[2] <= self._box[1][2] + GRASP_Z:
      self._sway_within_box = True
    if presented:
      # Beyond the reach by more than a sway (held too high or too far):
      # wait for a presentation the arm reaches, where the last one was,
      # instead of pushing the arm against its reach; held above the box
      # all along its sway, at home, clear of the hammer.
      q = obs['joint_positions']
      if speed < PRESENTED_SPEED and not self._sway_within_box:
        return self._go_home(obs, -1.0)
      if speed < PRESENTED_SPEED and self._graspable(grip, q):
        self._last_presented = grip.copy()
        return self._grasp(obs)
      hover = grip + (0.0, 0.0, HOVER_HEIGHT)
      if speed < PRESENTED_SPEED or not self._reachable(
          np.clip(hover, self._box[0], self._box[1]), q):
        return self._hover(obs, self._ready_point(grip))
      return self._hover(obs, hover)
    if held:   # Being lifted or swayed back: wait nearby.
      return self._hover(obs, self._ready_point(grip))
    # Lying on the table (before the person's pick, placed, or dropped:
    # the tool may not reach into the table): wait at home.
    return self._go_home(obs, -1.0)

  def _hover(self, obs, point):
    """Towards `point` (as far as gripper-down IK reaches), gripper open."""
    return self._step(obs, point - obs['eef_position'], -1.0)
