"""JAX agents for hrc_suite (Acme-shaped).

hrc_suite is imported first so that its headless rendering default
applies before anything imports dm_control (hrc_suite/__init__.py).
"""

import hrc_suite  # pylint: disable=unused-import
