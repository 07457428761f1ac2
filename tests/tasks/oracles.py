"""Scripted privileged oracles for task tests: drive the TCP to Cartesian
waypoints in either action space (joint space through gripper-down IK)."""

import numpy as np

from hrc_suite.tasks.runtime import actions


class WaypointDriver:
  """Actions that move the TCP towards a world point, gripper -1/+1."""

  def __init__(self, env, yaw=actions.GRIPPER_YAW):
    self.env, self.task = env, env.task
    self.yaw = yaw
    self._ik = None
    if self.task.action_space_name == 'joint':
      from hrc_suite.control import ik as ik_lib
      self._ik = ik_lib.InverseKinematics(self.task.kinematics)

  def tcp(self):
    return self.task.robot.tcp_pose(self.env.physics)[0]

  def action(self, point, gripper):
    physics, task = self.env.physics, self.task
    if self._ik is None:   # Straight towards the point (direction kept).
      delta = (np.asarray(point) - self.tcp()) / actions.CARTESIAN_STEP
      delta /= max(1.0, np.abs(delta).max())
      return np.append(delta, gripper)
    q = task.robot.joint_positions(physics)
    # Small Cartesian steps keep the joint path close to a straight line.
    step = np.asarray(point) - self.tcp()
    norm = np.linalg.norm(step)
    if norm > actions.CARTESIAN_STEP:
      step *= actions.CARTESIAN_STEP / norm
    result = self._ik.solve(self.tcp() + step, q, self.yaw)
    delta = np.clip((result.q - q) / actions.JOINT_STEP, -1.0, 1.0)
    return np.append(delta, gripper)
