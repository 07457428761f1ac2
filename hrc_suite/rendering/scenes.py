"""Renders one picture per registered task for docs/tasks.md.

  python -m hrc_suite.rendering.scenes --out=docs/images/tasks
  python -m hrc_suite.rendering.scenes --tasks=handover/human_to_robot \
      --motions=path/to/recordings --out=/tmp/real

Each task is loaded with a fixed seed (Panda, the task's defaults) and
stepped with a still arm until the human is in a characteristic pose:

* 'wait': the first RL step at which the person waits for the task's event
  (the handovers, inspection, hammering, stacking);
* 'closest': the RL step, within the scene's window, at which the person
  comes closest to the robot (shield's minimum distance; reach, pick and
  place, lifting). The episode is replayed to that step (same seed, same
  actions, same result).

The arm's action is zero (Cartesian: hold the TCP; joint: hold q); the
gripper stays closed where the robot starts holding something, open
elsewhere. A free camera (MuJoCo's lookat / distance / azimuth / elevation)
frames robot, objects, goals and person closer than the workcell's fixed
cameras. Frames are written as palette PNGs (256 colours, ~25-30 kB each);
maximum-coverage palettes keep small coloured things such as the cubes and
goal markers, which median cut merged into their surroundings.
"""

import collections
import os
import pathlib

# Offscreen rendering without a display, unless the caller chose a backend
# (set before dm_control is imported: it reads MUJOCO_GL on import).
os.environ.setdefault('MUJOCO_GL', 'egl')

from absl import app   # pylint: disable=g-import-not-at-top
from absl import flags
from dm_control.mujoco import engine
import numpy as np

from hrc_suite import rendering
from hrc_suite import suite

WIDTH, HEIGHT = 640, 400     # pixels (docs/tasks.md layout)
SEED = 0
ROBOT = 'panda'
PALETTE_COLOURS = 256        # PNG palette size (quantised frames)
MODES = ('wait', 'closest')

# view: (lookat (m, world), distance (m), azimuth (deg), elevation (deg)) of
# the free camera; steps: RL steps searched; mode: see the module doc;
# grip: gripper action (+1 closed, -1 open; None: the task has no gripper).
Scene = collections.namedtuple('Scene', 'view steps mode grip')
# Across the table: from the robot's right, a little behind it.
_ACROSS = ((0.75, 0.0, 1.05), 2.4, 70.0, -18.0)
# Beside the workspace: from the far end of the table, the person right.
_BESIDE = ((0.4, 0.35, 1.1), 2.6, 160.0, -25.0)
_BESIDE_HIGH = ((0.4, 0.35, 0.9), 2.4, 165.0, -40.0)
SCENES = {
    ('reach', 'dense'): Scene(_BESIDE, 99, 'closest', None),
    ('reach', 'sparse'): Scene(
        ((0.4, 0.35, 1.1), 2.6, 200.0, -25.0), 99, 'closest', None),
    ('pick_place', 'default'): Scene(_BESIDE_HIGH, 150, 'closest', -1.0),
    ('pick_place', 'close'): Scene(_BESIDE_HIGH, 150, 'closest', -1.0),
    ('inspection', 'default'): Scene(_ACROSS, 200, 'wait', -1.0),
    ('lifting', 'default'): Scene(
        ((0.75, 0.0, 1.0), 2.4, 70.0, -25.0), 80, 'closest', 1.0),
    ('handover', 'robot_to_human'): Scene(_ACROSS, 200, 'wait', 1.0),
    ('handover', 'human_to_robot'): Scene(
        ((0.75, 0.0, 1.05), 2.4, 110.0, -18.0), 200, 'wait', -1.0),
    ('hammering', 'default'): Scene(
        ((0.75, 0.0, 1.1), 2.2, 70.0, -15.0), 200, 'wait', 1.0),
    ('hammering', 'robot_hammers'): Scene(
        ((0.75, 0.0, 1.0), 2.2, 70.0, -25.0), 200, 'wait', 1.0),
    ('stacking', 'default'): Scene(
        ((0.75, 0.0, 1.0), 2.4, 70.0, -30.0), 300, 'wait', -1.0),
}

_OUT = flags.DEFINE_string('out', 'docs/images/tasks',
                           'Folder the PNGs are written to.')
_TASKS = flags.DEFINE_list('tasks', None, 'domain/task names to render '
                           '(default: every registered task).')
_MOTIONS = flags.DEFINE_string(
    'motions', None, "A folder of people for the tasks (task_kwargs["
    "'motions']: clips, BVH recordings or one sub-folder per task; "
    "docs/motion_library.md), played with outside_human_model='allow' "
    '(default: the shipped synthetic library).')


def file_name(domain, task):
  return f'{domain}_{task}.png'


def _load(domain, task, scene):
  kwargs = {'robot': ROBOT, 'seed': SEED}
  if _MOTIONS.value is not None:
    kwargs.update(motions=_MOTIONS.value, outside_human_model='allow')
  env = suite.load(domain, task, task_kwargs=kwargs)
  env.reset()
  action = np.zeros(env.action_spec().shape)
  if env.task.HAS_GRIPPER_ACTION:
    action[-1] = scene.grip
  return env, action


def _play(env, action, steps, name):
  for step in range(steps):
    if env.step(action).last():
      raise RuntimeError(f'{name}: the episode ended after {step + 1} RL '
                         'steps, before the scene was staged')


def stage(domain, task, scene):
  """The environment stepped to the scene's pose; returns (env, RL steps
  played)."""
  if scene.mode not in MODES:
    raise ValueError(f'Unknown scene mode {scene.mode!r}: expected one of '
                     f'{", ".join(MODES)}')
  name = f'{domain}/{task}'
  env, action = _load(domain, task, scene)
  if scene.mode == 'wait':
    for step in range(scene.steps):
      if env.task.player.waiting_for is not None:
        return env, step
      _play(env, action, 1, name)
    raise RuntimeError(f'{name}: the person did not wait for an event '
                       f'within {scene.steps} RL steps')
  distances = []
  for _ in range(scene.steps):
    last = env.step(action).last()
    distances.append(env.task.step_metrics['min_human_distance'])
    if last:
      break
  steps = int(np.argmin(distances)) + 1
  env.close()
  env, action = _load(domain, task, scene)
  _play(env, action, steps, name)
  return env, steps


def render_scene(env, view):
  """RGB frame (HEIGHT, WIDTH, 3) of the free camera at `view`."""
  camera = engine.MovableCamera(env.physics, height=HEIGHT, width=WIDTH)
  camera.set_pose(*view)
  return camera.render()


def to_png(frame, path):
  """Writes an RGB frame as an optimised palette PNG; returns its size."""
  from PIL import Image   # Pillow comes with imageio.
  image = Image.fromarray(frame).quantize(
      colors=PALETTE_COLOURS, method=Image.Quantize.MAXCOVERAGE)
  image.save(path, optimize=True)
  return path.stat().st_size


def render(names, out):
  out = pathlib.Path(out)
  out.mkdir(parents=True, exist_ok=True)
  for domain, task in names:
    if (domain, task) not in SCENES:
      raise ValueError(f'No scene for {domain}/{task}: expected one of '
                       f'{", ".join("/".join(k) for k in SCENES)}')
    scene = SCENES[(domain, task)]
    env, steps = stage(domain, task, scene)
    frame = render_scene(env, scene.view)
    if rendering.is_blank(frame):
      raise RuntimeError(f'{domain}/{task}: blank frame (check MUJOCO_GL)')
    path = out / file_name(domain, task)
    size = to_png(frame, path)
    print(f'{path}: {steps} RL steps, '
          f'clip {env.task.player.clip.name}, {size / 1024:.0f} kB')
    env.close()


def main(argv):
  del argv
  names = suite.all_tasks()
  if _TASKS.value:
    names = [tuple(n.split('/')) for n in _TASKS.value]
  render(names, _OUT.value)


if __name__ == '__main__':
  app.run(main)
