"""Runs one episode of a task with a policy and writes a video and its metrics.

    python -m hrc_suite.rendering.episode --domain=handover \
        --task=robot_to_human --policy=expert --out=handover.mp4

One frame per RL step (10 Hz), or one every --substeps_per_frame physics
steps (4 ms each) for a smooth video; played in real time unless --fps says
otherwise. Any workcell camera (--camera). The overlay (on unless
--nooverlay, `render_overlay`) draws the shield's reachable capsules of the
robot (blue) and the human (orange) into the scene, marks frames of RL steps
in which the shield intervened (yellow border and badge) or a contact
occurred (badges: violet static, green safe human, red critical human), and
writes a caption line: time, reward, return, success. `.mp4` (H.264) or
`.gif` (--gif_scale shrinks it). The episode's metrics are printed and
written to a JSON file beside the video.

Policies (--policy): `expert` (the task's hand-crafted expert,
`hrc_suite.experts`), `noisy_expert` (the expert with Ornstein-Uhlenbeck
noise, seeded), `random` (uniform in the action spec, seeded) and `zero`
(no motion, gripper closed), or a trained checkpoint: a directory (a
training run's logdir or one of its checkpoints) read by an installed
checkpoint loader (entry-point group `hrc_suite.checkpoint_policies`;
agents/ registers the SAC agents' one, so hrc_suite never imports it). A
checkpoint's episode runs in its training environment (domain, task, robot,
task arguments); --domain/--task/--robot may be left out, and must match
it if given.
"""

import dataclasses
import importlib.metadata
import json
import pathlib
from typing import Any, Callable, Dict

from absl import app
from absl import flags
import numpy as np

from hrc_suite.rendering import overlay as render_overlay
from hrc_suite import rendering
from hrc_suite import registry_flags

POLICIES = ('expert', 'noisy_expert', 'random', 'zero')
# Scene room for the overlay's capsules beyond dm_control's own estimate
# (robot: up to ~60 slices x 8 capsules; human: 13 bodies per slice).
OVERLAY_MAX_GEOMS = 2000
# RL steps rendered by default (30 s): the handover experts finish within
# 15-23 s (seeds 0-2, measured), a random policy is cut off.
DEFAULT_MAX_STEPS = 300
# Entry-point group of checkpoint loaders: path -> TrainedPolicy, raising
# ValueError for a directory they do not read.
CHECKPOINT_LOADERS = 'hrc_suite.checkpoint_policies'
# The episode a named policy runs when --domain/--task/--robot are not given.
DEFAULT_DOMAIN, DEFAULT_TASK, DEFAULT_ROBOT = ('handover', 'robot_to_human',
                                               'panda')

# -------------------------------------------------------------- policies


def _random_policy(env, seed):
  spec = env.action_spec()
  rng = np.random.RandomState(seed)
  return lambda timestep: rng.uniform(spec.minimum, spec.maximum, spec.shape)


def _zero_policy(env, seed):
  del seed
  action = np.zeros(env.action_spec().shape)
  if getattr(env.task, 'HAS_GRIPPER_ACTION', False):
    action[-1] = 1.0   # Keep the gripper closed (hold what it holds).
  return lambda timestep: action


def _expert_policy(env, seed):
  del seed   # Experts are deterministic.
  from hrc_suite import experts  # pylint: disable=g-import-not-at-top
  return experts.make(env)


def _noisy_expert_policy(env, seed):
  """The expert plus the reference's Ornstein-Uhlenbeck noise for the
  task's action space, seeded by `seed`."""
  from hrc_suite import experts  # pylint: disable=g-import-not-at-top
  try:
    from hrc_suite.experts import noise as noise_lib  # pylint: disable=g-import-not-at-top
  except ModuleNotFoundError as error:
    if error.name != 'hrc_suite.experts.noise':
      raise
    raise ValueError('--policy=noisy_expert needs hrc_suite/experts/noise.py '
                     '(OrnsteinUhlenbeckNoise, NoisyExpert), which this '
                     'checkout does not have') from error
  noise = noise_lib.OrnsteinUhlenbeckNoise.reference(
      env.action_spec().shape[0], env.task.action_space_name)
  return noise_lib.NoisyExpert(experts.make(env), noise, seed=seed)


_POLICY_FACTORIES = {
    'expert': _expert_policy,
    'noisy_expert': _noisy_expert_policy,
    'random': _random_policy,
    'zero': _zero_policy,
}


def policy_factory(name):
  """The factory (env, seed) -> policy (timestep -> action) of a named
  policy (checkpoints: `load_checkpoint`)."""
  if name not in _POLICY_FACTORIES:
    raise ValueError(f'Unknown policy {name!r}: expected one of '
                     f'{", ".join(POLICIES)} or a checkpoint directory')
  return _POLICY_FACTORIES[name]


@dataclasses.dataclass(frozen=True)
class TrainedPolicy:
  """A trained policy and the environment it was trained in."""
  domain: str
  task: str
  robot: str
  task_kwargs: Dict[str, Any]
  factory: Callable    # (env, seed) -> policy (timestep -> action)


def load_checkpoint(path):
  """The TrainedPolicy of a checkpoint directory, from the first installed
  loader (entry-point group CHECKPOINT_LOADERS) that reads it."""
  loaders = importlib.metadata.entry_points(group=CHECKPOINT_LOADERS)
  if not loaders:
    raise ValueError(f'{path} is a directory, but no checkpoint loader is '
                     f'installed (entry-point group {CHECKPOINT_LOADERS}; '
                     "`pip install -e '.[train]'` registers agents/' one)")
  errors = []
  for loader in loaders:
    try:
      return loader.load()(path)
    except ValueError as error:
      errors.append(f'{loader.name}: {error}')
  raise ValueError(f'No checkpoint loader reads {path}: ' + '; '.join(errors))


def _episode_setup(policy, domain, task, robot, task_kwargs):
  """(factory, domain, task, robot, task_kwargs) of a --policy value: a
  name or factory runs on the given (or default) task; a checkpoint
  directory on its training environment (given names must match it; given
  task_kwargs override its own)."""
  if callable(policy) or policy in POLICIES or not pathlib.Path(
      policy).is_dir():
    factory = policy if callable(policy) else policy_factory(policy)
    return (factory, domain or DEFAULT_DOMAIN, task or DEFAULT_TASK,
            robot or DEFAULT_ROBOT, dict(task_kwargs or {}))
  trained = load_checkpoint(policy)
  for name, given, own in (('domain', domain, trained.domain),
                           ('task', task, trained.task),
                           ('robot', robot, trained.robot)):
    if given is not None and given != own:
      raise ValueError(f'--{name}={given} differs from the checkpoint '
                       f'{policy}, trained with {name} {own!r}')
  return (trained.factory, trained.domain, trained.task, trained.robot,
          dict(trained.task_kwargs, **(task_kwargs or {})))


def make_policy(name, env, seed):
  """The policy (timestep -> action) of a --policy value on `env`."""
  return policy_factory(name)(env, seed)


# --------------------------------------------------------------- cameras


def camera_names(env):
  """Names of the workcell's cameras."""
  return tuple(camera.name for camera in env.task.arena.cameras)


def camera_index(env, name):
  """The compiled model's id of a workcell camera, by name."""
  cameras = {camera.name: camera for camera in env.task.arena.cameras}
  if name not in cameras:
    raise ValueError(f'Unknown camera {name!r}: expected one of '
                     f'{", ".join(cameras)}')
  return int(env.physics.bind(cameras[name]).element_id)


def _positive_int(name, value):
  if not isinstance(value, (int, np.integer)) or value < 1:
    raise ValueError(f'{name}: expected a positive integer, got {value!r}')
  return int(value)


# --------------------------------------------------------------- episode


@dataclasses.dataclass
class RenderedEpisode:
  frames: list          # (H, W, 3) uint8 frames, annotated if overlay
  infos: list           # render_overlay.FrameInfo per frame
  metrics: dict         # the task's episode_metrics
  frame_period: float   # s of simulated time between frames


def frame_period(env, substeps_per_frame=None):
  """Simulated seconds between frames: an RL step, or substeps_per_frame
  physics steps."""
  if substeps_per_frame is None:
    return float(env.control_timestep())
  return substeps_per_frame * float(env.physics.model.opt.timestep)


def render_episode(env, policy, camera='side', width=640, height=480,
                   overlay=True, substeps_per_frame=None, max_steps=None,
                   on_frame=None, keep_frames=True):
  """Plays one episode of `env` (an hrc_suite task) with `policy` and
  renders it: a frame after reset, then one per RL step or one every
  `substeps_per_frame` physics steps. Frames of an RL step carry that
  step's markers (the shield's interventions and contacts are counted per
  RL step). Each finished frame goes to `on_frame(frame)` if given and is
  kept in the result if keep_frames. Returns a RenderedEpisode."""
  from dm_control.mujoco import engine  # pylint: disable=g-import-not-at-top
  width, height = _positive_int('width', width), _positive_int('height',
                                                                height)
  if substeps_per_frame is not None:
    substeps_per_frame = _positive_int('substeps_per_frame',
                                       substeps_per_frame)
  if max_steps is not None:
    max_steps = _positive_int('max_steps', max_steps)
  camera_index(env, camera)   # Fails early on a bad name.
  timestep = env.reset()
  physics = env.physics
  callback = (render_overlay.ShieldOverlay(env.task.shield) if overlay
              else None)
  model = physics.model
  # What the model itself may put in the scene (geoms, frames, contacts),
  # as generously as dm_control's own estimate, plus the overlay's room.
  max_geom = (1000 + 5 * (model.ngeom + model.nbody + model.nsite)
              + OVERLAY_MAX_GEOMS)
  view = engine.Camera(physics, height, width, camera_index(env, camera),
                       max_geom=max_geom, scene_callback=callback)

  def shot():
    return view.render().copy(), float(physics.data.time)

  pending = []
  counter = {'substeps': 0, 'active': substeps_per_frame is not None}
  if substeps_per_frame is not None:
    def after_substep(physics, random_state):
      del physics, random_state
      if counter['active']:
        counter['substeps'] += 1
        if counter['substeps'] % substeps_per_frame == 0:
          pending.append(shot())
    env.add_extra_hook('after_substep', after_substep)
  frames, infos = [], []

  def finish(image, info):
    if overlay:
      image = render_overlay.annotate(image, info, legend=True)
    infos.append(info)
    if keep_frames:
      frames.append(image)
    if on_frame is not None:
      on_frame(image)

  image, time = shot()
  finish(image, render_overlay.FrameInfo(time=time, reward=None,
                                         episode_return=0.0, success=False))
  steps = 0
  try:
    while not timestep.last() and (max_steps is None or steps < max_steps):
      timestep = env.step(policy(timestep))
      steps += 1
      if substeps_per_frame is None:
        pending.append(shot())
      info = render_overlay.frame_info(env.task.step_metrics,
                                       env.task.episode_metrics, 0.0)
      for image, time in pending:
        finish(image, dataclasses.replace(info, time=time))
      pending.clear()
  finally:
    counter['active'] = False
  metrics = {k: float(v) for k, v in env.task.episode_metrics.items()}
  return RenderedEpisode(frames, infos, metrics,
                         frame_period(env, substeps_per_frame))


class VideoWriter:
  """Streams frames into an .mp4 (H.264, as `rendering.write_video`), or
  collects them, scaled by gif_scale, for a .gif written on close."""

  def __init__(self, path, fps, gif_scale=1.0):
    import imageio.v2 as imageio  # pylint: disable=g-import-not-at-top
    self.path = pathlib.Path(path)
    self.suffix = self.path.suffix.lower()
    if self.suffix not in ('.mp4', '.gif'):
      raise ValueError(f'Unsupported video format {self.suffix!r} for '
                       f'{self.path}: expected .mp4 or .gif')
    if not 0.0 < gif_scale <= 1.0:
      raise ValueError(f'gif_scale: expected a number in (0, 1], got '
                       f'{gif_scale!r}')
    self.fps, self.gif_scale, self.count = float(fps), gif_scale, 0
    self._gif_frames = []
    self._writer = None
    self.path.parent.mkdir(parents=True, exist_ok=True)
    if self.suffix == '.mp4':
      self._writer = imageio.get_writer(
          self.path, fps=self.fps, codec='libx264', quality=7,
          macro_block_size=1, pixelformat='yuv420p')

  def append(self, frame):
    frame = np.asarray(frame, dtype=np.uint8)
    self.count += 1
    if self._writer is not None:
      self._writer.append_data(frame)
    else:
      self._gif_frames.append(_scaled(frame, self.gif_scale))

  def close(self):
    if self._writer is not None:
      self._writer.close()
    elif self._gif_frames:
      rendering.write_video(self.path, self._gif_frames, fps=self.fps)
    return self.path


def _scaled(frame, scale):
  """A frame resized by `scale` (Pillow, area-averaging)."""
  from PIL import Image  # pylint: disable=g-import-not-at-top
  if scale == 1.0:
    return frame
  height, width = frame.shape[:2]
  size = (max(1, round(width * scale)), max(1, round(height * scale)))
  return np.asarray(Image.fromarray(frame).resize(size, Image.Resampling.BOX))


def run(domain=None, task=None, robot=None, policy='random',
        out='episode.mp4',
        camera='side', seed=0, max_steps=DEFAULT_MAX_STEPS, width=640,
        height=480, overlay=True, fps=None, substeps_per_frame=None,
        gif_scale=1.0, task_kwargs=None):
  """Runs and renders one episode; returns (video path, metrics dict).

  policy: a name (POLICIES), a checkpoint directory (`load_checkpoint`) or
    a factory (env, seed) -> policy.
  domain, task, robot: the episode's (None: DEFAULT_* for named policies,
    the training run's for a checkpoint).
  task_kwargs: more task arguments (e.g. {'shield': 'pfl'}).
  """
  from hrc_suite import suite  # pylint: disable=g-import-not-at-top
  factory, domain, task, robot, task_kwargs = _episode_setup(
      policy, domain, task, robot, task_kwargs)
  if not 0.0 < gif_scale <= 1.0:
    raise ValueError(f'gif_scale: expected a number in (0, 1], got '
                     f'{gif_scale!r}')
  if fps is not None and not fps > 0:
    raise ValueError(f'fps: expected > 0, got {fps!r}')
  suffix = pathlib.Path(out).suffix.lower()
  if suffix not in ('.mp4', '.gif'):
    raise ValueError(f'Unsupported video format {suffix!r} for {out}: '
                     'expected .mp4 or .gif')
  width, height = _positive_int('width', width), _positive_int('height',
                                                                height)
  if substeps_per_frame is not None:
    substeps_per_frame = _positive_int('substeps_per_frame',
                                       substeps_per_frame)
  if suffix == '.mp4' and (width % 2 or height % 2):
    raise ValueError(f'.mp4 (H.264, yuv420p) needs an even frame size, got '
                     f'width={width}, height={height}')
  env = suite.load(domain, task, task_kwargs=dict(
      task_kwargs, robot=robot, seed=seed))
  try:
    camera_index(env, camera)   # Before any file is written.
    policy_fn = factory(env, seed)
    writer = VideoWriter(out, fps or 1.0 / frame_period(
        env, substeps_per_frame), gif_scale)
    try:
      episode = render_episode(env, policy_fn, camera, width, height,
                               overlay, substeps_per_frame, max_steps,
                               on_frame=writer.append, keep_frames=False)
    finally:
      path = writer.close()
  finally:
    env.close()
  markers = {m: sum(m in info.markers() for info in episode.infos)
             for m in render_overlay.MARKERS}
  metrics_path = pathlib.Path(path).with_suffix('.json')
  metrics_path.write_text(json.dumps(dict(
      domain=domain, task=task, robot=robot,
      policy=policy if isinstance(policy, str) else getattr(
          policy, '__name__', repr(policy)),
      seed=seed, camera=camera, overlay=overlay, frames=writer.count,
      fps=writer.fps,
      frames_with_markers=markers, task_kwargs=task_kwargs or {},
      metrics=episode.metrics), indent=1) + '\n')
  return path, episode.metrics


def define_flags(flag_values=flags.FLAGS):
  """Defines the command's flags (only when run as a program, so that the
  module can be imported next to other binaries)."""
  fv = flag_values
  flags.DEFINE_string('domain', None, f'Task domain (default: '
                      f'{DEFAULT_DOMAIN}, or the checkpoint\'s).',
                      flag_values=fv)
  flags.DEFINE_string('task', None, f'Task name (default: {DEFAULT_TASK}, '
                      'or the checkpoint\'s).', flag_values=fv)
  flags.DEFINE_string('robot', None, 'Robot name or description file '
                      f'(default: {DEFAULT_ROBOT}, or the checkpoint\'s).',
                      flag_values=fv)
  flags.DEFINE_string('policy', 'random',
                      f'Policy to run: {", ".join(POLICIES)}, or a trained '
                      'checkpoint (run or checkpoint directory).',
                      flag_values=fv)
  flags.DEFINE_string('shield', None, 'Shield mode (default: the task\'s).',
                      flag_values=fv)
  flags.DEFINE_string('motions', None, 'A folder of people for the task '
                      "(task_kwargs['motions']: clips, BVH recordings or one "
                      'sub-folder per task; docs/motion_library.md), played '
                      "with outside_human_model='allow' (default: the "
                      'shipped synthetic library).', flag_values=fv)
  flags.DEFINE_string('out', 'episode.mp4', 'Video (.mp4 or .gif).',
                      flag_values=fv)
  flags.DEFINE_string('camera', 'side',
                      'Workcell camera (front, side, top, human_view).',
                      flag_values=fv)
  flags.DEFINE_integer('seed', 0, 'Seed of the episode and policy.',
                       flag_values=fv)
  flags.DEFINE_integer(
      'max_steps', DEFAULT_MAX_STEPS,
      'At most this many RL steps (the episode may end earlier).',
      flag_values=fv)
  flags.DEFINE_integer('width', 640, 'Frame width in pixels.',
                       flag_values=fv)
  flags.DEFINE_integer('height', 480, 'Frame height in pixels.',
                       flag_values=fv)
  flags.DEFINE_float('fps', None, 'Frames per second (default: real time).',
                     flag_values=fv)
  flags.DEFINE_boolean('overlay', True,
                       'Shield capsules, event markers and caption.',
                       flag_values=fv)
  flags.DEFINE_integer(
      'substeps_per_frame', None,
      'A frame every this many physics steps (default: one per RL step).',
      flag_values=fv)
  flags.DEFINE_float('gif_scale', 1.0, 'Scale of .gif frames, in (0, 1].',
                     flag_values=fv)
  # Names are checked against the registries at parse time.
  registry_flags.check_task('domain', 'task', fv)
  registry_flags.check_robot('robot', fv)
  registry_flags.check_shield('shield', fv)


def main(argv, flag_values=flags.FLAGS):
  del argv
  f = flag_values
  task_kwargs = {}
  if f.shield:
    task_kwargs['shield'] = f.shield
  if f.motions:
    task_kwargs.update(motions=f.motions, outside_human_model='allow')
  path, metrics = run(f.domain, f.task, f.robot, f.policy, f.out, f.camera,
                      f.seed, f.max_steps, f.width, f.height, f.overlay,
                      f.fps, f.substeps_per_frame, f.gif_scale,
                      task_kwargs or None)
  print('episode metrics:')
  for key, value in metrics.items():
    print(f'  {key}: {value:g}')
  print(f'Wrote {path.resolve()} and {path.with_suffix(".json").name}')


if __name__ == '__main__':
  define_flags()
  app.run(main)
