"""Where an imported recording stands (docs/motion_library.md).

A task plays its clips with the clip frame's origin at the task's station
(`layout.HUMAN_STATION_*`): the spot, facing the table, where a person
stands to work with the robot, 0.30 m behind the table's edge. The
shipped synthetic people walk in to that spot and stay there. A recording
starts wherever the person stood in the lab, usually a metre back, and walks
in; its first pose says nothing about where the table was. So a recording
is placed by where it ends up, not where it starts:

* facing: the clip's +x is the direction the person faces. Recordings of the
  reference (their `_info.json` has `orientation_quat`) share one lab
  frame, and the reference places every one of them with the same rotation,
  so the table's axes are the lab's axes: the estimated facing is snapped to
  the nearest lab axis (multiple of 90 degrees). Other recordings keep the
  facing estimated from their first half second (`bvh_import`).
* along the facing: the pelvis at the anchor frame lands on the station.
  The anchor is where the person waits for the robot (the first idle
  phase's keyframe) in tasks that wait, else the pelvis's farthest point
  forward (the closest approach to the table). Some people wait a step
  back and step in later: the pelvis may then pass the station by at most
  LEAN_ALLOWANCE, so it stays at least 0.10 m behind the table's edge, as
  close as the synthetic people come (less for stations closer to the
  edge, STATION_SHIFTS: stacking's).
* the task's point (`TaskPoint`, bvh_import.TASK_POINTS): where the
  recorded task happens (the handovers: the holding hand at the wait; the
  plank's set-down in hammering/robot_hammers: the hand on its handle at
  the set-down frame) must lie in a band ahead of the station, where the
  workcell needs it. A person whose hand is short of the band steps up,
  again at most LEAN_ALLOWANCE past the station; one whose hand is beyond
  it steps back. So a recording is placed by what the person does, not by
  where they stood: the same motion recorded closer to or further from
  the lab's table lands in the same place. Recorded handover people stand
  upright and hold the hand 0.43-0.58 m ahead of the pelvis, the
  synthetic ones lean in and reach 0.50-0.67 m.
* sideways: the pelvis at the anchor frame lands on the station's line;
  with a task point `on_line`, that keypoint does (recorded handover
  people hold the hand 0.26-0.37 m beside the pelvis, which with the
  task's +-0.2 m sideways randomisation put the hammer beyond the
  gripper-down reach: human_to_robot seeds 0-9, 8/10 on the Schunk and the
  Panda; anchored on the hand, 9/10 and 10/10, docs/tasks.md).

Only horizontal placement changes; heights stay as imported (floor at 0).
"""

import dataclasses
import math
from typing import Optional, Tuple

import numpy as np

from hrc_suite import layout
from hrc_suite import rotations
from hrc_suite.human import keypoints

_PELVIS = keypoints.KEYPOINT_INDEX['pelvis']
# Station to the table's edge, the same for both shared stations
# (layout.HUMAN_STATION_ACROSS: x 1.45 m, edge 1.15 m; HUMAN_STATION_BESIDE:
# y 1.05 m, edge 0.75 m).
TABLE_EDGE_CLEARANCE = layout.STATION_EDGE_CLEARANCE
LAB_AXIS = math.pi / 2   # rad; the lab frame's axes are this far apart.
# How far past the station the pelvis may come (m): the synthetic people's
# closest approach leaves 0.10 m to the table's edge (docs/motion_library.md).
LEAN_ALLOWANCE = TABLE_EDGE_CLEARANCE - 0.10
# Clip tasks whose station stands closer to the table's edge than the
# shared stations (m closer): their people may lean that much less.
STATION_SHIFTS = {'stacking': layout.STACKING_STATION_SHIFT}


def lean_allowance(task):
  """How far past its station the pelvis of a `task` clip may come (m)."""
  return LEAN_ALLOWANCE - STATION_SHIFTS.get(task, 0.0)


def snapped_turn(estimated_yaw_deg):
  """Turn (rad) from the estimated facing to the nearest lab axis."""
  estimated = math.radians(estimated_yaw_deg)
  snapped = LAB_AXIS * round(estimated / LAB_AXIS)
  return snapped - estimated


@dataclasses.dataclass(frozen=True)
class TaskPoint:
  """Where the recorded task happens, and where the workcell needs it.

  Attributes:
    keypoints: keypoint indices; the one farthest ahead at `frame` is the
      task's point (e.g. the hand that sets the plank down).
    ahead: (low, high) m ahead of the station the point lies in (high may
      be math.inf).
    frame: the task's frame; None: the anchor frame.
    on_line: the point, not the pelvis, lands on the station's line.
  """
  keypoints: Tuple[int, ...]
  ahead: Tuple[float, float]
  frame: Optional[int] = None
  on_line: bool = True

  def __post_init__(self):
    low, high = self.ahead
    if not low <= high:
      raise ValueError(f'TaskPoint ahead must be (low, high) with low <= '
                       f'high, got {self.ahead!r}')
    if not self.keypoints:
      raise ValueError('TaskPoint needs at least one keypoint')


def place_at_station(positions, turn=0.0, anchor=None, point=None,
                     lean=LEAN_ALLOWANCE):
  """(positions, facts) with the clip placed by the module's rule.

  Args:
    positions: (F, K, 3) in a clip frame facing +x (floor at z = 0).
    turn: rad; the positions are first turned by it about the vertical
      through the origin (the facing correction).
    anchor: the frame where the person waits for the robot (None: the
      closest approach).
    point: a `TaskPoint` or None.
    lean: how far past the station the pelvis may come (m;
      `lean_allowance` of the clip's task).

  Returns:
    The placed positions and a dict of what the rule did ('rule',
    'facing_turn_deg', 'anchor_frame', 'closest_frame', 'shift_m'; with a
    task point 'task_frame', 'task_keypoint').
  """
  positions = np.asarray(positions, dtype=np.float64)
  # Turning by `turn` moves the facing direction; turning the points by
  # -turn keeps +x the facing.
  rotation = rotations.yaw_to_mat(-turn)
  placed = positions @ rotation.T
  pelvis = placed[:, _PELVIS]
  closest = int(np.argmax(pelvis[:, 0]))
  frame = closest if anchor is None else int(anchor)
  limit = lean - pelvis[closest, 0]
  forward = min(-pelvis[frame, 0], limit)
  rule = ('anchor pelvis at the station, closest approach at most '
          f'{lean:.2f} m past it')
  sideways = pelvis[frame, 1]
  facts = {}
  if point is not None:
    at = frame if point.frame is None else int(point.frame)
    key = max(point.keypoints, key=lambda k: placed[at, k, 0])
    low, high = point.ahead
    x = placed[at, key, 0] + forward
    if x < low:       # Step up, as far as the lean allows.
      forward = max(forward, min(forward + low - x, limit))
    elif x > high:    # Step back.
      forward -= x - high
    rule += (f'; keypoint {key} at frame {at} {low:.2f}-{high:.2f} m ahead '
             'of it')
    if point.on_line:
      sideways = placed[at, key, 1]
      rule += ' and on its line'
    facts = {'task_frame': at, 'task_keypoint': int(key)}
  shift = np.array([forward, -sideways, 0.0])
  placed = placed + shift
  facts = {'rule': rule,
           'facing_turn_deg': round(math.degrees(turn), 3),
           'anchor_frame': frame, 'closest_frame': closest,
           'shift_m': [round(float(v), 4) for v in shift[:2]], **facts}
  return placed, facts
