"""Fixtures of the safety tests."""

import pytest

import shield_harness


@pytest.fixture
def motions_dir():
  """The real motion clips (../shared/motions), or skip."""
  if not shield_harness.MOTIONS_DIR.is_dir():
    pytest.skip('real motion clips not found at '
                f'{shield_harness.MOTIONS_DIR.resolve()}')
  return shield_harness.MOTIONS_DIR
