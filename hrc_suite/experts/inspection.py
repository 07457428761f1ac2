"""Inspection expert: pick the cube (as the pick-and-place expert), lift
it, carry it in a straight line to the inspection target and hold it there,
gripper closed, until the person has inspected it and left (the task's
success, at the end of their clip; docs/tasks.md).

Phases from the observed state each step: not in the hand: approach /
close / reopen exactly as `pick_place.PickPlaceExpert` (with the inspection
grasp height); in the hand and still low over the table (cube centre less
than LIFT above its resting height, far from the target): rise vertically;
otherwise aim the cube's centre at the target and hold. The shield stops the
robot while the person is close (they come to take a look): the aim stays,
so the expert holds the cube wherever the shield stopped it and continues
when allowed. Privileged: none (observables only).
"""

from typing import Mapping

import numpy as np

from hrc_suite import experts
from hrc_suite import layout
from hrc_suite.experts import pick_place as pick_place_expert
from hrc_suite.tasks import inspection

# Cube centre height over its resting height before it moves sideways
# (clears the table and nothing else is on it).
LIFT = 0.1                 # m
# Horizontal distance to the target under which the lift is not needed.
NEAR_TARGET = 0.05         # m
# Approach height over the grasp: the task checks IK reachability this high
# (inspection.HOVER_HEIGHT), not the reference's 0.2 m.
HOVER = inspection.HOVER_HEIGHT
RESTING_Z = layout.TABLE_TOP_Z + 0.02   # m, centre of a 4 cm cube on it


@experts.register('inspection', 'default')
class InspectionExpert(pick_place_expert.PickPlaceExpert):
  """Picks the cube and presents it at the inspection target."""

  OBSERVED = ('object_gripped', 'object_position', 'target_position',
              'gripper_aperture', 'eef_position', 'joint_positions')
  TASKS = (('inspection', 'default'),)
  GRASP_ABOVE = inspection.GRASP_TCP_ABOVE_CENTRE
  HOVER = HOVER

  def plan(self, observation: Mapping[str, np.ndarray]
           ) -> tuple[str, np.ndarray, float]:
    """The phase and where the TCP and gripper go
    (`pick_place.PickPlaceExpert.plan`).

    Args:
      observation: the OBSERVED observables now.

    Returns:
      (phase name, TCP aim (3,), gripper command).
    """
    if not self.in_hand(observation):
      return self._pick(observation)
    self._reopening = False
    tcp = observation['eef_position']
    cube = observation['object_position']
    target = observation['target_position']
    aim = target + (tcp - cube)   # The TCP where the cube is at the target.
    if (cube[2] < RESTING_Z + LIFT - 0.01 and
        np.linalg.norm(target[:2] - cube[:2]) > NEAR_TARGET):
      return 'lift', np.array([tcp[0], tcp[1], tcp[2] + (
          RESTING_Z + LIFT - cube[2])]), pick_place_expert.CLOSED
    return 'present', aim, pick_place_expert.CLOSED
