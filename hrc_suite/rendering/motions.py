"""Renders the human performing one shipped motion of each task.

  python -m hrc_suite.rendering.motions --out=DIR
      [--clip_index=0] [--camera=NAME] [--fps=25] [--robot=panda]

Writes DIR/<task>.mp4 per task and DIR/all_tasks.mp4 (all in a row). The
clip is played by the player at the task's station; whenever the human waits
for an event, the event is triggered after WAIT_BEFORE_EVENT seconds so the
motion goes on.
"""

import argparse
import pathlib

import numpy as np
from dm_control import mjcf

from hrc_suite import layout
from hrc_suite import rendering
from hrc_suite.entities import human as human_lib
from hrc_suite.entities import workcell
from hrc_suite.human import clip as clip_lib
from hrc_suite.human import player as player_lib

WAIT_BEFORE_EVENT = 2.0   # s of idle motion shown before each event.
BESIDE_TASKS = ('reach', 'pick_place')


def station_for(task):
  return (layout.HUMAN_STATION_BESIDE if task in BESIDE_TASKS
          else layout.HUMAN_STATION_ACROSS)


def camera_for(task):
  """A workcell camera that sees the person at the task's station."""
  return 'front' if task in BESIDE_TASKS else 'side'


def render_task(task, clip_index=0, camera=None, fps=25.0, robot='panda',
                width=640, height=480, max_seconds=40.0):
  """Frames of one clip of `task` played in the workcell."""
  clip = clip_lib.shipped_library(task)[clip_index]
  camera = camera or camera_for(task)
  arena = workcell.Workcell()
  robot_entity = None
  if robot:
    from hrc_suite.entities import robot as robot_lib
    robot_entity = robot_lib.make_robot(robot)
    arena.attach_robot(robot_entity)
  human = human_lib.Human()
  human.attach_to(arena)
  physics = mjcf.Physics.from_mjcf_model(arena.mjcf_model)
  if robot_entity is not None:  # In its ready pose, not stretched upright.
    robot_entity.set_joint_positions(physics,
                                     robot_entity.description.q_home)
  human.resize(physics, clip)
  player = player_lib.Player([clip], station=station_for(task))
  player.reset(np.random.RandomState(0))
  frames, waited, dt, last_time = [], 0.0, 1.0 / fps, 0.0
  while len(frames) < max_seconds * fps:
    human.set_keypoints(physics, player.positions)
    physics.forward()
    frames.append(rendering.render_frame(physics, camera, width, height))
    if player.waiting_for is not None:
      waited += dt
      if waited >= WAIT_BEFORE_EVENT:
        player.trigger(player.waiting_for)
        waited = 0.0
    player.advance(dt)
    # The player then starts the next clip of its stream: stop there.
    if player.clip_time < last_time - 0.5 or player.clip_time >= (
        clip.duration - 1e-6):
      break
    last_time = player.clip_time
  return frames


def main(argv=None):
  parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
  parser.add_argument('--out', required=True)
  parser.add_argument('--clip_index', type=int, default=0)
  parser.add_argument('--camera', default=None,
                      help='workcell camera; default: one per station')
  parser.add_argument('--fps', type=float, default=25.0)
  parser.add_argument('--robot', default='panda')
  parser.add_argument('--tasks', nargs='*', default=list(clip_lib.MOTION_TASKS),
                      choices=clip_lib.MOTION_TASKS)
  args = parser.parse_args(argv)
  out = pathlib.Path(args.out)
  everything = []
  for task in args.tasks:
    frames = render_task(task, args.clip_index, args.camera, args.fps,
                         args.robot)
    if rendering.is_blank(frames[len(frames) // 2]):
      raise RuntimeError(f'{task}: rendered frames are blank')
    path = rendering.write_video(out / f'{task}.mp4', frames, args.fps)
    print(f'{task}: {len(frames)} frames -> {path}')
    everything.extend(frames)
  path = rendering.write_video(out / 'all_tasks.mp4', everything, args.fps)
  print(f'all tasks -> {path}')


if __name__ == '__main__':
  main()
