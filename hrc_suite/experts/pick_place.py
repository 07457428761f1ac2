"""Pick-and-place expert: a state machine whose phase is read off the
observed state every step (docs/reference_benchmark.md, Experts).

Geometry (world frame; `grasp` = cube centre + GRASP_TCP_ABOVE_CENTRE, the
TCP position that grasps the cube from above):

* Approach (cube not in the hand, gripper open): the TCP aims at the grasp
  point, but never below a cone around its vertical axis: the aim's height
  is grasp + min(HOVER, CONE_SLOPE x (horizontal error - CONE_RADIUS)), so
  the TCP comes in at HOVER above the cube, then descends straight onto it.
  A TCP below the cone (e.g. after a slip, or the cube pushed) first rises
  vertically, so it never sweeps the fingers through the cube.
* Close: with the TCP within CLOSE_XY horizontally and CLOSE_DZ vertically
  of the grasp point, the gripper closes (+1) and the TCP holds there.
* Carry (the cube in the hand): the same cone around the place point (the
  target point + PLACE_ABOVE, cube centre), with the gripper closed: the
  TCP rises vertically to the cone, moves over the target at HOVER and
  descends. The cube's centre within SUCCESS_DISTANCE of the target is
  success (the episode ends there by default).
* Release: the cube low over the target (within RELEASE_DISTANCE of the
  place point): open. Then a cube at the target and not in the hand means
  done: the open TCP rises to HOVER above it and waits.
* Missed grasp: the gripper (nearly) closed without the cube: open again
  (hysteresis: until the aperture is above OPENED) before descending.

"In the hand": the gripped flag (both fingers touch the cube), or the cube
within IN_HAND of the grasp pose relative to the TCP with the aperture
below HOLDING (closing on the cube), so a flickering contact does not drop
the phase. Within NEAR of its aim the TCP asks for GAIN of the remaining
way per step (a proportional approach): the arm, whose plans accelerate
at 2 rad/s^2, then brakes on the aim instead of overshooting it (the
Schunk, folded over the table, overshot by 5 cm at full steps and lost
its grasps). The shield may slow or stop the robot anywhere: the aims do not
depend on time, the expert simply continues when the robot moves again.

Both action spaces through `steering` (Cartesian: straight TCP line; joint:
one-step gripper-down IK). Privileged: none (observables only).
"""

from typing import Mapping

from dm_control import composer
import numpy as np

from hrc_suite import experts
from hrc_suite.experts import base
from hrc_suite.experts import steering
from hrc_suite.tasks import pick_place

# Reference expert (docs/reference_benchmark.md, Experts): hover 0.2 m above
# the object, close when the horizontal error < 0.035 m and the vertical
# < 0.015 m.
HOVER = 0.2                # m above the grasp / place point
CLOSE_XY = 0.035           # m
CLOSE_DZ = 0.015           # m
# Descent cone: the allowed height over the grasp or place point grows by
# CONE_SLOPE per metre of horizontal error beyond CONE_RADIUS.
CONE_RADIUS = 0.02         # m
CONE_SLOPE = 4.0
# A TCP more than this below the cone rises vertically first.
BELOW_CONE = 0.03          # m
# Within NEAR of the grasp or place aim the TCP asks for GAIN of the way
# per step: the arm (shield plans at 2 rad/s^2) brakes without overshooting.
NEAR = 0.1                 # m
GAIN = 0.5
# TCP above the target's resting-cube centre when placing (cube 2 cm over
# its resting height, TCP at the grasp offset above the cube centre).
PLACE_ABOVE = 0.02 + pick_place.GRASP_TCP_ABOVE_CENTRE   # m
RELEASE_DISTANCE = 0.03    # m, cube centre to its place height over target
# Normalised apertures (0 closed, 1 open 8.5 cm; a 4 cm cube holds the
# gripper at ~0.47): closing on the cube below HOLDING; missed below MISSED;
# fully opened again above OPENED.
HOLDING = 0.7
MISSED = 0.25
OPENED = 0.9
IN_HAND = 0.03             # m, cube centre from where a grasp holds it
OPEN, CLOSED = -1.0, 1.0


def cone_aim(point: np.ndarray, tcp: np.ndarray, hover: float,
             slope: float = CONE_SLOPE, radius: float = CONE_RADIUS,
             below: float = BELOW_CONE) -> np.ndarray:
  """The TCP aim towards `point` from above, inside the descent cone.

  Args:
    point: where the TCP goes (3,), m.
    tcp: the TCP now (3,), m.
    hover: the largest height over `point` (m).
    slope: the cone's height over `point` per metre of horizontal error
      beyond `radius`.
    radius: horizontal error (m) within which the aim is `point` itself.
    below: a TCP more than this (m) below the cone rises vertically first.

  Returns:
    The aim (3,): above `point` at the cone's height, or straight above
    the TCP when it is below the cone.
  """
  horizontal = np.linalg.norm(point[:2] - tcp[:2])
  height = point[2] + min(hover, slope * max(0.0, horizontal - radius))
  if tcp[2] < height - below:   # Below the cone: straight up first.
    return np.array([tcp[0], tcp[1], height])
  return np.array([point[0], point[1], height])


@experts.register('pick_place', 'default', 'close')
class PickPlaceExpert(base.Expert):
  """Picks the cube and puts it on the target (both action spaces).

  Args:
    env: the environment (hrc_suite.suite.load) whose task it solves.
  """

  OBSERVED = ('object_gripped', 'object_position', 'target_position',
              'object_at_target', 'gripper_aperture', 'eef_position',
              'joint_positions')
  TASKS = (('pick_place', 'default'), ('pick_place', 'close'))
  GRASP_ABOVE = pick_place.GRASP_TCP_ABOVE_CENTRE
  HOVER = HOVER

  def __init__(self, env: composer.Environment):
    super().__init__(env)
    self._steer = steering.Steering(self._task)
    self.reset()

  def reset(self) -> None:
    """Forgets the missed-grasp hysteresis and the last phase."""
    self._reopening = False   # Hysteresis of a missed grasp.
    self.phase = None         # The last phase (for inspection and tests).

  def in_hand(self, observation: Mapping[str, np.ndarray]) -> bool:
    """Whether the cube is held (gripped, or closing on it in place).

    Args:
      observation: the OBSERVED observables now.

    Returns:
      True if it is.
    """
    if observation['object_gripped'][0] > 0.5:
      return True
    grasp_pose = observation['object_position'] + (0, 0, self.GRASP_ABOVE)
    return bool(observation['gripper_aperture'][0] < HOLDING and
                np.linalg.norm(grasp_pose - observation['eef_position'])
                < IN_HAND)

  def _pick(self, observation):
    """(phase, aim, gripper) while the cube is not in the hand."""
    tcp = observation['eef_position']
    aperture = observation['gripper_aperture'][0]
    grasp = observation['object_position'] + (0, 0, self.GRASP_ABOVE)
    if aperture < MISSED:
      self._reopening = True
    elif aperture > OPENED:
      self._reopening = False
    offset = grasp - tcp
    at_grasp = (np.linalg.norm(offset[:2]) < CLOSE_XY and
                abs(offset[2]) < CLOSE_DZ)
    if self._reopening:   # Open where we are (rise a little) before trying.
      return 'reopen', tcp + (0, 0, 0.02), OPEN
    if at_grasp:
      return 'close', grasp, CLOSED
    return 'approach', cone_aim(grasp, tcp, self.HOVER), OPEN

  def _place(self, observation, place):
    """(phase, aim, gripper) with the cube in the hand: over `place` (the
    cube centre's goal), then release."""
    tcp = observation['eef_position']
    cube = observation['object_position']
    if np.linalg.norm(cube - place) < RELEASE_DISTANCE:
      return 'release', tcp, OPEN
    aim = cone_aim(place + (0, 0, self.GRASP_ABOVE), tcp, self.HOVER)
    return 'carry', aim, CLOSED

  def plan(self, observation: Mapping[str, np.ndarray]
           ) -> tuple[str, np.ndarray, float]:
    """The state machine's phase, TCP aim and gripper command.

    Args:
      observation: the OBSERVED observables now.

    Returns:
      (phase name, TCP aim (3,), gripper command: OPEN or CLOSED).
    """
    target = observation['target_position']
    if self.in_hand(observation):
      self._reopening = False
      return self._place(observation, target + (0, 0, PLACE_ABOVE
                                                - self.GRASP_ABOVE))
    if observation['object_at_target'][0] > 0.5:
      return 'done', target + (0, 0, PLACE_ABOVE + self.HOVER), OPEN
    return self._pick(observation)

  def action(self, observation: Mapping[str, np.ndarray]) -> np.ndarray:
    """The action now.

    Args:
      observation: the OBSERVED observables now (`base.Expert.observe`).

    Returns:
      The action towards `plan`'s aim (GAIN of the way within NEAR).
    """
    self.phase, aim, gripper = self.plan(observation)
    tcp = observation['eef_position']
    gain = GAIN if np.linalg.norm(aim - tcp) < NEAR else 1.0
    return self._steer.action(aim, tcp, observation['joint_positions'],
                              gripper, gain=gain)
