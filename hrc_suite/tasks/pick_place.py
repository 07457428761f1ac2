"""Pick and place: move a cube to a target on the table while a person works
beside the robot (docs/reference_benchmark.md, Tasks).

* Scene: a 4 cm cube (`props.Cube`) and a flat target disc on the table,
  one on each side of the robot's centre line (the side is drawn per
  episode). Both are drawn uniformly in REGION_X (or the robot's own,
  `layout.cube_region_x`: the iiwa's) x REGION_ABS_Y (robot base
  frame) and kept only if gripper-down IK reaches the point above them
  (APPROACH_HEIGHT) and the grasp height from there without static or self
  collision, so every robot (the Schunk included) can do the task.
* The person (the 12 'pick_place' clips, station `layout.HUMAN_STATION_
  BESIDE`) picks and places their own things beside the workspace; the
  clips wait for no event. `pick_place/close` shifts the station
  CLOSE_STATION_SHIFT towards the robot's centre line, so the reaches enter
  the shared space (and can reach the +y half of the object regions).
* Success: the cube's centre within SUCCESS_DISTANCE of the target point
  (the centre of a cube resting on the target disc).
* Reward (sparse, reference): +1 at success, -0.25 while the cube is
  gripped, -1 otherwise; illegal contacts add the collision reward. Done at
  success (configurable); horizon 1000 RL steps; no reward delay; SSM.
* Observations: 'paper' = object gripped, EEF->object, EEF->target
  (world-frame vectors), gripper aperture, distances EEF->head / left hand /
  right hand; 'full' adds everything in `HrcTask` and the cube's and
  target's world positions, positions in the TCP frame, distances, the
  cube's quaternion and whether it is at the target.
* Counters: grasps (RL steps at which the cube became gripped),
  gripped_steps, object_at_target_steps.

The tool capsule (radius ~6.4 cm around the fingers) reaches 7.4 cm below
the TCP; collision prevention lets it into the table (the base's
FINGERTIP_TABLE_CLEARANCE) so the fingers can go down around the cube
(fingertips at least TABLE_CLEARANCE above the table).
"""

import math

from dm_control import mjcf
import numpy as np

from hrc_suite import layout
from hrc_suite import suite
from hrc_suite.control import ik as ik_lib
from hrc_suite.entities import markers
from hrc_suite.entities import props
from hrc_suite.tasks.runtime import actions
from hrc_suite.tasks import base
from hrc_suite.tasks import common
from hrc_suite.tasks.runtime import robot_payload

SUCCESS_DISTANCE = 0.1       # m, cube to target (reference)
REWARD_SUCCESS = common.SUCCESS_REWARD     # reference sparse reward
REWARD_GRIPPED = common.GRIPPED_REWARD
REWARD_OTHERWISE = common.IDLE_REWARD
# Object and target regions in the robot base frame (m): x ahead of the
# base, |y| to either side. Chosen where gripper-down IK of the Schunk (low,
# close workspace) and the KUKA iiwa (reaches from x ~0.35 m) overlap with
# the other robots': about 70 % of draws are reachable for those two, all
# for the others.
REGION_X = (0.30, 0.45)
REGION_ABS_Y = (0.10, 0.25)
# Sampled points are kept if the TCP reaches this far above them and, from
# there, down to the grasp (the Sawyer's capsule model self-collides 0.2 m
# above points on its +y side, where the reference expert hovers).
APPROACH_HEIGHT = 0.1        # m above the cube centre
# A grasp puts the TCP (1 cm above the fingertips) this far above the cube
# centre, at the Cartesian workspace's floor (actions.WORKSPACE_LOW, 3 cm
# above the table): the 4 cm pads cover the cube's upper 2 cm.
GRASP_TCP_ABOVE_CENTRE = 0.01    # m
SAMPLE_ATTEMPTS = 200
# Fingertips' minimum clearance above the table allowed by collision
# prevention (see module doc): goals may put the TCP down to 2.8 cm above
# the table, 2 mm below the Cartesian workspace floor (so IK's 1 mm
# tolerance never flags a goal there). The margin absorbs small overshoots
# of the shield's commanded motion past a goal (it reverses a descent only
# after ~0.1-0.4 s: 2 cm and more were seen with random actions); larger
# overshoots reach the table (a static contact).
TABLE_CLEARANCE = 0.018      # m
TARGET_RGBA = (0.1, 0.8, 0.2, 0.35)
TARGET_HALF_THICKNESS = 0.0005   # m, the drawn disc
# `close`: the beside station moved towards the robot's centre line (-y),
# the person then stands 0.15 m from the table's side edge instead of 0.3 m
# (layout: station y 1.05 m, table edge y 0.75 m), and hands at the clips'
# pick and place points come within ~0.15 m of the centre line.
CLOSE_STATION_SHIFT = 0.15   # m


@suite.register('pick_place', 'default',
                tags=('coexistence', 'sparse', 'ssm'))
class PickPlace(robot_payload.CarriesPayload, base.HrcTask):
  """Pick a cube up and put it on the target on the other side."""

  MOTIONS = 'pick_place'
  HUMAN_STATION = layout.HUMAN_STATION_BESIDE
  HUMAN_PLACEMENT_RANGE = (0.0, 0.0, 0.0)
  DEFAULT_SHIELD = 'ssm'
  DEFAULT_ACTION_SPACE = 'cartesian'
  REWARDS = ('sparse',)
  DEFAULT_REWARD_DELAY = 0
  HORIZON = 1000
  HAS_GRIPPER_ACTION = True
  OBSERVATION_PRESETS = {'paper': ('object_gripped', 'eef_to_object',
                                   'eef_to_target', 'gripper_aperture',
                                   'human_distances')}
  EXTRA_COUNTERS = ('grasps', 'gripped_steps', 'object_at_target_steps')
  FINGERTIP_TABLE_CLEARANCE = TABLE_CLEARANCE
  TASK_STATE = ('_target', '_object_side', '_success', '_gripped',
                '_distance')

  def _build_task(self):
    self._cube = props.Cube()
    self._arena.add_free_entity(self._cube)
    self._object_geoms.extend(self._cube.geoms)
    # The target marker's mocap frame is physics state, so snapshots carry
    # it: a flat disc whose radius is the success distance, on the table
    # under the target (the cube's centre).
    self._marker = markers.TargetMarker(
        radius=SUCCESS_DISTANCE, rgba=TARGET_RGBA, shape='disc',
        name='pick_place_target', half_thickness=TARGET_HALF_THICKNESS,
        offset=(0.0, 0.0, -self._cube.size / 2 + TARGET_HALF_THICKNESS))
    self._marker.attach_mocap(self._arena)
    self._ik = ik_lib.InverseKinematics(self._kinematics)
    self._region_x = layout.cube_region_x(self._robot.description.name,
                                          REGION_X)
    self._target = np.zeros(3)
    self._object_side = 1.0
    self._reset_progress()

  def _reset_progress(self):
    self._success = False
    self._gripped = False
    self._distance = math.inf

  # ---------------------------------------------------------------- props

  @property
  def cube(self) -> props.Cube:
    """The cube to pick and place."""
    return self._cube

  @property
  def region_x(self) -> tuple[float, float]:
    """x range (m, base frame) of the cube and target: REGION_X, or the
    robot's own (layout.cube_region_x)."""
    return self._region_x

  @property
  def target_position(self) -> np.ndarray:
    """World position of the target point (a resting cube's centre)."""
    return self._target.copy()

  def object_position(self, physics: mjcf.Physics) -> np.ndarray:
    """The cube's world position.

    Args:
      physics: the environment's physics.

    Returns:
      (3,) position.
    """
    return self._cube.position(physics)

  def _reachable(self, centre):
    """True if the TCP reaches above `centre` and down to grasp it, gripper
    down, collision free."""
    return common.top_grasp_reachable(
        self._ik, self._collision_checker, centre,
        self._robot.description.q_home, GRASP_TCP_ABOVE_CENTRE,
        APPROACH_HEIGHT - GRASP_TCP_ABOVE_CENTRE, actions.GRIPPER_YAW)

  def _sample_point(self, side, random_state):
    region_y = (side * REGION_ABS_Y[0], side * REGION_ABS_Y[1])
    return common.sample_table_point(
        random_state, self._kinematics.base_pose, self.region_x, region_y,
        layout.TABLE_TOP_Z + self._cube.size / 2, self._reachable,
        SAMPLE_ATTEMPTS, f'PickPlace point on side {side:+.0f} for '
        f'{self._robot.description.name}')

  def _initialize_task(self, physics, random_state):
    self._object_side = 1.0 if random_state.uniform() < 0.5 else -1.0
    start = self._sample_point(self._object_side, random_state)
    self._target = self._sample_point(-self._object_side, random_state)
    self._cube.set_pose(physics, position=start,
                        quaternion=np.array([1.0, 0.0, 0.0, 0.0]))
    self._cube.set_velocity(physics, velocity=np.zeros(3),
                            angular_velocity=np.zeros(3))
    self._marker.set_mocap_position(physics, self._target)
    physics.forward()
    self._reset_progress()
    self._distance = float(np.linalg.norm(start - self._target))

  # ------------------------------------------------------------- progress

  def _update_task(self, physics):
    gripped = self._gripper.is_grasping(physics, self._cube.body)
    grasped_now = gripped and not self._gripped
    self._gripped = gripped
    self._distance = float(np.linalg.norm(
        self._cube.position(physics) - self._target))
    self._success = self._distance <= SUCCESS_DISTANCE
    return {'success': float(self._success),
            'object_distance': self._distance,
            'grasps': int(grasped_now), 'gripped_steps': int(gripped),
            'object_at_target_steps': int(self._success)}

  def _held_bodies(self):
    return (self._cube.body,) if self._gripped else ()

  def _task_reward(self, physics):
    del physics
    return common.object_reward(self._success, self._gripped)

  def _task_reward_range(self):
    return (REWARD_OTHERWISE, REWARD_SUCCESS)

  # ---------------------------------------------------------- observables

  def _task_observables(self):
    return common.object_target_observables(
        self._robot.tcp_frame, self._cube,
        lambda physics: self._target, lambda: self._gripped,
        SUCCESS_DISTANCE)


@suite.register('pick_place', 'close', tags=('coexistence', 'sparse', 'ssm'))
class PickPlaceClose(PickPlace):
  """Pick and place with the person CLOSE_STATION_SHIFT closer."""

  HUMAN_STATION = (layout.HUMAN_STATION_BESIDE[0],
                   layout.HUMAN_STATION_BESIDE[1] - CLOSE_STATION_SHIFT,
                   layout.HUMAN_STATION_BESIDE[2])
