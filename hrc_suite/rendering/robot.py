"""Renders a robot in the workcell following a jerk-limited trajectory.

    python -m hrc_suite.rendering.robot --robot=panda --out=panda.mp4

The arm is simulated (MuJoCo physics at 4 ms, torque control by the joint
tracking controller) while it visits a few configurations around its home
pose and opens and closes the gripper.
"""

import pathlib

from absl import app
from absl import flags
import numpy as np

from hrc_suite import rendering
from hrc_suite import registry_flags

_ROBOT = flags.DEFINE_string('robot', 'panda', 'Which robot to render: a name '
                             'or a description file (robot_description).')
registry_flags.check_robot('robot')
_OUT = flags.DEFINE_string('out', 'robot.mp4', 'Output video (.mp4 or .gif).')
_CAMERA = flags.DEFINE_string('camera', 'front', 'Camera name.')
_WIDTH = flags.DEFINE_integer('width', 640, 'Frame width in pixels.')
_HEIGHT = flags.DEFINE_integer('height', 480, 'Frame height in pixels.')
_FPS = flags.DEFINE_integer('fps', 25, 'Video frame rate.')
_SEED = flags.DEFINE_integer('seed', 0, 'Seed of the visited configurations.')

PHYSICS_TIMESTEP = 0.004  # s, the benchmark's physics step (250 Hz).


def waypoints(description, seed: int, count: int = 4):
  """Configurations around home: random offsets of up to 0.6 rad per joint."""
  rng = np.random.RandomState(seed)
  q_min, q_max = description.limits.q_min, description.limits.q_max
  points = [description.q_home]
  for _ in range(count):
    offset = rng.uniform(-0.6, 0.6, size=description.dof)
    offset[1:3] *= 0.5  # Keep shoulder and elbow near home: stay above the table.
    points.append(np.clip(description.q_home + offset, q_min + 0.05,
                          q_max - 0.05))
  points.append(description.q_home)
  return points


def render(robot_name: str, out: str, camera: str = 'front', width: int = 640,
           height: int = 480, fps: int = 25, seed: int = 0) -> pathlib.Path:
  """Simulates and renders; returns the path of the written video."""
  from dm_control import mjcf
  from hrc_suite.control import controller as controller_lib
  from hrc_suite.control import trajectory
  from hrc_suite.entities import gripper as gripper_lib
  from hrc_suite.entities import robot as robot_lib
  from hrc_suite.entities import workcell as workcell_lib

  arena = workcell_lib.Workcell()
  robot = robot_lib.make_robot(robot_name)
  gripper = gripper_lib.ParallelGripper()
  robot.attach_gripper(gripper)
  arena.attach_robot(robot)
  arena.mjcf_model.option.timestep = PHYSICS_TIMESTEP
  physics = mjcf.Physics.from_mjcf_model(arena.mjcf_model)
  desc = robot.description
  q_d, dq_d, ddq_d = trajectory.jerk_limited_trajectory(
      desc, waypoints(desc, seed), dt=PHYSICS_TIMESTEP, limits='ltt')
  robot.set_joint_positions(physics, q_d[0])
  physics.forward()
  controller = controller_lib.JointTrackingController(physics, robot)
  steps_per_frame = max(1, int(round(1.0 / (fps * PHYSICS_TIMESTEP))))
  frames = []
  for k in range(len(q_d)):
    # Open and close the gripper every 1.5 s so the fingers are seen moving.
    gripper.set_command(physics, 1.0 if (k * PHYSICS_TIMESTEP) % 3.0 > 1.5
                        else -1.0)
    controller(physics, q_d[k], dq_d[k], ddq_d[k])
    physics.step()
    if k % steps_per_frame == 0:
      frames.append(rendering.render_frame(physics, camera, width, height))
  return rendering.write_video(out, frames, fps=fps)


def main(argv):
  del argv
  path = render(_ROBOT.value, _OUT.value, _CAMERA.value, _WIDTH.value,
                _HEIGHT.value, _FPS.value, _SEED.value)
  print(f'Wrote {path.resolve()} ({_ROBOT.value} in the workcell, camera '
        f'{_CAMERA.value!r}).')


if __name__ == '__main__':
  app.run(main)
