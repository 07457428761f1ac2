"""Shared test set-up: hrc_suite's import, the real recordings, fixtures.

pytest imports this before any test module: hrc_suite first, so that its
headless rendering default applies before a test imports dm_control
(hrc_suite/__init__.py).

Real human recordings are test data the package never needs. The motions
folder is `../shared/motions` from the repository root, or the folder that
the environment variable HRC_SUITE_RECORDINGS names (a relative path is
taken from the repository root); the recordings are its
`human-robot-animations` folder. Tests that need them carry the marker
`recordings` (pytest.ini) and get the folder from the `recordings_dir`
fixture, or one recording folder or file per test through the arguments
`recording_folder` (a task folder's name) and `recording_file` (a .bvh
file's path), which this module parametrizes. When the folder is absent
every marked test is skipped with a message naming it; a test that uses
these fixtures without the marker is a usage error.

  HRC_SUITE_RECORDINGS=/elsewhere/motions python -m pytest -m recordings
"""

import os
import pathlib

import hrc_suite  # pylint: disable=unused-import
import pytest

REPO = pathlib.Path(__file__).resolve().parents[1]
RECORDINGS_ENV = 'HRC_SUITE_RECORDINGS'
# The motions folder, and the recordings in it that the tests use.
MOTIONS_ROOT = (REPO / (os.environ.get(RECORDINGS_ENV)
                       or os.path.join('..', 'shared', 'motions'))).resolve()
RECORDINGS_DIR = MOTIONS_ROOT / 'human-robot-animations'
# Arguments that need the recordings: tests taking them are marked.
RECORDING_ARGUMENTS = ('recordings_dir', 'recording_folder', 'recording_file')


def _recording_folders():
  """Names of the task folders in RECORDINGS_DIR (none when absent)."""
  if not RECORDINGS_DIR.is_dir():
    return []
  return sorted(p.name for p in RECORDINGS_DIR.iterdir() if p.is_dir())


def _recording_files():
  """Paths of the .bvh files of RECORDINGS_DIR's task folders."""
  if not RECORDINGS_DIR.is_dir():
    return []
  return sorted(RECORDINGS_DIR.glob('*/*.bvh'))


def pytest_generate_tests(metafunc):
  """One test per task folder (`recording_folder`) or per .bvh file
  (`recording_file`); a single 'absent' case when there are none, which
  the marker's skip reports."""
  if 'recording_folder' in metafunc.fixturenames:
    metafunc.parametrize('recording_folder',
                         _recording_folders() or ['absent'])
  if 'recording_file' in metafunc.fixturenames:
    files = _recording_files()
    metafunc.parametrize(
        'recording_file', files or [None],
        ids=[f'{p.parent.name}/{p.name}' for p in files] or ['absent'])


def pytest_collection_modifyitems(config, items):
  """Fails on unmarked tests that use the recordings; skips the marked
  tests when the recordings are absent."""
  del config
  unmarked = [
      item.nodeid for item in items
      if set(RECORDING_ARGUMENTS) & set(getattr(item, 'fixturenames', ()))
      and item.get_closest_marker('recordings') is None]
  if unmarked:
    raise pytest.UsageError(
        'tests that use the recordings need @pytest.mark.recordings: '
        + ', '.join(unmarked))
  if RECORDINGS_DIR.is_dir():
    return
  skip = pytest.mark.skip(reason=(
      f'real recordings not found: no folder {RECORDINGS_DIR} (set '
      f'{RECORDINGS_ENV} to the folder holding human-robot-animations)'))
  for item in items:
    if item.get_closest_marker('recordings') is not None:
      item.add_marker(skip)


@pytest.fixture(scope='session')
def recordings_dir():
  """The real recordings' folder (`human-robot-animations`)."""
  return RECORDINGS_DIR


@pytest.fixture(scope='session')
def library_events():
  """{shipped motion library: the events (EVENTS) of the shipped tasks
  that play it}, asked of the task registry; the tasks agree."""
  from hrc_suite import suite  # pylint: disable=g-import-not-at-top
  events = {}
  for domain, task in suite.all_tasks():
    cls = suite.task_class(domain, task)
    if cls is None or not cls.__module__.startswith('hrc_suite.tasks.'):
      continue   # A task a test module registered.
    assert events.setdefault(cls.MOTIONS, cls.EVENTS) == cls.EVENTS, cls
  return events
