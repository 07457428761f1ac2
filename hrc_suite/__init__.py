"""hrc_suite: human-robot collaboration benchmarks on dm_control composer.

OpenGL is loaded when something first renders, not at import. dm_control
and MuJoCo load the backend MUJOCO_GL names when they are first imported
(MuJoCo maps libEGL at `import mujoco` under MUJOCO_GL=egl), and a
program that never renders (training with libraries whose own compilers
clash with Mesa's, e.g. torch's triton: README.md, "Rendering without a
display") should not carry it. So importing hrc_suite before them imports
both with no backend and has them load it at the first rendering context
(dm_control's Renderer, MuJoCo's GLContext):

* the backend MUJOCO_GL names, where it is 'egl', 'osmesa' or 'glfw'
  (MUJOCO_GL itself is left as set, for subprocesses);
* on Linux without a display (neither DISPLAY nor WAYLAND_DISPLAY set),
  with MUJOCO_GL unset and EGL installed, EGL (MUJOCO_GL stays unset).

Any other MUJOCO_GL ('off', 'disable', ...) is dm_control's and MuJoCo's
to read, and nothing is deferred if either was imported before hrc_suite.
"""

import ctypes.util
import importlib
import os
import sys

# dm_control's name for "no rendering backend" (dm_control/_render/
# constants.py, NO_RENDERER), which MuJoCo also reads as none
# (mujoco/rendering/classic/gl_context.py).
_NO_RENDERER = 'disable'
# Backends that load a native library when imported.
_DEFERRABLE = ('egl', 'osmesa', 'glfw')


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


def deferred_gl_backend(environ, platform,
                        find_library=ctypes.util.find_library):
  """The backend to load at the first rendering context: the one MUJOCO_GL
  names where it loads a native library ('egl', 'osmesa', 'glfw'), else
  `headless_gl_backend`'s default where MUJOCO_GL is unset, else None."""
  named = environ.get('MUJOCO_GL')
  if named is not None:
    named = named.lower().strip()
    return named if named in _DEFERRABLE else None
  return headless_gl_backend(environ, platform, find_library)


def _load_on_first_use(backend):
  """Imports dm_control's rendering module and MuJoCo with no backend and
  makes dm_control's Renderer and MuJoCo's GLContext import `backend`
  when the first context is made."""
  named = os.environ.get('MUJOCO_GL')
  os.environ['MUJOCO_GL'] = _NO_RENDERER
  try:
    from dm_control import _render   # pylint: disable=g-import-not-at-top
    import mujoco   # pylint: disable=g-import-not-at-top
    from mujoco.rendering.classic import gl_context   # pylint: disable=g-import-not-at-top
  finally:
    if named is None:
      del os.environ['MUJOCO_GL']
    else:
      os.environ['MUJOCO_GL'] = named
  importer = {'egl': _render._import_egl,   # pylint: disable=protected-access
              'osmesa': _render._import_osmesa,   # pylint: disable=protected-access
              'glfw': _render._import_glfw}[backend]   # pylint: disable=protected-access

  def renderer(*args, **kwargs):
    context = importer()
    _render.Renderer = context
    # dm_control's value for the backend (dm_control/_render/__init__.py).
    _render.USING_GPU = backend in ('egl', 'glfw')
    return context(*args, **kwargs)

  def mujoco_context(*args, **kwargs):
    context = importlib.import_module(f'mujoco.{backend}').GLContext
    gl_context.GLContext = mujoco.GLContext = context
    return context(*args, **kwargs)

  _render.Renderer = renderer
  _render.BACKEND = backend
  gl_context.GLContext = mujoco.GLContext = mujoco_context


_BACKEND = deferred_gl_backend(os.environ, sys.platform)
if (_BACKEND is not None and 'dm_control._render' not in sys.modules
    and 'mujoco' not in sys.modules):
  _load_on_first_use(_BACKEND)
