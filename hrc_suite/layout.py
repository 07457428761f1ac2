"""Where things stand in the workcell (world frame: z up, floor at z = 0).

The robot sits on a pedestal at the near edge of the table and faces +x; a
human partner either stands across the table facing the robot (-x) or beside
the robot's workspace. Tasks place objects and the human relative to these.
"""

import dataclasses
import math
from typing import Optional

import numpy as np

# Table: top height about 0.82 m (a standard workbench, DIN EN 527-1 range
# 0.72-0.90 m, chosen to match the reference's tabletop scenes).
TABLE_TOP_Z = 0.82
TABLE_THICKNESS = 0.04
TABLE_X = (0.15, 1.15)    # near edge (robot side), far edge (human side)
TABLE_Y = (-0.75, 0.75)


@dataclasses.dataclass(frozen=True)
class Table:
  """The table top's extent (world, m): x from the robot's side to the
  person's, y across; its top face at TABLE_TOP_Z."""
  x: tuple
  y: tuple = TABLE_Y

  def __post_init__(self):
    for name in ('x', 'y'):
      low, high = getattr(self, name)
      if not low < high:
        raise ValueError(f'Table.{name}: expected (low, high) with low < '
                         f'high, got {getattr(self, name)!r}')


# The table of every task but stacking: 1 m deep (TABLE_X), 1.5 m wide.
DEFAULT_TABLE = Table(TABLE_X, TABLE_Y)

# Robot base frame (default mount): on the pedestal top, flush with the
# table top, x forward.
ROBOT_BASE_POS = (0.0, 0.0, TABLE_TOP_Z)
PEDESTAL_HALF_SIZE = (0.17, 0.17)  # x, y half extents; from floor to base.
PEDESTAL_CENTER_XY = (-0.03, 0.0)


@dataclasses.dataclass(frozen=True)
class RobotMount:
  """Where a robot's base frame stands (facing +x) and the pedestal under it
  (a box from the floor up to the base)."""
  base_position: tuple                 # world, m
  pedestal_center_xy: tuple = PEDESTAL_CENTER_XY
  pedestal_half_size: tuple = PEDESTAL_HALF_SIZE
  # Scale of the table workspace boxes about the base (ik.table_workspace_box);
  # None: from the robot's home TCP distance.
  workspace_scale: Optional[float] = None
  # x range (m, base frame) of the table cubes of pick_place and inspection
  # for this robot; None: the tasks' own (cube_region_x).
  cube_region_x: Optional[tuple] = None

  @property
  def height_above_table(self) -> float:
    """m, base frame origin above the table top."""
    return self.base_position[2] - TABLE_TOP_Z

  def base_pose(self):
    """4x4 world pose of the base frame."""
    pose = np.eye(4)
    pose[:3, 3] = self.base_position
    return pose


DEFAULT_MOUNT = RobotMount(ROBOT_BASE_POS)

# The Schunk LWA 4P is a short arm: 0.65 m from shoulder to wrist, and
# 0.358 m from its wrist centre to our TCP (the flange's 0.163 m tool offset
# + the 0.12 m gripper); its wrist bends at most 1.85 rad. On the default
# mount gripper-down IK reaches at most ~0.21 m above the table (0.42 m
# ahead) and 0.64 m ahead: not the handover heights, the nail, the lifted
# board or the stack. Raised 0.4 m and moved to the pedestal's front edge
# (the pedestal's front face flush with the table edge), it reaches every
# task point with the gripper down (measured, docs/tasks.md) except the
# highest handover points, which it serves in joint space.
SCHUNK_MOUNT = RobotMount(
    base_position=(0.15, 0.0, TABLE_TOP_Z + 0.40),
    pedestal_center_xy=(-0.02, 0.0),
    workspace_scale=0.85)

# Jaco and Kinova Gen3: on the default mount their gripper-down IK
# (scripts/reachability.py, docs/robots.md) reaches none (Jaco) and 6
# of 45 (Gen3) of the robot-to-human handover points, 16 and 17 of 49
# human-to-robot ones, 1 and 9 of 11 nail targets: those TCP points lie
# 0.49-0.75 m ahead of the default base and 0.19-0.51 m above the table,
# past what their long hands (flange 0.16 m and 0.06 m past the last
# joint, then our 0.12 m gripper) reach held vertically. Both stand at the
# pedestal's front edge like the Schunk (base 0.15 m ahead, the pedestal's
# front face flush with the table edge), raised by the lowest height in
# 0.1 m steps that reaches every handover and nail point: Jaco 0.3 m
# (45/45, 49/49, 11/11; at 0.2 m one palm and 4 inspection points stay
# out), Gen3 0.2 m (45/45, 49/49, 11/11). The table regions given in the
# base frame (reach box, cube regions) move with the base and are reached
# at least as well as on the default mount.
JACO_MOUNT = RobotMount(
    base_position=(0.15, 0.0, TABLE_TOP_Z + 0.30),
    pedestal_center_xy=(-0.02, 0.0))
KINOVA3_MOUNT = RobotMount(
    base_position=(0.15, 0.0, TABLE_TOP_Z + 0.20),
    pedestal_center_xy=(-0.02, 0.0))

# KUKA iiwa: on the default mount its gripper-down IK reaches
# the table's centre line (y = 0) only from x 0.40 m ahead of the base at
# the cube's grasp height and from 0.375 m at the pick-and-place hover
# (0.2 m above), its elbow (joint 4, +-2.09 rad) folded to the limit
# nearer in (reachability grid, 30 IK restarts, the 30-episode expert
# sweep). The tasks' cube regions (x 0.30-0.45 m) keep only cubes the arm
# can grasp, but pick and place carries the cube across y = 0 at the
# hover: from cubes at x 0.33-0.37 m every Cartesian step failed IK for
# the rest of the episode (seeds 4, 8, 15 of 30, default and close). Its
# cube regions lie 0.1 m further out, as wide as the others'.
IIWA_MOUNT = RobotMount(ROBOT_BASE_POS, cube_region_x=(0.40, 0.55))

ROBOT_MOUNTS = {'schunk': SCHUNK_MOUNT, 'jaco': JACO_MOUNT,
                'kinova3': KINOVA3_MOUNT, 'iiwa': IIWA_MOUNT}


def robot_mount(robot_name: str) -> RobotMount:
  """The mount of the named robot (DEFAULT_MOUNT unless listed)."""
  return ROBOT_MOUNTS.get(robot_name, DEFAULT_MOUNT)


def cube_region_x(robot_name: str, task_region_x: tuple) -> tuple:
  """x range (m, base frame) of a task's table cubes for the named robot:
  its mount's cube_region_x, else the task's own `task_region_x`."""
  own = robot_mount(robot_name).cube_region_x
  return tuple(task_region_x if own is None else own)


# A point a person chooses for the robot (a clip's inspection point) that
# the robot cannot reach: it is moved towards the robot's home TCP along
# the straight line, to the first of FIT_STEPS evenly spaced points the
# robot reaches (the layout decides; docs/robots.md, "Reachability of the
# task regions", counts each robot's moved points).
FIT_STEPS = 21


def fit_into_reach(point, home, reachable, steps=FIT_STEPS):
  """`point` (world, m) moved towards `home` (the robot's home TCP) to the
  first of `steps` points on the line between them (point first, home
  last) for which reachable(candidate) holds; home if none does."""
  point, home = np.asarray(point, dtype=float), np.asarray(home, dtype=float)
  for s in np.linspace(0.0, 1.0, steps):
    candidate = point + s * (home - point)
    if reachable(candidate):
      return candidate
  return home

# Human stations: (x, y, yaw) of the clip frame's origin on the floor. A clip
# is authored with the person at the origin facing +x; yaw turns it.
# The shared stations stand this far behind the table's edge.
STATION_EDGE_CLEARANCE = 0.30   # m
HUMAN_STATION_ACROSS = (DEFAULT_TABLE.x[1] + STATION_EDGE_CLEARANCE, 0.0,
                        math.pi)                    # facing the robot.
HUMAN_STATION_BESIDE = (0.55, DEFAULT_TABLE.y[1] + STATION_EDGE_CLEARANCE,
                        -math.pi / 2)               # beside the workspace.

# Stacking: the person works across a shallower table, as in the reference,
# whose stacking table (1.2 m x 2.0 m, its environment config) is centred on
# the robot, its far edge 0.6 m from the base. People put the stack 0.40-0.65
# m ahead of their pelvis (recordings 0.40-0.63 m, synthetic 0.55-0.65 m,
# docs/tasks.md); across our 1 m table that would be 0.71-0.94 m from the
# robot, beyond most arms' gripper-down reach of the top slot. Every robot
# on its mount reaches the top slot for x 0.40-0.75 m and the robot's cubes
# for x 0.40-0.55 m, |y| 0.22-0.36 m (world; docs/tasks.md,
# stacking/default), so the station stands where a stack 0.40-0.62 m ahead
# lands in 0.48-0.70 m (with the station at x 1.05 m the stack comes within
# 0.25 m of the raised Schunk's base, where carrying cube 4 sideways folds
# it into itself: docs/tasks.md).
# The person stands STACKING_STATION_SHIFT closer to the table's edge than
# at the shared stations (pelvis 0.18 m from it: a stack 0.55-0.65 m ahead
# is within reach of a person standing upright).
STACKING_STATION_SHIFT = 0.12   # m
STACKING_STATION_X = 1.10       # m, world
STACKING_TABLE = Table(
    (TABLE_X[0], STACKING_STATION_X - STATION_EDGE_CLEARANCE
     + STACKING_STATION_SHIFT), TABLE_Y)
HUMAN_STATION_STACKING = (STACKING_STATION_X, 0.0, math.pi)

# Reach's joint goals (reach/dense, reach/sparse with joint actions). The
# reference draws them uniformly within the joint limits, rejecting
# colliding ones (docs/reference_benchmark.md, Tasks); we do too for
# every joint whose range is at most one turn. A joint whose range exceeds
# one turn (UR5e: five joints, Kinova Gen3 and Jaco: the four continuous
# ones, +-2 pi; Sawyer's last, +-1.5 pi) repeats every pose of its link
# over 2 pi, so the goals are drawn from one turn of it: the turn centred
# on q_home, shifted inside the limits where a limit is nearer than pi.
# Every goal pose stays possible; what goes is the unwinding: uniform over
# +-2 pi a goal lay up to 4 pi (mean 4/3 pi) from home on each such joint,
# 10.7-11.6 rad in norm on the UR5e (seeds 0-5), whose straight joint path
# then swung the upper arm through the table and pedestal; unhindered,
# the expert covers ~0.12 rad per RL step in norm (Gen3 seed 3: 11.4 rad
# in 92 of the 100 steps), so such goals barely fit the horizon
# (docs/robots.md, "Reach goals").
ONE_TURN = 2 * math.pi
# rad: a range of one turn written with 11 decimals (UR5e elbow, +-pi) is
# one turn.
ONE_TURN_TOLERANCE = 1e-9


def reach_joint_goal_range(description):
  """(low, high) joint positions (dof,) from which reach draws its joint
  goals: each joint's limits, cut to one turn around q_home (see above)."""
  q_min = np.asarray(description.limits.q_min, float)
  q_max = np.asarray(description.limits.q_max, float)
  home = np.asarray(description.q_home, float)
  wide = q_max - q_min > ONE_TURN + ONE_TURN_TOLERANCE
  low = np.maximum(q_min, np.minimum(home - ONE_TURN / 2, q_max - ONE_TURN))
  return (np.where(wide, low, q_min),
          np.where(wide, low + ONE_TURN, q_max))

# Reach's goals keep the robot on its side of the table's edge beside
# which the person stands (HUMAN_STATION_BESIDE, STATION_EDGE_CLEARANCE
# beyond it): every capsule of the goal configuration (gripper included)
# within y <= REACH_GOAL_MAX_Y. The reference's joint goals ignore the
# person (docs/reference_benchmark.md, Tasks); beyond the edge a goal puts
# the arm into the person's body, where SSM holds it for the rest of the
# episode. The experts fail there without this bound (seeds 0-9, and
# experts.json's 50): goals with the TCP at y 0.78-1.00 m, held for 61-83
# of 100 RL steps (Jaco seeds 1 and 8, iiwa 1 and 3, Schunk 8, Panda 42),
# the arm pushed by the person (robot-human distance down to -0.14 m).
REACH_GOAL_MAX_Y = DEFAULT_TABLE.y[1]
