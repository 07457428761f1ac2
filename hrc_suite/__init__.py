"""hrc_suite: human-robot collaboration benchmarks on dm_control composer.

Headless rendering by default, loaded when something renders: dm_control
picks its OpenGL backend from MUJOCO_GL when it is first imported, and
its first choice, GLFW, needs a display. On Linux without a display
(neither DISPLAY nor WAYLAND_DISPLAY set), with MUJOCO_GL unset and EGL
installed, importing hrc_suite imports dm_control's rendering module with
no backend and has it load EGL at the first rendering context. Nothing of
EGL is loaded by a program that never renders (training with libraries
whose own compilers clash with Mesa's, e.g. torch's triton: README.md,
"Rendering without a display"). An explicit MUJOCO_GL always wins; the
default applies only if hrc_suite is imported before dm_control.
"""

import ctypes.util
import os
import sys

# dm_control's name for "no rendering backend" (dm_control/_render/
# constants.py, NO_RENDERER).
_NO_RENDERER = 'disable'


def headless_gl_backend(environ, platform,
                        find_library=ctypes.util.find_library):
  """The MUJOCO_GL backend to load on first use ('egl'), or None to leave
  dm_control's choice alone."""
  if 'MUJOCO_GL' in environ or not platform.startswith('linux'):
    return None
  if environ.get('DISPLAY') or environ.get('WAYLAND_DISPLAY'):
    return None
  # Without libEGL, loading EGL would fail; dm_control's own choice
  # (OSMesa, or no renderer) is better then.
  return 'egl' if find_library('EGL') else None


def _load_egl_on_first_use():
  """Imports dm_control's rendering module without a backend and makes
  its Renderer import EGL when the first context is made."""
  os.environ['MUJOCO_GL'] = _NO_RENDERER
  try:
    from dm_control import _render   # pylint: disable=g-import-not-at-top
  finally:
    del os.environ['MUJOCO_GL']

  def renderer(*args, **kwargs):
    context = _render._import_egl()   # pylint: disable=protected-access
    _render.Renderer = context
    _render.USING_GPU = True   # dm_control's value for EGL
    return context(*args, **kwargs)

  _render.Renderer = renderer
  _render.BACKEND = 'egl'


if (headless_gl_backend(os.environ, sys.platform) == 'egl'
    and 'dm_control._render' not in sys.modules):
  _load_egl_on_first_use()
