"""Episode videos with the shield overlay: real renders, decoded and checked."""

import json
import os

os.environ.setdefault('MUJOCO_GL', 'egl')

from dm_control.mujoco import engine
import numpy as np
import pytest

from hrc_suite.rendering import episode as render
from hrc_suite.rendering import overlay as render_overlay
from hrc_suite import rendering
from hrc_suite import layout
from hrc_suite import suite
# The modules behind render.make_policy's 'expert' and 'noisy_expert'
# policies, imported plainly so that a broken one fails here.
# pylint: disable=unused-import
from hrc_suite.experts import noise
from hrc_suite.experts import reach as reach_expert
# pylint: enable=unused-import
from hrc_suite.human import clip as clip_lib
from hrc_suite.human import keypoints
from hrc_suite.tasks import reach

WIDTH, HEIGHT = 128, 96
# A person gliding from the reach station into the Panda at home: the pelvis
# glides in a straight line at 1.5 m/s (below the shield model's 2 m/s
# keypoint bound) to this point beside the robot's upper arm (world xy,
# relative to the robot base). Measured: with SSM and random actions the
# shield intervenes from RL step 7 and the person touches the stopped robot
# (safe contact) from step 9; unshielded, contacts at steps 9-11 are
# critical.
_GLIDE_TARGET = np.array([0.45, 0.25])   # m
_GLIDE_SPEED = 1.5                       # m/s
_WALK_IN_STEPS = 12                      # RL steps rendered


def _walk_in_clip():
  """The first pose of a shipped reach clip, gliding into the robot."""
  pose = clip_lib.shipped_library('reach')[0].positions[0]
  x, y, yaw = reach.Reach.HUMAN_STATION
  rotation = np.array([[np.cos(yaw), -np.sin(yaw)],
                       [np.sin(yaw), np.cos(yaw)]])   # clip -> world
  pelvis = rotation @ pose[keypoints.KEYPOINT_INDEX['pelvis'], :2] + (x, y)
  target = np.asarray(layout.ROBOT_BASE_POS[:2]) + _GLIDE_TARGET
  glide = rotation.T @ (target - pelvis)               # in the clip frame
  distance = np.linalg.norm(glide)
  fps = 25.0
  t = np.arange(0.0, 3.0 + 1e-9, 1.0 / fps)
  shift = np.minimum(t * _GLIDE_SPEED, distance) / distance
  positions = np.repeat(pose[None], len(t), axis=0)
  positions[:, :, :2] += shift[:, None, None] * glide
  return clip_lib.validate(clip_lib.Clip(
      name='walk_in', task='reach', fps=fps,
      positions=positions.astype(np.float32)))


def _walk_in(shield):
  """Random actions while the person walks into the robot: the frames, their
  infos and each RL step's step_metrics as the task reported them."""
  env = suite.load('reach', 'dense', task_kwargs={
      'robot': 'panda', 'shield': shield, 'motions': [_walk_in_clip()],
      'done_at_success': False}, environment_kwargs={'random_state': 0})
  random_policy = render.make_policy('random', env, 0)
  reported = []

  def policy(timestep):
    if not timestep.first():
      reported.append(dict(env.task.step_metrics))
    return random_policy(timestep)

  episode = render.render_episode(env, policy, 'side', WIDTH, HEIGHT,
                                  max_steps=_WALK_IN_STEPS)
  reported.append(dict(env.task.step_metrics))
  return episode, reported


def _has_marker(frame, marker):
  """Most of the marker's badge is its colour."""
  left, top, right, bottom = render_overlay.marker_box(marker, WIDTH, HEIGHT)
  badge = frame[top:bottom + 1, left:right + 1].astype(int)
  colour = np.array(render_overlay.MARKER_COLOURS[marker])
  return np.mean(np.abs(badge - colour).max(axis=-1) <= 2) > 0.5


def test_render_writes_a_video_with_the_overlay(tmp_path):
  path, metrics = render.run('handover', 'robot_to_human', robot='panda',
                             policy='random', out=tmp_path / 'h.mp4', seed=3,
                             max_steps=6, width=WIDTH, height=HEIGHT)
  video = rendering.read_video(path)
  assert video.shape == (7, HEIGHT, WIDTH, 3)
  assert not any(rendering.is_blank(frame) for frame in video)
  assert video.mean() > 20   # Not black.
  assert np.abs(video[0].astype(int) - video[-1]).mean() > 1.0
  saved = json.loads(path.with_suffix('.json').read_text())
  assert saved['overlay'] and saved['frames'] == 7 and saved['fps'] == 10
  assert saved['metrics'] == metrics and metrics['steps'] == 6
  # The caption bar is drawn: a dark strip at the bottom.
  bar = render_overlay.caption_height(HEIGHT)
  assert video[:, -bar + 1:, :].mean() < 60


def test_overlay_changes_pixels(tmp_path):
  videos, metrics = {}, {}
  for overlay in (True, False):
    path, metrics[overlay] = render.run(
        'reach', 'dense', robot='schunk', policy='random',
        out=tmp_path / f'{overlay}.mp4', seed=1, max_steps=3, width=WIDTH,
        height=HEIGHT, overlay=overlay)
    videos[overlay] = rendering.read_video(path).astype(int)
  assert videos[True].shape == videos[False].shape
  assert metrics[True] == metrics[False]   # Drawing changes no dynamics.
  assert np.abs(videos[True] - videos[False]).mean() > 3.0


def test_shield_capsules_are_drawn_into_the_scene():
  env = suite.load('handover', 'robot_to_human',
                   task_kwargs={'robot': 'panda', 'seed': 0})
  env.reset()
  env.step(np.array([0.0, 0.0, 0.0, 1.0]))
  physics = env.physics
  camera = render.camera_index(env, 'side')
  overlay = render_overlay.ShieldOverlay(env.task.shield)
  plain = engine.Camera(physics, HEIGHT, WIDTH, camera).render().copy()
  drawn = engine.Camera(physics, HEIGHT, WIDTH, camera, max_geom=3000,
                        scene_callback=overlay).render().copy()
  assert overlay.drawn['robot'] > 0 and overlay.drawn['human'] > 0
  assert overlay.dropped == 0
  changed = np.abs(drawn.astype(int) - plain).max(axis=-1) > 8
  assert changed.mean() > 0.05
  # Robot blue and human orange tints both appear.
  shift = drawn.astype(int) - plain
  assert np.any(changed & (shift[..., 2] > shift[..., 0]))
  assert np.any(changed & (shift[..., 0] > shift[..., 2]))


def test_markers_appear_where_step_metrics_say_so():
  shielded, reported = _walk_in('ssm')
  assert len(shielded.frames) == len(reported) + 1 == _WALK_IN_STEPS + 1
  # The first frame shows the reset: no step, no marker.
  assert not any(_has_marker(shielded.frames[0], m)
                 for m in render_overlay.MARKERS)
  seen = set()
  for frame, step in zip(shielded.frames[1:], reported):
    expected = {
        'intervention': step['shield_interventions'] > 0,
        'static': step['contacts_static'] > 0,
        'human_allowed': step['contacts_human_allowed'] > 0,
        'human_critical': step['contacts_human_critical'] > 0}
    for marker, present in expected.items():
      assert _has_marker(frame, marker) == present, (marker, step)
      if present:
        seen.add(marker)
  # The scenario makes the shield intervene and the person touch the
  # stopped robot.
  assert {'intervention', 'human_allowed'} <= seen
  unshielded, reported = _walk_in('off')
  critical = [_has_marker(f, 'human_critical')
              for f in unshielded.frames[1:]]
  assert critical == [s['contacts_human_critical'] > 0 for s in reported]
  assert any(critical)


def test_substep_frames_and_small_gif(tmp_path):
  path, _ = render.run('reach', 'dense', robot='schunk', policy='random',
                       out=tmp_path / 'r.gif', seed=2, max_steps=2,
                       width=WIDTH, height=HEIGHT, substeps_per_frame=5,
                       gif_scale=0.5)
  video = rendering.read_video(path)
  # A frame after reset, then one every 5 of the 25 physics steps.
  assert video.shape == (11, HEIGHT // 2, WIDTH // 2, 3)
  saved = json.loads(path.with_suffix('.json').read_text())
  assert saved['fps'] == pytest.approx(50.0)   # 20 ms a frame: real time.


def test_annotate_draws_each_marker_and_the_caption():
  frame = np.full((HEIGHT, WIDTH, 3), 128, dtype=np.uint8)
  quiet = render_overlay.FrameInfo(time=1.0, reward=-1.0,
                                   episode_return=-10.0, success=False)
  plain = render_overlay.annotate(frame, quiet)
  assert not any(_has_marker(plain, m) for m in render_overlay.MARKERS)
  for marker in render_overlay.MARKERS:
    info = render_overlay.FrameInfo(
        time=1.0, reward=-1.0, episode_return=-10.0, success=True,
        intervened=marker == 'intervention',
        contacts=() if marker == 'intervention' else (marker,))
    marked = render_overlay.annotate(frame, info)
    assert [_has_marker(marked, m) for m in render_overlay.MARKERS] == [
        m == marker for m in render_overlay.MARKERS]
  assert 'success yes' in info.caption() and 'return -10.00' in info.caption()
  with pytest.raises(ValueError, match='marker'):
    render_overlay.marker_box('nope', WIDTH, HEIGHT)


def test_union_keeps_capsules_not_inside_others():
  c1 = np.array([[[0.0, 0, 0]], [[0.0, 0, 0]], [[0.0, 0, 0]], [[2.0, 0, 0]]])
  c2 = c1 + [0.0, 0.0, 0.5]
  r = np.array([[0.1], [0.1], [0.3], [0.1]])
  # Slices 0, 1 (identical) lie inside slice 2; slice 3 is elsewhere.
  kept = render_overlay.union_capsules(c1, c2, r)
  assert sorted(kept[2].tolist()) == [0.1, 0.3]
  assert {tuple(p) for p in kept[0]} == {(0.0, 0.0, 0.0), (2.0, 0.0, 0.0)}
  same = render_overlay.union_capsules(c1[:2], c2[:2], r[:2])
  assert len(same[2]) == 1
  with pytest.raises(ValueError, match='K, L'):
    render_overlay.union_capsules(c1[0], c2[0], r[0])


def test_smallest_model_per_body():
  c1 = np.zeros((2, 1, 2, 3))
  c2 = np.zeros((2, 1, 2, 3))
  c2[0, 0, 0, 2] = 1.0      # model 0, body 0: long and thin
  r = np.array([[[0.1, 0.5]], [[0.3, 0.2]]])
  _, p2, radius = render_overlay.smallest_model(c1, c2, r)
  assert radius.tolist() == [[0.1, 0.2]]
  assert p2[0, 0, 2] == 1.0


def test_bad_camera_and_policy_names_are_clear_errors(tmp_path):
  with pytest.raises(ValueError, match="'nope'.*expert, noisy_expert, "
                     'random, zero'):
    render.run('reach', 'dense', policy='nope', out=tmp_path / 'x.mp4')
  with pytest.raises(ValueError, match="'nope'.*front, side, top, "
                     'human_view'):
    render.run('reach', 'dense', robot='schunk', camera='nope',
               out=tmp_path / 'x.mp4', max_steps=1)
  with pytest.raises(ValueError, match="'.avi'"):
    render.run('reach', 'dense', out=tmp_path / 'x.avi')
  with pytest.raises(ValueError, match='even frame size.*width=95'):
    render.run('reach', 'dense', out=tmp_path / 'x.mp4', width=95)
  with pytest.raises(ValueError, match='gif_scale'):
    render.run('reach', 'dense', out=tmp_path / 'x.gif', gif_scale=2.0)


def test_expert_and_noisy_expert_policies():
  env = suite.load('reach', 'dense', task_kwargs={'robot': 'schunk',
                                                 'seed': 0})
  timestep = env.reset()
  expert = render.make_policy('expert', env, 0)(timestep)
  noisy = [render.make_policy('noisy_expert', env, seed)(timestep)
           for seed in (0, 0, 1)]
  assert expert.shape == env.action_spec().shape
  np.testing.assert_array_equal(noisy[0], noisy[1])
  assert not np.array_equal(noisy[0], noisy[2])
  # The noise's share of the action is 2 % (the reference's mixing).
  assert np.abs(noisy[0] - expert).max() < 0.2
