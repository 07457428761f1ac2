"""Rendering: real offscreen frames and videos that are not blank."""

import os

os.environ.setdefault('MUJOCO_GL', 'egl')

from dm_control import mjcf
import numpy as np
import pytest

from hrc_suite import rendering


def _scene():
  model = mjcf.RootElement()
  model.worldbody.add('light', pos=[0, 0, 3], dir=[0, 0, -1])
  model.worldbody.add('geom', type='plane', size=[2, 2, 0.1],
                      rgba=[0.3, 0.3, 0.35, 1])
  model.worldbody.add('geom', type='sphere', size=[0.2], pos=[0, 0, 0.2],
                      rgba=[0.9, 0.2, 0.1, 1])
  model.worldbody.add('camera', name='eye', pos=[0, -1.5, 0.8],
                      xyaxes=[1, 0, 0, 0, 0.5, 1])
  return mjcf.Physics.from_mjcf_model(model)


def test_render_frame_from_named_camera():
  frame = rendering.render_frame(_scene(), 'eye', width=96, height=64)
  assert frame.shape == (64, 96, 3) and frame.dtype == np.uint8
  assert not rendering.is_blank(frame)


def test_unknown_camera_lists_cameras():
  with pytest.raises(ValueError, match="'nope'.*eye"):
    rendering.render_frame(_scene(), 'nope')


@pytest.mark.parametrize('suffix', ['.mp4', '.gif'])
def test_video_round_trip(tmp_path, suffix):
  physics = _scene()
  frames = []
  for k in range(6):
    physics.named.data.geom_xpos  # Touch to make sure data is live.
    frame = rendering.render_frame(physics, 'eye', width=96, height=64)
    frames.append(np.roll(frame, 4 * k, axis=1))
  path = rendering.write_video(tmp_path / f'clip{suffix}', frames, fps=10)
  video = rendering.read_video(path)
  assert video.shape[1:] == (64, 96, 3)
  assert len(video) >= 5
  assert not rendering.is_blank(video[len(video) // 2])


def test_rejects_unknown_format(tmp_path):
  with pytest.raises(ValueError, match="'.avi'"):
    rendering.write_video(tmp_path / 'x.avi', [np.zeros((8, 8, 3))])


def test_render_command_writes_video_and_metrics(tmp_path):
  from hrc_suite.rendering import episode as render
  import json
  path, metrics = render.run('reach', 'dense', robot='schunk',
                             policy='random', out=tmp_path / 'reach.mp4',
                             seed=1, max_steps=4, width=96, height=64)
  video = rendering.read_video(path)
  assert len(video) == 5 and not rendering.is_blank(video[-1])
  saved = json.loads(path.with_suffix('.json').read_text())
  assert saved['metrics'] == metrics
  assert metrics['steps'] == 4
  assert {'success', 'return', 'shield_interventions',
          'contacts_human_critical'} <= set(metrics)


def test_render_rejects_unknown_policy():
  from hrc_suite.rendering import episode as render
  with pytest.raises(ValueError, match="'nope'.*random"):
    render.make_policy('nope', None, 0)
