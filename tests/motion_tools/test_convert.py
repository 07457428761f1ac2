"""Tests for the BVH folder conversion command."""

import importlib.util
import io
import json
import pathlib
import subprocess
import sys

import pytest

from hrc_suite.human import clip as clip_lib
from hrc_suite.human import recording_cache
from hrc_suite.motion_tools import convert

REPO = pathlib.Path(__file__).resolve().parents[2]


def _stick_figure(per_metre, frames):
  """The T-pose stick figure BVH of tests/human/test_bvh.py (loaded from
  its file)."""
  spec = importlib.util.spec_from_file_location(
      'hrc_test_bvh', REPO / 'tests' / 'human' / 'test_bvh.py')
  module = importlib.util.module_from_spec(spec)
  spec.loader.exec_module(module)
  return module.stick_figure(per_metre, frames)


@pytest.fixture(name='recordings')
def recordings_fixture(tmp_path):
  """A reference-style tree: two task folders, BVH files and info JSON."""
  src = tmp_path / 'src'
  inspection = src / 'ObjectInspection'
  inspection.mkdir(parents=True)
  (inspection / '0.bvh').write_text(_stick_figure(1000, 300))
  (inspection / '0_info.json').write_text(json.dumps({
      'keyframes': [100, 200], 'loop_amplitudes': [10, 4.1, 7.7],
      'loop_speeds': [0.15, 0.21, 0.0165]}))
  (inspection / '1.bvh').write_text(_stick_figure(1000, 120))
  (inspection / '1_info.json').write_text(json.dumps({
      'keyframes': [50, 100], 'loop_amplitudes': [10, 4.1, 7.7],
      'loop_speeds': [0.15, 0.21, 0.0165]}))
  other = src / 'Dance'
  other.mkdir()
  (other / 'a.bvh').write_text(_stick_figure(100, 80))
  return src


def test_converts_a_tree_of_task_folders(recordings, tmp_path):
  out, err = io.StringIO(), io.StringIO()
  failures = convert.convert(recordings, tmp_path / 'dst', out=out, err=err)
  assert failures == 0 and not err.getvalue()
  lines = out.getvalue().splitlines()
  assert len(lines) == 3
  assert 'Dance_a.json: 80 frames at 100 fps' in lines[0]
  assert 'ObjectInspection_0.json: 300 frames at 100 fps (3.0 s), task ' \
         "inspection, 1 idle phase(s) ['object_presented']" in lines[1]
  clips = clip_lib.load_folder(tmp_path / 'dst' / 'inspection')
  assert [c.name for c in clips] == ['ObjectInspection_0', 'ObjectInspection_1']
  (phase,) = clips[0].idle_phases
  assert phase.event == 'object_presented'
  assert clips[0].keyframes[phase.keyframe] == 100
  (dance,) = clip_lib.load_folder(tmp_path / 'dst' / 'Dance')
  assert dance.task == 'other' and dance.idle_phases == ()
  assert dance.metadata['units_m'] == 0.01


def test_broken_file_is_named_with_its_line(recordings, tmp_path):
  broken = recordings / 'ObjectInspection' / '1.bvh'
  lines = broken.read_text().splitlines()
  lines[-2] = lines[-2] + ' 7'   # one value too many on the next-to-last frame.
  broken.write_text('\n'.join(lines) + '\n')
  out, err = io.StringIO(), io.StringIO()
  failures = convert.convert(recordings, tmp_path / 'dst', out=out, err=err)
  assert failures == 1
  assert len(out.getvalue().splitlines()) == 2
  message = err.getvalue()
  assert f'FAILED {broken}: {broken}: line {len(lines) - 1}: expected 39 ' \
         f'channel values, found 40' in message


def test_bad_info_is_named(recordings, tmp_path):
  info = recordings / 'ObjectInspection' / '0_info.json'
  info.write_text('{"keyframes": [100, 900]}')
  err = io.StringIO()
  assert convert.convert(recordings, tmp_path / 'dst', out=io.StringIO(),
                         err=err) == 1
  assert f"{info}: field 'keyframes'" in err.getvalue()


def test_flat_folder_with_task_flag_loads_as_the_task_loads_it(recordings, tmp_path):
  folder = recordings / 'ObjectInspection'
  assert convert.main([str(folder), str(tmp_path / 'flat'),
                       '--task=inspection', '--units=mm']) == 0
  names = sorted(p.name for p in (tmp_path / 'flat').iterdir())
  assert names == ['ObjectInspection_0.json', 'ObjectInspection_0.npz',
                   'ObjectInspection_1.json', 'ObjectInspection_1.npz']
  saved = recording_cache.load_task_folder(tmp_path / 'flat', 'inspection')
  direct = recording_cache.load_task_folder(folder, 'inspection',
                                            use_cache=False)
  assert [c.name for c in saved] == [c.name for c in direct]
  assert (saved[0].positions == direct[0].positions).all()
  with pytest.raises(clip_lib.ClipError, match='no clips or .bvh files'):
    recording_cache.load_task_folder(tmp_path, 'inspection')


def test_command_line(recordings, tmp_path):
  ok = subprocess.run(
      [sys.executable, '-m', 'hrc_suite.motion_tools.convert', str(recordings),
       str(tmp_path / 'dst')], capture_output=True, text=True, cwd=REPO,
      check=False)
  assert ok.returncode == 0, ok.stderr
  assert ok.stdout.count('\n') == 3
  missing = subprocess.run(
      [sys.executable, '-m', 'hrc_suite.motion_tools.convert',
       str(tmp_path / 'nowhere'), str(tmp_path / 'dst')],
      capture_output=True, text=True, cwd=REPO, check=False)
  assert missing.returncode == 2 and 'not a folder' in missing.stderr


@pytest.mark.recordings
def test_real_recordings_convert(tmp_path, recordings_dir):
  out = io.StringIO()
  assert convert.convert(recordings_dir, tmp_path, out=out,
                         err=io.StringIO()) == 0
  expected = len(list(recordings_dir.glob('*/*.bvh')))
  assert len(out.getvalue().splitlines()) == expected
  for task in ('handover_robot_to_human', 'stacking', 'pick_place'):
    assert clip_lib.load_folder(tmp_path / task)
