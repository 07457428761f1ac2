"""pytest imports this before any test module: hrc_suite first, so that
its headless rendering default applies before a test imports dm_control
(hrc_suite/__init__.py)."""

import hrc_suite  # pylint: disable=unused-import
import pytest


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
