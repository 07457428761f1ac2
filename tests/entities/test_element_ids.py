"""Ids looked up once per Physics read what the bindings read."""

from dm_control import mjcf
import numpy as np
import pytest

from hrc_suite.entities import element_ids
from hrc_suite.entities import gripper as gripper_lib
from hrc_suite.entities import robot as robot_lib


def _model():
  root = mjcf.RootElement()
  bodies = []
  for i in range(3):
    body = root.worldbody.add('body', name=f'b{i}', pos=(i, 0.0, 1.0))
    body.add('freejoint')
    body.add('geom', type='sphere', size=(0.1,))
    bodies.append(body)
  return root, bodies


def test_ids_are_the_bindings_and_follow_a_new_physics():
  root, bodies = _model()
  ids = element_ids.ElementIds(bodies[::-1])
  physics = mjcf.Physics.from_mjcf_model(root)
  np.testing.assert_array_equal(
      ids(physics), physics.bind(bodies[::-1]).element_id)
  assert ids(physics) is ids(physics)   # Cached.
  with pytest.raises(ValueError):
    ids(physics)[0] = 5   # Read-only: the cache cannot be changed.
  # A body added before recompiling shifts the ids: a new Physics looks
  # them up again.
  root.worldbody.insert('body', 0, name='first').add(
      'geom', type='sphere', size=(0.1,))
  other = mjcf.Physics.from_mjcf_model(root)
  np.testing.assert_array_equal(ids(other),
                                other.bind(bodies[::-1]).element_id)
  assert not np.array_equal(ids(other), physics.bind(bodies[::-1]).element_id)


def test_synced_data_reads_what_a_binding_reads_after_a_write():
  root, bodies = _model()
  physics = mjcf.Physics.from_mjcf_model(root)
  physics.forward()
  ids = element_ids.ElementIds(bodies)
  # A qpos write through a binding marks the physics dirty.
  physics.bind(bodies[1].freejoint).qpos = (0.0, 5.0, 1.0, 1.0, 0.0, 0.0,
                                            0.0)
  stale = physics.data.xpos[ids(physics)].copy()
  assert physics.is_dirty
  synced = element_ids.synced_data(physics).xpos[ids(physics)]
  assert not physics.is_dirty
  np.testing.assert_array_equal(
      synced, np.array([physics.bind(b).xpos for b in bodies]))
  assert not np.array_equal(stale, synced)   # The raw read alone was stale.


def test_robot_tcp_frame_and_gripper_reads_match_their_bindings():
  robot = robot_lib.make_robot('panda')
  gripper = robot.attach_gripper(gripper_lib.ParallelGripper())
  physics = mjcf.Physics.from_mjcf_model(robot.mjcf_model)
  rs = np.random.RandomState(0)
  limits = robot.description.limits
  for _ in range(5):
    robot.set_joint_positions(physics, rs.uniform(limits.q_min,
                                                  limits.q_max))
    physics.bind(gripper.finger_joints).qpos = rs.uniform(0.0, 0.04, 2)
    xpos, xmat = robot.tcp_frame(physics)   # Synchronised: no forward().
    site = physics.bind(gripper.tcp_site)
    np.testing.assert_array_equal(xpos, site.xpos)
    np.testing.assert_array_equal(xmat, site.xmat)
    opening = np.sum(physics.bind(gripper.finger_joints).qpos)
    assert gripper.aperture(physics) == float(
        np.clip(opening / gripper_lib.MAX_APERTURE, 0.0, 1.0))
