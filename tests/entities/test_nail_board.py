"""Nail board: hammer blows drive the nail in through physics, step by step;
a nail left alone stays put."""

import numpy as np
import pytest
from dm_control import mjcf

from hrc_suite import layout
from hrc_suite.entities import collision_groups
from hrc_suite.entities import nail_board
from hrc_suite.entities import props
from hrc_suite.entities import workcell

import grasping   # tests/entities/grasping.py

BOARD_HEIGHT = 1.0   # m, block centre in the strike rig.
HAMMER_MASS = props.HAMMER_HEAD_MASS + props.HAMMER_HANDLE_MASS


def _strike_rig():
  """A fixed nail board and a hammer head (the Hammer's face, the whole
  hammer's mass) on a vertical slide right above the nail."""
  root = mjcf.RootElement()
  root.option.timestep = workcell.PHYSICS_TIMESTEP
  board = nail_board.NailBoard()
  root.attach(board.mjcf_model).pos = (0, 0, BOARD_HEIGHT)
  head = root.worldbody.add('body', name='hammer_head',
                            pos=(nail_board.NAIL_X, 0, BOARD_HEIGHT))
  slide = head.add('joint', name='drop', type='slide', axis=(0, 0, 1))
  half = props.HAMMER_FACE_OFFSET
  collision_groups.set_object(head.add(
      'geom', type='cylinder', size=(props.HAMMER_FACE_RADIUS, half),
      pos=(0, 0, half), mass=HAMMER_MASS, solref=props.STRIKE_SOLREF,
      solimp=props.STRIKE_SOLIMP))
  physics = mjcf.Physics.from_mjcf_model(root)
  return board, physics, physics.bind(slide)


def _blow(board, physics, slide, speed, clearance=0.02, steps=60,
          record=None):
  """Starts the face `clearance` above the nail head moving down at
  `speed`; returns the depth driven (m)."""
  physics.forward()
  head_top = physics.bind(board.nail_head_site).xpos[2]
  slide.qpos = head_top + clearance - BOARD_HEIGHT
  slide.qvel = -speed
  physics.forward()
  before = board.depth(physics)
  for _ in range(steps):
    physics.step()
    if record is not None:
      record.append(board.progress(physics))
  return board.depth(physics) - before


def test_compiles_alone_with_the_nail_out():
  board = nail_board.NailBoard()
  physics = mjcf.Physics.from_mjcf_model(board.mjcf_model)
  assert board.progress(physics) == 0.0
  head = physics.bind(board.nail_head_site).xpos
  top = nail_board.BLOCK_HALF_SIZE[2]
  assert head[2] == pytest.approx(
      top + nail_board.NAIL_TRAVEL + 2 * nail_board.NAIL_HEAD_HALF_THICKNESS)
  assert nail_board.NAIL_TRAVEL > 0.025
  np.testing.assert_allclose(physics.bind(board.nail_joint).range,
                             (0, nail_board.NAIL_TRAVEL))
  board.set_progress(physics, 1.0)
  physics.forward()
  # Fully driven: the head's underside sits on the block.
  assert physics.bind(board.nail_head_site).xpos[2] == pytest.approx(
      top + 2 * nail_board.NAIL_HEAD_HALF_THICKNESS)
  assert board.progress(physics) == 1.0
  obs = board.observables
  np.testing.assert_allclose(obs.nail_progress(physics), [1.0])
  np.testing.assert_allclose(obs.nail_head_position(physics),
                             physics.bind(board.nail_head_site).xpos)
  with pytest.raises(ValueError, match='progress'):
    board.set_progress(physics, 1.5)


def test_blows_drive_the_nail_in_step_by_step_and_monotonically():
  board, physics, slide = _strike_rig()
  history = [board.progress(physics)]
  depths = []
  while board.progress(physics) < 1.0 and len(depths) < 20:
    depths.append(_blow(board, physics, slide, 1.0, record=history))
  history = np.array(history)
  assert np.all(np.diff(history) >= -1e-9)    # Never backs out.
  assert history.max() <= 1.0
  # Progressive: several blows, each a few millimetres.
  assert 4 <= len(depths) <= 10, depths
  assert 0.002 < depths[0] < 0.3 * nail_board.NAIL_TRAVEL
  assert board.progress(physics) > 0.95
  # Once home, further blows change nothing.
  assert _blow(board, physics, slide, 2.0) == pytest.approx(0, abs=1e-4)


def test_harder_blows_drive_deeper():
  board, physics, slide = _strike_rig()
  random_state = np.random.RandomState(0)
  speeds = np.array([0.75, 1.25, 2.0])
  mean_depth = []
  for speed in speeds:
    depths = []
    for _ in range(4):
      board.set_progress(physics, 0.0)
      # The face meets the head at any point of a 4 ms step.
      clearance = 0.02 + random_state.uniform(0, speed * 0.004)
      depths.append(_blow(board, physics, slide, speed, clearance))
    mean_depth.append(np.mean(depths))
  assert 0 < mean_depth[0] < mean_depth[1] < mean_depth[2]
  # Roughly the blow's energy over the friction.
  energy = 0.5 * HAMMER_MASS * speeds ** 2
  ratio = np.array(mean_depth) * nail_board.NAIL_FRICTION / energy
  assert np.all((ratio > 0.5) & (ratio < 2.0)), ratio


def test_blows_drive_the_nail_of_a_block_the_robot_holds():
  board = nail_board.NailBoard()
  arena, robot, gripper = grasping.scene(board)
  start = np.array([0.5, 0.1, layout.TABLE_TOP_Z
                    + nail_board.BLOCK_HALF_SIZE[2]])
  # A hammer head on a vertical slide over where the lifted nail will be
  # (gravity compensated, so it waits above until struck down).
  over_nail = start + (nail_board.NAIL_X, 0, 0.4)
  head = arena.mjcf_model.worldbody.add('body', name='hammer_head',
                                        pos=over_nail, gravcomp=1)
  slide = head.add('joint', name='drop', type='slide', axis=(0, 0, 1))
  half = props.HAMMER_FACE_OFFSET
  face = head.add('geom', type='cylinder',
                  size=(props.HAMMER_FACE_RADIUS, half), pos=(0, 0, half),
                  mass=HAMMER_MASS, solref=props.STRIKE_SOLREF,
                  solimp=props.STRIKE_SOLIMP)
  collision_groups.set_object(face)
  physics = mjcf.Physics.from_mjcf_model(arena.mjcf_model)
  board.set_pose(physics, start, (1.0, 0.0, 0.0, 0.0))
  pick = grasping.PickUp(physics, robot, gripper, board, board.grip_site)
  assert pick.pick()
  pick.hold(0.4)
  assert board.progress(physics) < 1e-4   # Lifting does not move the nail.
  slide_state = physics.bind(slide)
  face_id = physics.bind(face).element_id
  gripper_ids = set(physics.bind(gripper.geoms).element_id)
  hit_gripper = []

  def watch():
    contacts = physics.data.contact[:physics.data.ncon]
    for pair in zip(contacts.geom1, contacts.geom2):
      hit_gripper.append(face_id in pair and bool(gripper_ids & set(pair)))

  progress = [0.0]
  while progress[-1] < 1.0 and len(progress) <= 12:
    nail_top = physics.bind(board.nail_head_site).xpos[2]
    slide_state.qpos = nail_top + 0.02 - over_nail[2]
    slide_state.qvel = -2.0
    physics.forward()
    pick.hold(0.24, hook=watch)            # The blow.
    slide_state.qpos, slide_state.qvel = 0.0, 0.0
    physics.forward()
    pick.hold(0.2)                         # Hammer raised again.
    progress.append(board.progress(physics))
  gripped, distance = np.array(pick.held).T
  # A blow can jolt one pad off the handle for a step (4 ms); the grasp
  # holds throughout.
  assert gripped.mean() > 0.97 and gripped[-100:].all()
  assert not any(hit_gripper)
  assert np.all(np.diff(progress) >= -1e-6)
  assert progress[-1] > 0.95
  assert 3 <= len(progress) - 1 <= 8, progress
  # The block slips a little in the fingers with each blow, no more.
  assert distance.max() < 0.02


def test_a_resting_nail_does_not_move():
  board = nail_board.NailBoard()
  arena = workcell.Workcell()
  arena.add_free_entity(board)
  physics = mjcf.Physics.from_mjcf_model(arena.mjcf_model)
  board.set_pose(physics, (0.6, 0.0, layout.TABLE_TOP_Z + 0.07),
                 (1.0, 0.0, 0.0, 0.0))
  board.set_progress(physics, 0.3)
  physics.forward()
  before = board.depth(physics)
  physics.step(1250)   # Dropped 5 cm, then 5 s at rest.
  assert physics.bind(board.body).xpos[2] == pytest.approx(
      layout.TABLE_TOP_Z + nail_board.BLOCK_HALF_SIZE[2], abs=2e-3)
  assert abs(board.depth(physics) - before) < 1e-6


def test_the_hammer_prop_drives_the_nail():
  board = nail_board.NailBoard()
  hammer = props.Hammer()
  root = mjcf.RootElement()
  root.option.timestep = workcell.PHYSICS_TIMESTEP
  root.attach(board.mjcf_model).pos = (0, 0, BOARD_HEIGHT)
  root.attach(hammer.mjcf_model).add('freejoint')
  physics = mjcf.Physics.from_mjcf_model(root)
  physics.forward()
  # Handle level and pointing away from the block's handle, face down,
  # 1 cm above the nail, falling at 2.5 m/s.
  target = physics.bind(board.nail_head_site).xpos + (0, 0, 0.01)
  face = np.asarray(hammer.head_site.pos)   # On the head's axis: yaw-free.
  hammer.set_pose(physics, target - face, (0.0, 0.0, 0.0, 1.0))
  hammer.set_velocity(physics, (0.0, 0.0, -2.5), (0.0, 0.0, 0.0))
  physics.forward()
  struck = set()
  for _ in range(50):
    physics.step()
    contacts = physics.data.contact[:physics.data.ncon]
    struck.update(zip(contacts.geom1, contacts.geom2))
  head_on_nail = tuple(physics.bind([hammer.head, board.nail_head]).element_id)
  assert head_on_nail in struck or head_on_nail[::-1] in struck
  assert 0.1 < board.progress(physics) < 0.9
