"""Props: sizes and masses, resting on the table, grasped by the robot, held
by the human, observables, markers and the target helpers."""

import numpy as np
import pytest
from dm_control import composer
from dm_control import mjcf

from hrc_suite import layout
from hrc_suite.control import controller as controller_lib
from hrc_suite.entities import collision_groups
from hrc_suite.entities import gripper as gripper_lib
from hrc_suite.entities import human as human_lib
from hrc_suite.entities import markers
from hrc_suite.entities import nail_board
from hrc_suite.entities import props
from hrc_suite.entities import workcell
from hrc_suite.human import clip as clip_lib
from hrc_suite.human import keypoints
from hrc_suite.human import task_motions

import grasping   # tests/entities/grasping.py

TOP = layout.TABLE_TOP_Z
# Hammer lying on its side, +y (the grip site's approach side) up.
ON_ITS_SIDE = np.array([np.cos(np.pi / 4), np.sin(np.pi / 4), 0.0, 0.0])
IDENTITY = np.array([1.0, 0.0, 0.0, 0.0])

# Each prop, its pose on the table (centre height above the top, quat) and
# its documented mass.
PROPS = {
    'cube': (props.Cube, props.CUBE_SIZE / 2, IDENTITY, props.CUBE_MASS),
    'hammer': (props.Hammer, props.HAMMER_HANDLE_HALF_SECTION[0],
               ON_ITS_SIDE, props.HAMMER_HEAD_MASS + props.HAMMER_HANDLE_MASS),
    'board': (props.Board, props.BOARD_SIZE[2] / 2, IDENTITY,
              props.BOARD_MASS),
    'nail_board': (nail_board.NailBoard, nail_board.BLOCK_HALF_SIZE[2],
                   IDENTITY, None),
}


def _scene(*entities, robot_name='ur5e'):
  """grasping.scene, with markers attached as fixed entities."""
  free = [e for e in entities if not isinstance(e, markers.TargetMarker)]
  arena, robot, gripper = grasping.scene(*free, robot_name=robot_name)
  for entity in entities:
    if isinstance(entity, markers.TargetMarker):
      arena.attach(entity)
  return arena, robot, gripper


@pytest.mark.parametrize('name', list(PROPS))
def test_compiles_alone_with_documented_mass(name):
  factory, _, _, mass = PROPS[name]
  prop = factory()
  physics = mjcf.Physics.from_mjcf_model(prop.mjcf_model)
  total = physics.model.body_mass.sum()
  if mass is not None:
    assert total == pytest.approx(mass, rel=1e-9)
  for geom in prop.geoms:
    assert (geom.contype, geom.conaffinity) == (
        collision_groups.OBJECT_CONTYPE, collision_groups.OBJECT_CONAFFINITY)


def test_sizes_are_as_documented_and_fit_the_gripper():
  cube = props.Cube()
  assert cube.size == 0.04 and cube.mass == 0.1
  np.testing.assert_allclose(cube.geom.size, [0.02] * 3)
  hammer = props.Hammer()
  assert 0.5 <= hammer.mass <= 0.65
  length = (props.HAMMER_HANDLE_LENGTH + props.HAMMER_FACE_RADIUS)
  assert 0.3 <= length <= 0.36                     # 13 in claw hammer.
  assert 2 * max(props.HAMMER_HANDLE_HALF_SECTION) < 0.8 * (
      gripper_lib.MAX_APERTURE)
  board = props.Board()
  assert board.size == (1.0, 0.4, 0.03) and 2.0 <= board.mass <= 3.0
  assert 2 * props.HANDLE_HALF_SIZE[0] < 0.8 * gripper_lib.MAX_APERTURE
  assert 2 * nail_board.HANDLE_HALF_SIZE[0] < 0.8 * gripper_lib.MAX_APERTURE
  # What the human's clips assume (hrc_suite/human/task_motions.py).
  cubes = props.make_stacking_cubes()
  assert len(cubes) == 4 and {c.size for c in cubes} == {
      task_motions.CUBE_SIZE}
  assert len({tuple(c.geom.rgba) for c in cubes}) == 4
  assert props.HAMMER_HUMAN_GRIP == task_motions.HAMMER_REACH
  assert props.HAMMER_FACE_OFFSET == task_motions.HAMMER_FACE_BELOW_PALM
  site = np.asarray(hammer.human_grip_site.pos) - hammer.head_site.pos
  np.testing.assert_allclose(site, [-task_motions.HAMMER_REACH, 0,
                                    task_motions.HAMMER_FACE_BELOW_PALM])


def test_bad_arguments_raise_clear_errors():
  with pytest.raises(ValueError, match='Cube size'):
    props.Cube(size=-0.04)
  with pytest.raises(ValueError, match='Cube mass'):
    props.Cube(mass=float('nan'))
  with pytest.raises(ValueError, match='rgba'):
    props.Cube(rgba=(1, 0, 0))
  with pytest.raises(ValueError, match='Board size'):
    props.Board(size=(1.0, 0.4))
  with pytest.raises(ValueError, match='too small'):
    props.Board(size=(0.1, 0.4, 0.03))
  with pytest.raises(ValueError, match='too small'):
    props.Board(handle_inset=0.48)
  with pytest.raises(ValueError, match='handle_inset'):
    props.Board(handle_inset=-0.1)
  with pytest.raises(ValueError, match='handle'):
    props.Board(mass=0.01)
  with pytest.raises(ValueError, match='4 colours'):
    props.make_stacking_cubes(colours=((1, 0, 0, 1),))
  with pytest.raises(ValueError, match='radius'):
    markers.TargetMarker(radius=0)
  with pytest.raises(ValueError, match='shape'):
    markers.TargetMarker(shape='cone')
  with pytest.raises(ValueError, match='half_thickness'):
    markers.TargetMarker(shape='disc', half_thickness=-0.001)
  with pytest.raises(ValueError, match='offset'):
    markers.TargetMarker(offset=(0.0, 1.0))


@pytest.mark.parametrize('name', list(PROPS))
def test_dropped_on_the_table_it_comes_to_rest_on_it(name):
  factory, height, quat, _ = PROPS[name]
  prop = factory()
  arena, robot, _ = _scene(prop)
  physics = mjcf.Physics.from_mjcf_model(arena.mjcf_model)
  robot.set_joint_positions(physics, robot.description.q_home)
  xy = (0.6, 0.3)
  prop.set_pose(physics, (*xy, TOP + height + 0.05), quat)
  physics.forward()
  # The arm (torque controlled) would sag; hold it with the controller.
  controller = controller_lib.JointTrackingController(physics, robot)
  zeros = np.zeros(robot.dof)
  for _ in range(500):   # 2 s
    controller(physics, robot.description.q_home, zeros, zeros)
    physics.step()
  body = physics.bind(prop.body)
  assert body.xpos[2] == pytest.approx(TOP + height, abs=2e-3)
  np.testing.assert_allclose(body.xpos[:2], xy, atol=0.02)
  assert np.abs(body.cvel).max() < 1e-2
  np.testing.assert_allclose(np.abs(body.xquat @ quat), 1.0, atol=1e-3)


def test_four_stacked_cubes_stand():
  cubes = props.make_stacking_cubes()
  arena, _, _ = _scene(*cubes, robot_name=None)
  physics = mjcf.Physics.from_mjcf_model(arena.mjcf_model)
  size = props.STACKING_CUBE_SIZE
  for i, cube in enumerate(cubes):
    cube.set_pose(physics, (0.6, 0.0, TOP + size * (i + 0.5) + 1e-4),
                  IDENTITY)
  physics.forward()
  physics.step(750)   # 3 s
  positions = np.array([physics.bind(c.body).xpos for c in cubes])
  np.testing.assert_allclose(positions[:, :2], [[0.6, 0.0]] * 4, atol=2e-3)
  np.testing.assert_allclose(positions[:, 2],
                             TOP + size * (np.arange(4) + 0.5), atol=3e-3)


def test_observables_and_board_tilt():
  board = props.Board()
  cube = props.Cube()
  arena, _, _ = _scene(board, cube)
  physics = mjcf.Physics.from_mjcf_model(arena.mjcf_model)
  angle = 0.3
  quat = np.array([np.cos(angle / 2), np.sin(angle / 2), 0, 0])
  board.set_pose(physics, (0.6, 0.0, 1.2), quat)
  cube.set_pose(physics, (0.4, -0.2, 1.0), IDENTITY)
  physics.forward()
  assert board.tilt(physics) == pytest.approx(angle, abs=1e-9)
  np.testing.assert_allclose(board.normal(physics),
                             [0, -np.sin(angle), np.cos(angle)], atol=1e-9)
  obs = board.observables
  np.testing.assert_allclose(obs.position(physics), (0.6, 0.0, 1.2))
  np.testing.assert_allclose(obs.quaternion(physics), quat, atol=1e-9)
  np.testing.assert_allclose(obs.normal(physics), board.normal(physics))
  np.testing.assert_allclose(cube.observables.position(physics),
                             (0.4, -0.2, 1.0))
  np.testing.assert_allclose(cube.position(physics), (0.4, -0.2, 1.0))
  np.testing.assert_allclose(cube.quaternion(physics), IDENTITY, atol=1e-12)
  # Grip sites sit where documented: on the board's handle, human's end.
  robot_site = physics.bind(board.robot_grip_site).xpos
  human_site = physics.bind(board.human_grip_site).xpos
  assert np.linalg.norm(human_site - robot_site) == pytest.approx(
      1.0 - props.HANDLE_INSET - props.HANDLE_HALF_SIZE[0]
      - props.HUMAN_GRIP_INSET, abs=0.03)   # Up to the sites' heights.
  inset = props.Board(handle_inset=0.3)
  assert inset.robot_grip_site.pos[0] == pytest.approx(-0.5 + 0.3 + 0.015)


@pytest.mark.parametrize('shape', markers.SHAPES)
def test_target_marker_compiles_alone_and_with_a_robot(shape):
  marker = markers.TargetMarker(shape=shape)
  physics = mjcf.Physics.from_mjcf_model(marker.mjcf_model)
  assert physics.model.nv == 0 and physics.model.ngeom == 0
  arena, _, _ = _scene(marker)
  physics = mjcf.Physics.from_mjcf_model(arena.mjcf_model)
  marker.set_pose(physics, (0.5, 0.0, 1.0))
  physics.forward()
  np.testing.assert_allclose(marker.position(physics), (0.5, 0.0, 1.0))


def test_a_mocap_marker_moves_as_physics_state_with_its_offset_site():
  offset = np.array([0.0, 0.0, -0.02])
  marker = markers.TargetMarker(shape='disc', half_thickness=0.0005,
                                offset=offset)
  goal = np.array([0.5, 0.1, TOP + 0.3])
  with pytest.raises(ValueError, match='attach_mocap'):
    marker.set_mocap_position(None, goal)
  arena, _, _ = grasping.scene(robot_name=None)
  marker.attach_mocap(arena)
  physics = mjcf.Physics.from_mjcf_model(arena.mjcf_model)
  assert physics.bind(marker.site).size[1] == 0.0005
  marker.set_mocap_position(physics, goal)
  physics.forward()
  # The goal is the mocap frame; the site is drawn at the offset from it.
  np.testing.assert_array_equal(marker.mocap_position(physics), goal)
  np.testing.assert_allclose(marker.position(physics), goal + offset)
  # Physics state: a snapshot of mocap_pos carries the goal.
  saved = physics.data.mocap_pos.copy()
  marker.set_mocap_position(physics, goal + 0.1)
  physics.data.mocap_pos[:] = saved
  np.testing.assert_array_equal(marker.mocap_position(physics), goal)


def test_target_marker_is_visual_only_and_helpers_measure_distance():
  marker = markers.TargetMarker(radius=0.05, rgba=(0, 1, 0, 0.5))
  cube = props.Cube()
  arena, _, _ = _scene(cube, marker, robot_name=None)
  physics = mjcf.Physics.from_mjcf_model(arena.mjcf_model)
  masses = physics.model.body_mass.copy()
  body_id = physics.bind(marker.body).element_id
  # Welded to the world (no joint), no geoms: nothing to collide or weigh.
  assert physics.model.body_weldid[body_id] == 0
  assert physics.model.body_geomnum[body_id] == 0
  assert physics.bind(marker.site).size[0] == 0.05
  # A cube falls straight through the marker onto the table.
  target = np.array([0.5, 0.1, TOP + 0.1])
  marker.set_pose(physics, target)
  cube.set_pose(physics, target + (0, 0, 0.1), IDENTITY)
  physics.forward()
  np.testing.assert_allclose(marker.observables.position(physics), target)
  np.testing.assert_allclose(marker.position(physics), target)
  assert not markers.is_within(physics, cube, marker, 0.099)
  assert markers.is_within(physics, cube, marker, 0.101)
  physics.step(250)
  np.testing.assert_allclose(physics.bind(cube.body).xpos,
                             (0.5, 0.1, TOP + 0.02), atol=2e-3)
  np.testing.assert_array_equal(physics.model.body_mass, masses)
  assert markers.distance_to_target(physics, cube, marker) == pytest.approx(
      0.08, abs=2e-3)
  assert markers.is_within(physics, cube.body, target, 0.085)
  assert markers.is_within(physics, cube, cube.grip_site, 0.0)
  with pytest.raises(ValueError, match='3-vector'):
    markers.distance_to_target(physics, cube, (1.0, 2.0))
  with pytest.raises(ValueError, match='joint'):
    markers.distance_to_target(physics, cube,
                               cube.root_body.find_all('joint')[0])
  with pytest.raises(ValueError, match='non-negative'):
    markers.is_within(physics, cube, target, -1.0)


# --- The robot grasps a prop at its grip site and lifts it for 2 s. ---


def _grasp_and_lift(prop, site, position, quat, robot_name='ur5e'):
  """Returns (gripped every step of the lift and 2 s hold, prop lift (m),
  largest TCP to grip-site distance while held (m))."""
  arena, robot, gripper = _scene(prop, robot_name=robot_name)
  physics = mjcf.Physics.from_mjcf_model(arena.mjcf_model)
  prop.set_pose(physics, position, quat)
  physics.forward()
  start = physics.bind(prop.body).xpos.copy()
  pick = grasping.PickUp(physics, robot, gripper, prop, site)
  assert pick.pick()
  pick.hold(2.0)
  gripped, distance = np.array(pick.held).T
  lift = physics.bind(prop.body).xpos[2] - start[2]
  return gripped.all(), lift, distance.max()


def test_robot_grasps_and_lifts_the_cube():
  cube = props.Cube()
  gripped, lift, distance = _grasp_and_lift(
      cube, cube.grip_site, (0.45, 0.1, TOP + 0.02), IDENTITY)
  assert gripped
  assert lift > 0.14
  assert distance < 0.01


def test_robot_grasps_and_lifts_the_hammer_by_its_handle():
  hammer = props.Hammer()
  gripped, lift, distance = _grasp_and_lift(
      hammer, hammer.grip_site,
      (0.55, 0.1, TOP + props.HAMMER_HANDLE_HALF_SECTION[0]), ON_ITS_SIDE)
  assert gripped
  assert lift > 0.14
  assert distance < 0.01


def test_robot_grasps_and_lifts_the_nail_board_by_its_handle():
  board = nail_board.NailBoard()
  gripped, lift, distance = _grasp_and_lift(
      board, board.grip_site,
      (0.5, 0.1, TOP + nail_board.BLOCK_HALF_SIZE[2]), IDENTITY)
  assert gripped
  assert lift > 0.14
  assert distance < 0.01


def test_robot_and_a_partner_lift_the_board_level():
  board = props.Board()
  arena, robot, gripper = _scene(board)
  start = np.array([0.85, 0.0, TOP + props.BOARD_SIZE[2] / 2])
  board.root_body.pos = start   # The weld's relative pose is taken here.
  # The partner's hand: a mocap body welded at the human's end.
  hand_position = start + np.asarray(board.human_grip_site.pos)
  hand = arena.mjcf_model.worldbody.add('body', name='partner_hand',
                                        mocap=True, pos=hand_position)
  arena.mjcf_model.equality.add('weld', body1=hand, body2=board.body,
                                solref=(0.01, 1.0))
  physics = mjcf.Physics.from_mjcf_model(arena.mjcf_model)
  pick = grasping.PickUp(physics, robot, gripper, board,
                         board.robot_grip_site)
  start_height = []
  tilts = []

  def partner_follows():   # The hand rises as the robot's TCP does.
    if not start_height:
      start_height.append(pick.tcp.xpos[2])
    rise = max(0.0, pick.tcp.xpos[2] - start_height[0])
    physics.data.mocap_pos[0] = hand_position + (0, 0, rise)
    tilts.append(board.tilt(physics))

  pick.follow(pick.rest(pick.q_above, 75), -1)
  pick.follow(pick.move(pick.q_above, pick.q_grasp), -1)
  pick.follow(pick.rest(pick.q_grasp, 50), 1)
  pick.follow(pick.move(pick.q_grasp, pick.q_above), 1, record=True,
              hook=partner_follows)
  pick.hold(2.0, hook=partner_follows)
  gripped, distance = np.array(pick.held).T
  assert gripped.all() and distance.max() < 0.01
  assert max(tilts) < np.radians(2.0)
  assert physics.bind(board.body).xpos[2] - start[2] == pytest.approx(
      0.15, abs=0.01)


# --- The human holds the hammer and it follows the hand. ---


def test_human_holds_the_hammer_and_it_follows_the_hand():
  clip = clip_lib.shipped_library('hammering')[0]
  arena = workcell.Workcell()
  human = human_lib.Human()
  human.attach_to(arena)
  hammer = props.Hammer()
  arena.add_free_entity(hammer)
  human.add_holdable(hammer.body)
  # The hand's capsule encloses a gripped handle; without this exclusion
  # the contact pushes the hammer ~6 cm out of the hand against the weld.
  arena.mjcf_model.contact.add(
      'exclude', body1=human.segment_bodies[
          [s[0] for s in human_lib.SEGMENTS].index('right_hand')],
      body2=hammer.body)
  physics = mjcf.Physics.from_mjcf_model(arena.mjcf_model)
  x, y, yaw = layout.HUMAN_STATION_ACROSS
  c, s = np.cos(yaw), np.sin(yaw)
  rotation = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
  positions = clip.positions.astype(np.float64) @ rotation.T + (x, y, 0)
  human.resize(physics, clip)
  human.set_keypoints(physics, positions[0])
  physics.forward()
  hand = keypoints.KEYPOINT_INDEX['right_hand']
  # Handle in the palm, head ahead of the person (towards -x), face down.
  facing = np.array([[-1.0, 0, 0], [0, -1.0, 0], [0, 0, 1.0]])
  grip_local = np.asarray(hammer.human_grip_site.pos)
  quat = np.array([0.0, 0.0, 0.0, 1.0])   # Half turn about z.
  hammer.set_pose(physics, positions[0][hand] - facing @ grip_local, quat)
  physics.forward()
  human.hold(physics, hammer.body, 'right')
  site = physics.bind(hammer.human_grip_site)
  offsets, travelled = [], 0.0
  steps_per_frame = int(round(1 / (clip.fps * workcell.PHYSICS_TIMESTEP)))
  previous = site.xpos.copy()
  for frame in range(1, 100):   # 4 s of the clip
    for k in range(1, steps_per_frame + 1):
      alpha = k / steps_per_frame
      human.set_keypoints(physics, (1 - alpha) * positions[frame - 1]
                          + alpha * positions[frame])
      physics.step()
    offsets.append(np.linalg.norm(site.xpos - positions[frame][hand]))
    travelled += np.linalg.norm(site.xpos - previous)
    previous = site.xpos.copy()
  assert travelled > 0.5
  # The weld is soft: ~2 cm lag at the clip's 1 m/s hand speed.
  assert max(offsets) < 0.03, max(offsets)
  human.release(physics, hammer.body)
  height = site.xpos[2]
  physics.step(100)
  assert site.xpos[2] < height - 0.05


def test_observables_in_a_composer_environment():
  cube = props.Cube()
  hammer = props.Hammer()
  board = nail_board.NailBoard()
  marker = markers.TargetMarker()
  arena = workcell.Workcell()
  for entity in (cube, hammer, board):
    arena.add_free_entity(entity)
    entity.observables.enable_all()
  arena.attach(marker)
  marker.observables.enable_all()
  task = composer.NullTask(arena)
  env = composer.Environment(task, strip_singleton_obs_buffer_dim=True)
  env.reset()
  cube.set_pose(env.physics, (0.5, 0.0, TOP + 0.3), IDENTITY)
  hammer.set_pose(env.physics, (0.6, 0.3, TOP + 0.3), IDENTITY)
  board.set_pose(env.physics, (0.4, 0.3, TOP + 0.03), IDENTITY)
  marker.set_pose(env.physics, (0.4, -0.2, TOP + 0.1))
  env.physics.forward()
  observation = env.step(np.zeros(0)).observation
  physics = env.physics
  assert observation['cube/position'][2] < TOP + 0.3   # Falling.
  np.testing.assert_allclose(observation['cube/position'],
                             physics.bind(cube.body).xpos)
  np.testing.assert_allclose(observation['cube/quaternion'],
                             physics.bind(cube.body).xquat)
  np.testing.assert_allclose(observation['hammer/head_position'],
                             physics.bind(hammer.head_site).xpos)
  np.testing.assert_allclose(observation['nail_board/nail_progress'], [0.0])
  np.testing.assert_allclose(observation['target/position'],
                             (0.4, -0.2, TOP + 0.1))
