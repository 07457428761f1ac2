"""OpenGL loads at the first render only: without a display, importing
hrc_suite has dm_control load EGL when something first renders, and a
backend MUJOCO_GL names loads then too, not at import."""

import ctypes.util
import os
import subprocess
import sys

import pytest

import hrc_suite

_REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
_HEADLESS = pytest.mark.skipif(
    not sys.platform.startswith('linux') or not ctypes.util.find_library(
        'EGL'), reason='the EGL default applies on Linux with libEGL')
# Steps a task, then renders a small scene through dm_control, after
# importing hrc_suite; reports whether libEGL was mapped before and after.
_RENDER = """
import os
import numpy as np
from hrc_suite import suite
from dm_control import mujoco
from dm_control import _render

def egl_loaded():
  with open('/proc/self/maps') as maps:
    return 'libEGL' in maps.read()

env = suite.load('reach', 'dense', task_kwargs={'seed': 0})
env.reset()
env.step(np.zeros(env.action_spec().shape))
before = egl_loaded()
physics = mujoco.Physics.from_xml_string(
    '<mujoco><worldbody><light pos="0 0 3"/><geom type="sphere" size="0.2"'
    ' rgba="1 0 0 1"/></worldbody></mujoco>')
frame = physics.render(48, 64)
print(os.environ.get('MUJOCO_GL'), _render.BACKEND, before, egl_loaded(),
      frame.shape, int(frame.max()))
"""


def _run(code, **environ):
  env = {k: v for k, v in os.environ.items()
         if k not in ('MUJOCO_GL', 'DISPLAY', 'WAYLAND_DISPLAY')}
  env.update(environ, PYTHONPATH=_REPO)
  return subprocess.run([sys.executable, '-c', code], env=env, cwd=_REPO,
                        capture_output=True, text=True, timeout=300,
                        check=False)


@pytest.mark.parametrize('environ, platform, expected', [
    ({}, 'linux', 'egl'),
    ({'DISPLAY': ':0'}, 'linux', None),
    ({'WAYLAND_DISPLAY': 'wayland-0'}, 'linux', None),
    ({'MUJOCO_GL': 'osmesa'}, 'linux', None),   # An explicit choice wins.
    ({}, 'darwin', None),                       # No EGL on macOS.
])
def test_backend_default_needs_linux_without_display(environ, platform,
                                                     expected):
  assert hrc_suite.headless_gl_backend(
      environ, platform, find_library=lambda name: 'libEGL.so.1') == expected


@pytest.mark.parametrize('environ, expected', [
    ({'MUJOCO_GL': 'egl'}, 'egl'),
    ({'MUJOCO_GL': ' OSMesa '}, 'osmesa'),
    ({'MUJOCO_GL': 'glfw', 'DISPLAY': ':0'}, 'glfw'),
    ({'MUJOCO_GL': 'off'}, None),        # no backend: nothing to defer
    ({'MUJOCO_GL': 'disable'}, None),
    ({}, 'egl'),                         # the headless default
    ({'DISPLAY': ':0'}, None),
])
def test_deferred_backend(environ, expected):
  assert hrc_suite.deferred_gl_backend(
      environ, 'linux', find_library=lambda name: 'libEGL.so.1') == expected


def test_no_default_without_libegl():
  assert hrc_suite.headless_gl_backend(
      {}, 'linux', find_library=lambda name: None) is None


@_HEADLESS
def test_without_display_egl_loads_at_the_first_render_only():
  result = _run(_RENDER)
  assert result.returncode == 0, result.stderr
  assert 'GLFW' not in result.stderr, result.stderr
  gl, backend, before, after, *_, brightest = result.stdout.split()
  # MUJOCO_GL stays unset for the program and its subprocesses.
  assert (gl, backend) == ('None', 'egl')
  assert (before, after) == ('False', 'True')
  assert int(brightest) > 0, 'blank frame'


@_HEADLESS
def test_explicit_mujoco_gl_wins():
  result = _run('import os, hrc_suite; from dm_control import _render; '
                'print(os.environ["MUJOCO_GL"], _render.BACKEND)',
                MUJOCO_GL='off')
  assert result.returncode == 0, result.stderr
  assert result.stdout.split() == ['off', 'off']   # dm_control's no-renderer


@_HEADLESS
def test_a_named_backend_loads_at_the_first_render_too():
  """MUJOCO_GL=egl, as dm_control tells headless users: stepping a task
  maps no libEGL (MuJoCo alone would at import); rendering through
  dm_control and through MuJoCo's own Renderer then works."""
  code = _RENDER + """
import mujoco
model = mujoco.MjModel.from_xml_string(
    '<mujoco><worldbody><light pos="0 0 3"/><geom type="sphere" size="0.2"'
    ' rgba="1 0 0 1"/></worldbody></mujoco>')
data = mujoco.MjData(model)
mujoco.mj_forward(model, data)
with mujoco.Renderer(model, 48, 64) as renderer:
  renderer.update_scene(data)
  print(int(renderer.render().max()))
"""
  result = _run(code, MUJOCO_GL='egl')
  assert result.returncode == 0, result.stderr
  lines = result.stdout.split()
  gl, backend, before, after = lines[:4]
  assert (gl, backend) == ('egl', 'egl')   # MUJOCO_GL kept as set
  assert (before, after) == ('False', 'True')
  assert int(lines[-2]) > 0 and int(lines[-1]) > 0, 'blank frame'
