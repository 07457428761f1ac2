"""HrcTask hooks: human grips in snapshots, clip counter, table clearance,
Cartesian gripper yaw."""

from dm_control import composer
import numpy as np

from hrc_suite import layout
from hrc_suite.control import ik as ik_lib
from hrc_suite.entities import props
from hrc_suite.tasks.runtime import actions
from hrc_suite.tasks import pick_place
from hrc_suite.tasks import reach


class _ReachWithCube(reach.Reach):
  """Reach plus a cube the human can hold (a hook test bed)."""

  def _build_task(self):
    super()._build_task()
    self.cube = props.Cube()
    self._arena.add_free_entity(self.cube)
    self._object_geoms.extend(self.cube.geoms)
    self.welds = self._grips.add(self.cube.body)

  def _initialize_task(self, physics, random_state):
    super()._initialize_task(physics, random_state)
    self.cube.set_pose(physics, np.array([0.5, 0.3, layout.TABLE_TOP_Z + 0.5]),
                       np.array([1.0, 0.0, 0.0, 0.0]))


class _YawedReach(reach.Reach):
  CARTESIAN_YAW = np.pi / 2


def _env(task, seed=0):
  return composer.Environment(task, random_state=seed,
                              strip_singleton_obs_buffer_dim=True)


def _model_bits(physics, task):
  geoms = physics.bind(task.cube.geoms)
  return (np.array(geoms.contype), np.array(geoms.conaffinity),
          physics.model.eq_data.copy())


def test_snapshot_restores_the_humans_grip_and_weld_data():
  task = _ReachWithCube(time_limit=5.0, reward='dense')
  env = _env(task)
  env.reset()
  physics = env.physics
  released_bits = _model_bits(physics, task)
  task._grips.hold(physics, task.cube.body, 'left')
  eq_id = physics.bind(task.welds['left']).element_id
  physics.model.eq_data[eq_id, 0:3] = (0.01, -0.02, 0.03)   # an anchor
  held_bits = _model_bits(physics, task)
  state = task.get_state(physics)
  task._grips.release(physics, task.cube.body)
  np.testing.assert_array_equal(_model_bits(physics, task)[0],
                                released_bits[0])
  task.set_state(physics, state)
  assert task.human.holding(task.cube.body) == 'left'
  for restored, saved in zip(_model_bits(physics, task), held_bits):
    np.testing.assert_array_equal(restored, saved)
  assert physics.data.eq_active[eq_id] == 1
  # A snapshot without the grip lets go again.
  task._grips.release(physics, task.cube.body)
  free = task.get_state(physics)
  task._grips.hold(physics, task.cube.body, 'right')
  task.set_state(physics, free)
  assert task.human.holding(task.cube.body) is None
  np.testing.assert_array_equal(_model_bits(physics, task)[1],
                                released_bits[1])


def test_reset_lets_go_of_held_objects():
  task = _ReachWithCube(time_limit=5.0, reward='dense')
  env = _env(task)
  env.reset()
  task._grips.hold(env.physics, task.cube.body, 'right')
  env.reset()
  assert task.human.holding(task.cube.body) is None


def test_clip_counter_marks_the_step_a_clip_ends():
  task = reach.Reach(time_limit=60.0, reward='dense', action_space='joint')
  env = _env(task, seed=3)
  env.reset()
  zero = np.zeros(env.action_spec().shape)
  ended_at = []
  for step in range(600):
    before = task.player.clip_index
    env.step(zero)
    assert task.clips_completed == task.player.clip_index
    assert task.clip_ended == (task.player.clip_index != before)
    if task.clip_ended:
      ended_at.append(step)
    if len(ended_at) == 2:
      break
  assert len(ended_at) == 2, 'two clips should end within 60 s'
  # Clips last longer than one RL step: the flag is not stuck on.
  assert ended_at[1] > ended_at[0] + 1


def test_table_clearance_constant_sets_the_tool_allowance():
  default = reach.Reach()
  assert default.tool_table_allowance == 0.0
  task = pick_place.PickPlace()
  _, _, radius = task.gripper.enclosing_capsule()
  assert task.tool_table_allowance == (
      radius - pick_place.PickPlace.FINGERTIP_TABLE_CLEARANCE)
  # The allowance reaches collision prevention: a grasp pose low over the
  # table is free for pick and place, a collision for reach.
  q_home = task.robot.description.q_home
  point = np.array([0.55, 0.0, layout.TABLE_TOP_Z + 0.02 + 0.01])
  result = ik_lib.InverseKinematics(task.kinematics).solve(
      point, q_home, actions.GRIPPER_YAW)
  assert result.success
  assert not task.collision_checker.in_collision(result.q)
  assert default.collision_checker.in_collision(result.q)


def test_cartesian_yaw_constant_turns_the_gripper():
  axes = []
  for task in (reach.Reach(reward='dense', action_space='cartesian'),
               _YawedReach(reward='dense', action_space='cartesian')):
    assert task._action_space.yaw == task.CARTESIAN_YAW
    env = _env(task)
    env.reset()
    env.step(np.zeros(3))
    rotation = task.kinematics.tcp_pose(task.q_goal)[:3, :3]
    axes.append(rotation[:, 0])
  assert abs(axes[0] @ axes[1]) < 1e-3
