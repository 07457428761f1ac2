"""Static and self-collision prevention of goals (docs/safety.md).

`prevention.CollisionPrevention` checks a goal and the path to it against
the workcell and the robot itself; `from hrc_suite.safety import
collision_prevention` and `collision_prevention.CollisionPrevention(...)`
reach it here too. Modules: `prevention` (the checks and their NumPy
reference), `kernels` (the compiled checks) and `bounds` (the compiled
sweep's conservative broad phase).
"""

from hrc_suite.safety.collision_prevention.prevention import CollisionPrevention
from hrc_suite.safety.collision_prevention.prevention import FilteredAction
from hrc_suite.safety.collision_prevention.prevention import POLICIES
from hrc_suite.safety.collision_prevention.prevention import workcell_boxes

__all__ = ('POLICIES', 'CollisionPrevention', 'FilteredAction',
           'workcell_boxes')
