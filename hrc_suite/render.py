"""Runs one episode of a task with a policy and writes a video and its metrics.

    MUJOCO_GL=egl python -m hrc_suite.render --domain=handover \
        --task=robot_to_human --policy=random --out=handover.mp4

One frame per RL step (10 Hz, so the video plays in real time), from any
named camera. The episode's metrics (success, return, shield interventions,
contacts by type, ...) are printed and written to a JSON file beside the
video. Policies: `random` (uniform in the action spec, seeded) and `zero`
(no motion, gripper closed: the shielded robot holding still while the human
moves).
"""

import json
import pathlib

from absl import app
from absl import flags
import numpy as np

from hrc_suite import rendering
from hrc_suite import robot_description

POLICIES = ('random', 'zero')

_DOMAIN = flags.DEFINE_string('domain', 'handover', 'Task domain.')
_TASK = flags.DEFINE_string('task', 'robot_to_human', 'Task name.')
_ROBOT = flags.DEFINE_enum('robot', 'panda', robot_description.ROBOT_NAMES,
                           'Robot.')
_POLICY = flags.DEFINE_enum('policy', 'random', POLICIES, 'Policy to run.')
_OUT = flags.DEFINE_string('out', 'episode.mp4', 'Video (.mp4 or .gif).')
_CAMERA = flags.DEFINE_string(
    'camera', 'side', 'Camera name (front, side, top, human_view).')
_SEED = flags.DEFINE_integer('seed', 0, 'Seed of the episode and policy.')
_MAX_STEPS = flags.DEFINE_integer('max_steps', 200,
                                  'At most this many RL steps.')
_WIDTH = flags.DEFINE_integer('width', 640, 'Frame width in pixels.')
_HEIGHT = flags.DEFINE_integer('height', 480, 'Frame height in pixels.')


def make_policy(name, action_spec, seed):
  """A function timestep -> action for a named policy."""
  if name == 'random':
    rng = np.random.RandomState(seed)
    return lambda timestep: rng.uniform(action_spec.minimum,
                                        action_spec.maximum,
                                        action_spec.shape)
  if name == 'zero':
    action = np.zeros(action_spec.shape)
    if action.shape[0] in (4,):  # Cartesian: keep the gripper closed.
      action[-1] = 1.0
    return lambda timestep: action
  raise ValueError(f'Unknown policy {name!r}: expected one of '
                   f'{", ".join(POLICIES)}')


def run(domain, task, robot='panda', policy='random', out='episode.mp4',
        camera='side', seed=0, max_steps=200, width=640, height=480):
  """Runs and renders one episode; returns (video path, metrics dict)."""
  from hrc_suite import suite
  env = suite.load(domain, task, task_kwargs=dict(robot=robot, seed=seed))
  act = make_policy(policy, env.action_spec(), seed)
  timestep = env.reset()
  frames = [rendering.render_frame(env.physics, camera, width, height)]
  for _ in range(max_steps):
    if timestep.last():
      break
    timestep = env.step(act(timestep))
    frames.append(rendering.render_frame(env.physics, camera, width, height))
  metrics = {k: float(v) for k, v in env.task.episode_metrics.items()}
  fps = 1.0 / env.control_timestep()
  path = rendering.write_video(out, frames, fps=fps)
  metrics_path = pathlib.Path(path).with_suffix('.json')
  metrics_path.write_text(json.dumps(dict(
      domain=domain, task=task, robot=robot, policy=policy, seed=seed,
      camera=camera, metrics=metrics), indent=1) + '\n')
  env.close()
  return path, metrics


def main(argv):
  del argv
  path, metrics = run(_DOMAIN.value, _TASK.value, _ROBOT.value, _POLICY.value,
                      _OUT.value, _CAMERA.value, _SEED.value,
                      _MAX_STEPS.value, _WIDTH.value, _HEIGHT.value)
  print('episode metrics:')
  for key, value in metrics.items():
    print(f'  {key}: {value:g}')
  print(f'Wrote {path.resolve()} and {path.with_suffix(".json").name}')


if __name__ == '__main__':
  app.run(main)
