"""Workcell arena: compiles with every robot, contacts, cameras render."""

import os

os.environ.setdefault('MUJOCO_GL', 'egl')

# pylint: disable=g-import-not-at-top,wrong-import-position
import numpy as np
import pytest
from dm_control import composer
from dm_control import mjcf
from dm_control.composer.observation import observable

from hrc_suite import layout
from hrc_suite.entities import collision_groups
from hrc_suite.entities import gripper as gripper_lib
from hrc_suite.entities import robot as robot_lib
from hrc_suite.entities import workcell as workcell_lib

CAMERAS = ('front', 'side', 'top', 'human_view')


def _scene(name, gripper=True):
  arena = workcell_lib.Workcell()
  robot = robot_lib.make_robot(name)
  if gripper:
    robot.attach_gripper(gripper_lib.ParallelGripper())
  arena.attach_robot(robot)
  return arena, robot


def _centre(description):
  lim = description.limits
  return np.where((lim.q_min <= 0) & (lim.q_max >= 0), 0.0,
                  (lim.q_min + lim.q_max) / 2)


@pytest.mark.parametrize('name', robot_lib.ROBOTS)
def test_every_robot_compiles_in_the_workcell_without_contact(name):
  arena, robot = _scene(name)
  physics = mjcf.Physics.from_mjcf_model(arena.mjcf_model)
  assert physics.model.opt.timestep == workcell_lib.PHYSICS_TIMESTEP
  robot.set_joint_positions(physics, _centre(robot.description))
  physics.forward()
  # Base frame on the pedestal, facing +x.
  base = physics.bind(robot.link_bodies[0])
  frames = robot.description.forward_kinematics(_centre(robot.description))
  np.testing.assert_allclose(
      base.xpos, frames[0, :3, 3] +
      layout.robot_mount(name).base_position, atol=1e-12)
  np.testing.assert_allclose(base.xmat.reshape(3, 3), frames[0, :3, :3],
                             atol=1e-12)
  assert physics.data.ncon == 0   # Nothing touches at the centre pose.


def test_static_geometry_matches_layout():
  arena = workcell_lib.Workcell()
  physics = mjcf.Physics.from_mjcf_model(arena.mjcf_model)
  table = physics.bind(arena.table)
  assert table.xpos[2] + table.size[2] == pytest.approx(layout.TABLE_TOP_Z)
  assert table.xpos[0] - table.size[0] == pytest.approx(layout.TABLE_X[0])
  assert table.xpos[0] + table.size[0] == pytest.approx(layout.TABLE_X[1])
  assert table.xpos[1] + table.size[1] == pytest.approx(layout.TABLE_Y[1])
  pedestal = physics.bind(arena.pedestal)
  assert pedestal.xpos[2] + pedestal.size[2] == pytest.approx(
      layout.ROBOT_BASE_POS[2])
  static = physics.bind(arena.static_geoms)
  assert set(static.contype) == {collision_groups.STATIC}
  names = {g.name for g in arena.static_geoms}
  assert {'floor', 'table_top', 'pedestal'} <= names


def test_a_falling_arm_hits_the_table():
  arena, robot = _scene('panda')
  physics = mjcf.Physics.from_mjcf_model(arena.mjcf_model)
  # Stretched forward over the table, then unpowered: it falls onto it.
  robot.set_joint_positions(physics, [0, 0.9, 0, -0.5, 0, 1.5, 0])
  physics.forward()
  assert physics.data.ncon == 0
  robot_geoms = set(physics.bind(robot.link_geoms).element_id) | set(
      physics.bind(robot.gripper.geoms).element_id)
  table = physics.bind(arena.table).element_id
  touched = False
  for _ in range(500):
    physics.step()
    contacts = physics.data.contact[:physics.data.ncon]
    pairs = set(zip(contacts.geom1, contacts.geom2))
    touched |= any((a == table and b in robot_geoms) or
                   (b == table and a in robot_geoms) for a, b in pairs)
  assert touched
  # The table holds it: nothing sinks far below the table top.
  lowest = (physics.bind(robot.link_geoms).xpos[:, 2] -
            physics.bind(robot.link_geoms).size[:, 0]).min()
  assert lowest > layout.TABLE_TOP_Z - 0.01


def test_cameras_exist_and_render_the_scene():
  arena, robot = _scene('panda')
  physics = mjcf.Physics.from_mjcf_model(arena.mjcf_model)
  robot.set_joint_positions(physics, [0, 0.3, 0, -2.2, 0, 2.5, 0.8])
  physics.forward()
  names = [physics.model.id2name(i, 'camera')
           for i in range(physics.model.ncam)]
  assert set(CAMERAS) <= set(names)
  robot_colour = np.array([0.93, 0.93, 0.93]) * 255
  for camera in CAMERAS:
    frame = physics.render(height=120, width=160, camera_id=camera)
    assert frame.shape == (120, 160, 3)
    assert frame.std() > 10, camera   # Not blank.
    # The robot (white links) is in view.
    near_white = np.all(np.abs(frame - robot_colour) < 50, axis=-1)
    assert near_white.mean() > 0.002, camera


class _HoldStill(composer.Task):
  """A trivial task: the arena and robot, no reward."""

  def __init__(self, arena, robot):
    self._arena, self._robot = arena, robot
    self._robot.observables.joint_positions.enabled = True
    self._robot.observables.end_effector_position.enabled = True
    self.control_timestep = 0.1

  @property
  def root_entity(self):
    return self._arena

  def initialize_episode(self, physics, random_state):
    del random_state
    self._robot.set_joint_positions(physics, _centre(self._robot.description))

  def get_reward(self, physics):
    return 0.0


def test_composer_environment_steps():
  arena, robot = _scene('schunk')
  env = composer.Environment(_HoldStill(arena, robot),
                             strip_singleton_obs_buffer_dim=True)
  timestep = env.reset()
  position = timestep.observation['schunk/end_effector_position']
  assert position.shape == (3,) and position[2] > layout.TABLE_TOP_Z
  assert env.action_spec().shape == (robot.description.dof + 1,)
  timestep = env.step(np.zeros(env.action_spec().shape))
  assert timestep.reward == 0.0
  assert isinstance(robot.observables.end_effector_position,
                    observable.Generic)
