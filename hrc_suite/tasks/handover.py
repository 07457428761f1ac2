"""Handovers of a hammer between the robot and a human across the table
(docs/reference_benchmark.md, Tasks).

Robot to human (`RobotToHuman`): the episode starts with the hammer in the
closed gripper at the home pose, handle towards the human. The robot brings
the handle to the human, who reaches out and waits for 'object_received'. The
handover happens when the handle touches the palm (the hand capsule of the
clip's holding hand; checked geometrically, within TOUCH_TOLERANCE, because a
held object's contact with its hand is off) while the human waits: the human
holds it (`Human.hold`), the event fires, the robot must let go and the human
finishes the clip (takes it back, retreats).

Human to robot (`HumanToRobot`): the hammer lies where the clip picks it up
('object_pick'). At the clip's first keyframe the human holds it and, until
the presentation keyframe, turns it in the hand to the presenting grip
(handle along the hand, head forward, lying on its side so a gripper-down
grasp at `Hammer.grip_site` works; tilted down no further than keeps it
PRESENT_CLEARANCE above the table, `presenting_grip`). Collision prevention
lets the fingertips down to TABLE_CLEARANCE above the table, as pick and
place: people may present it low. While the human waits for 'object_taken'
a robot grasp (both fingers touch it, gripper commanded closed) makes the
human let go and fires the event; the robot places it within
SUCCESS_DISTANCE of a target on the table ('object_placed' fires once it lies
there released) and the human retreats. The target is drawn in the region
until the robot reaches its put-down (PUT_DOWN_ABOVE, PUT_DOWN_APPROACH).

Success (both): the object is where it belongs (held by the human / at the
target) and the human's motion has completed: by default the end of the
episode's first clip (the base's `clips_completed`), so the success reward arrives after the human's
retreat, 1.5-4 s after the event for the shipped clips (the task's
reward delay). `success_after=s` instead counts success s seconds after
the handover event (object received / placed). The base's extra
`reward_delay` (RL steps) stays 0 by default.

Rewards (sparse): +1 success; robot to human: 0 while the human holds the
object and the robot does not, -0.25 while the robot grips it, -1
otherwise; human to robot: 0 with the object at the target, -0.25 while
gripped, -1 otherwise. Failure: the hammer falls off the table (below
DROP_HEIGHT under its top, not held by the human). PFL shield,
horizon 1000 RL steps, human placement +-(0, 0.2 m, 0.1 rad).

Observations: 'paper' = object gripped, EEF->object, EEF->target (world
vectors), gripper aperture, distances EEF->head / left / right hand. The
target is the holding hand's palm (robot to human) or the table target.
"""

import math
from typing import Any, Optional, Sequence

from dm_control import mjcf
from dm_control.composer.observation import observable
import numpy as np

from hrc_suite import layout
from hrc_suite import rotations
from hrc_suite import suite
from hrc_suite.control import ik as ik_lib
from hrc_suite.entities import element_ids
from hrc_suite.entities import human as human_lib
from hrc_suite.entities import markers
from hrc_suite.entities import props
from hrc_suite.human import clip as clip_lib
from hrc_suite.human import keypoints
from hrc_suite.safety import geometry
from hrc_suite.tasks import base
from hrc_suite.tasks import common
from hrc_suite.tasks.runtime import robot_payload

# Reference: human placement randomisation for the handovers.
PLACEMENT_RANGE = (0.0, 0.2, 0.1)        # m, m, rad
SUCCESS_DISTANCE = 0.1                   # m, object to target (reference)
GRIPPED_REWARD = -0.25                   # reference
# The handle touches the palm: hand capsule to handle capsule distance, m.
TOUCH_TOLERANCE = 0.01
# Handle capsule radius: its half width (props.HAMMER_HANDLE_HALF_SECTION).
HANDLE_RADIUS = props.HAMMER_HANDLE_HALF_SECTION[0]
# The touch test settles "no touch" from the capsules' centres alone only
# this far (m) beyond TOUCH_TOLERANCE: far beyond the exact distance's
# round-off, so both give the same verdict wherever the first settles.
_FAR_MARGIN = 1e-9
# The hammer lies on its side: body origin this high above the table top.
REST_HEIGHT = props.HAMMER_HANDLE_HALF_SECTION[0]
# Below the table top by this much the hammer has fallen off: failure.
DROP_HEIGHT = 0.1                        # m
# Robot-to-human start: the grasp point lies up to this far from the grip
# site along the handle (uniform +-), m.
GRASP_SHIFT = 0.01
# Initial finger positions this much inside the handle's faces, m, so the
# pads touch it from the first step.
GRASP_SQUEEZE = 0.0005
# Rotation of Hammer.grip_site in the hammer's body frame (columns: its x,
# y, z axes; props.Hammer builds it with xyaxes (1,0,0, 0,0,1)).
_SITE_IN_BODY = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
# Sampling region (fraction of the robot's table workspace box) for the
# hammer's centre of mass (robot to human) and the target (human to robot).
REGION_X = (0.15, 0.75)
REGION_Y = (0.2, 0.8)
# Human to robot: a target is kept if gripper-down IK reaches its put-down
# free of collisions: the TCP (at the hammer's grip point) PUT_DOWN_ABOVE
# over the target, where a robot lets the hammer drop (the expert's
# RELEASE_HEIGHT), and PUT_DOWN_APPROACH above that, where it carries it
# in (CARRY_HEIGHT). The region's near corner lies inside the iiwa's
# gripper-down reach hole (~0.35 m ahead of its base): 2 of 16 region
# points out of reach (docs/robots.md); without this check its targets
# there (seeds 6 and 9, x 0.35 m ahead) fail their episodes, the hammer
# taken but never set down, and the Sawyer's seed 6 target there, reached
# only with a colliding posture, fails the same way. Where the first draw
# is reached (Panda and Schunk, seeds 0-9) it is the target.
PUT_DOWN_ABOVE = 0.08                    # m
PUT_DOWN_APPROACH = 0.07                 # m
TARGET_ATTEMPTS = 200
TARGET_RGBA = (0.1, 0.8, 0.2, 0.4)
# The human picks the hammer if the palm is this close to its grip point.
PICK_DISTANCE = 0.15                     # m
# Human to robot: the tool capsule may dip into the table so that the
# fingertips stay this far above it (pick_place.TABLE_CLEARANCE, the same
# gripper): a person may present the hammer a few centimetres above the
# table (recordings: palm 0.05 m above it).
TABLE_CLEARANCE = 0.018                  # m
# A presented hammer's head axis stays this far above the table: its face
# (radius 0.0125 m) clear, and the grip point high enough for fingertips
# 0.01 m below the TCP and TABLE_CLEARANCE above the table.
PRESENT_CLEARANCE = 0.04                 # m
# A hand whose axis has less than this horizontal part (sin of its angle to
# the vertical) presents the hammer along the person's facing instead.
MIN_HEADING = 0.3


def _lying_quaternion(yaw):
  """Hammer on its side (body y up), handle axis (body x) at `yaw`."""
  c, s = math.cos(yaw), math.sin(yaw)
  return rotations.axes_to_quat((c, s, 0.0), (0.0, 0.0, 1.0), (s, -c, 0.0))


class _Handover(robot_payload.CarriesPayload, base.HrcTask):
  """Hammer, table region, human holding logic shared by both handovers."""

  HUMAN_STATION = layout.HUMAN_STATION_ACROSS
  HUMAN_PLACEMENT_RANGE = PLACEMENT_RANGE
  DEFAULT_SHIELD = 'pfl'
  DEFAULT_ACTION_SPACE = 'cartesian'
  REWARDS = ('sparse',)
  HORIZON = 1000
  HAS_GRIPPER_ACTION = True
  EXTRA_COUNTERS = ('handovers',)
  OBSERVATION_PRESETS = {'paper': (
      'object_gripped', 'eef_to_object', 'eef_to_target',
      'gripper_aperture', 'human_distances')}
  TASK_STATE = ('_success', '_gripped', '_event_time', '_holding_hand')
  EVENT = None   # the event after which success_after counts

  def __init__(self, success_after: Optional[float] = None, **kwargs: Any):
    """Builds the handover task.

    Args:
      success_after: None (success when the first clip ends) or seconds
        after the handover event.
      **kwargs: `base.HrcTask`'s task kwargs.

    Raises:
      ValueError: a success_after that is not None or a number >= 0, or
        a task kwarg HrcTask rejects.
    """
    if success_after is not None and not (
        isinstance(success_after, (int, float))
        and math.isfinite(success_after) and success_after >= 0):
      raise ValueError('success_after must be None or a number of seconds '
                       f'>= 0, got {success_after!r}')
    self.success_after = success_after
    super().__init__(**kwargs)

  def _build_task(self):
    self._hammer = props.Hammer()
    self._arena.add_free_entity(self._hammer)
    self._grips.add(self._hammer.body)
    self._object_geoms.extend(self._hammer.geoms)
    # The human's capsules (by segment) and the handle: palm_touches_handle.
    self._touch_geoms = element_ids.ElementIds(
        tuple(self._human.geoms) + (self._hammer.handle,))
    low, high = ik_lib.table_workspace_box(self._kinematics)
    base_pos = self._kinematics.base_pose[:3, 3]
    fx, fy = np.array(REGION_X), np.array(REGION_Y)
    self._region = (base_pos[:2] + [low[0] + fx[0] * (high[0] - low[0]),
                                    low[1] + fy[0] * (high[1] - low[1])],
                    base_pos[:2] + [low[0] + fx[1] * (high[0] - low[0]),
                                    low[1] + fy[1] * (high[1] - low[1])])
    self._palm = keypoints.KEYPOINT_INDEX
    self._holding_hand = 'right'    # until the first episode's clip
    self._reset_flags()

  def _reset_flags(self):
    self._success = False
    self._gripped = False
    self._event_time = None     # player episode time of the handover event
    self._at_target = False

  @property
  def hammer(self) -> props.Hammer:
    """The hammer handed over."""
    return self._hammer

  # ------------------------------------------------------------ progress

  def _holder(self):
    return self._human.holding(self._hammer.body)

  def _hand(self):
    """The current clip's holding hand (its palm is the target)."""
    return self._holding_hand

  def _hand_segment(self):
    """Index of the holding hand's capsule in human.SEGMENTS."""
    names = [seg[0] for seg in human_lib.SEGMENTS]
    return names.index(f'{self._hand()}_hand')

  def _palm_position(self, physics):
    index = self._palm[f'{self._hand()}_hand']
    return self._human.keypoint_positions(physics)[index]

  def _object_position(self, physics):
    return physics.bind(self._hammer.grip_site).xpos.copy()

  @property
  def _clip_done(self):
    """The episode's first clip has ended."""
    return self.clips_completed > 0

  def _update_common(self, physics):
    self._holding_hand = self._player.clip.holding_hand or 'right'
    self._gripped = self._gripper.is_grasping(physics, self._hammer.body)

  def _held_bodies(self):
    return (self._hammer.body,) if self._gripped else ()

  def _completed(self):
    if self.success_after is None:
      return self._clip_done
    return (self._event_time is not None and self._player.episode_time
            - self._event_time >= self.success_after - 1e-9)

  def _failed(self, physics):
    """The hammer fell off the table (not while the human holds it: the
    kinematic hand can drag it into the table)."""
    height = physics.bind(self._hammer.body).xpos[2]
    return bool(self._holder() is None
                and height < layout.TABLE_TOP_Z - DROP_HEIGHT)

  def _task_reward_range(self):
    return (-1.0, 1.0)

  def _sample_in_region(self, random_state):
    xy = random_state.uniform(*self._region)
    return np.array([xy[0], xy[1], layout.TABLE_TOP_Z + REST_HEIGHT])

  def _place_hammer(self, physics, grip_point, yaw):
    """Lies the hammer on its side with `grip_site` at grip_point."""
    quat = _lying_quaternion(yaw)
    offset = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    site_x = self._hammer.grip_site.pos[0]
    self._hammer.set_pose(physics, grip_point - site_x * offset, quat)
    self._hammer.set_velocity(physics, np.zeros(3), np.zeros(3))

  # -------------------------------------------------------- observables

  def target(self, physics: mjcf.Physics) -> np.ndarray:
    """World position of the target (the palm, or the table target).

    Args:
      physics: the environment's physics.

    Returns:
      (3,) the position.
    """
    return self._target(physics)

  def _target(self, physics):
    raise NotImplementedError

  def _task_observables(self):
    tcp = self._robot.tcp_frame
    observables = {
        'object_gripped': observable.Generic(
            lambda physics: np.array([float(self._gripped)])),
        'object_quaternion': self._hammer.observables.quaternion,
        'object_held_by_human': observable.Generic(
            lambda physics: np.array([float(self._holder() is not None)])),
    }
    observables.update(common.point_observables(tcp, 'object',
                                                self._object_position))
    observables.update(common.point_observables(tcp, 'target',
                                                self._target))
    return observables


@suite.register('handover', 'robot_to_human',
                tags=('handover', 'sparse', 'delayed', 'pfl'))
class RobotToHuman(_Handover):
  """The robot hands the hammer to the human."""

  MOTIONS = 'handover_robot_to_human'
  EVENT = clip_lib.Event.object_received
  EVENTS = (EVENT,)   # the person holds a hand out until they have it

  def _initialize_task(self, physics, random_state):
    self._reset_flags()
    self._holding_hand = self._player.clip.holding_hand or 'right'
    # The hammer starts in the closed gripper at the home pose (grasped at
    # its grip site, shifted along the handle), head towards the robot.
    tcp = physics.bind(self._robot.tcp_site)
    r_tcp = tcp.xmat.reshape(3, 3)
    flip = -1.0 if r_tcp[0, 0] > 0 else 1.0
    r_site = r_tcp * np.array([flip, flip, 1.0])
    site = self._hammer.grip_site
    shift = random_state.uniform(-GRASP_SHIFT, GRASP_SHIFT)
    r_body = r_site @ _SITE_IN_BODY.T
    position = tcp.xpos - r_body @ (np.asarray(site.pos) + [shift, 0, 0])
    self._hammer.set_pose(physics, position, rotations.axes_to_quat(
        r_body[:, 0], r_body[:, 1], r_body[:, 2]))
    self._hammer.set_velocity(physics, np.zeros(3), np.zeros(3))
    physics.bind(self._gripper.finger_joints).qpos = (
        props.HAMMER_HANDLE_HALF_SECTION[1] - GRASP_SQUEEZE)
    self._gripper.set_command(physics, 1.0)
    physics.forward()

  def palm_touches_handle(self, physics: mjcf.Physics) -> bool:
    """Whether the holding hand's capsule is within TOUCH_TOLERANCE of the
    handle (both as capsules).

    Args:
      physics: the environment's physics.

    Returns:
      Whether they touch.
    """
    ids = self._touch_geoms(physics)
    hand, handle = ids[self._hand_segment()], ids[-1]
    data, size = element_ids.synced_data(physics), physics.model.geom_size
    # Every point of a capsule's axis lies within its half length of its
    # centre: centres farther apart than both half lengths, both radii and
    # the tolerance cannot touch (most steps: the hand is far).
    reach = (size[hand, 1] + size[handle, 0] + size[hand, 0] + HANDLE_RADIUS
             + TOUCH_TOLERANCE + _FAR_MARGIN)
    if math.dist(data.geom_xpos[hand], data.geom_xpos[handle]) > reach:
      return False
    axis = data.geom_xmat[hand].reshape(3, 3)[:, 2] * size[hand, 1]
    half = data.geom_xmat[handle].reshape(3, 3)[:, 0] * size[handle, 0]
    hand_centre, handle_centre = data.geom_xpos[hand], data.geom_xpos[handle]
    distance = geometry.capsule_distance(
        hand_centre - axis, hand_centre + axis, size[hand, 0],
        handle_centre - half, handle_centre + half, HANDLE_RADIUS)
    return bool(distance <= TOUCH_TOLERANCE)

  def _update_task(self, physics):
    self._update_common(physics)
    handovers = 0
    if (self._holder() is None and self._event_time is None
        and self._player.waiting_for == self.EVENT
        and self.palm_touches_handle(physics)):
      self._grips.hold(physics, self._hammer.body, self._hand())
      self._event_time = self._player.episode_time
      handovers = 1
    self._success = self._holder() is not None and self._completed()
    return {'success': float(self._success), 'handovers': handovers}

  def _human_events(self, physics):
    del physics
    if self._holder() is not None:
      return (self.EVENT,)
    return ()

  def _task_reward(self, physics):
    del physics
    if self._success:
      return 1.0
    if self._gripped:
      return GRIPPED_REWARD
    if self._holder() is not None:
      return 0.0
    return -1.0

  def _target(self, physics):
    return self._palm_position(physics)


@suite.register('handover', 'human_to_robot',
                tags=('handover', 'sparse', 'delayed', 'pfl'))
class HumanToRobot(_Handover):
  """The human hands the hammer to the robot, which places it on the table."""

  MOTIONS = 'handover_human_to_robot'
  EVENT = clip_lib.Event.object_placed
  # The person presents the hammer until the robot has it, then watches
  # until it is placed.
  EVENTS = (clip_lib.Event.object_taken, EVENT)
  FINGERTIP_TABLE_CLEARANCE = TABLE_CLEARANCE
  TASK_STATE = _Handover.TASK_STATE + ('_picked', '_pick_grip',
                                       '_at_target', '_turn')

  def _build_task(self):
    super()._build_task()
    # A disc whose radius is the success distance.
    self._marker = markers.TargetMarker(
        radius=SUCCESS_DISTANCE, rgba=TARGET_RGBA, shape='disc',
        name='handover_target')
    self._marker.attach_mocap(self._arena)
    self._ik = ik_lib.InverseKinematics(self._kinematics)
    self._picked = False
    self._pick_grip = None
    self._turn = 0.0

  def presenting_grip(self, physics: mjcf.Physics,
                      hand_pose: Optional[Sequence[np.ndarray]] = None
                      ) -> tuple[np.ndarray, np.ndarray]:
    """The hammer's pose in the holding hand's capsule frame when presented
    (`presenting_grips`).

    Args:
      physics: the environment's physics.
      hand_pose: None (the hand's mocap pose: this physics step's
        keypoints) or (centre (3,), quaternion (4,)) of the hand's capsule.

    Returns:
      (position (3,), quaternion (4,)).
    """
    if hand_pose is None:
      mocap = physics.bind(
          self._human.segment_bodies[self._hand_segment()]).mocapid
      hand_pose = (physics.data.mocap_pos[mocap],
                   physics.data.mocap_quat[mocap])
    positions, quaternions = self.presenting_grips(
        physics, np.asarray(hand_pose[0], dtype=float)[None],
        np.asarray(hand_pose[1], dtype=float)[None])
    return positions[0], quaternions[0]

  def presenting_grips(self, physics: mjcf.Physics, centres: np.ndarray,
                       hand_quaternions: np.ndarray
                       ) -> tuple[np.ndarray, np.ndarray]:
    """The hammer's poses in the holding hand's capsule frame when
    presented, for n poses of the hand's capsule.

    The hammer lies along the hand's axis (head
    forward), lying on its side (body y in the vertical plane through the
    handle, upwards), `human_grip_site` at the capsule's distal end; never
    pointing up, and tilted down at most so far that its head's axis stays
    PRESENT_CLEARANCE above the table (level if the palm is lower). The
    capsule hand has no wrist: a recording's hand continues its forearm,
    which points 15-35 degrees down while presenting; held along it, a palm
    0.05 m above the table put the hammer into the table. Row by row the
    values of one pose (products and norms by stacked np.matmul, which
    gives each row what a single product gives).

    Args:
      physics: the environment's physics.
      centres: (n, 3) centres of the hand's capsule.
      hand_quaternions: (n, 4) its quaternions, w first.

    Returns:
      (positions (n, 3), quaternions (n, 4)).
    """
    half = physics.bind(self._human.geoms[self._hand_segment()]).size[1]
    r_hand = rotations.quat_to_mat(hand_quaternions)
    r_hand_t = r_hand.transpose(0, 2, 1)
    axis = r_hand[:, :, 2]
    heading = axis * (1.0, 1.0, 0.0)
    upright = human_lib.row_norms(heading) < MIN_HEADING
    if upright.any():
      # A hand pointing straight up or down: the person's facing.
      yaw = self._player.placement[2]
      heading[upright] = (math.cos(yaw), math.sin(yaw), 0.0)
    heading /= human_lib.row_norms(heading)[:, None]
    end = centres + half * axis
    lowest = (layout.TABLE_TOP_Z + PRESENT_CLEARANCE - end[:, 2]) / (
        props.HAMMER_HUMAN_GRIP)
    sine = np.array([min(max(a, min(b, 0.0), -1.0), 0.0) for a, b in zip(
        axis[:, 2].tolist(), lowest.tolist())])[:, None]
    cosine = np.sqrt(1.0 - sine * sine)
    up = np.array([0.0, 0.0, 1.0])
    x = cosine * heading + sine * up
    y = cosine * up - sine * heading
    r_world = np.stack([x, y, np.cross(x, y)], axis=2)
    origin = end + props.HAMMER_HUMAN_GRIP * x
    positions = np.matmul(r_hand_t, (origin - centres)[:, :, None])[:, :, 0]
    local = np.matmul(r_hand_t, r_world)
    return positions, rotations.axes_to_quat(local[:, :, 0], local[:, :, 1],
                                             local[:, :, 2])

  def _presenting(self):
    """The person holds the hammer in the presenting grip (turned)."""
    return (self._holder() is not None and self._pick_grip is None
            and self._turn >= 1.0)

  def _works_before_physics_steps(self):
    return self._presenting()   # Changes only between RL steps.

  def _physics_step_writes(self, physics):
    """The presenting grip's weld data for each physics step of the RL
    step (what _before_physics_step sets), from the hand capsule's poses
    the person's playback shows at those steps."""
    target, index = self._human.grip_slots(physics, self._hammer.body)
    middles, quaternions = self._playback.segment_poses(
        self._hand_segment())
    values = self._human.grip_rows(*self.presenting_grips(
        physics, middles, quaternions))
    return ((target, index, values),)

  def _before_physics_step(self, physics):
    if self._presenting():
      # The presenting grip at every physics step: a fixed weld to the
      # hand's frame would also turn the hammer with the frame's roll about
      # the hand's axis (arbitrary for a capsule; it jumps where the
      # shoulder line that fixes it nears the hand's axis,
      # Human.set_keypoints) and with the hand's pitch into the table.
      self._human.set_grip(physics, self._hammer.body,
                           *self.presenting_grip(physics))

  def _reachable_target(self, target):
    """Whether the robot reaches the put-down over `target`."""
    return common.top_grasp_reachable(
        self._ik, self._collision_checker, target,
        self._robot.description.q_home, PUT_DOWN_ABOVE, PUT_DOWN_APPROACH)

  def _sample_target(self, random_state):
    for _ in range(TARGET_ATTEMPTS):
      target = self._sample_in_region(random_state)
      if self._reachable_target(target):
        return target
    raise RuntimeError(
        f'HumanToRobot: no reachable table target for '
        f'{self._robot.description.name} in {TARGET_ATTEMPTS} draws in '
        f'{self._region}')

  def _initialize_task(self, physics, random_state):
    self._reset_flags()
    self._holding_hand = self._player.clip.holding_hand or 'right'
    self._picked = False
    self._pick_grip = None
    self._turn = 0.0
    target = self._sample_target(random_state)
    self._marker.set_mocap_position(physics, target)
    # The hammer where this clip's hand picks it, head towards the robot,
    # the palm over its human grip point.
    pick = np.array(self._player.targets_world['object_pick'], dtype=float)
    yaw = self._player.placement[2]    # the human faces -x at yaw pi.
    direction = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    grip = pick + [0.0, 0.0, REST_HEIGHT] + direction * (
        props.HAMMER_HUMAN_GRIP + self._hammer.grip_site.pos[0])
    self._place_hammer(physics, grip, yaw)
    physics.forward()
    if self._player.clip.keyframes[0] == 0:
      self._start_in_hand(physics)

  def _start_in_hand(self, physics):
    """A clip whose pick keyframe is its first frame (recordings: the
    person walks in carrying the object, human/task_targets.py) starts with
    the hammer in the presenting grip of the holding hand."""
    self._grips.hold(physics, self._hammer.body, self._holding_hand,
                     self.presenting_grip(physics))
    physics.forward()
    self._hammer.set_velocity(physics, np.zeros(3), np.zeros(3))
    self._picked, self._turn = True, 1.0

  def _target(self, physics):
    return self._marker.mocap_position(physics)

  def _object_at_target(self, physics):
    delta = self._object_position(physics) - self._target(physics)
    return bool(np.linalg.norm(delta) <= SUCCESS_DISTANCE)

  def _clip_times(self):
    clip = self._player.clip
    return clip.keyframe_time(0), clip.keyframe_time(1)

  def _update_task(self, physics):
    self._update_common(physics)
    hand, handovers = self._hand(), 0
    t_pick, t_present = self._clip_times()
    first_clip = not self._clip_done
    clip_time = self._player.clip_time
    if (not self._picked and first_clip and not self._gripped
        and not self._player.in_transition and clip_time >= t_pick):
      grip = physics.bind(self._hammer.human_grip_site).xpos
      if np.linalg.norm(grip - self._palm_position(physics)) < PICK_DISTANCE:
        self._grips.hold(physics, self._hammer.body, hand)
        self._pick_grip = self._human.relative_pose(
            physics, self._hammer.body, hand)
        self._turn = 0.0
      self._picked = True
    if self._holder() is not None and self._pick_grip is not None:
      # Turning the hammer in the hand from the picking to the presenting
      # grip between the two keyframes (the capsule hand has no wrist);
      # then `_before_physics_step` holds it in the presenting grip.
      # Monotone: a backward warp while presenting keeps the presenting grip.
      s = min(max((clip_time - t_pick) / (t_present - t_pick), 0.0), 1.0)
      self._turn = max(self._turn, s * s * (3.0 - 2.0 * s))
      s = self._turn
      end_pos, end_quat = self.presenting_grip(physics)
      position = (1 - s) * self._pick_grip[0] + s * end_pos
      self._human.set_grip(physics, self._hammer.body, position,
                           rotations.slerp(self._pick_grip[1], end_quat, s))
      self._grips.mark_changed()
      if s >= 1.0:
        self._pick_grip = None
    # The person lets go of a grasp, not of fingers that merely touch both
    # sides of the hammer while the gripper is commanded open.
    closing = float(physics.bind(self._gripper.actuator).ctrl) > 0.0
    if self._holder() is not None and self._gripped and closing and (
        self._player.waiting_for == clip_lib.Event.object_taken):
      self._grips.release(physics, self._hammer.body)
      self._pick_grip = None
      handovers = 1
    self._at_target = self._object_at_target(physics)
    placed = (self._picked and self._holder() is None and self._at_target
              and not self._gripped)
    if placed and self._event_time is None:
      self._event_time = self._player.episode_time
    self._success = placed and self._completed()
    return {'success': float(self._success), 'handovers': handovers}

  def _human_events(self, physics):
    del physics
    events = []
    if self._holder() is None and self._gripped:
      events.append(clip_lib.Event.object_taken)
    if self._event_time is not None and self._at_target:
      events.append(self.EVENT)
    return events

  def _task_reward(self, physics):
    del physics
    if self._success:
      return 1.0
    if self._at_target:
      return 0.0
    if self._gripped:
      return GRIPPED_REWARD
    return -1.0
