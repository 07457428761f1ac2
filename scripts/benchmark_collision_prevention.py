"""CPU time of collision prevention's check of new goals (docs/benchmarks.md).

  MUJOCO_GL=egl python scripts/benchmark_collision_prevention.py \\
      [DOMAIN TASK ROBOT ACTION_SPACE]

Defaults: reach dense schunk cartesian. Steps the task with random
actions (seed 0) for 30 + 300 RL steps and reports, per RL step, the CPU
time of CollisionPrevention.filter_action (the IK of Cartesian actions
included), planned_paths_free and long_term_plan.plan_to_goal (the
shield's own calls included) while the environment runs; then replays the
recorded planned_paths_free calls back to back (plan cache cleared before
each: best of 7 rounds), per call and for plan_to_goal with the plan's
samples alone. Only stable public names are wrapped, so the script runs
on older commits too (`git archive` them).
"""

import collections
import sys
import time
import types

import numpy as np

from hrc_suite import suite
from hrc_suite.safety import collision_prevention as cp_lib
from hrc_suite.safety import long_term_plan as ltp

_WARM_UP, _STEPS, _ROUNDS = 30, 300, 7


def _wrap(owner, name, totals, record=None):
  """Adds the CPU time of owner.name to totals[name] (and calls
  record(*args) first)."""
  original = getattr(owner, name)

  def timed(*args, **kwargs):
    if record is not None:
      record(*args)
    start = time.process_time()
    try:
      return original(*args, **kwargs)
    finally:
      totals[name] += time.process_time() - start
  setattr(owner, name, timed)
  return original


def main(domain='reach', task='dense', robot='schunk', space='cartesian'):
  env = suite.load(domain, task, task_kwargs=dict(
      robot=robot, action_space=space, seed=0))
  spec = env.action_spec()
  rs = np.random.RandomState(0)
  totals, calls = collections.Counter(), []

  def record(self, goals, shield):
    """The check's goals and a copy of the shield's state now."""
    calls.append((self, np.array(goals, dtype=float), types.SimpleNamespace(
        q=np.array(shield.q), dq=np.array(shield.dq),
        ddq=np.array(shield.ddq), s=float(shield.s), limits=shield.limits,
        cycle_time=float(shield.cycle_time))))

  prevention = cp_lib.CollisionPrevention
  originals = {
      'filter_action': _wrap(prevention, 'filter_action', totals),
      'planned_paths_free': _wrap(prevention, 'planned_paths_free', totals,
                                  record),
      'plan_to_goal': _wrap(ltp, 'plan_to_goal', totals)}

  def steps(count):
    for _ in range(count):
      if env.step(rs.uniform(spec.minimum, spec.maximum)).last():
        env.reset()

  env.reset()
  steps(_WARM_UP)
  totals.clear()
  calls.clear()
  start = time.process_time()
  steps(_STEPS)
  total = time.process_time() - start
  for name, original in originals.items():
    setattr(prevention if name != 'plan_to_goal' else ltp, name, original)
  print(f'{domain}/{task} {robot} {space}: {total / _STEPS * 1e6:.0f} us '
        f'per RL step; in it, per RL step:')
  for name in originals:
    print(f'  {name}: {totals[name] / _STEPS * 1e6:.0f} us')

  # Replay: the same goals from the same shield states, back to back.
  replay = calls

  def checks():
    for self, goals, state in replay:
      ltp._RECENT._plans.clear()
      self.planned_paths_free(goals, state)

  def plans():
    for _, goals, state in replay:
      ltp._RECENT._plans.clear()
      for goal in goals:
        try:
          ltp.plan_to_goal(state.q, state.dq, state.ddq, goal, state.limits,
                           state.cycle_time, state.s).q
        except ltp.PlanningError:
          pass

  goals = sum(len(goals) for _, goals, _ in replay)
  for label, run, count in (('planned_paths_free', checks, len(replay)),
                            ('plan_to_goal + samples', plans, goals)):
    best = np.inf
    for _ in range(_ROUNDS):
      start = time.process_time()
      run()
      best = min(best, time.process_time() - start)
    print(f'replayed {label}: {best / count * 1e6:.1f} us per call '
          f'({count} calls)')


if __name__ == '__main__':
  main(*sys.argv[1:])
