"""pytest imports this before any test module: hrc_suite first, so that
its headless rendering default applies before a test imports dm_control
(hrc_suite/__init__.py)."""

import hrc_suite  # pylint: disable=unused-import
