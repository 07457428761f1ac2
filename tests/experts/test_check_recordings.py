"""The recordings check: per clip what was derived, speed, expert outcome."""

import io

from hrc_suite.experts import check_recordings
from hrc_suite.human import clip as clip_lib


def test_check_prints_each_clip_and_the_expert_outcome(tmp_path):
  folder = tmp_path / 'motions' / 'handover_robot_to_human'
  folder.mkdir(parents=True)
  clip = clip_lib.shipped_library('handover_robot_to_human')[0]
  clip_lib.save_clip(clip, folder)
  out = io.StringIO()
  ok = check_recordings.check(
      tmp_path / 'motions', [('handover', 'robot_to_human'),
                             ('handover', 'human_to_robot')],
      [('panda', 'expert')], episodes=1, work=tmp_path / 'work', out=out)
  text = out.getvalue()
  assert ok, text
  assert f'{clip.name}:' in text
  assert 'targets: handover_point' in text
  assert 'speed: peak' in text and 'within the model' in text
  assert 'panda expert: success 1/1' in text
  # The folder holds no human-to-robot people: that task is not listed.
  assert 'handover/human_to_robot' not in text


def test_check_reports_a_refused_recording(tmp_path):
  """A recording the rules refuse is printed with the import's error and
  fails the check."""
  folder = tmp_path / 'RobotHumanHandover'
  folder.mkdir()
  (folder / '0.bvh').write_text('HIERARCHY\nROOT hip\n')
  out = io.StringIO()
  ok = check_recordings.check(tmp_path, [('handover', 'robot_to_human')],
                              [('panda', 'expert')], episodes=1,
                              work=tmp_path / 'work', out=out)
  assert not ok
  assert '0.bvh: REFUSED:' in out.getvalue()
