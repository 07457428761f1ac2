"""A shield's state as a flat dict of arrays, strings, numbers and
booleans (no callables), for np.savez / JSON (after .tolist()): what
`Shield.get_state` gives and `Shield.set_state` restores (task snapshots,
tasks/runtime/snapshots.py).

Plans are stored by what defines them (`LongTermPlan.get_state`: a
Ruckig plan's inputs) and rebuilt; caches (the pending candidate plan,
PFL speed tables, lazy read-outs) are recomputed from the same inputs.
"""

from typing import Any, Mapping, Protocol

import numpy as np

from hrc_suite import robot_description as robot_description_lib
from hrc_suite.safety import long_term_plan as ltp
from hrc_suite.safety.shield import human_reach as human_reach_lib
from hrc_suite.safety.shield import path as path_lib
from hrc_suite.safety.shield import shield_state


class StatefulShield(Protocol):
  """What the dict reads and sets of a shield (members of
  `shield.Shield`, which imports this module)."""
  description: robot_description_lib.RobotDescription
  mode: str
  cycle_time: float
  dof: int
  limits: robot_description_lib.JointLimits
  human: human_reach_lib.HumanReach
  state: shield_state.ShieldState   # Settable: installs a state.

  @property
  def reach_distance(self) -> float:
    """The last check's clearance, m (mode 'off': the check runs)."""


def state_dict(shield: StatefulShield) -> dict[str, Any]:
  """A shield's state as a flat dict (see the module). In mode 'off' the
  cycle's check runs first (the read-outs are saved).

  Args:
    shield: the shield.

  Returns:
    The snapshot: name -> value.
  """
  reach_distance = float(shield.reach_distance)
  state = shield.state
  plan = state.plan.get_state()
  human = shield.human.get_state()
  checked = state.verification
  edges = checked.edges
  dof = shield.dof
  snapshot = {
      'robot': shield.description.name, 'mode': shield.mode,
      'cycle_time': shield.cycle_time, 'time': state.time,
      'command': np.array(state.command), 'previous_q': np.array(
          state.previous_q),
      'verified': shield_state.path_array(state.verified),
      'has_intended': state.intended is not None,
      'intended': shield_state.path_array(state.intended
                                          or path_lib.Path()),
      'has_goal': state.goal is not None,
      'goal': (np.zeros(dof) if state.goal is None
               else np.array(state.goal)),
      'goal_pending': state.goal_pending,
      'is_safe': bool(checked.is_safe),
      'intervened': bool(state.intervened),
      'first_unsafe_interval': int(checked.first_unsafe_interval),
      'reach_distance': reach_distance,
      'has_reach': edges is not None,
      's_edges': np.array([] if edges is None else edges.s_edges),
      't_edges': np.array([] if edges is None else edges.t_edges),
      'q_edges': (np.zeros((0, dof)) if edges is None
                  else np.array(edges.q_edges)),
  }
  snapshot.update({f'plan_{k}': v for k, v in plan.items()})
  snapshot.update({f'human_{k}': v for k, v in human.items()})
  return snapshot


def restore(shield: StatefulShield, state: Mapping[str, Any]) -> None:
  """Restores a `state_dict` of a shield of the same robot, mode and cycle
  (the shield's human model and state are set).

  Args:
    shield: the shield to restore.
    state: a `state_dict` (arrays may be lists, as after JSON; 0-d arrays
      as after np.load).

  Raises:
    ValueError: the state is of another robot, mode or cycle, or its
      command has the wrong shape.
  """
  def scalar(name):
    return np.asarray(state[name]).item()
  dof = shield.dof
  for name, mine in (('robot', shield.description.name),
                     ('mode', shield.mode),
                     ('cycle_time', shield.cycle_time)):
    if scalar(name) != mine:
      raise ValueError(f'shield state {name}: expected {mine!r}, got '
                       f'{scalar(name)!r}')
  command = np.array(state['command'], dtype=float)
  if command.shape != (5, dof):
    raise ValueError(f'shield state command: expected shape (5, '
                     f'{dof}), got {command.shape}')
  plan = ltp.LongTermPlan.from_state(
      {k[5:]: v for k, v in state.items() if k.startswith('plan_')},
      shield.limits)
  human = shield.human
  human.set_state(
      {k[6:]: v for k, v in state.items() if k.startswith('human_')})
  edges = None
  if scalar('has_reach'):
    edges = shield_state.ReachEdges(
        plan, np.asarray(state['s_edges'], dtype=float).tolist(),
        np.asarray(state['t_edges'], dtype=float).tolist(),
        np.array(state['q_edges'], dtype=float).reshape(-1, dof))
  shield.state = shield_state.ShieldState(
      command=command,
      previous_q=np.array(state['previous_q'], dtype=float),
      verified=shield_state.path_from_array(state['verified']),
      intended=(shield_state.path_from_array(state['intended'])
                if scalar('has_intended') else None),
      plan=plan,
      goal=(np.array(state['goal'], dtype=float)
            if scalar('has_goal') else None),
      goal_pending=bool(scalar('goal_pending')),
      candidate=None, candidate_key=None,
      time=float(scalar('time')),
      intervened=bool(scalar('intervened')),
      verification=shield_state.Verification(
          is_safe=bool(scalar('is_safe')),
          first_unsafe_interval=int(scalar('first_unsafe_interval')),
          reach_distance=float(scalar('reach_distance')), edges=edges),
      human=human.state)
