"""Stable-Baselines3's SAC trains on hrc_suite (examples/sb3_sac.py), in a
fresh process without a display, with MUJOCO_GL unset and set to egl:
torch's triton and an EGL renderer loaded at import would crash
(hrc_suite/__init__.py loads a renderer at the first render only)."""

import importlib.util
import os
import subprocess
import sys

import pytest

_REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
_MISSING = [name for name in ('torch', 'stable_baselines3', 'gymnasium')
            if importlib.util.find_spec(name) is None]


@pytest.mark.slow
@pytest.mark.skipif(bool(_MISSING), reason=(
    f'needs {", ".join(_MISSING)} (pip install -e \'.[gym]\' torch '
    'stable-baselines3)'))
@pytest.mark.parametrize('backend', [None, 'egl'])
def test_sb3_sac_trains_a_thousand_steps(backend):
  env = {k: v for k, v in os.environ.items()
         if k not in ('MUJOCO_GL', 'DISPLAY', 'WAYLAND_DISPLAY')}
  if backend is not None:
    env['MUJOCO_GL'] = backend
  env['PYTHONPATH'] = _REPO
  result = subprocess.run(
      [sys.executable, os.path.join(_REPO, 'examples', 'sb3_sac.py'),
       '--steps=1000'], env=env, capture_output=True, text=True,
      timeout=1800, check=False)
  assert result.returncode == 0, result.stderr[-2000:]
  assert 'SAC trained 1000 steps' in result.stdout
