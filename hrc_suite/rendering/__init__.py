"""Frames and videos from any composer environment or MuJoCo physics.

The viewer replacement: works headless with MUJOCO_GL=egl (software EGL on
machines without a GPU). Videos are written with imageio's ffmpeg plugin
(mp4, H.264) or as GIF.
"""

import os
import pathlib
from typing import Iterable, Sequence, Union

import numpy as np

DEFAULT_WIDTH = 640
DEFAULT_HEIGHT = 480


def _physics_of(source):
  """Accepts an environment (composer or control) or a physics object."""
  return getattr(source, 'physics', source)


def camera_names(source) -> Sequence[str]:
  """Names of all cameras in the model, in id order."""
  physics = _physics_of(source)
  model = physics.model
  return tuple(model.id2name(i, 'camera') for i in range(model.ncam))


def render_frame(source, camera: Union[str, int] = 0,
                 width: int = DEFAULT_WIDTH, height: int = DEFAULT_HEIGHT,
                 scene_option=None) -> np.ndarray:
  """One RGB frame (height, width, 3) uint8 from a named or numbered camera."""
  physics = _physics_of(source)
  if isinstance(camera, str):
    names = camera_names(physics)
    matches = [n for n in names if n == camera or n.endswith('/' + camera)]
    if not matches:
      raise ValueError(f'Unknown camera {camera!r}: expected one of '
                       f'{", ".join(names) or "(the model has no camera)"}')
    camera = matches[0]
  return physics.render(height=height, width=width, camera_id=camera,
                        scene_option=scene_option)


def is_blank(frame: np.ndarray, min_std: float = 2.0) -> bool:
  """True if a frame is (nearly) one colour, e.g. a failed render."""
  return float(np.asarray(frame, dtype=np.float32).std()) < min_std


def write_video(path: Union[str, os.PathLike], frames: Iterable[np.ndarray],
                fps: float = 25.0) -> pathlib.Path:
  """Writes frames to .mp4 (H.264) or .gif, chosen by the file suffix."""
  import imageio.v2 as imageio  # Deferred: only needed when writing.
  path = pathlib.Path(path)
  suffix = path.suffix.lower()
  if suffix not in ('.mp4', '.gif'):
    raise ValueError(f'Unsupported video format {suffix!r} for {path}: '
                     'expected .mp4 or .gif')
  frames = list(frames)
  if not frames:
    raise ValueError(f'No frames to write to {path}')
  path.parent.mkdir(parents=True, exist_ok=True)
  if suffix == '.mp4':
    # macro_block_size=1 keeps odd sizes; yuv420p plays everywhere.
    with imageio.get_writer(path, fps=fps, codec='libx264', quality=7,
                            macro_block_size=1,
                            pixelformat='yuv420p') as writer:
      for frame in frames:
        writer.append_data(np.asarray(frame, dtype=np.uint8))
  else:
    imageio.mimsave(path, [np.asarray(f, dtype=np.uint8) for f in frames],
                    duration=1.0 / fps, loop=0)
  return path


def read_video(path: Union[str, os.PathLike]) -> np.ndarray:
  """All frames of a video as (T, H, W, 3) uint8 (for tests and checks)."""
  import imageio.v2 as imageio
  return np.stack([np.asarray(f)[..., :3] for f in imageio.mimread(
      path, memtest=False)])
