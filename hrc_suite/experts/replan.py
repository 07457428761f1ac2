"""Re-planning: a detour when collision prevention keeps replacing the
expert's actions.

Collision prevention (hrc_suite/safety/collision_prevention/prevention.py)
replaces an action whose planned path would hit the table, the static scene
or the robot itself (the task's step metric `action_replacements`). An
expert whose aim leads through such a pose, e.g. a gripper-down IK step
that folds the arm into itself, asks for the same blocked action again and
again: with the default 'zero' policy the robot stands where it is for the
rest of the episode (stacking, CollaborativeStacking_5 recording, Schunk
noisy expert: 2767 of 3000 actions replaced in a row; with the detours
below, success in 573 steps).

`Replanner` watches the task's `action_replacements` of the RL step just
done. After REPLAN_AFTER consecutive replaced actions it plans a detour:
a waypoint DETOUR_DISTANCE from the TCP, raised above the obstacle, backed
off towards the robot's base, to the side, out, or combinations of these
(`DETOUR_DIRECTIONS`, in that order), or the home configuration (a pose
free of collisions by construction) last. A waypoint qualifies if
gripper-down IK reaches it in a collision-free configuration and the
first step towards it passes the task's own check (the joint goal the
task's action space makes of the detour's action, checked along the
shield's plan from its command: `CollisionPrevention.planned_paths_free`,
i.e. it would not be replaced). The first that qualifies is steered to
(`steering.Steering`, the expert's gripper command kept) until the TCP is
within DETOUR_REACHED of it (home: within HOME_REACHED rad), for at most
DETOUR_STEPS RL steps, or until REPLAN_AFTER of the detour's own actions in
a row are replaced; then the expert's own actions resume, and the expert
aims again from where the detour left the arm (gripper-down IK from another
start finds another branch). Consecutive detours start their search one
direction further each (`_attempt`), so that an expert which steers back
into the same trap is taken elsewhere the next time; the count restarts
once RECOVERED of the expert's actions in a row went through. Where no
waypoint qualifies, the expert's action is passed on and the search is
tried again after another REPLAN_AFTER replaced actions.

It engages only after REPLAN_AFTER replaced actions in a row: an episode in
which that never happens gets the expert's actions unchanged. Everything is
deterministic (docs/tasks.md, "Experts: re-planning"). Memory: the count
of replaced actions in a row, the detour (waypoint, steps left, its
replaced actions in a row) and the detour count; all are forgotten at
reset.

What is counted are the actions the task executed. An expert queried on
an agent's states (action-based imitation) has re-planning switched off
(`Expert.disable_replanning`): its advice there is its own action at each
state, not a detour that depends on the agent's past actions.
"""

from typing import Optional

from dm_control import composer
from dm_control import mjcf
import numpy as np

from hrc_suite.experts import steering
from hrc_suite.tasks.runtime import actions

# Replaced actions in a row after which the expert re-plans (RL steps, 2 s).
# Runs that end by themselves occur: a moving robot overshoots along the
# shield's plan before it turns to a new goal, and a waiting robot's aim
# (a swaying palm) moves out of a blocked pose again; the longest such run
# in the 33 expert episodes of scripts/episode_hashes.py is 14 RL steps
# (handover/robot_to_human, UR5e, seed 0; the episode succeeds), and 13
# with a person leaning 0.4 m over the table towards the Schunk
# (robot_to_human, shipped clip 00, joint space; it succeeds too). A robot
# whose action is still replaced after 20 steps is held: with the 'zero'
# policy it stands still, and the expert asks for the same action from the
# same state.
REPLAN_AFTER = 20
# Distance of a detour's waypoint from the TCP (m): one and a half full
# Cartesian actions (actions.CARTESIAN_STEP), two RL steps of travel.
DETOUR_DISTANCE = 0.15
# Directions of the waypoints, tried in this order from the TCP (each
# normalised): (up, towards the base horizontally, sideways horizontally).
# Up first: over a table, a cube or a person's hand; back towards the base
# and out away from it change the elbow's fold (a self-collision).
DETOUR_DIRECTIONS = (
    (1.0, 0.0, 0.0),     # up
    (1.0, 1.0, 0.0),     # up and back
    (0.0, 1.0, 0.0),     # back
    (1.0, 0.0, 1.0),     # up and to the left
    (1.0, 0.0, -1.0),    # up and to the right
    (0.0, 0.0, 1.0),     # left
    (0.0, 0.0, -1.0),    # right
    (1.0, -1.0, 0.0),    # up and out
    (0.0, -1.0, 0.0),    # out
)
# The detour ends at the waypoint (TCP within this, m), home within
# HOME_REACHED (rad, largest joint error), or after DETOUR_STEPS RL steps
# (1 s: a waypoint DETOUR_DISTANCE away takes 2 steps at full speed, more
# where the shield slows the robot near the person).
DETOUR_REACHED = 0.01
HOME_REACHED = 0.05
DETOUR_STEPS = 10
# Expert actions in a row that went through after which the detour count
# restarts (the expert left the trap): two detours' worth of steps.
RECOVERED = 2 * DETOUR_STEPS


class Replanner:
  """Detours an expert whose actions collision prevention keeps replacing
  (module doc).

  Args:
    task: the task (an HrcTask) whose expert it re-plans.
  """

  def __init__(self, task: composer.Task):
    self._task = task
    self._steer = None        # made at the first plan (none if never)
    self._space = None
    self._callables = None
    self.reset()

  def reset(self) -> None:
    """Forgets the episode (called at every first timestep; the physics
    may have been rebuilt)."""
    self._callables = None
    self._replaced_run = 0     # expert actions replaced in a row
    self._through_run = 0      # expert actions through in a row
    self._attempt = 0          # detours since the expert recovered
    self._waypoint = None      # the detour's TCP waypoint, or
    self._home = False         # ... the home configuration
    self._steps_left = 0
    self._detour_replaced = 0
    self.detours = 0           # detours planned this episode

  @property
  def waypoint(self) -> Optional[np.ndarray]:
    """The detour's TCP waypoint (world, m) while on a detour to one, else
    None."""
    return None if self._waypoint is None else self._waypoint.copy()

  @property
  def on_detour(self) -> bool:
    """Whether the last action was a detour's."""
    return self._waypoint is not None or self._home

  def _read(self, physics):
    if self._callables is None:
      observables = self._task.task_observables
      self._callables = {
          name: observables[name]._callable(physics)   # pylint: disable=protected-access
          for name in ('joint_positions', 'eef_position')}
    return (np.asarray(self._callables['joint_positions'](), float),
            np.asarray(self._callables['eef_position'](), float))

  def action(self, expert_action: np.ndarray, physics: mjcf.Physics,
             first: bool) -> np.ndarray:
    """The action to take: the expert's, or a detour's (module doc).

    Args:
      expert_action: the expert's action now (the action spec's shape).
      physics: the environment's physics.
      first: whether this is the episode's first timestep (no RL step
        done yet).

    Returns:
      `expert_action` itself, or the detour's action (the expert's
      gripper command kept).
    """
    replaced = (not first and bool(
        self._task.step_metrics.get('action_replacements', 0)))
    if self.on_detour:
      self._detour_replaced = self._detour_replaced + 1 if replaced else 0
      q, tcp = self._read(physics)
      if (self._steps_left > 0 and not self._arrived(q, tcp)
          and self._detour_replaced < REPLAN_AFTER):
        return self._detour_action(expert_action, q, tcp)
      self._waypoint, self._home = None, False
      self._replaced_run = self._through_run = 0
      return expert_action
    if replaced:
      self._replaced_run += 1
      self._through_run = 0
    elif not first:
      self._replaced_run = 0
      self._through_run += 1
      if self._through_run >= RECOVERED:
        self._attempt = 0
    if self._replaced_run < REPLAN_AFTER:
      return expert_action
    self._replaced_run = 0
    q, tcp = self._read(physics)
    if not self._plan(expert_action, q, tcp):
      return expert_action
    self.detours += 1
    self._attempt += 1
    return self._detour_action(expert_action, q, tcp)

  # ------------------------------------------------------------ planning

  def _gripper(self, expert_action):
    return float(expert_action[-1]) if self._steer.has_gripper else None

  def _arrived(self, q, tcp):
    if self._home:
      q_home = self._task.kinematics.description.q_home
      return bool(np.abs(q - q_home).max() < HOME_REACHED)
    return bool(np.linalg.norm(tcp - self._waypoint) < DETOUR_REACHED)

  def _detour_action(self, expert_action, q, tcp):
    self._steps_left -= 1
    gripper = self._gripper(expert_action)
    if self._home:
      q_home = self._task.kinematics.description.q_home
      return self._steer.joint_goal_action(q_home, q, tcp, gripper)
    return self._steer.action(self._waypoint, tcp, q, gripper)

  def _directions(self, tcp):
    """The waypoint directions (unit vectors, DETOUR_DIRECTIONS' order)."""
    base = np.asarray(self._task.kinematics.base_pose)[:3, 3]
    back = base - tcp
    back[2] = 0.0
    norm = np.linalg.norm(back)
    # Straight above the base: 'back' is the base's -x (its front is +x).
    back = back / norm if norm > 1e-9 else -np.asarray(
        self._task.kinematics.base_pose)[:3, 0] * (1.0, 1.0, 0.0)
    left = np.array([-back[1], back[0], 0.0])
    up = np.array([0.0, 0.0, 1.0])
    out = []
    for u, b, s in DETOUR_DIRECTIONS:
      direction = u * up + b * back + s * left
      out.append(direction / np.linalg.norm(direction))
    return out

  def _plan(self, expert_action, q, tcp):
    """Picks the detour (module doc); False if no waypoint qualifies."""
    if self._steer is None:
      self._steer = steering.Steering(self._task)
      self._space = actions.make_action_space(
          self._steer.space, self._task.kinematics, yaw=self._steer.yaw)
    checker = self._task.collision_checker
    gripper = self._gripper(expert_action)
    low, high = actions.workspace_box(self._task.kinematics)
    q_home = np.asarray(self._task.kinematics.description.q_home, float)
    candidates = []   # (waypoint or None for home, first step's goal)
    for direction in self._directions(tcp):
      waypoint = np.clip(tcp + DETOUR_DISTANCE * direction, low, high)
      if np.linalg.norm(waypoint - tcp) < DETOUR_REACHED:
        continue
      if not self._steer.reaches(waypoint, q, checker):
        continue
      arm = self._steer.action(waypoint, tcp, q, gripper)[:self._space.num_arm]
      goal, solved = self._space.goal(q, arm, q)
      if solved:
        candidates.append((waypoint, goal))
    turn = self._attempt % max(len(candidates), 1)
    candidates = candidates[turn:] + candidates[:turn]
    arm = self._steer.joint_goal_action(q_home, q, tcp, gripper)
    goal, solved = self._space.goal(q, arm[:self._space.num_arm], q)
    if solved:
      candidates.append((None, goal))
    if not candidates:
      return False
    free = checker.planned_paths_free(
        np.array([goal for _, goal in candidates]), self._task.shield)
    if not free.any():
      return False
    waypoint = candidates[int(np.argmax(free))][0]
    self._waypoint = None if waypoint is None else waypoint.copy()
    self._home = waypoint is None
    self._steps_left = DETOUR_STEPS
    self._detour_replaced = 0
    return True
