"""hammering/robot_hammers: the reference's roles. The robot holds the
hammer and drives the nail; the person brings the nail plank, holds it on
the table meanwhile and takes it away (docs/tasks.md; the reference's
recordings, CollaborativeHammering, record these roles).

* Start: the robot at home with the hammer in its gripper (face down,
  handle level along world y, head towards +y, gripped at its centre of
  mass: HAMMER_GRIP), turned to HOLD_YAW where the IK finds that turn
  (`hammering.turn_at_home`). The person walks in carrying the nail plank
  (NailBoard, PLANK_*): the plank follows the holding hand and the
  person's heading rigidly (kinematic, no collisions: it is part of the
  person while carried).
* Set-down (the clip's first keyframe): the plank is put on the table with
  its handle at the clip's 'board_place' (under the holding hand;
  task_targets) and its nail towards the robot; from then it is a free
  body. The person's hand rests on it (person-plank contacts are off: the
  kinematic hand would shove it). The nail's place follows from the
  plank's.
* Wait: the person's idle phase until 'nail_hammered' (progress >
  SUCCESS_PROGRESS). Take-back (the clip's last keyframe, after the wait):
  the plank is carried again, rigidly from where it lies, and the person
  leaves.
* Success (reference: the human motion completes without failure): the
  nail is in and the person's clip ends. Failure: the hammer out of the
  gripper for more than DROP_STEPS RL steps. Reward: sparse, +1 at
  success, -1 otherwise. PFL (SHIELD); horizon 1000 RL steps.
* Observations: 'paper' = hammer gripped, TCP -> hammer grip, hammer face
  -> nail head ('eef_to_target'), gripper aperture, distances to the
  person's head and hands. 'full' adds the plank's pose, nail progress,
  nail head and hammer face positions and whether the plank lies on the
  table ('board_placed').
"""

import collections

from dm_control import mjcf
from dm_control.composer.observation import observable
import mujoco
import numpy as np

from hrc_suite import layout
from hrc_suite import rotations
from hrc_suite import suite
from hrc_suite.control import ik as ik_lib
from hrc_suite.entities import element_ids
from hrc_suite.entities import human as human_lib
from hrc_suite.entities import nail_board as nail_board_lib
from hrc_suite.entities import props
from hrc_suite.human import keypoints
from hrc_suite.tasks import base
from hrc_suite.tasks import hammering
from hrc_suite.tasks.runtime import robot_payload

SUCCESS_PROGRESS = hammering.SUCCESS_PROGRESS
BLOW_PROGRESS = hammering.BLOW_PROGRESS
# RL steps without the hammer before failure: as hammering/default's
# (hammering.NailOutcome).
DROP_STEPS = hammering.DROP_STEPS
EVENT = hammering.EVENT
# The nail plank: 30 x 10 x 4 cm of pine (0.8 kg with its handle), the
# handle at its person end (-x), the nail 5 cm from its robot end: the
# recordings' resting hands lie 0.70-0.89 m from the robot base, so the
# nail lands 0.47-0.66 m from it, 0.235 m from the hand (inside the
# Schunk's and the Panda's gripper-down reach, 0.30-0.75 m at the plank's
# height; with a 40 cm plank, nails 0.37-0.38 m from the base, the
# Schunk's expert stalled: collision prevention rejected its steps).
PLANK_HALF_SIZE = (0.15, 0.05, 0.02)
PLANK_NAIL_X = 0.1
PLANK_HANDLE_X = (-PLANK_HALF_SIZE[0] + nail_board_lib.HANDLE_INSET
                  + nail_board_lib.HANDLE_HALF_SIZE[0])
# Set down this far above the table (m): it settles in the first steps.
SET_DOWN_GAP = 0.001
# The hammer in the gripper: its grasp frame (TCP frame) on the handle's
# axis at the centre of mass (no gravity torque about the fingers' closing
# axis), fingers closing across the handle, approach down onto the head's
# top: the face points down, the handle along the TCP's x axis.
_HAMMER_COM_X = -(props.HAMMER_HANDLE_LENGTH / 2 * props.HAMMER_HANDLE_MASS
                  / (props.HAMMER_HANDLE_MASS + props.HAMMER_HEAD_MASS))
GripFrame = collections.namedtuple('GripFrame', 'pos xyaxes')
HAMMER_GRIP = GripFrame((_HAMMER_COM_X, 0.0, 0.0), props.TOP_GRASP_CLOSING_Y)
# The handle level along world y (yaw pi/2: the TCP's x axis along y), so it
# reaches sideways, clear of the arm; head towards +y.
HOLD_YAW = np.pi / 2
# The gripper's squeeze (N; 2F-85 range 20-235, lifting's value): the
# hammer, held by friction, must not slip up when its face presses on the
# nail (the nail's friction: 60 N, nail_board.NAIL_FRICTION).
GRIP_FORCE = 100.0
SETTLE_STEPS = 50              # physics steps closing on the handle
# Fingertips' clearance above the table kept by collision prevention (m):
# with the nail in, the face is 4 cm above the plank (8.5 cm over the
# table) and the fingertips ~1 cm above the face.
TABLE_CLEARANCE = 0.03
CARRIED, PLACED, TAKEN = 'carried', 'placed', 'taken'
# PFL, not the reference's SSM for hammering: the nail lies within the
# standing person's reach (their arm's 0.825 m reach ball, shield human
# model), and SSM held the arm still there for the whole wait (Panda, seed
# 0, the expert waiting with the face 3 cm over the nail head: no blow in
# 1000 RL steps, 958 of them shielded; docs/tasks.md). PFL lets it move at
# v_safe where contact is possible, as in the handovers, where the robot
# works at the person's hand.
SHIELD = 'pfl'


def heading(points: np.ndarray) -> float:
  """The person's facing yaw from world keypoints: perpendicular to the
  shoulder line, horizontal.

  Args:
    points: (N_kp, 3) world keypoints.

  Returns:
    The yaw, rad.
  """
  return float(headings(np.asarray(points)[None])[0])


def headings(points: np.ndarray) -> np.ndarray:
  """`heading` of each row of keypoints.

  Args:
    points: (n, N_kp, 3) world keypoints.

  Returns:
    (n,) yaws, rad.
  """
  across = (points[:, keypoints.KEYPOINT_INDEX['left_shoulder']]
            - points[:, keypoints.KEYPOINT_INDEX['right_shoulder']])
  return np.arctan2(-across[:, 0], across[:, 1])


@suite.register('hammering', 'robot_hammers',
                tags=('manufacturing', 'sparse', 'delayed', 'pfl'))
class RobotHammers(hammering.NailOutcome, robot_payload.CarriesPayload,
                   base.HrcTask):
  """Drive the nail of the plank the person brings with the held hammer."""

  MOTIONS = 'hammering_board'
  EVENTS = (EVENT,)   # the person holds the plank until the nail is in
  HUMAN_STATION = layout.HUMAN_STATION_ACROSS
  HUMAN_PLACEMENT_RANGE = (0.0, 0.0, 0.0)
  DEFAULT_SHIELD = SHIELD
  DEFAULT_ACTION_SPACE = 'cartesian'
  REWARDS = ('sparse',)
  DEFAULT_REWARD_DELAY = 0
  HORIZON = 1000
  HAS_GRIPPER_ACTION = True
  OBSERVATION_PRESETS = {'paper': (
      'object_gripped', 'eef_to_object', 'eef_to_target', 'gripper_aperture',
      'human_distances')}
  EXTRA_COUNTERS = ('nail_blows',)
  FINGERTIP_TABLE_CLEARANCE = TABLE_CLEARANCE
  CARTESIAN_YAW = HOLD_YAW
  GRIP_FORCE = GRIP_FORCE
  TASK_STATE = ('_success', '_nailed', '_gripped', '_free_steps',
                '_progress', '_blow', '_phase', '_carry', '_place_pose',
                '_hand')

  def _build_task(self):
    self._hold_ik = ik_lib.InverseKinematics(self._kinematics)
    self._board = nail_board_lib.NailBoard(
        name='nail_plank', block_half_size=PLANK_HALF_SIZE,
        nail_x=PLANK_NAIL_X)
    self._hammer = props.Hammer()
    for prop in (self._board, self._hammer):
      self._arena.add_free_entity(prop)
      self._object_geoms.extend(prop.geoms)
    # The person handles the plank kinematically (carried, or a hand
    # resting on it): their capsules would shove it.
    for segment in self._human.segment_bodies:
      self._arena.mjcf_model.contact.add('exclude', body1=segment,
                                         body2=self._board.body)
    self._board_bits = None    # (physics ptr, geoms, contype, conaffinity)
    self._hand = 'left'
    self._reset_progress()

  def _reset_progress(self):
    self._success = False
    self._nailed = False
    self._gripped = True
    self._free_steps = 0
    self._progress = 0.0
    self._blow = False
    self._phase = CARRIED
    # The plank relative to the holding hand in the person's heading frame
    # (position, rotation) while carried; its pose on the table.
    self._carry = (np.zeros(3), np.eye(3))
    self._place_pose = (np.zeros(3), np.eye(3))

  @property
  def board(self) -> nail_board_lib.NailBoard:
    """The plank with the nail, which the person brings."""
    return self._board

  @property
  def hammer(self) -> props.Hammer:
    """The robot's hammer."""
    return self._hammer

  @property
  def board_phase(self) -> str:
    """'carried' (in), 'placed' (on the table) or 'taken' (back)."""
    return self._phase

  # ------------------------------------------------------------- episode

  def _initialize_task(self, physics, random_state):
    del random_state   # The clip (drawn by the player) sets the place.
    self._reset_progress()
    hammering.turn_at_home(self, physics, self._hold_ik, HOLD_YAW)
    tcp_x = physics.bind(self._robot.tcp_site).xmat.reshape(3, 3)[:, 0]
    hammering.place_in_gripper(physics, self._robot.tcp_site, self._hammer,
                               HAMMER_GRIP, turned=bool(tcp_x[1] < 0.0))
    physics.data.qpos[self._finger_qpos_index] = (
        props.HAMMER_HANDLE_HALF_SECTION[0])
    self._gripper.set_command(physics, 1.0)
    self._board.set_progress(physics, 0.0)
    self._plan_carry(physics)
    self._set_board_collisions(physics, False)
    self._carry_board(physics, self._player.positions)
    # dm_control's step starts from the last forward pass: without one, the
    # first step used the props' previous poses (the plank inside the
    # table: its contacts drove the nail in before the episode began).
    physics.forward()
    q = physics.data.qpos[self._qpos_index].copy()
    zeros = np.zeros_like(q)
    # The plank's free-joint rows _carry_board writes (the person stands
    # still): written directly, not through composer's set_pose each step.
    joint = physics.bind(mjcf.get_frame_freejoint(self._board.mjcf_model))
    rows = slice(int(joint.qposadr), int(joint.qposadr) + 7)
    velocity = slice(int(joint.dofadr), int(joint.dofadr) + 6)
    data = physics.data
    carried = data.qpos[rows].copy()
    model_ptr, data_ptr = physics.model.ptr, data.ptr
    for _ in range(SETTLE_STEPS):
      self._stepper.controller(physics, q, zeros, zeros)
      physics.step()
      data.qpos[rows] = carried
      data.qvel[velocity] = 0.0
      # What the next step needs of a forward pass (the positions' and
      # velocities' stages; mj_step2 makes the accelerations).
      mujoco.mj_step1(model_ptr, data_ptr)
    physics.data.time = 0.0    # The settling is not part of the episode.
    physics.forward()
    self._gripped = self._gripper.is_grasping(physics, self._hammer.body)

  def _plan_carry(self, physics):
    """The plank's place on the table (handle at 'board_place', nail
    along the person's heading at the set-down) and, from it, its carrying
    offset from the holding hand."""
    del physics
    clip = self._player.clip
    self._hand = clip.holding_hand or 'left'
    x, y, yaw = self._player.placement
    frame = clip.keyframes[0]
    pose = (clip.positions[frame].astype(float)
            @ rotations.yaw_to_mat(yaw).T + [x, y, 0.0])
    facing = heading(pose)
    rotation = rotations.yaw_to_mat(facing)
    handle = np.asarray(self._player.targets_world['board_place'], float)
    centre = handle - rotation[:, 0] * PLANK_HANDLE_X
    centre[2] = (layout.TABLE_TOP_Z + PLANK_HALF_SIZE[2] + SET_DOWN_GAP)
    self._place_pose = (centre, rotation)
    hand = pose[keypoints.KEYPOINT_INDEX[f'{self._hand}_hand']]
    self._carry = (rotation.T @ (centre - hand), np.eye(3))

  def _take_back(self, physics):
    """The carrying offset from where the plank lies now."""
    points = self._player.positions
    rotation = rotations.yaw_to_mat(heading(points))
    board = physics.bind(self._board.body)
    hand = points[keypoints.KEYPOINT_INDEX[f'{self._hand}_hand']]
    self._carry = (rotation.T @ (board.xpos - hand),
                   rotation.T @ board.xmat.reshape(3, 3))

  def _carry_pose(self, points):
    """The carried plank's (position, quaternion) at the holding hand
    (heading frame offset) of the keypoints `points`."""
    positions, quaternions = self._carry_poses(np.asarray(points)[None])
    return positions[0], quaternions[0]

  def _carry_poses(self, points):
    """`_carry_pose` of each row of keypoints (n, N_kp, 3): positions
    (n, 3), quaternions (n, 4); stacked np.matmul gives each row what the
    single product gives."""
    turns = rotations.yaw_to_mat(headings(points))
    offset, relative = self._carry
    hand = points[:, keypoints.KEYPOINT_INDEX[f'{self._hand}_hand']]
    quaternions = rotations.mat_to_quat(np.matmul(turns, relative))
    return hand + np.matmul(turns, offset), quaternions

  def _carry_board(self, physics, points):
    """Puts the plank at the holding hand, at rest."""
    self._board.set_pose(physics, *self._carry_pose(points))
    self._board.set_velocity(physics, np.zeros(3), np.zeros(3))

  def _physics_step_writes(self, physics):
    """The carried plank's free-joint position and velocity rows for each
    physics step of the RL step: what _carry_board writes (set_pose
    normalises the quaternion, set_velocity zeroes the velocity)."""
    joint = physics.bind(mjcf.get_frame_freejoint(self._board.mjcf_model))
    positions, quaternions = self._carry_poses(self._playback.positions)
    qpos = np.empty((len(positions), 7))
    qpos[:, :3] = positions
    qpos[:, 3:] = quaternions / human_lib.row_norms(quaternions)[:, None]
    data = physics.data
    return ((data.qpos, int(joint.qposadr) + np.arange(7), qpos),
            (data.qvel, int(joint.dofadr) + np.arange(6),
             np.zeros((len(positions), 6))))

  def _set_board_collisions(self, physics, on):
    """A carried plank is part of the kinematic person: no collisions."""
    if self._board_bits is None or self._board_bits[0] is not (
        physics.data.ptr):
      model = physics.model
      body = physics.bind(self._board.body).element_id
      geoms = np.flatnonzero(np.isin(model.geom_bodyid, [
          body, physics.bind(self._board.nail).element_id]))
      self._board_bits = (physics.data.ptr, geoms,
                          model.geom_contype[geoms].copy(),
                          model.geom_conaffinity[geoms].copy())
    _, geoms, contype, conaffinity = self._board_bits
    physics.model.geom_contype[geoms] = contype if on else 0
    physics.model.geom_conaffinity[geoms] = conaffinity if on else 0

  def _works_before_physics_steps(self):
    return self._phase != PLACED   # Changes only between RL steps.

  def _before_physics_step(self, physics):
    if self._phase != PLACED:
      self._carry_board(physics, self._playback.positions[
          self._stepper.physics_step])

  def _set_task_state(self, physics, state):
    super()._set_task_state(physics, state)
    self._set_board_collisions(physics, self._phase == PLACED)

  # ------------------------------------------------------------ progress

  def _update_phase(self, physics):
    player, clip = self._player, self._player.clip
    if self.clip_ended:       # A new person brings the plank in again.
      self._phase = CARRIED
      self._plan_carry(physics)
      self._set_board_collisions(physics, False)
      self._grips.mark_changed()
      return
    t = player.clip_time
    if self._phase == CARRIED and not player.in_transition and (
        t >= clip.keyframes[0] / clip.fps):
      self._phase = PLACED
      centre, rotation = self._place_pose
      self._board.set_pose(physics, centre,
                           rotations.mat_to_quat(rotation))
      self._board.set_velocity(physics, np.zeros(3), np.zeros(3))
      self._set_board_collisions(physics, True)
      self._grips.mark_changed()
    elif (self._phase == PLACED and player.waiting_for is None
          and t >= clip.keyframes[-1] / clip.fps):
      self._phase = TAKEN
      self._take_back(physics)
      self._set_board_collisions(physics, False)
      self._grips.mark_changed()

  def _update_task(self, physics):
    metrics = self._nail_outcome(physics, self._hammer.body)
    self._update_phase(physics)
    metrics['board_placed'] = float(self._phase == PLACED)
    return metrics

  def _held_bodies(self):
    return (self._hammer.body,) if self._gripped else ()

  # -------------------------------------------------------- observables

  def _task_observables(self):
    board, hammer = self._board, self._hammer
    body = element_ids.ElementIds([hammer.body])
    sites = element_ids.ElementIds([board.nail_head_site, hammer.head_site])

    def eef_to_object(physics):
      data, row = element_ids.synced_data(physics), body(physics)[0]
      point = data.xpos[row] + data.xmat[row].reshape(3, 3) @ np.asarray(
          HAMMER_GRIP.pos)
      return point - self._robot.tcp_frame(physics)[0]

    def eef_to_target(physics):
      nail, head = sites(physics)
      data = element_ids.synced_data(physics)
      return data.site_xpos[nail] - data.site_xpos[head]

    return {
        'object_gripped': observable.Generic(
            lambda physics: np.array([float(self._gripper.is_grasping(
                physics, hammer.body))])),
        'eef_to_object': observable.Generic(eef_to_object),
        'eef_to_target': observable.Generic(eef_to_target),
        'object_position': board.observables.position,
        'object_quaternion': board.observables.quaternion,
        'nail_progress': board.observables.nail_progress,
        'nail_head_position': board.observables.nail_head_position,
        'hammer_head_position': hammer.observables.head_position,
        'board_placed': observable.Generic(
            lambda physics: np.array([float(self._phase == PLACED)])),
    }
