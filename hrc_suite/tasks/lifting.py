"""Collaborative lifting: the robot and a person lift a board together and
keep it level while the person moves (docs/reference_benchmark.md, Tasks).

* Scene: the 1.0 x 0.4 x 0.03 m board (`props.Board`) lies on the table
  along x, its robot end BOARD_NEAR_END_X from the base (about 2 cm onto
  the table) and centred between the clip's board grasps in y (plus a
  small random offset); its handle is HANDLE_INSET from that end, so the
  grip site is ~0.40 m ahead of the world origin (the default mount's
  base; the Schunk's stands 0.15 m further forward), where every robot
  reaches it gripper down. Where the robot could not then lift the handle
  LIFT_CHECK straight up by Cartesian actions (local gripper-down IK steps
  of LIFT_CHECK_STEP from the grip posture, free of static and
  self-collision), the board lies further from the robot, by BOARD_SHIFT
  steps up to MAX_BOARD_SHIFT (unshifted if none lifts; the links kept
  LIFT_SELF_CLEARANCE apart): the Schunk's elbow
  folds against its upper arm when it raises a handle less than 0.44 m
  ahead of the world origin, so it stayed down while recorded people lifted
  their end by up to 1 m and the board tipped over (docs/tasks.md). The
  episode starts with the robot holding the handle: IK to the grip site,
  fingers closed on it, SETTLE_STEPS physics steps.
* Human: the 9 lifting clips (no idle phases). At the clip's first
  keyframe (hands at the board) the person takes the board with both hands
  (`Human.hold` plus the other hand's weld, each anchored at the board
  point under its hand, rotation free: HOLD_TORQUE_SCALE, compliant:
  HOLD_SOLREF); at the last
  keyframe (board put down) they let go. Contacts between the
  person's capsules and the board are excluded (the weld is the grasp).
* Cartesian actions keep the grip's yaw (CARTESIAN_YAW = GRIP_YAW: fingers
  closing along the board), not the suite's default yaw 0, which would
  twist the board. The fingers hold a handle 6 cm above the table, so
  collision prevention lets the tool capsule into the table
  (FINGERTIP_TABLE_CLEARANCE).
* Reward (dense): while the robot grips the board, 1 - tilt / MAX_TILT
  (+1 when level, 0 at the limit); 0 in a step without the grip; -10 and
  termination when the board normal's z component drops below
  MIN_NORMAL_Z (~37 deg) or the robot lets go for more than
  MAX_RELEASED_STEPS RL steps.
* Success: a clip (the person's whole lift) ends without failure (the
  base's `clip_ended`). SSM; no reward delay; horizon 5000 RL steps.
* Observations: 'paper' = board quaternion, distance EEF->head, vectors
  EEF->left / right hand (world frame).
  'full' adds the shared observables, the board's position and normal,
  the handle's position, EEF->handle and whether the board is gripped.
* Counters: released_steps (RL steps without the grip), lifts (times the
  person took the board).
* Snapshots: the base saves and restores the hold welds (model data).
"""

from typing import Optional

from dm_control.composer.observation import observable
import numpy as np

from hrc_suite import layout
from hrc_suite import suite
from hrc_suite.control import ik as ik_lib
from hrc_suite.entities import element_ids
from hrc_suite.entities import props
from hrc_suite.human import keypoints
from hrc_suite.tasks import base
from hrc_suite.tasks.runtime import robot_payload

MIN_NORMAL_Z = 0.8           # reference: board normal z below it fails
MAX_TILT = float(np.arccos(MIN_NORMAL_Z))   # rad, ~37 deg
MAX_RELEASED_STEPS = 5       # reference: RL steps without the grip
FAILURE_REWARD = -10.0       # reference
BALANCED_REWARD = 1.0        # reference, per step while balanced
# The board's robot end 2 cm onto the table (layout.TABLE_X: near edge).
BOARD_NEAR_END_X = layout.TABLE_X[0] + 0.02   # m, world
# Handle 0.235 m from the robot end: grip site ~0.42 m ahead of the world
# origin (the default mount's base), inside every robot's gripper-down
# workspace (the iiwa's starts at ~0.4 m, the Schunk's ends at ~0.5 m).
HANDLE_INSET = 0.235         # m
BOARD_OFFSET = 0.02          # m, uniform +- in x and y per episode
# How high the robot must be able to lift the handle from its grip: the
# synthetic people lift their hands by up to 0.4 m (lifting_01: 0.87 ->
# 1.27 m), recorded ones by up to 1 m, of which a tilt of MAX_TILT lets the
# robot end stay ~0.36 m lower. Checked in Cartesian steps of
# LIFT_CHECK_STEP (a policy's steps; the expert's are 0.03 m).
LIFT_CHECK = 0.4             # m
LIFT_CHECK_STEP = 0.02       # m
BOARD_SHIFT = 0.01           # m, away from the robot per try
# Clearance between the robot's own links kept along that lift: the
# robot starts where the settled grip puts it, not at the IK solution.
LIFT_SELF_CLEARANCE = 0.002  # m
MAX_BOARD_SHIFT = 0.12       # m (the board's far end then 0.06 m over)
# Gripper yaw of the handle grasp: the site's x axis along world y.
GRIP_YAW = np.pi / 2
# Fingertips' clearance above the table kept by collision prevention (the
# inspection task's value: low enough for the handle 6 cm up).
TABLE_CLEARANCE = 0.005      # m
GRIP_IK_RESTARTS = 20
SETTLE_STEPS = 50            # physics steps (0.2 s) closing on the handle
HANDS = ('left', 'right')
# The hold weld's rotational stiffness relative to its translational one
# (MuJoCo weld `torquescale`): a full weld would turn the board with the
# person's hand segment, whose orientation follows the forearm (~25 deg
# during a lift); two people carrying a board hinge it at their hands.
HOLD_TORQUE_SCALE = 0.0
# The hold welds' time constant and damping ratio (MuJoCo solref): arms are
# compliant. With the add_holdable default (0.01 s) any centimetre of
# mismatch between the hands' path and the robot's grip becomes a force
# that pries the gripper's fingers open (the fingers close along the
# board); 0.3 s lets the oracle keep its grasp through a lift.
HOLD_SOLREF = (0.3, 1.0)
# The gripper's squeeze on the handle (N; 2F-85 range 20-235, the suite's
# default 40). The handle is 8 cm wide between 2 cm pads: when the person's
# hands turn the board's heading, the twist about the vertical pries the
# fingers open against the grip force. With 40 N a stiff wrist (the
# Schunk's) let the handle twist out in 7 of 20 expert episodes; at 100 N
# it held in all of 45 (seeds 0-44).
GRIP_FORCE = 100.0


@suite.register('lifting', 'default',
                tags=('object_handling', 'dense', 'ssm'))
class Lifting(robot_payload.CarriesPayload, base.HrcTask):
  """Keep a board level together with a person who lifts and carries it."""

  MOTIONS = 'lifting'
  HUMAN_STATION = layout.HUMAN_STATION_ACROSS
  DEFAULT_SHIELD = 'ssm'
  DEFAULT_ACTION_SPACE = 'cartesian'
  REWARDS = ('dense',)
  DEFAULT_REWARD_DELAY = 0
  HORIZON = 5000
  HAS_GRIPPER_ACTION = True
  OBSERVATION_PRESETS = {'paper': ('board_quaternion', 'head_distance',
                                   'eef_to_hands')}
  EXTRA_COUNTERS = ('released_steps', 'lifts')
  FINGERTIP_TABLE_CLEARANCE = TABLE_CLEARANCE
  CARTESIAN_YAW = GRIP_YAW
  GRIP_FORCE = GRIP_FORCE
  TASK_STATE = ('_released', '_gripped', '_failed_now', '_success', '_tilt',
                '_lifted', '_hand')

  def _build_task(self):
    self._board = props.Board(handle_inset=HANDLE_INSET)
    self._arena.add_free_entity(self._board)
    self._object_geoms.extend(self._board.geoms)
    self._welds = self._grips.add(self._board.body)
    for weld in self._welds.values():
      weld.torquescale = HOLD_TORQUE_SCALE
      weld.solref = HOLD_SOLREF
    # The person handles the board through the hold weld only: their
    # kinematic capsules would shove it out of the robot's fingers.
    for segment in self._human.segment_bodies:
      self._arena.mjcf_model.contact.add('exclude', body1=segment,
                                         body2=self._board.body)
    self._ik = ik_lib.InverseKinematics(self._kinematics)
    self._hand = HANDS[1]
    self._reset_progress()

  def _reset_progress(self):
    self._released = 0
    self._gripped = True
    self._failed_now = False
    self._success = False
    self._tilt = 0.0
    self._lifted = 0

  @property
  def board(self) -> props.Board:
    """The board the robot and the person lift together."""
    return self._board

  @property
  def holding_hand(self) -> Optional[str]:
    """The hand the person holds the board with (None: not holding)."""
    return self._human.holding(self._board.body)

  # --------------------------------------------------------------- episode

  def _initialize_task(self, physics, random_state):
    self._reset_progress()
    self._hand = HANDS[random_state.randint(2)]
    targets = self._player.targets_world
    hands_y = 0.5 * (targets['board_grasp_left'][1]
                     + targets['board_grasp_right'][1])
    length, _, thickness = self._board.size
    offset = random_state.uniform(-BOARD_OFFSET, BOARD_OFFSET, 2)
    centre = np.array([BOARD_NEAR_END_X + length / 2 + offset[0],
                       hands_y + offset[1], layout.TABLE_TOP_Z + thickness / 2])
    shifts = np.arange(0.0, MAX_BOARD_SHIFT + 1e-9, BOARD_SHIFT)
    for shift in shifts:
      result, grip = self._grip(physics, centre + (shift, 0.0, 0.0),
                                random_state)
      if result.success and self._liftable(result.q):
        break
    else:   # No shift lifts: the board where it was drawn.
      result, grip = self._grip(physics, centre, random_state)
    if not result.success:
      raise RuntimeError(f'Lifting: IK cannot reach the handle at {grip} for '
                         f'{self._robot.description.name}')
    q = result.q
    data = physics.data
    data.qpos[self._qpos_index] = q
    data.qvel[self._qvel_index] = 0.0
    # Each finger opens by half the aperture: closed on the handle.
    data.qpos[self._finger_qpos_index] = props.HANDLE_HALF_SIZE[0]
    self._gripper.set_command(physics, 1.0)
    self._episode.q_goal = q.copy()
    self._shield.reset(q, 0.0)
    zeros = np.zeros_like(q)
    for _ in range(SETTLE_STEPS):
      self._stepper.controller(physics, q, zeros, zeros)
      physics.step()
    data.time = 0.0    # The settling is not part of the episode.
    physics.forward()
    self._gripped = props.is_gripped(physics, self._gripper, self._board)

  def _grip(self, physics, centre, random_state):
    """(IK result, grip site) with the board lying level at `centre`."""
    self._board.set_pose(physics, centre, np.array([1.0, 0.0, 0.0, 0.0]))
    physics.forward()
    grip = physics.bind(self._board.robot_grip_site).xpos.copy()
    result = self._ik.solve_with_restarts(
        grip, self._robot.description.q_home, random_state, yaw=GRIP_YAW,
        restarts=GRIP_IK_RESTARTS)
    return result, grip

  def _liftable(self, q):
    """Whether Cartesian steps lift the TCP LIFT_CHECK straight up from q
    (gripper-down IK from the last step, no static collision, the links
    LIFT_SELF_CLEARANCE apart)."""
    checker = self._collision_checker

    def free(q):
      _, pairs = checker.penetrations(q)
      return (not checker.in_collision(q)
              and np.all(pairs <= -LIFT_SELF_CLEARANCE))

    if not free(q):
      return False
    start = self._kinematics.tcp_pose(q)[:3, 3]
    steps = int(np.ceil(LIFT_CHECK / LIFT_CHECK_STEP))
    for k in range(1, steps + 1):
      point = start + (0.0, 0.0, LIFT_CHECK * k / steps)
      result = self._ik.solve(point, q, GRIP_YAW)
      if not result.success or not free(result.q):
        return False
      q = result.q
    return True

  # ------------------------------------------------------------ progress

  def _update_hold(self, physics):
    """The person takes the board at the clip's first keyframe and lets go
    at its last one (the board is down again)."""
    player = self._player
    clip = player.clip
    t = player.clip_time
    grasp, down = (clip.keyframes[0] / clip.fps, clip.keyframes[-1] / clip.fps)
    holding = self.holding_hand is not None
    should_hold = not player.in_transition and grasp <= t < down
    if should_hold and not holding:
      self._grips.hold(physics, self._board.body, self._hand)
      self._anchor_at_hands(physics)
      self._lifted = 1
    elif holding and not should_hold:
      self._grips.release(physics, self._board.body)

  def _anchor_at_hands(self, physics):
    """Both hands hold the board at the points under them, rotation free.

    Human.hold welds one hand; the other hand's weld (made by
    add_holdable, released with the first) is switched on here. Each
    weld's anchor is the board point at its hand, so the two hands act as
    hinges on the board's end (a full weld would turn the board with the
    hand segments, one point alone would let it roll).
    """
    board = physics.bind(self._board.body)
    board_rot = board.xmat.reshape(3, 3)
    positions = self._human.keypoint_positions(physics)
    for hand in HANDS:
      eq_id = physics.bind(self._welds[hand]).element_id
      point = positions[keypoints.index((f'{hand}_hand',))[0]]
      hand_body = physics.model.eq_obj1id[eq_id]
      hand_rot = physics.data.xmat[hand_body].reshape(3, 3)
      data = physics.model.eq_data[eq_id]
      data[0:3] = board_rot.T @ (point - board.xpos)
      data[3:6] = hand_rot.T @ (point - physics.data.xpos[hand_body])
      physics.data.eq_active[eq_id] = 1
    self._grips.mark_changed()

  def _update_task(self, physics):
    self._gripped = props.is_gripped(physics, self._gripper, self._board)
    self._released = 0 if self._gripped else self._released + 1
    normal_z = float(self._board.normal(physics)[2])
    self._tilt = self._board.tilt(physics)
    self._failed_now = (normal_z < MIN_NORMAL_Z
                        or self._released > MAX_RELEASED_STEPS)
    self._success = False
    if self.clip_ended:   # A whole lift ended.
      self._success = not self._failed_now
    self._lifted = 0
    self._update_hold(physics)
    return {'success': float(self._success), 'board_tilt': self._tilt,
            'board_normal_z': normal_z,
            'board_gripped': float(self._gripped),
            'released_steps': int(not self._gripped),
            'lifts': self._lifted}

  def _held_bodies(self):
    return (self._board.body,) if self._gripped else ()

  def _failed(self, physics):
    del physics
    return self._failed_now

  def _task_reward(self, physics):
    del physics
    if self._failed_now:
      return FAILURE_REWARD
    if not self._gripped:
      return 0.0
    return BALANCED_REWARD * max(0.0, 1.0 - self._tilt / MAX_TILT)

  def _task_reward_range(self):
    return (FAILURE_REWARD, BALANCED_REWARD)

  def _task_failure_reward(self):
    return (FAILURE_REWARD, 0.0)   # 0: released, or tilted to MAX_TILT

  # -------------------------------------------------------- observables

  def _task_observables(self):
    board = self._board
    head = keypoints.index(('head',))[0]
    hands = np.array(keypoints.index(('left_hand', 'right_hand')))

    handle = element_ids.ElementIds([board.robot_grip_site])

    def eef_to(indices):
      def observe(physics):
        points = self._human.keypoint_positions(physics)[indices]
        return points - self._robot.tcp_frame(physics)[0]
      return observe

    def eef_to_handle(physics):
      point = element_ids.synced_data(physics).site_xpos[handle(physics)[0]]
      return point - self._robot.tcp_frame(physics)[0]

    return {
        'board_quaternion': board.observables.quaternion,
        'head_distance': observable.Generic(
            lambda physics: np.array([np.linalg.norm(eef_to(head)(physics))])),
        'eef_to_hands': observable.Generic(eef_to(hands)),
        'board_position': board.observables.position,
        'board_normal': board.observables.normal,
        'handle_position': observable.MJCFFeature(
            'xpos', self._board.robot_grip_site),
        'eef_to_handle': observable.Generic(eef_to_handle),
        'board_gripped': observable.Generic(
            lambda physics: np.array([float(props.is_gripped(
                physics, self._gripper, self._board))])),
    }
