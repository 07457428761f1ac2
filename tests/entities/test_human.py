"""Tests for the kinematic human entity."""

import numpy as np
import pytest
from dm_control import composer
from dm_control import mjcf

from hrc_suite import layout
from hrc_suite.entities import collision_groups
from hrc_suite.entities import human as human_lib
from hrc_suite.entities import workcell
from hrc_suite.human import clip as clip_lib
from hrc_suite.human import keypoints


def _placed(clip, station=layout.HUMAN_STATION_ACROSS):
  x, y, yaw = station
  c, s = np.cos(yaw), np.sin(yaw)
  rotation = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
  return clip.positions.astype(np.float64) @ rotation.T + (x, y, 0)


def _scene(with_robot=False):
  arena = workcell.Workcell()
  robot = None
  if with_robot:
    from hrc_suite.entities import robot as robot_lib
    robot = robot_lib.make_robot('panda')
    arena.attach_robot(robot)
  human = human_lib.Human()
  human.attach_to(arena)
  box = arena.mjcf_model.worldbody.add('body', name='box', pos=(1.0, 0, 1.2))
  box.add('freejoint')
  collision_groups.set_object(
      box.add('geom', type='box', size=(0.03, 0.03, 0.03), mass=0.3))
  human.add_holdable(box)
  physics = mjcf.Physics.from_mjcf_model(arena.mjcf_model)
  return arena, robot, human, box, physics


@pytest.fixture(scope='module')
def clip():
  return clip_lib.shipped_library('handover_robot_to_human')[0]


def test_follows_a_clip_to_a_millimetre(clip):
  _, _, human, _, physics = _scene()
  positions = _placed(clip)
  human.resize(physics, clip)
  for frame in range(0, clip.num_frames, 5):
    human.set_keypoints(physics, positions[frame])
    physics.forward()
    np.testing.assert_allclose(human.keypoint_positions(physics),
                               positions[frame], atol=1e-3)
    # Capsule ends sit on the keypoints of their segment.
    geoms = physics.bind(human.geoms)
    axis = geoms.xmat.reshape(-1, 3, 3)[:, :, 2]
    ends = geoms.xpos + axis * geoms.size[:, 1:2]
    starts = geoms.xpos - axis * geoms.size[:, 1:2]
    a = positions[frame][keypoints.index([s[1] for s in human_lib.SEGMENTS])]
    b = positions[frame][keypoints.index([s[2] for s in human_lib.SEGMENTS])]
    np.testing.assert_allclose(ends, b, atol=1e-3)
    np.testing.assert_allclose(starts, a, atol=1e-3)


def test_resize_sets_size_and_rbound(clip):
  _, _, human, _, physics = _scene()
  lengths = human.resize(physics, clip)
  geoms = physics.bind(human.geoms)
  np.testing.assert_allclose(2 * geoms.size[:, 1], list(lengths.values()))
  np.testing.assert_allclose(physics.model.geom_rbound[geoms.element_id],
                             geoms.size[:, 0] + geoms.size[:, 1])


def test_no_self_collision_and_robot_link_in_path_makes_contact(clip):
  _, robot, human, _, physics = _scene(with_robot=True)
  human.resize(physics, clip)
  positions = _placed(clip)
  human.set_keypoints(physics, positions[0])
  physics.forward()
  human_geoms = set(physics.bind(human.geoms).element_id)

  def human_robot_contacts():
    robot_geoms = set(physics.bind(robot.mjcf_model.find_all(
        'geom')).element_id)
    found = 0
    for c in physics.data.contact[:physics.data.ncon]:
      pair = {c.geom1, c.geom2}
      assert not pair <= human_geoms, 'human self-contact'
      found += bool(pair & human_geoms and pair & robot_geoms)
    return found

  assert human_robot_contacts() == 0
  # Put the human's hand on a robot link: a contact must appear.
  link = physics.bind(robot.mjcf_model.find_all('body')[3]).xpos.copy()
  hand = keypoints.KEYPOINT_INDEX['right_hand']
  moved = positions[0] + (link - positions[0][hand])
  human.set_keypoints(physics, moved)
  physics.forward()
  assert human_robot_contacts() > 0


def test_hold_moves_the_object_with_the_hand_and_release_drops_it(clip):
  _, _, human, box, physics = _scene()
  positions = _placed(clip)
  frame = clip.keyframes[0]
  human.set_keypoints(physics, positions[frame])
  physics.forward()
  hand = human.keypoint_positions(physics)[
      keypoints.KEYPOINT_INDEX['left_hand']]
  physics.bind(box.freejoint).qpos[:3] = hand + (0, 0, 0.06)
  physics.forward()
  human.hold(physics, box, 'left')
  assert human.holding(box) == 'left'
  start = physics.bind(box).xpos.copy()
  shift = np.array([0.0, 0.25, 0.1])
  for i in range(1, 401):
    human.set_keypoints(physics, positions[frame] + shift * min(1, i / 250))
    physics.step()
  np.testing.assert_allclose(physics.bind(box).xpos - start, shift, atol=0.01)
  human.release(physics, box)
  assert human.holding(box) is None
  height = physics.bind(box).xpos[2]
  # The box overlaps the hand it was held in; lower the body away from it.
  human.set_keypoints(physics, positions[frame] + shift - (0, 0, 0.5))
  for _ in range(100):
    physics.step()
  assert physics.bind(box).xpos[2] < height - 0.05


def test_observables_world_and_relative(clip):
  arena = workcell.Workcell()
  human = human_lib.Human()
  human.attach_to(arena)
  site = arena.mjcf_model.worldbody.add('site', name='probe',
                                       pos=(1.0, 0.2, 1.0))
  human.add_relative_observables(site, ('head', 'right_hand'))
  physics = mjcf.Physics.from_mjcf_model(arena.mjcf_model)
  positions = _placed(clip)[10]
  human.set_keypoints(physics, positions)
  physics.forward()
  obs = human.observables
  np.testing.assert_allclose(obs.keypoint_positions(physics), positions,
                             atol=1e-9)
  rel = obs.get_observable('keypoints_in_probe_frame')(physics)
  idx = keypoints.index(['head', 'right_hand'])
  np.testing.assert_allclose(rel, positions[idx] - (1.0, 0.2, 1.0), atol=1e-9)
  dist = obs.get_observable('keypoint_distances_to_probe')(physics)
  np.testing.assert_allclose(dist, np.linalg.norm(rel, axis=-1))


def test_errors_are_clear():
  human = human_lib.Human()
  with pytest.raises(RuntimeError, match='attach_to'):
    human.add_holdable(None)
  arena = workcell.Workcell()
  human.attach_to(arena)
  physics = mjcf.Physics.from_mjcf_model(arena.mjcf_model)
  with pytest.raises(ValueError, match='shape'):
    human.set_keypoints(physics, np.zeros((3, 3)))


def test_runs_in_a_composer_environment(clip):
  arena = workcell.Workcell()
  human = human_lib.Human()
  human.attach_to(arena)
  task = composer.NullTask(arena)
  env = composer.Environment(task)
  env.reset()
  human.set_keypoints(env.physics, _placed(clip)[0])
  env.step(np.zeros(0))
  np.testing.assert_allclose(human.keypoint_positions(env.physics),
                             _placed(clip)[0], atol=1e-9)


def test_follows_a_player_in_an_environment(clip):
  from hrc_suite.human import player as player_lib
  arena = workcell.Workcell()
  human = human_lib.Human()
  human.attach_to(arena)
  station = layout.HUMAN_STATION_ACROSS
  player = player_lib.Player([clip], station=station)
  human.follow(player)
  task = composer.NullTask(arena)
  task.control_timestep = 0.1
  env = composer.Environment(task, random_state=0)
  env.reset()
  for _ in range(5):
    env.step(np.zeros(0))
  assert player.episode_time == pytest.approx(0.5)
  np.testing.assert_allclose(human.keypoint_positions(env.physics),
                             player.positions, atol=1e-9)
  expected = _placed(clip)[int(round(0.5 * clip.fps))]
  assert np.abs(player.positions - expected).max() < 0.05


def _hand_box_contacts(physics, human, box, hand):
  names = [s[0] for s in human_lib.SEGMENTS]
  hand_geom = physics.bind(human.geoms[names.index(f'{hand}_hand')]).element_id
  box_geoms = set(np.flatnonzero(physics.model.geom_bodyid
                                 == physics.bind(box).element_id))
  count = 0
  for c in physics.data.contact[:physics.data.ncon]:
    pair = {c.geom1, c.geom2}
    count += hand_geom in pair and bool(pair & box_geoms)
  return count


def test_holding_hand_does_not_push_the_held_object_out(clip):
  _, _, human, box, physics = _scene()
  positions = _placed(clip)
  frame = clip.keyframes[0]
  human.set_keypoints(physics, positions[frame])
  physics.forward()
  hand = human.keypoint_positions(physics)[
      keypoints.KEYPOINT_INDEX['left_hand']]
  # The box overlaps the hand capsule: without the exclusion the contact
  # pushes it out against the weld.
  physics.bind(box.freejoint).qpos[:3] = hand
  physics.forward()
  assert _hand_box_contacts(physics, human, box, 'left') > 0
  default = (physics.model.geom_contype.copy(),
             physics.model.geom_conaffinity.copy())
  human.hold(physics, box, 'left')
  start = physics.bind(box).xpos.copy()
  for _ in range(250):
    physics.step()
    assert _hand_box_contacts(physics, human, box, 'left') == 0
  assert np.linalg.norm(physics.bind(box).xpos - start) < 0.005
  # The other hand still collides with the held box.
  other = human.geoms[[s[0] for s in human_lib.SEGMENTS].index('right_hand')]
  box_geom = np.flatnonzero(physics.model.geom_bodyid
                            == physics.bind(box).element_id)[0]
  right = physics.bind(other).element_id
  m = physics.model
  assert (m.geom_contype[right] & m.geom_conaffinity[box_geom]) or (
      m.geom_contype[box_geom] & m.geom_conaffinity[right])
  human.release(physics, box)
  np.testing.assert_array_equal(physics.model.geom_contype, default[0])
  np.testing.assert_array_equal(physics.model.geom_conaffinity, default[1])
  physics.forward()
  assert _hand_box_contacts(physics, human, box, 'left') > 0


def test_hold_at_a_given_relative_pose_and_set_grip(clip):
  _, _, human, box, physics = _scene()
  positions = _placed(clip)
  human.set_keypoints(physics, positions[clip.keyframes[0]])
  physics.forward()
  offset = np.array([0.0, 0.0, 0.15])
  human.hold(physics, box, 'right', relative_pose=(offset, (1, 0, 0, 0)))
  for _ in range(300):
    physics.step()
  pos, quat = human.relative_pose(physics, box, 'right')
  np.testing.assert_allclose(pos, offset, atol=0.01)
  assert abs(abs(quat[0]) - 1.0) < 1e-3
  human.set_grip(physics, box, -offset, (0, 0, 0, 1))
  for _ in range(300):
    physics.step()
  pos, quat = human.relative_pose(physics, box, 'right')
  np.testing.assert_allclose(pos, -offset, atol=0.01)
  assert abs(abs(quat[3]) - 1.0) < 1e-2
  human.release(physics, box)
  with pytest.raises(ValueError, match='not held'):
    human.set_grip(physics, box, offset, (1, 0, 0, 0))
