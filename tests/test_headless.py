"""Headless by default: without a display, importing hrc_suite picks EGL."""

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
# Renders a small scene through dm_control after importing hrc_suite.
_RENDER = """
import os
import hrc_suite
from dm_control import mujoco
from dm_control import _render
physics = mujoco.Physics.from_xml_string(
    '<mujoco><worldbody><light pos="0 0 3"/><geom type="sphere" size="0.2"'
    ' rgba="1 0 0 1"/></worldbody></mujoco>')
frame = physics.render(48, 64)
print(os.environ.get('MUJOCO_GL'), _render.BACKEND, frame.shape,
      int(frame.max()))
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


def test_no_default_without_libegl():
  assert hrc_suite.headless_gl_backend(
      {}, 'linux', find_library=lambda name: None) is None


@_HEADLESS
def test_import_without_display_renders_with_egl_and_no_glfw_error():
  result = _run(_RENDER)
  assert result.returncode == 0, result.stderr
  assert 'GLFW' not in result.stderr, result.stderr
  gl, backend, *_, brightest = result.stdout.split()
  assert (gl, backend) == ('egl', 'egl')
  assert int(brightest) > 0, 'blank frame'


@_HEADLESS
def test_explicit_mujoco_gl_wins():
  result = _run('import os, hrc_suite; print(os.environ["MUJOCO_GL"])',
                MUJOCO_GL='osmesa')
  assert result.returncode == 0, result.stderr
  assert result.stdout.split() == ['osmesa']
