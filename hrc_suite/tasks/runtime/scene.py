"""The scene every HrcTask builds before its own entities.

The workcell with its table, the robot with the parallel gripper, the
person (mocap capsules), and the models built from them: the kinematic
model for IK, the shield, collision prevention (the gripper's enclosing
capsule as the tool) and the self-collision check, the agent's action
space, and the person's clips with their player and playback. `build`
makes them from a task's facts (`defaults.TaskDefaults`) and its checked
options (`options.TaskOptions`); the task adds its own entities after.
For a compiled physics the scene gives the robot's joint addresses and
the contact monitor (`bind`) and starts an episode (`start_episode`). A
task shows the scene's parts as read-only attributes (`SceneParts`).
"""

import dataclasses
import operator
from typing import Any, NamedTuple, Tuple

import numpy as np

from hrc_suite import layout
from hrc_suite.control import kinematics as kinematics_lib
from hrc_suite.entities import gripper as gripper_lib
from hrc_suite.entities import human as human_lib
from hrc_suite.entities import human_playback
from hrc_suite.entities import robot as robot_lib
from hrc_suite.entities import workcell as workcell_lib
from hrc_suite.human import player as player_lib
from hrc_suite.safety import collision_prevention as cp_lib
from hrc_suite.safety import contact_energy
from hrc_suite.safety import robot_energy
from hrc_suite.safety import shield as shield_lib
from hrc_suite.safety.shield import modes
from hrc_suite.tasks.runtime import actions
from hrc_suite.tasks.runtime import contact_energies
from hrc_suite.tasks.runtime import contacts
from hrc_suite.tasks.runtime import motions as motions_lib
from hrc_suite.tasks.runtime import self_collision as self_collision_lib


class JointIndices(NamedTuple):
  """The robot's addresses in a compiled physics."""
  qpos: np.ndarray          # the arm's joints in qpos
  qvel: np.ndarray          # the arm's joints in qvel
  finger_qpos: np.ndarray   # the gripper's finger joints in qpos


@dataclasses.dataclass(frozen=True)
class Scene:
  """A task's shared entities and the models made from them."""
  arena: workcell_lib.Workcell
  robot: Any                         # robot_lib.make_robot's entity
  gripper: gripper_lib.ParallelGripper
  human: human_lib.Human
  kinematics: kinematics_lib.KinematicModel
  # (p1, p2, radius): the gripper's enclosing capsule in the last link's
  # frame, as the shield and collision prevention use it.
  tool_capsule: Tuple[np.ndarray, np.ndarray, float]
  shield: shield_lib.Shield
  # m the tool capsule may dip into the table (FINGERTIP_TABLE_CLEARANCE).
  tool_table_allowance: float
  collision_checker: cp_lib.CollisionPrevention
  self_colliding: self_collision_lib.SelfCollision
  action_space: Any                  # actions.make_action_space's
  player: player_lib.Player
  playback: human_playback.HumanPlayback

  def bind(self, physics, object_geoms, critical_speed, compiled):
    """The contact monitor and the robot's joint addresses of a compiled
    physics. The monitor measures every robot-human contact's energy
    (tasks/runtime/contact_energies.py; the gripper as the payload, the shield's
    clamp geometry and static boxes) and, in the shield mode 'pfl_energy', judges the
    contact by it.

    Args:
      physics: the compiled physics.
      object_geoms: the task's object geoms (contacts.ContactMonitor).
      critical_speed: m/s, robot speed above which a human contact is
        critical.
      compiled: whether the monitor classifies in compiled kernels.

    Returns:
      (contacts.ContactMonitor, JointIndices).
    """
    joints = physics.bind(self.robot.joints)
    static = list(self.arena.static_geoms)
    robot_geoms = list(self.robot.link_geoms) + list(self.gripper.geoms)
    shield = self.shield
    clamp = shield.energy.clamp_geometry
    energies = contact_energies.ContactEnergies(
        contact_energy.ContactEnergyMeter(
            self.robot.description,
            robot_energy.gripper_payload(self.robot.description.name)),
        physics.model.ngeom,
        physics.bind(list(self.robot.link_geoms)).element_id,
        physics.bind(list(self.gripper.geoms)).element_id,
        physics.bind(list(self.human.geoms)).element_id,
        physics.bind(static).element_id,
        clamp.clampable, shield.robot.frame_index, physics.data.ptr,
        physics.model.geom_size, clamp.box_min, clamp.box_max)
    monitor = contacts.ContactMonitor(
        physics, static, robot_geoms, object_geoms, self.human.geoms,
        critical_speed=critical_speed, robot_dofs=joints.dofadr,
        robot_qpos=joints.qposadr, compiled=compiled, energies=energies,
        critical_by_energy=shield.mode == modes.PflEnergy.name)
    fingers = physics.bind(self.gripper.finger_joints)
    return monitor, JointIndices(
        qpos=np.array(joints.qposadr), qvel=np.array(joints.dofadr),
        finger_qpos=np.array(fingers.qposadr))

  def start_episode(self, physics, indices, random_state):
    """Puts the robot at rest at its home pose, the gripper half open and
    commanded open, the shield at home, and the person at the start of
    the episode's first clip.

    Args:
      physics: the episode's physics.
      indices: the physics' JointIndices (`bind`).
      random_state: the episode's random numbers (the person's clips).
    """
    data = physics.data
    q_home = self.robot.description.q_home
    data.qpos[indices.qpos] = q_home
    data.qvel[indices.qvel] = 0.0
    data.qpos[indices.finger_qpos] = gripper_lib.MAX_APERTURE / 2
    self.gripper.set_command(physics, -1.0)
    self.player.reset(random_state)
    self.playback.show_current(physics)
    self.shield.reset(q_home, 0.0)


def _part(name, doc):
  """A read-only property: the part `name` of the task's scene."""
  return property(operator.attrgetter(f'_scene.{name}'), doc=doc)


class SceneParts:
  """The parts of a task's scene (its `_scene`, a Scene) as its read-only
  attributes (HrcTask has them), and the Cartesian actions' yaw."""
  root_entity = arena = _part('arena', 'The workcell (entities/).')
  robot = _part('robot', 'The robot arm (entities/robot.py).')
  gripper = _part('gripper', 'The parallel gripper (entities/gripper.py).')
  human = _part('human', 'The person (entities/human.py).')
  player = _part('player', "The person's clip player (human/player.py).")
  shield = _part('shield', 'The shield (safety/shield/shield.py).')
  kinematics = _part('kinematics', "The robot's kinematic model for IK.")
  tool_capsule = _part('tool_capsule',
                       '(p1, p2, radius) in the last link frame.')
  tool_table_allowance = _part('tool_table_allowance',
                               'm the tool capsule may dip into the table.')
  collision_checker = _part('collision_checker', 'Collision prevention.')
  action_space_name = _part('action_space.name', "'joint' or 'cartesian'.")

  def set_cartesian_yaw(self, yaw: float) -> None:
    """Sets the gripper yaw of Cartesian actions' IK goals (nothing in
    joint action spaces).

    Args:
      yaw: rad about world z.
    """
    if self._scene.action_space.name == 'cartesian':
      self._scene.action_space.yaw = yaw


def build(defaults, options, motions=None, outside_human_model='refuse'):
  """The scene of a task.

  Args:
    defaults: the task's `defaults.TaskDefaults` (table, grip force,
      fingertip clearance, Cartesian yaw, motion library, events, human
      station and placement range).
    options: the task's `options.TaskOptions`.
    motions: the task's motions argument (`options.TaskOptions`; None: the
      shipped library `defaults.motions`).
    outside_human_model: 'refuse' or 'allow' (`motions.check_motions`).

  Returns:
    A Scene.
  """
  fast_path = options.fast_path
  arena = workcell_lib.Workcell(table=defaults.table)
  robot = robot_lib.make_robot(options.robot)
  gripper = robot.attach_gripper(
      gripper_lib.ParallelGripper(grip_force=defaults.grip_force))
  arena.attach_robot(robot)
  human = human_lib.Human()
  human.attach_to(arena)

  # Models of the robot for IK, the shield and collision prevention.
  description = robot.description
  base_pose = layout.robot_mount(description.name).base_pose()
  kinematic_model = kinematics_lib.KinematicModel(
      description, base_pose, tcp_offset=gripper_lib.TCP_OFFSET)
  p1, p2, radius = gripper.enclosing_capsule()
  rotation, translation = (description.flange_rotation,
                           description.flange_translation)
  tool_capsule = (translation + rotation @ p1, translation + rotation @ p2,
                  radius)
  tool_table_allowance = 0.0
  if defaults.fingertip_table_clearance is not None:
    # The capsule's lowest point is `radius` below the fingertips (its
    # end point, gripper.enclosing_capsule).
    tool_table_allowance = radius - defaults.fingertip_table_clearance
  collision_checker = cp_lib.CollisionPrevention(
      description, base_pose=base_pose, tool_capsule=tool_capsule,
      tool_table_allowance=tool_table_allowance, compiled=fast_path,
      table=defaults.table)
  # The shield's static boxes (energy PFL's clamping) are those collision
  # prevention keeps the robot out of; its payload the gripper's
  # (the shield's `energy.set_payload` changes it).
  shield = shield_lib.Shield(
      description, mode=options.shield,
      cycle_time=options.physics_timestep, base_pose=base_pose,
      tool_capsule=tool_capsule, v_safe=options.v_safe,
      static_boxes=dict(zip(collision_checker.box_names,
                            zip(collision_checker.box_min,
                                collision_checker.box_max))))
  self_colliding = self_collision_lib.SelfCollision(
      collision_checker, compiled=fast_path)
  action_space = actions.make_action_space(
      options.action_space, kinematic_model, yaw=defaults.cartesian_yaw)
  # The shipped library's documented fast phases (hammer blows,
  # docs/motion_library.md) are played; they are counted in
  # steps_outside_human_model like any clip over the model.
  clips = motions_lib.check_motions(
      motions_lib.load_motions(motions, defaults.motions), defaults.motions,
      defaults.events, defaults.human_station,
      shield.human.config.v_max,
      'allow' if motions is None else outside_human_model)
  player = player_lib.Player(
      clips, station=defaults.human_station,
      placement_range=defaults.human_placement_range)
  playback = human_playback.HumanPlayback(
      human, player, options.shield_substeps, compiled=fast_path)
  return Scene(
      arena=arena, robot=robot, gripper=gripper, human=human,
      kinematics=kinematic_model, tool_capsule=tool_capsule, shield=shield,
      tool_table_allowance=tool_table_allowance,
      collision_checker=collision_checker, self_colliding=self_colliding,
      action_space=action_space, player=player, playback=playback)
