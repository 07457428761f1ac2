"""The check of a monitored path: is the robot on it clear of the human?

The monitored path (docs/shield_maths.md, 4) is cut into slices: the one
from the current command to the intended step, then the failsafe's of
one reachability interval each (docs/shield_maths.md, 6). Before the
mode's exact verdict (`modes.ShieldMode.verdict`), cheap broad phases
(docs/shield_maths.md, 5.3) try to settle the cycle under SSM's "some
model is collision-free" rule: the human's maximal-velocity (VEL) balls
over the whole horizon against the robot's workspace ball, then against
a bound of the robot's reach capsules from one forward kinematics
(kernels.swept_balls_gap), then against the reach capsules themselves.
The compiled cycles' twin is cycle_kernels.ssm_cycles'.
"""

import math
from typing import Any, MutableMapping

import numpy as np

from hrc_suite.safety import kernels
from hrc_suite.safety import long_term_plan as ltp
from hrc_suite.safety import robot_reach as robot_reach_lib
from hrc_suite.safety.shield import cycle_terms
from hrc_suite.safety.shield import human_reach as human_reach_lib
from hrc_suite.safety.shield import modes as modes_lib
from hrc_suite.safety.shield import path as path_lib
from hrc_suite.safety.shield import shield_state

_BROAD_PHASE_SLACK = cycle_terms.BROAD_PHASE_SLACK


class PathCheck:
  """Checks monitored paths of one robot against one human model.

  Args:
    terms: the shield's cycle constants (`cycle_terms.CycleTerms`).
    robot: the robot's capsules and reach capsules.
    human: the human's reachable-set model (its last measurement is the
      one checked against).
    cycle_time: the shield's cycle, s.
    interval: a reachability slice's length, s.
  """

  def __init__(self, terms: cycle_terms.CycleTerms,
               robot: robot_reach_lib.RobotReach,
               human: human_reach_lib.HumanReach, cycle_time: float,
               interval: float):
    self._terms = terms
    self._robot = robot
    self._human = human
    self._cycle_time = cycle_time
    self._interval = interval
    self._dof = len(terms.q_min)

  def verify(self, plan: ltp.LongTermPlan, current: path_lib.Path,
             failsafe: path_lib.Path, previous_q: np.ndarray, now: float,
             mode: modes_lib.ShieldMode, shield: modes_lib.ShieldView,
             readouts: MutableMapping[str, Any]
             ) -> shield_state.Verification:
    """Checks the slice current -> intended step, then the failsafe, at
    cycle time `now` from the command previous_q.

    Args:
      plan: the plan the monitored path is on.
      current: the path at the cycle's start.
      failsafe: the failsafe path from the intended step on.
      previous_q: (dof,) the command's joint positions at the cycle's
        start.
      now: the cycle's time, s.
      mode: the shield's mode (its exact verdict).
      shield: the shield whose cycle this is (what the verdict reads).
      readouts: the shield's lazy read-outs: the reach capsules computed
        are kept there ('robot_reach', 'human_reach').

    Returns:
      The check (its reach_distance is a broad phase's bound when one
      settled the cycle, None when the exact verdict did).
    """
    dt = self._cycle_time
    interval = self._interval
    end = failsafe.end_time()
    count = max(math.ceil(end / interval - 1e-9), 1)
    times = [i * interval for i in range(count)] + [end]
    pieces = failsafe.segments()
    s = failsafe.sample(times, pieces)[0]
    s_edges = [current.s] + s
    t_edges = [0.0] + [x + dt for x in times]
    q_edges = np.empty((count + 2, self._dof))
    q_edges[0] = previous_q
    plan.positions(s, out=q_edges, first=1)
    edges = shield_state.ReachEdges(plan, s_edges, t_edges, q_edges)
    result = lambda safe, first, distance: shield_state.Verification(
        safe, first, distance, edges)
    end_q = q_edges[-1].tolist()
    terms = self._terms
    if not all(low <= q <= high for low, q, high in zip(
        terms.q_min, end_q, terms.q_max)):
      return result(False, count, -np.inf)
    human = self._human
    if human.positions is None:
      return result(True, -1, np.inf)
    # Broad phase 1: the human's horizon balls against the robot's whole
    # workspace ball (no kinematics needed).
    age = now - human.last_measurement_time + terms.human_delay + t_edges[-1]
    centre, radius, gap = kernels.horizon_balls(
        human.positions, human.velocities, terms.human_v_max,
        terms.body_ends, terms.half_thickness, age, terms.human_error_pos,
        terms.base)
    bound = gap - terms.workspace_radius
    if bound > 0.0:
      return result(True, -1, bound)
    # Broad phase 2, bounded from the robot's capsules at q_edges[0] alone
    # (one forward kinematics instead of one per edge; a lower bound of
    # the test below, so it settles only cycles that test settles).
    model = self._robot
    fixed, points = model.kernel_model
    bound = kernels.swept_balls_gap(
        q_edges, np.asarray(s_edges, dtype=float),
        kernels._frames(q_edges[:1], fixed)[0], points,
        model.kernel_frames, model.kernel_alpha, model.kernel_static,
        model.kernel_levers, model.kernel_half_lengths, centre, radius,
        _BROAD_PHASE_SLACK) - _BROAD_PHASE_SLACK
    if bound > 0.0:
      return result(True, -1, bound)
    robot = readouts['robot_reach'] = model.reach_capsules(
        q_edges, np.array(s_edges))
    # Broad phase 2: the same balls against every robot reach capsule.
    bound = kernels.balls_capsules_distance(centre, radius,
                                            *robot) - _BROAD_PHASE_SLACK
    if bound > 0.0:
      return result(True, -1, bound)
    human = readouts['human_reach'] = human.reach_capsules(
        now, np.array(t_edges))
    # The exact check: the mode's verdict (modes.ShieldMode.verdict).
    safe, first = mode.verdict(shield, modes_lib.Slices(
        plan, current, failsafe, times, s_edges, pieces, robot, human))
    return result(safe, first, None)
