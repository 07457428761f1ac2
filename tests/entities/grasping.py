"""Test helper: a robot with the parallel gripper picks a prop up at its grip
site (IK to the site's frame, jerk-limited moves, joint tracking)."""

import numpy as np

from hrc_suite import layout
from hrc_suite.control import controller as controller_lib
from hrc_suite.control import ik as ik_lib
from hrc_suite.control import kinematics
from hrc_suite.control import trajectory
from hrc_suite.entities import gripper as gripper_lib
from hrc_suite.entities import props
from hrc_suite.entities import robot as robot_lib
from hrc_suite.entities import workcell


def _base(description):
  """World pose of the robot's base on its mount (layout.robot_mount)."""
  return layout.robot_mount(description.name).base_pose()


def scene(*free_entities, robot_name='ur5e'):
  """Workcell, robot with gripper (None, None if robot_name is None) and the
  entities as free bodies. Returns (arena, robot, gripper)."""
  arena = workcell.Workcell()
  robot = gripper = None
  if robot_name is not None:
    robot = robot_lib.make_robot(robot_name)
    gripper = robot.attach_gripper(gripper_lib.ParallelGripper())
    arena.attach_robot(robot)
  for entity in free_entities:
    arena.add_free_entity(entity)
  return arena, robot, gripper


def yaw_of(site_binding):
  """Heading of a site's x axis about world z."""
  x_axis = site_binding.xmat.reshape(3, 3)[:, 0]
  return float(np.arctan2(x_axis[1], x_axis[0]))


class PickUp:
  """Moves the robot's TCP onto `site` (gripper down, the site's yaw),
  closes and lifts; records whether the prop stays gripped."""

  def __init__(self, physics, robot, gripper, prop, site, lift=0.15):
    self.physics, self.robot, self.gripper, self.prop = (physics, robot,
                                                         gripper, prop)
    description = robot.description
    model = kinematics.KinematicModel(description,
                                      base_pose=_base(description),
                                      tcp_offset=gripper_lib.TCP_OFFSET)
    solver = ik_lib.InverseKinematics(model)
    physics.forward()
    self.site = physics.bind(site)
    yaw = yaw_of(self.site)
    grasp = solver.solve(self.site.xpos.copy(), description.q_home, yaw)
    above = solver.solve(self.site.xpos + (0, 0, lift), grasp.q, yaw)
    if not (grasp.success and above.success):
      raise AssertionError(f'IK failed for a grasp at {self.site.xpos}')
    self.q_grasp, self.q_above = grasp.q, above.q
    robot.set_joint_positions(physics, above.q)
    physics.forward()
    self.controller = controller_lib.JointTrackingController(physics, robot)
    self.tcp = physics.bind(robot.tcp_site)
    self.held = []   # (gripped, |TCP - grip site|) per step once closed.

  def follow(self, path, command, record=False, hook=None):
    for q, dq, ddq in zip(*path):
      self.controller(self.physics, q, dq, ddq)
      self.gripper.set_command(self.physics, command)
      self.physics.step()
      if record:
        self.held.append((props.is_gripped(self.physics, self.gripper,
                                           self.prop),
                          np.linalg.norm(self.tcp.xpos - self.site.xpos)))
      if hook is not None:
        hook()

  def rest(self, q, steps):
    zeros = np.zeros((steps, self.robot.dof))
    return np.repeat(q[None], steps, 0), zeros, zeros

  def move(self, q0, q1):
    return trajectory.jerk_limited_trajectory(self.robot.description,
                                              [q0, q1], limits='ltt')

  def pick(self):
    """Approach open, close for 0.2 s, lift; True if the approach did not
    already grip the prop."""
    self.follow(self.rest(self.q_above, 75), -1)
    self.follow(self.move(self.q_above, self.q_grasp), -1)
    untouched = not props.is_gripped(self.physics, self.gripper, self.prop)
    self.follow(self.rest(self.q_grasp, 50), 1)
    self.follow(self.move(self.q_grasp, self.q_above), 1, record=True)
    return untouched

  def hold(self, seconds, hook=None):
    steps = int(round(seconds / workcell.PHYSICS_TIMESTEP))
    self.follow(self.rest(self.q_above, steps), 1, record=True, hook=hook)
