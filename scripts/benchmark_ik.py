"""Measures the workspace IK per robot: success rate and time per solve.

    python scripts/benchmark_ik.py [--targets=200] [robot ...]

Targets are uniform in each robot's table workspace box
(`ik.sample_table_targets`). A target counts as reachable when a thorough
reference search (the same solver with 300 iterations from q_home and then
from up to 100 uniform random seeds) finds a solution within the joint limits
and tolerances. On the reachable targets the fast solver (default settings)
is measured
* from q_home (a far jump: up to ~0.5 m), and
* along a random walk from the home TCP with steps of 0.1 m (the
  reference's largest workspace action), each solve seeded with the previous
  successful solution (the realistic per-RL-step use);
"success" is the solver's own verdict (1 mm, 0.01 rad), "within 5 mm" the
TCP position error of the returned q. Median wall time and iterations per
solve are for the reachable random-walk steps (ms/fail: unreachable ones).
Deterministic (seed 0) apart from the times.
"""

import argparse
import time

import numpy as np

from hrc_suite import layout
from hrc_suite import robot_description
from hrc_suite.control import ik
from hrc_suite.control import kinematics

STEP = 0.1          # m, largest TCP move per RL step (reference benchmark).
ACCURACY = 5e-3     # m, the TCP error a returned solution must stay within.


def world_model(name):
  return kinematics.KinematicModel(
      robot_description.load(name),
      base_pose=layout.robot_mount(name).base_pose())


def reference_solver(model):
  return ik.InverseKinematics(model, max_iterations=300)


def random_walk(model, num_targets, random_state):
  """Targets from the home TCP, each STEP from the previous, in the box."""
  base = model.base_pose
  low, high = ik.table_workspace_box(model)
  home = base[:3, :3].T @ (
      model.tcp_pose(model.description.q_home)[:3, 3] - base[:3, 3])
  points, point = [], home
  for _ in range(num_targets):
    for _ in range(100):  # A full STEP in a random direction, inside the box.
      direction = random_state.standard_normal(3)
      candidate = point + STEP * direction / np.linalg.norm(direction)
      if np.all(candidate >= low) and np.all(candidate <= high):
        break
    point = np.clip(candidate, low, high)
    points.append(point)
  return np.array(points) @ base[:3, :3].T + base[:3, 3]


def measure(name, num_targets, seed=0):
  model = world_model(name)
  q_home = model.description.q_home
  fast = ik.InverseKinematics(model)
  reference = reference_solver(model)
  random_state = np.random.RandomState(seed)

  targets = ik.sample_table_targets(model, num_targets, random_state)
  reachable = np.array([
      reference.solve_with_restarts(t, q_home, random_state,
                                    restarts=100).success for t in targets])
  from_home = [fast.solve(t, q_home) for t in targets[reachable]]

  walk = random_walk(model, num_targets, random_state)
  walk_reachable = np.array([
      reference.solve_with_restarts(t, q_home, random_state,
                                    restarts=100).success for t in walk])
  walk_results, times, fail_times, q = [], [], [], q_home
  for target, is_reachable in zip(walk, walk_reachable):
    start = time.perf_counter()
    result = fast.solve(target, q)
    elapsed = time.perf_counter() - start
    if is_reachable:
      walk_results.append(result)
      times.append(elapsed)
    else:
      fail_times.append(elapsed)
    if result.success:
      q = result.q

  def rates(results):
    success = np.mean([r.success for r in results])
    accurate = np.mean([r.position_error <= ACCURACY for r in results])
    return success, accurate
  return dict(
      reachable=reachable.mean(), from_home=rates(from_home),
      walk_reachable=walk_reachable.mean(), walk=rates(walk_results),
      median_ms=1e3 * np.median(times),
      unreachable_ms=1e3 * np.median(fail_times) if fail_times else np.nan,
      median_iterations=np.median([r.iterations for r in walk_results]))


def main():
  parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
  parser.add_argument('robots', nargs='*',
                      default=robot_description.ROBOT_NAMES)
  parser.add_argument('--targets', type=int, default=200)
  args = parser.parse_args()
  print(f'{"robot":8s} {"reach%":>6s} {"home ok%":>8s} {"home<5mm%":>9s} '
        f'{"walk reach%":>11s} {"walk ok%":>8s} {"walk<5mm%":>9s} '
        f'{"ms/solve":>8s} {"iters":>5s} {"ms/fail":>7s}')
  for name in args.robots:
    m = measure(name, args.targets)
    print(f'{name:8s} {100 * m["reachable"]:6.1f} '
          f'{100 * m["from_home"][0]:8.1f} {100 * m["from_home"][1]:9.1f} '
          f'{100 * m["walk_reachable"]:11.1f} {100 * m["walk"][0]:8.1f} '
          f'{100 * m["walk"][1]:9.1f} {m["median_ms"]:8.3f} '
          f'{m["median_iterations"]:5.0f} {m["unreachable_ms"]:7.3f}',
          flush=True)


if __name__ == '__main__':
  main()
