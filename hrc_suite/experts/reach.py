"""Reach expert: straight to the goal (the reference's goal difference as
the action), with a via point when the straight joint path collides.

Joint space: the action is the joint difference q_goal - q / JOINT_STEP,
scaled as a whole into [-1, 1] (a straight joint-space path; the reference
clips per joint, which bends the path and can run it into the table). If the
straight path from q to the goal hits the table, pedestal or the robot
itself (the task's collision model: collision prevention would replace
every action and the robot would stand still), the expert plans one via
point with a collision-free straight path from q and a collision-free
straight path on to the goal: the home configuration, then q with one joint
already at its goal value, then q with all but one joint at their goal
values (in that order; the first that works), then VIA_SAMPLES random
configurations within the task's joint goal range (explicit seed VIA_SEED,
the same every plan), shortest total joint path first: the UR5e and the
Sawyer had goals that no one-joint-at-a-time via point reaches
(docs/robots.md, "Reach goals"). A path counts as free only if it also
keeps every capsule on the robot's side of the table edge beside the
person (y <= layout.REACH_GOAL_MAX_Y, the goals' own rule; a start
already beyond it may not go further): the straight joint path to a goal
there can swing the arm into the person, where SSM holds it for the rest
of the episode (the 30-episode sweep, docs/robots.md, "Reach
goals"). Each step it steers straight
to the goal if that path is free, else to the via point (planned again when
the path to it is no longer free, e.g. after the shield braked off the line).

Cartesian space: the TCP moves in a straight line to the goal position
(`steering`, gripper-down IK by the action space).

The shield (SSM) stops the robot while the person is close; the expert
keeps its aim and continues when the shield lets it (no timeout).

The path to the goal counts as free if its straight joint path is free
and the first step's goal passes the task's own collision prevention check
(along the shield's plan from its command: a robot that overshot into a
pose near the table can have a free straight path whose planned first
step is still rejected; the Panda then stood still for 64 steps).

Privileged: the task's collision model (`task.collision_checker`, the
robot's capsules and the workcell boxes) and the shield's command
(`task.shield`, for the planned-path check), for the via point.
"""

from typing import Mapping, Optional

from dm_control import composer
import numpy as np

from hrc_suite import experts
from hrc_suite import layout
from hrc_suite.experts import base
from hrc_suite.experts import steering
from hrc_suite.tasks.runtime import actions

# Joint distance (rad, max norm) under which the expert aims at the goal
# without checking the path (the last step is tiny).
NEAR_GOAL = 0.05
# Random via points tried when no structured one works, and their seed.
VIA_SAMPLES = 400
VIA_SEED = 0
# rad: goals read as q + (q_goal - q) from observations differ by rounding.
GOAL_TOLERANCE = 1e-9
# rad (largest joint motion) between the configurations at which a path's
# capsules are held to layout.REACH_GOAL_MAX_Y: at most ~5 cm of motion at
# a 1 m lever, below the capsules' radii (planning, not a safety check).
SIDE_STEP = 0.05


@experts.register('reach', 'dense', 'sparse')
class ReachExpert(base.Expert):
  """Moves the joints (joint space) or the TCP (Cartesian) to the goal.

  Args:
    env: the environment (hrc_suite.suite.load) whose task it solves.
  """

  OBSERVED = ('goal_joint_difference', 'goal_position', 'eef_position',
              'joint_positions')
  TASKS = (('reach', 'dense'), ('reach', 'sparse'))

  def __init__(self, env: composer.Environment):
    super().__init__(env)
    self._steer = steering.Steering(self._task)
    self._checker = self._task.collision_checker
    description = self._task.robot.description
    self._q_home = np.asarray(description.q_home, float)
    self._via_range = layout.reach_joint_goal_range(description)
    self.reset()

  def reset(self) -> None:
    """Forgets the via point and the last fruitless search."""
    self._via = None      # None: straight to the goal.
    self._failed_search = None   # (q, goal) of the last fruitless search.

  @property
  def via(self) -> Optional[np.ndarray]:
    """The planned via point (joint positions) or None."""
    return None if self._via is None else self._via.copy()

  def _free(self, q_start, q_goals):
    q_goals = np.atleast_2d(q_goals)
    ok = self._checker.paths_free(q_start, q_goals)
    ok[ok] = self._robot_side(q_start, q_goals[ok])
    return ok

  def _robot_side(self, q_start, q_goals):
    """Flags (G,): the straight joint paths q_start -> q_goals keep every
    capsule at y <= layout.REACH_GOAL_MAX_Y (or, from a start beyond it,
    no further than the start's)."""
    if not len(q_goals):
      return np.zeros(0, dtype=bool)
    delta = q_goals - q_start
    samples = max(1, int(np.ceil(np.abs(delta).max() / SIDE_STEP)))
    fraction = np.linspace(0.0, 1.0, samples + 1)[None, :, None]
    p1, p2, radii = self._checker.reach.capsules(
        q_start + fraction * delta[:, None, :])
    side = np.maximum(p1[..., 1], p2[..., 1]) + radii      # (G, S, L)
    bound = max(layout.REACH_GOAL_MAX_Y, side[0, 0].max())
    return np.all(side.max(axis=-1) <= bound, axis=-1)

  def _step_free(self, q, aims):
    """Flags: the one-step joint goals towards each aim pass the task's own
    check (the shield's planned path from its command, `collision_
    prevention.planned_paths_free`), i.e. would not be replaced."""
    model = self._task.kinematics
    aims = np.atleast_2d(aims)
    if not len(aims):
      return np.zeros(0, dtype=bool)
    steps = np.array([q + actions.JOINT_STEP * self._steer.joint_arm(a, q)
                      for a in aims])
    steps = np.clip(steps, model.q_min, model.q_max)
    return self._checker.planned_paths_free(steps, self._task.shield)

  def _plan(self, q, goal):
    """A via point v whose first step is accepted, with free straight paths
    q -> v -> goal, or None."""
    one_first = np.eye(len(q), dtype=bool)
    candidates = np.concatenate([
        self._q_home[None], np.where(one_first, goal, q),
        np.where(~one_first, goal, q)])
    via = self._first_via(q, goal, candidates)
    if via is None and not self._searched_near(q, goal):
      rng = np.random.default_rng(VIA_SEED)
      samples = rng.uniform(*self._via_range, (VIA_SAMPLES, len(q)))
      length = (np.linalg.norm(samples - q, axis=1)
                + np.linalg.norm(goal - samples, axis=1))
      via = self._first_via(q, goal, samples[np.argsort(length)])
      self._failed_search = None if via is not None else (q.copy(),
                                                          goal.copy())
    return via

  def _searched_near(self, q, goal):
    """Whether the random search failed for this goal within NEAR_GOAL
    of q (an arm held by collision prevention: searching every step cost
    0.4 s per RL step, UR5e seed 1)."""
    if self._failed_search is None:
      return False
    q_failed, goal_failed = self._failed_search
    return (np.abs(goal - goal_failed).max() < GOAL_TOLERANCE
            and np.abs(q - q_failed).max() < NEAR_GOAL)

  def _first_via(self, q, goal, candidates):
    """The first candidate whose first step is accepted and whose straight
    paths q -> v -> goal are free, or None."""
    ok = self._free(q, candidates)
    ok[ok] = self._step_free(q, candidates[ok])
    for v in candidates[ok]:
      if self._free(v, goal)[0]:
        return v
    return None

  def _joint_aim(self, q, goal):
    if np.abs(goal - q).max() < NEAR_GOAL or (
        self._free(q, goal)[0] and self._step_free(q, goal)[0]):
      self._via = None
      return goal
    if self._via is None or not (self._free(q, self._via)[0] and
                                 self._step_free(q, self._via)[0]):
      self._via = self._plan(q, goal)
    return goal if self._via is None else self._via

  def action(self, observation: Mapping[str, np.ndarray]) -> np.ndarray:
    """The action now.

    Args:
      observation: the OBSERVED observables now (`base.Expert.observe`).

    Returns:
      The action: joint space towards the goal, through a via point where
      the straight path is not free; Cartesian straight to the goal.
    """
    q = observation['joint_positions']
    tcp = observation['eef_position']
    if self._steer.space == 'joint':
      goal = q + observation['goal_joint_difference']
      return self._steer.joint_goal_action(self._joint_aim(q, goal), q, tcp)
    return self._steer.action(observation['goal_position'], tcp, q)
