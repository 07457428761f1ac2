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
* reaching out (`reach`, the handovers: bvh_import.REACH_TASKS): a person
  who holds a hand out to the robot at the anchor steps up until that hand
  is at least a given distance ahead of the station (the synthetic people's
  handover points), again at most LEAN_ALLOWANCE past it. Recorded people
  stand upright and hold the hand 0.43-0.58 m ahead of the pelvis, the
  synthetic ones lean in and reach 0.50-0.67 m.
* sideways: the pelvis at the anchor frame lands on the station's line;
  with `reach`, that keypoint does (recorded handover people hold the
  hand 0.26-0.37 m beside the pelvis, which with the task's +-0.2 m
  sideways randomisation put the hammer beyond the gripper-down reach:
  human_to_robot seeds 0-9, 8/10 on the Schunk and the Panda; anchored on
  the hand, 9/10 and 10/10, docs/tasks.md).

Only horizontal placement changes; heights stay as imported (floor at 0).
"""

import math

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


def place_at_station(positions, turn=0.0, anchor=None, reach=None,
                     lean=LEAN_ALLOWANCE):
  """(positions, facts) with the clip placed by the module's rule.

  `positions` (F, K, 3) are in a clip frame facing +x (floor at z = 0);
  `turn` (rad) first turns them about the vertical through the origin (the
  facing correction). `anchor` is the frame where the person waits for the
  robot (None: the closest approach). `reach` (keypoint index, distance m)
  or None: that keypoint at the anchor frame lies at least `distance`
  ahead of the station where the lean allows, and on its line sideways.
  `lean` (m): how far past the station the pelvis may come
  (`lean_allowance` of the clip's task).
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
  if reach is not None:
    point, distance = reach
    short = distance - (placed[frame, point, 0] + forward)
    forward = max(forward, min(forward + short, limit))
    rule += (f'; keypoint {point} at least {distance:.2f} m ahead of it '
             'and on its line')
  sideways = (pelvis[frame, 1] if reach is None
              else placed[frame, reach[0], 1])
  shift = np.array([forward, -sideways, 0.0])
  placed = placed + shift
  facts = {'rule': rule,
           'facing_turn_deg': round(math.degrees(turn), 3),
           'anchor_frame': frame, 'closest_frame': closest,
           'shift_m': [round(float(v), 4) for v in shift[:2]]}
  return placed, facts
