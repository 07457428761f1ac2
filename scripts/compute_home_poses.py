"""Computes each robot's home pose and writes it as "q_home" into its JSON.

Developer tool, run when a description's kinematics change:
    python scripts/compute_home_poses.py [robot ...]

Home pose: a natural "ready" configuration with the gripper pointing down
(TCP x axis along world +x or -x: the gripper is symmetric under a half
turn) and the TCP `HOME_TCP` in front of and above the base (base frame =
table top height, x forward). Among the IK solutions (many seeds), each is
refined by SLSQP to minimise

    mean(((q - q_mid) / min(q_half_range, pi))^2)
        - SINGULAR_WEIGHT * log(sigma_min(J)) - ELBOW_WEIGHT * elbow_height

(central in the joint ranges, far from singularities, elbow up in the arm's
vertical plane; J is the TCP Jacobian with angular rows in metres) subject to
the TCP pose, the elbow at least ELBOW_MIN_HEIGHT above the shoulder-wrist
line and every link capsule clear of the table top and the pedestal; the best
one, among those from which the workspace IK reaches (nearly) the most
table targets, is written. Deterministic (fixed seed).
"""

import json
import re
import sys

import numpy as np
import pinocchio as pin
from scipy import optimize

from hrc_suite import layout
from hrc_suite import robot_description
from hrc_suite.control import ik
from hrc_suite.control import kinematics

# TCP relative to the default mount's base (world offset), m: 0.45 m in
# front of it, 0.25 m above the table top. Every robot's home TCP is this
# world point; the Schunk LWA 4P (on its raised mount, layout.py, whose
# wrist cannot hold the gripper vertical much higher) too.
HOME_TCP = {name: (0.45, 0.0, 0.25) for name in robot_description.ROBOT_NAMES}

# Link indices (0-based) whose frame origins are the shoulder, elbow and
# wrist, from the chains in hrc_suite/assets/robots/*.json.
ARM_POINTS = {
    'panda': (1, 3, 5), 'sawyer': (1, 3, 5), 'iiwa': (1, 3, 5),
    'jaco': (1, 3, 5), 'kinova3': (1, 3, 5), 'ur5e': (1, 2, 3),
    'schunk': (1, 2, 4),
}
ELBOW_MIN_HEIGHT = 0.03   # m, elbow above the shoulder-wrist line.
CLEARANCE_MARGIN = 0.03   # m, capsules above the table / beside the pedestal.
SINGULAR_WEIGHT = 0.1
ELBOW_WEIGHT = 0.5        # per m of elbow height.
ANGULAR_SCALE = 0.2       # m per rad in the Jacobian's singular values.
NUM_SEEDS = 300
# Home branches are ranked by how many of these table targets the fast
# workspace IK reaches from them (a ready pose should not need a branch
# switch); those within COVERAGE_SLACK of the best compete on cost.
NUM_COVERAGE_TARGETS = 60
COVERAGE_SLACK = 0.02
SEED = 0

_ROBOTS_DIR = robot_description.ROBOTS_DIR
_SEGMENT_SAMPLES = np.linspace(0.0, 1.0, 11)


def to_json(value):
  """JSON with every list of numbers on one line, for readable diffs (the
  layout of the description files)."""
  text = json.dumps(value, indent=1)

  def join(match):
    return '[' + ', '.join(x.strip() for x in match.group(1).split(',')) + ']'
  for _ in range(2):  # Inner lists first, then lists of lists.
    text = re.sub(r'\[([^\[\]{}"]*)\]', join, text)
    text = re.sub(r'\[((?:\s*\[[^\[\]]*\],?)+\s*)\]', join, text)
  return text + '\n'

def world_model(description):
  mount = layout.robot_mount(description.name)
  return kinematics.KinematicModel(description, base_pose=mount.base_pose())


def workcell_clearance(model, q):
  """Smallest clearance (m) of the link capsules from table top and pedestal.

  Points along each capsule axis that lie (within their radius) over the
  table must be a radius above the table top; points lower than the pedestal
  top must be a radius away from the pedestal's sides.
  """
  p1, p2, radius = model.link_capsules(q)
  points = (p1[:, None, :] +
            _SEGMENT_SAMPLES[None, :, None] * (p2 - p1)[:, None, :])
  r = radius[:, None]
  x, y, z = points[..., 0], points[..., 1], points[..., 2]
  over_table = ((x + r > layout.TABLE_X[0]) & (y + r > layout.TABLE_Y[0]) &
                (y - r < layout.TABLE_Y[1]))
  table_gap = np.where(over_table, z - r - layout.TABLE_TOP_Z, np.inf)
  mount = layout.robot_mount(model.description.name)
  cx, cy = mount.pedestal_center_xy
  hx, hy = mount.pedestal_half_size
  outside = np.hypot(np.maximum(np.abs(x - cx) - hx, 0.0),
                     np.maximum(np.abs(y - cy) - hy, 0.0))
  below_top = z - r < mount.base_position[2]
  pedestal_gap = np.where(below_top, outside - r, np.inf)
  return float(min(table_gap.min(), pedestal_gap.min()))


def elbow_height(model, q, points):
  """Height of the elbow above the straight shoulder-wrist line, m."""
  frames = model.link_frames(q)
  shoulder, elbow, wrist = (frames[i, :3, 3] for i in points)
  axis = wrist - shoulder
  t = np.dot(elbow - shoulder, axis) / np.dot(axis, axis)
  return float(elbow[2] - (shoulder[2] + t * axis[2]))


def _pose_error(model, q, target, rotation):
  pose = model.tcp_pose(q)
  return np.concatenate([target - pose[:3, 3],
                         pin.log3(rotation @ pose[:3, :3].T)])


def _cost(model, q, points):
  limits = model.description.limits
  mid = 0.5 * (limits.q_max + limits.q_min)
  # Joints that turn (almost) fully around count as +-pi from their middle.
  half = np.minimum(0.5 * (limits.q_max - limits.q_min), np.pi)
  jacobian = model.tcp_jacobian(q).copy()
  jacobian[3:] *= ANGULAR_SCALE
  sigma_min = np.linalg.svd(jacobian, compute_uv=False)[-1]
  return (float(np.mean(((q - mid) / half) ** 2)) -
          SINGULAR_WEIGHT * float(np.log(max(sigma_min, 1e-9))) -
          ELBOW_WEIGHT * elbow_height(model, q, points))


def _refine(model, q0, target, rotation, points):
  constraints = [
      dict(type='eq', fun=lambda q: _pose_error(model, q, target, rotation)),
      dict(type='ineq',
           fun=lambda q: workcell_clearance(model, q) - CLEARANCE_MARGIN),
      dict(type='ineq',
           fun=lambda q: elbow_height(model, q, points) - ELBOW_MIN_HEIGHT),
  ]
  limits = model.description.limits
  result = optimize.minimize(
      lambda q: _cost(model, q, points), q0, method='SLSQP',
      bounds=list(zip(limits.q_min, limits.q_max)), constraints=constraints,
      options=dict(maxiter=300, ftol=1e-10))
  return np.clip(result.x, limits.q_min, limits.q_max)


def _coverage_targets(model, name):
  """Fixed table-workspace TCP targets (the box of ik.table_workspace_box)."""
  mount = layout.robot_mount(name)
  scale = (mount.workspace_scale if mount.workspace_scale is not None else
           min(1.0, np.linalg.norm(HOME_TCP[name]) /
               np.linalg.norm(ik.NOMINAL_HOME_TCP)))
  random_state = np.random.RandomState(SEED + 1)
  local = scale * random_state.uniform(
      ik.TABLE_WORKSPACE_LOW, ik.TABLE_WORKSPACE_HIGH,
      size=(NUM_COVERAGE_TARGETS, 3))
  local[:, 2] -= mount.height_above_table
  return local + model.base_pose[:3, 3]


def _coverage(solver, q, targets):
  """Fraction of targets the fast IK solves when seeded with q."""
  return float(np.mean([solver.solve(t, q).success for t in targets]))


def _feasible(model, q, target, rotation, points):
  error = _pose_error(model, q, target, rotation)
  return (np.linalg.norm(error[:3]) < 1e-4 and
          np.linalg.norm(error[3:]) < 1e-3 and
          workcell_clearance(model, q) >= CLEARANCE_MARGIN - 1e-4 and
          elbow_height(model, q, points) >= ELBOW_MIN_HEIGHT - 1e-4)


def compute_home(name):
  """Best home pose for one robot and a summary dict."""
  description = robot_description.load(name)
  model = world_model(description)
  solver_fast = ik.InverseKinematics(model)
  solver = ik.InverseKinematics(model, max_iterations=200,
                                position_tolerance=1e-5,
                                orientation_tolerance=1e-4)
  target = np.asarray(layout.ROBOT_BASE_POS) + np.asarray(HOME_TCP[name])
  base = model.base_pose[:3, 3]
  rotation = ik.gripper_down_rotation(0.0)
  points = ARM_POINTS[name]
  random_state = np.random.RandomState(SEED)
  candidates = []  # (q, rotation)
  limits = description.limits
  mid = 0.5 * (limits.q_max + limits.q_min)
  spread = 0.5 * np.minimum(0.5 * (limits.q_max - limits.q_min), np.pi)
  for i in range(NUM_SEEDS):
    # Half the seeds uniform, half near the middle of the joint ranges (where
    # the cost is low), since the local refinement keeps an IK branch.
    if i % 2:
      seed = random_state.uniform(limits.q_min, limits.q_max)
    else:
      seed = np.clip(mid + spread * random_state.standard_normal(model.dof),
                     limits.q_min, limits.q_max)
    result = solver.solve(target, seed)
    if result.success:
      candidates.append((result.q, ik.gripper_down_rotation(result.yaw)))
  if not candidates:
    raise RuntimeError(f'{name}: no IK solution for the home TCP {target}')
  # Refine every candidate: the cost has many local minima (IK branches).
  refined = {}
  for q0, rotation in candidates:
    q = _refine(model, q0, target, rotation, points)
    if _feasible(model, q, target, rotation, points):
      refined.setdefault(tuple(np.round(q, 2)), (q, _cost(model, q, points)))
  if not refined:
    raise RuntimeError(f'{name}: no home pose meets the constraints')
  # Among the branches from which the workspace IK reaches (nearly) the most
  # table targets, the lowest cost wins.
  targets = _coverage_targets(model, name)
  scored = [(_coverage(solver_fast, q, targets), cost, q)
            for q, cost in refined.values()]
  top = max(coverage for coverage, _, _ in scored)
  best_coverage, best_cost, best = min(
      (s for s in scored if s[0] >= top - COVERAGE_SLACK),
      key=lambda s: s[1])
  summary = dict(
      tcp=model.tcp_pose(best)[:3, 3] - base,
      clearance=workcell_clearance(model, best),
      elbow=elbow_height(model, best, points),
      limit_margin=float(np.min(np.minimum(best - limits.q_min,
                                           limits.q_max - best))),
      cost=best_cost, coverage=best_coverage, solutions=len(candidates),
      branches=len(refined),
      x_axis=model.tcp_pose(best)[:3, 0])
  return best, summary


def main(argv):
  names = argv[1:] or robot_description.ROBOT_NAMES
  for name in names:
    q_home, summary = compute_home(name)
    path = _ROBOTS_DIR / f'{name}.json'
    data = json.loads(path.read_text())
    # Six decimals (~1e-6 m at the TCP); tiny values snap to a clean 0.
    data['q_home'] = [0.0 if abs(v) < 1e-5 else round(float(v), 6)
                      for v in q_home]
    path.write_text(to_json(data))
    robot_description.load(name)  # Validates the written file.
    print(f'{name}: q_home={data["q_home"]}')
    print('  ' + ', '.join(f'{k}={np.round(v, 4)}' for k, v in summary.items()))


if __name__ == '__main__':
  main(sys.argv)
