"""Object inspection: the robot picks a cube from the table and holds it in
front of a person, who inspects it and leaves (docs/reference_benchmark.md,
Tasks).

* Scene: a 4 cm cube on the table, uniform in OBJECT_REGION_X x
  OBJECT_REGION_Y (robot base frame, where the Schunk's and the iiwa's
  gripper-down workspaces overlap the others'), kept only if gripper-down
  IK reaches the grasp and the point HOVER_HEIGHT above it without static
  or self-collision; the person stands across the table.
* Collision prevention lets the tool capsule (radius ~6.4 cm around the
  fingers) into the table by its radius minus TABLE_CLEARANCE, so the
  fingertips can reach a cube on the table (FINGERTIP_TABLE_CLEARANCE).
* Human: the clip approaches and waits (idle phase 'object_presented')
  until the cube is gripped and within SUCCESS_DISTANCE of the inspection
  target, then inspects it with the hands and retreats.
* Inspection target: the clip's 'inspection_point' (in front of the person,
  0.33-0.53 m above the table); where a policy holding the cube cannot bring
  its centre there (short robots, e.g. the Schunk; recorded people who hold
  their hands high), the nearest point on the segment from it towards the
  robot's home TCP where it can. Reachable means as Cartesian actions reach
  it: local gripper-down IK steps (CARTESIAN_STEP) along the straight line
  from the home TCP to the TCP over the cube, each from the last solution,
  free of static and self-collision and inside the action box, for the TCP
  GRASP_TCP_ABOVE_CENTRE above the cube's centre and up to SLIP_ALLOWANCE
  higher (the cube slips down in the pads while carried). A target checked
  for the TCP at the point itself with IK restarts from random postures lay
  at the edge of the reach, 1-2 cm too high for the TCP over a held cube:
  the Panda's expert stalled with every IK failing. Computed once per clip.
* Success (delayed by the retreat): the clip ends after the event and the
  cube stayed within SUCCESS_DISTANCE of the target from the event on. The
  next clip (if the episode goes on) asks again.
* Reward (sparse, as pick and place): +1 success, -0.25 while the cube is
  gripped, -1 otherwise. SSM shield; horizon 1000 RL steps.
* Observations: 'paper' = object gripped, EEF->object, EEF->target,
  gripper aperture, distances EEF->head / left hand / right hand.
  'full' adds the shared observables and the cube's and target's world
  positions, positions in the TCP frame, distances, the cube's quaternion
  and whether it is at the target.
* Counters: presentations (RL steps at which the waiting person got the
  cube). The clip's end is the base's `clip_ended`.
"""

import numpy as np

from hrc_suite import layout
from hrc_suite import rotations
from hrc_suite import suite
from hrc_suite.control import ik as ik_lib
from hrc_suite.entities import markers
from hrc_suite.entities import props
from hrc_suite.human import clip as clip_lib
from hrc_suite.tasks.runtime import actions
from hrc_suite.tasks import base
from hrc_suite.tasks import common
from hrc_suite.tasks.runtime import robot_payload

EVENT = clip_lib.Event.object_presented
SUCCESS_DISTANCE = 0.1       # m, object to inspection target (reference)
GRIPPED_REWARD = common.GRIPPED_REWARD   # reference: as pick and place
SUCCESS_REWARD = common.SUCCESS_REWARD
IDLE_REWARD = common.IDLE_REWARD
OBJECT_ATTEMPTS = 100        # cube placements tried before giving up
# Cube region in the robot base frame (m); see the module doc. x: the
# robot's own where its layout gives one (layout.cube_region_x: the iiwa's).
OBJECT_REGION_X = (0.30, 0.45)
OBJECT_REGION_Y = (-0.2, 0.2)
HOVER_HEIGHT = 0.1           # m above the grasp, checked for IK
# The TCP (1 cm above the fingertips) this far above the cube's centre in
# a grasp: the 4 cm pads cover the cube's upper 3 cm.
GRASP_TCP_ABOVE_CENTRE = 0.005   # m
TABLE_CLEARANCE = 0.005      # m, fingertips above the table (see doc)
OBJECT_MAX_YAW = 0.3         # rad, cube heading about the fingers' axes
# How far a gripped cube slides down in the pads while it is carried: the
# TCP was 0.015-0.020 m above the centre of a carried cube (Panda, recorded
# inspection clips; docs/tasks.md), 0.010-0.015 m below the grasp's.
SLIP_ALLOWANCE = 0.02        # m
TARGET_RADIUS = 0.02         # m, the visual marker
TARGET_RGBA = (0.2, 0.4, 0.9, 0.4)


@suite.register('inspection', 'default',
                tags=('object_handling', 'sparse', 'delayed', 'ssm'))
class Inspection(robot_payload.CarriesPayload, base.HrcTask):
  """Hold a cube at the person's inspection point until they leave."""

  MOTIONS = 'inspection'
  EVENTS = (EVENT,)   # the person waits until the cube is presented
  HUMAN_STATION = layout.HUMAN_STATION_ACROSS
  DEFAULT_SHIELD = 'ssm'
  DEFAULT_ACTION_SPACE = 'cartesian'
  REWARDS = ('sparse',)
  DEFAULT_REWARD_DELAY = 0     # the retreat delays success itself
  HORIZON = 1000
  HAS_GRIPPER_ACTION = True
  OBSERVATION_PRESETS = {'paper': ('gripper_aperture', 'human_distances',
                                   'object_gripped', 'eef_to_object',
                                   'eef_to_target')}
  EXTRA_COUNTERS = ('presentations',)
  FINGERTIP_TABLE_CLEARANCE = TABLE_CLEARANCE
  TASK_STATE = ('_target', '_inspecting', '_kept', '_success', '_gripped',
                '_at_target', '_presented')

  def _build_task(self):
    self._cube = props.Cube()
    self._arena.add_free_entity(self._cube)
    self._object_geoms.extend(self._cube.geoms)
    # Visual-only mocap marker: its position is physics state.
    self._marker = markers.TargetMarker(
        radius=TARGET_RADIUS, rgba=TARGET_RGBA, name='inspection_target')
    self._marker.attach_mocap(self._arena)
    self._ik = ik_lib.InverseKinematics(self._kinematics)
    self._target_cache = {}
    self._target = np.zeros(3)
    self._reset_progress()

  def _reset_progress(self):
    self._inspecting = False
    self._kept = False
    self._success = False
    self._gripped = False
    self._at_target = False
    self._presented = 0

  # ------------------------------------------------------ objects, goals

  @property
  def cube(self) -> props.Cube:
    """The cube the robot shows the person."""
    return self._cube

  @property
  def target_position(self) -> np.ndarray:
    """(3,) world position where the cube is to be held up."""
    return self._target.copy()

  def _reachable(self, point, q_home):
    """Whether Cartesian actions from home bring a held cube's centre to
    `point` (see the module doc)."""
    home = self._kinematics.tcp_pose(q_home)[:3, 3]
    grasp = np.asarray(point, dtype=float) + (0.0, 0.0,
                                              GRASP_TCP_ABOVE_CENTRE)
    slipped = grasp + (0.0, 0.0, SLIP_ALLOWANCE)
    low, high = actions.workspace_box(self._kinematics)
    if not all(np.all((p >= low) & (p <= high)) for p in (grasp, slipped)):
      return False
    steps = int(np.ceil(np.linalg.norm(slipped - home)
                        / actions.CARTESIAN_STEP))
    waypoints = [home + (slipped - home) * (k + 1) / max(steps, 1)
                 for k in range(steps)] + [grasp]
    q = q_home
    for waypoint in waypoints:
      result = self._ik.solve(waypoint, q, self.CARTESIAN_YAW)
      if not result.success or self._collision_checker.in_collision(
          result.q):
        return False
      q = result.q
    return True

  def _clip_target(self):
    """The current clip's inspection point where the robot reaches it
    (layout.fit_into_reach decides where a point out of reach moves)."""
    clip = self._player.clip
    if clip.name not in self._target_cache:
      point = np.asarray(self._player.targets_world['inspection_point'])
      q_home = self._robot.description.q_home
      self._target_cache[clip.name] = layout.fit_into_reach(
          point, self._kinematics.tcp_pose(q_home)[:3, 3],
          lambda candidate: self._reachable(candidate, q_home))
    return self._target_cache[clip.name].copy()

  def _initialize_task(self, physics, random_state):
    self._reset_progress()
    q_home = self._robot.description.q_home
    position = common.sample_table_point(
        random_state, self._kinematics.base_pose,
        layout.cube_region_x(self._robot.description.name, OBJECT_REGION_X),
        OBJECT_REGION_Y, layout.TABLE_TOP_Z + self._cube.size / 2,
        lambda point: common.top_grasp_reachable(
            self._ik, self._collision_checker, point, q_home,
            GRASP_TCP_ABOVE_CENTRE, HOVER_HEIGHT, actions.GRIPPER_YAW),
        OBJECT_ATTEMPTS,
        f'Inspection cube position for {self._robot.description.name}')
    yaw = random_state.uniform(-OBJECT_MAX_YAW, OBJECT_MAX_YAW)
    self._cube.set_pose(physics, position, rotations.yaw_to_quat(yaw))
    self._target = self._clip_target()
    self._marker.set_mocap_position(physics, self._target)
    physics.forward()

  # ------------------------------------------------------------ progress

  def _object_position(self, physics):
    return self._cube.position(physics)

  def _update_task(self, physics):
    self._gripped = props.is_gripped(physics, self._gripper, self._cube)
    distance = float(np.linalg.norm(self._object_position(physics)
                                    - self._target))
    self._at_target = distance <= SUCCESS_DISTANCE
    if self._inspecting and not self._at_target:
      self._kept = False
    self._success = False
    if self.clip_ended:   # The clip (approach, inspection, retreat) ended.
      self._success = self._inspecting and self._kept
      self._inspecting, self._kept = False, False
      self._target = self._clip_target()
      self._marker.set_mocap_position(physics, self._target)
    # The person waits for the cube: the base triggers the event right
    # after this (`_human_events`), which ends the wait.
    self._presented = int(self._gripped and self._at_target
                          and self._player.waiting_for == EVENT)
    if self._presented:
      self._inspecting, self._kept = True, True
    return {'success': float(self._success), 'target_distance': distance,
            'object_gripped': float(self._gripped),
            'object_at_target': float(self._at_target),
            'presentations': self._presented}

  def _human_events(self, physics):
    del physics
    return (EVENT,) if self._presented else ()

  def _held_bodies(self):
    return (self._cube.body,) if self._gripped else ()

  def _task_reward(self, physics):
    del physics
    return common.object_reward(self._success, self._gripped)

  def _task_reward_range(self):
    return (IDLE_REWARD, SUCCESS_REWARD)

  # -------------------------------------------------------- observables

  def _task_observables(self):
    return common.object_target_observables(
        self._robot.tcp_frame, self._cube,
        lambda physics: self._target, lambda: self._gripped,
        SUCCESS_DISTANCE)
