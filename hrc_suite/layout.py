"""Where things stand in the workcell (world frame: z up, floor at z = 0).

The robot sits on a pedestal at the near edge of the table and faces +x; a
human partner either stands across the table facing the robot (-x) or beside
the robot's workspace. Tasks place objects and the human relative to these.
"""

import math

# Table: top height about 0.82 m (a standard workbench, DIN EN 527-1 range
# 0.72-0.90 m, chosen to match the reference's tabletop scenes).
TABLE_TOP_Z = 0.82
TABLE_THICKNESS = 0.04
TABLE_X = (0.15, 1.15)    # near edge (robot side), far edge (human side)
TABLE_Y = (-0.75, 0.75)

# Robot base frame: on the pedestal top, flush with the table top, x forward.
ROBOT_BASE_POS = (0.0, 0.0, TABLE_TOP_Z)
PEDESTAL_HALF_SIZE = (0.17, 0.17)  # x, y half extents; from floor to base.
PEDESTAL_CENTER_XY = (-0.03, 0.0)

# Human stations: (x, y, yaw) of the clip frame's origin on the floor. A clip
# is authored with the person at the origin facing +x; yaw turns it.
HUMAN_STATION_ACROSS = (1.45, 0.0, math.pi)         # facing the robot.
HUMAN_STATION_BESIDE = (0.55, 1.05, -math.pi / 2)   # beside the workspace.
