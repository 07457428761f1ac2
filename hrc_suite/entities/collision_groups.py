"""MuJoCo collision bits shared by every entity of the workcell.

MuJoCo lets two geoms collide if (contype_a & conaffinity_b) or
(contype_b & conaffinity_a). The scheme:

* static world (floor, table, pedestal) collides with the robot and objects;
* the robot (links and gripper) collides with everything but itself: its
  enclosing capsules overlap at the joints, so self-collision is checked
  geometrically by collision prevention and the contact monitor instead;
* objects collide with everything;
* the human collides with the robot and objects only (it is kinematic, so
  contacts with the table or itself would only cost time).
"""

STATIC = 1
ROBOT = 2
OBJECT = 4
HUMAN = 8

STATIC_CONTYPE, STATIC_CONAFFINITY = STATIC, ROBOT | OBJECT
ROBOT_CONTYPE, ROBOT_CONAFFINITY = ROBOT, STATIC | OBJECT | HUMAN
OBJECT_CONTYPE, OBJECT_CONAFFINITY = OBJECT, STATIC | ROBOT | OBJECT | HUMAN
HUMAN_CONTYPE, HUMAN_CONAFFINITY = HUMAN, ROBOT | OBJECT


def set_static(geom):
  geom.contype, geom.conaffinity = STATIC_CONTYPE, STATIC_CONAFFINITY


def set_robot(geom):
  geom.contype, geom.conaffinity = ROBOT_CONTYPE, ROBOT_CONAFFINITY


def set_object(geom):
  geom.contype, geom.conaffinity = OBJECT_CONTYPE, OBJECT_CONAFFINITY


def set_human(geom):
  geom.contype, geom.conaffinity = HUMAN_CONTYPE, HUMAN_CONAFFINITY
