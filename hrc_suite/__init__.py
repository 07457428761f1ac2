"""hrc_suite: human-robot collaboration benchmarks on dm_control composer.

Headless rendering by default: dm_control picks its OpenGL backend from
MUJOCO_GL when it is first imported, and its first choice, GLFW, needs a
display. So on Linux without a display (neither DISPLAY nor WAYLAND_DISPLAY
set) and with EGL installed, importing hrc_suite sets MUJOCO_GL=egl if
MUJOCO_GL is unset. An explicit MUJOCO_GL always wins; it takes effect only
if hrc_suite is imported before dm_control (README.md, "Rendering").
"""

import ctypes.util
import os
import sys


def headless_gl_backend(environ, platform,
                        find_library=ctypes.util.find_library):
  """The MUJOCO_GL to set by default ('egl'), or None to leave it alone."""
  if 'MUJOCO_GL' in environ or not platform.startswith('linux'):
    return None
  if environ.get('DISPLAY') or environ.get('WAYLAND_DISPLAY'):
    return None
  # Without libEGL, MUJOCO_GL=egl would make importing dm_control fail;
  # dm_control's own choice (OSMesa, or no renderer) is better then.
  return 'egl' if find_library('EGL') else None


_BACKEND = headless_gl_backend(os.environ, sys.platform)
if _BACKEND is not None:
  os.environ['MUJOCO_GL'] = _BACKEND
