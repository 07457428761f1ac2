"""Static and self-collision prevention of goal configurations (all robots).

Before a goal goes to the shield, the configuration it reaches and the
straight joint-space path to it are checked against the workcell (table top,
pedestal, floor, extra boxes) and against self-collision of non-adjacent
capsules, with the robot description's capsules and exact capsule maths
(`geometry`). Unsafe actions are replaced ('zero', 'resample', 'closest').

Rules (derived per robot at construction, see `self_collision_pairs`):
* Capsule i and i+1 (and the last link and the tool) are adjacent and never
  checked against each other; the base-mounted first link is not checked
  against the pedestal it stands on.
* A non-adjacent pair is excluded if it overlaps at q_home (the robot is
  not in collision at home: the capsules are conservative enclosures that
  overlap there by construction) or in every one of `exclusion_samples`
  random configurations within the joint limits (e.g. around a compact
  wrist). A home-overlapping pair that separates elsewhere (UR5e forearm
  and wrist 2) is thus not checked: a documented blind spot. (Keeping it
  with its home penetration as tolerance rejected about half of all small
  moves around home.)
* The tool capsule may touch the table top (grasping) up to
  `tool_table_allowance` metres of penetration (default 0: no contact).
* Pairs the robot description lists as `self_collision_exempt` (capsules
  that touch by construction without overlapping at q_home, e.g. the
  Sawyer's wrist, sawyer.json's notes) are not checked either.

Path sampling: a surface point of a capsule moves at most sum_k lever_k
|dq_k| for a joint step dq, lever_k bounding the distance of any later
capsule point from joint k's origin. The path is cut into steps moving no
point more than `max_step` (1 cm); every configuration between two samples
is within half a step of a sample, so capsules are inflated by the motion
of half a step at the samples: a collision anywhere on the path is detected
(flagged samples are refined, see `paths_free`).

Planned paths (`planned_paths_free`, `filter_action(plan_from=shield)`):
the robot does not move on the straight path but along the shield's
long-term plan from its current command, which overshoots when the robot
is moving; the plan is made exactly as the shield will make it and sampled
on the shield's own per-cycle polynomial, with margins from its
derivatives. Escape rule (both kinds): a start already in collision does
not reject every path; an element in collision at the start may not
penetrate deeper until it is free (see `paths_free`).

Compiled (compiled=True): the capsule tests run in `collision_kernels`
(collision_prevention/kernels.py), and a plan from a free start is swept
in one call (`collision_kernels.planned_path_collides`, with a
conservative broad phase that skips only capsule tests proven not to hit:
collision_prevention/bounds.py); compiled=False
runs the NumPy reference (`_colliding_reference`, `_planned_sweep`). Both
make the same decisions (the same operations in the same order where a
test is done; tests on random goals, near the table and near
self-collision).
"""

import typing
from typing import Callable, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from hrc_suite import layout
from hrc_suite import robot_description as robot_description_lib
from hrc_suite.safety import geometry
from hrc_suite.safety import kernels
from hrc_suite.safety import long_term_plan as ltp
from hrc_suite.safety import robot_reach
from hrc_suite.safety.collision_prevention import kernels as collision_kernels

POLICIES = ('zero', 'resample', 'closest')

# Default number of replacement samples (reference benchmark: 20;
# docs/reference_benchmark.md, Safety).
DEFAULT_NUM_SAMPLES = 20
# Largest motion of any capsule point between path samples (m).
DEFAULT_MAX_STEP = 0.01
# Refinement of samples flagged with inflated capsules: sub-samples per
# sample and levels (inflation 5 mm -> 1.25 -> 0.31 -> 0.08 mm).
REFINE = 4
REFINE_LEVELS = 3
# Samples per run of the compiled plan sweep's broad phase (bounds.py):
# one forward kinematics at a run's centre proves most capsule tests free
# for all of its samples (16: the fastest of 4 to 64 on reach's plans,
# docs/benchmarks.md, "Collision prevention's check of a new goal").
SWEEP_RUN = 16
# Sub-sample positions in (-1, 1), in half widths of the refined sample.
_REFINE_OFFSETS = (2.0 * np.arange(REFINE) + 1.0) / REFINE - 1.0
# Escape rule: a penetration may grow this much (m) from sample to sample
# (round-off of sliding along a surface) and still count as not increasing.
_ESCAPE_SLACK = 1e-9
# A pair overlapping in this fraction of random configurations (and at
# q_home) overlaps by construction.
_ALWAYS_FRACTION = 1.0


# A box (min (3,), max (3,)), world frame, m.
Box = Tuple[Sequence[float], Sequence[float]]


class FilteredAction(typing.NamedTuple):
  """`CollisionPrevention.filter_action`'s result."""
  action: np.ndarray
  q_goal: np.ndarray
  replaced: bool
  plan: typing.Optional[ltp.LongTermPlan]   # The goal's plan, if made.


class PlanStart(typing.Protocol):
  """What `CollisionPrevention.planned_paths_free` reads of the shield
  that will execute a goal (`shield.Shield` is one): its command, where
  the goal's long-term plan starts."""

  @property
  def q(self) -> np.ndarray:
    """The command's joint positions (dof,)."""

  @property
  def dq(self) -> np.ndarray:
    """The command's joint velocities (dof,)."""

  @property
  def ddq(self) -> np.ndarray:
    """The command's joint accelerations (dof,)."""

  @property
  def s(self) -> float:
    """The plan time (s) a new plan starts at."""

  @property
  def limits(self) -> robot_description_lib.JointLimits:
    """The joint limits plans keep."""

  @property
  def cycle_time(self) -> float:
    """The plans' sample period, s."""


def workcell_boxes(floor: bool = True,
                   mount: layout.RobotMount = layout.DEFAULT_MOUNT,
                   table: layout.Table = layout.DEFAULT_TABLE
                   ) -> dict[str, Box]:
  """Named static boxes of the workcell (layout).

  Args:
    floor: whether the floor is one (a slab below z = 0).
    mount: the robot's mount, whose pedestal is one.
    table: the table, whose top is one.

  Returns:
    name -> (min (3,), max (3,)), world frame, m: 'table', 'pedestal' and
    (with floor) 'floor'.
  """
  table_min = (table.x[0], table.y[0],
               layout.TABLE_TOP_Z - layout.TABLE_THICKNESS)
  table_max = (table.x[1], table.y[1], layout.TABLE_TOP_Z)
  cx, cy = mount.pedestal_center_xy
  hx, hy = mount.pedestal_half_size
  base_z = mount.base_position[2]
  boxes = {'table': (table_min, table_max),
           'pedestal': ((cx - hx, cy - hy, 0.0), (cx + hx, cy + hy, base_z))}
  if floor:  # The floor as a thick slab below z = 0.
    boxes['floor'] = ((-10.0, -10.0, -1.0), (10.0, 10.0, 0.0))
  return boxes


def _lever_sum(x, levers):
  """x (N, dof) @ levers (dof, M), summed joint by joint in order (the
  compiled sweep's order, collision_kernels._lever_sum; a BLAS product may sum
  in another, and a margin one ulp off can flip a decision)."""
  total = x[:, :1] * levers[0]
  for k in range(1, levers.shape[0]):
    total = total + x[:, k:k + 1] * levers[k]
  return total


def _polynomial(plan):
  """The compiled sweep's PlanPolynomial of a LongTermPlan."""
  return collision_kernels.PlanPolynomial(*_polynomial_fields(plan))


def _polynomial_fields(plan):
  """`_polynomial`'s fields as a plain tuple, as the compiled sweep takes
  them (kernels.as_fields)."""
  cycle = plan.cycle_time
  return (plan._all(), plan.start_time, plan._inverse_cycle, cycle,
          cycle ** 2, cycle ** 3, plan.num_samples - 1)


class CollisionPrevention:
  """Checks goals and straight joint paths; replaces unsafe actions.

  Args:
    description: the robot's description.
    base_pose: the robot base's pose, a 4x4 matrix or (x, y, z, roll,
      pitch, yaw) (None: the robot's mount, layout.robot_mount).
    tool_capsule: (p1 (3,), p2 (3,), radius) of the tool's capsule in the
      last link's frame, m (None: no tool).
    extra_boxes: static boxes (min (3,), max (3,)), world frame, m,
      besides the workcell's (`workcell_boxes`).
    floor: whether the floor is checked.
    tool_table_allowance: how deep (m) the tool capsule may enter the table
      top (grasping).
    max_step: the largest motion (m) of any capsule point between path
      samples, > 0.
    exclusion_samples: random configurations a capsule pair must overlap
      in (with q_home) to be excluded as overlapping by construction.
    seed: the seed of those configurations.
    compiled: False runs the NumPy reference of the checks.
    table: the table, whose top is a box.

  Raises:
    ValueError: max_step is not positive, an extra box is not (min (3,),
      max (3,)) with min <= max, or the tool capsule is malformed.
  """

  def __init__(
      self, description: robot_description_lib.RobotDescription,
      base_pose: Optional[Union[np.ndarray, Sequence[float]]] = None,
      tool_capsule: Optional[Tuple[np.ndarray, np.ndarray, float]] = None,
      extra_boxes: Sequence[Box] = (), floor: bool = True,
      tool_table_allowance: float = 0.0, max_step: float = DEFAULT_MAX_STEP,
      exclusion_samples: int = 2000, seed: int = 0, compiled: bool = True,
      table: layout.Table = layout.DEFAULT_TABLE):
    self.description = description
    # Compiled collision tests (`collision_kernels`); False runs the NumPy
    # reference (`_colliding_reference`), which the kernel is tested
    # against.
    self.compiled = bool(compiled)
    if self.compiled:
      collision_kernels.warm_up()   # Once per process, not mid-run.
    self.reach = robot_reach.RobotReach(description, base_pose=base_pose,
                                        tool_capsule=tool_capsule,
                                        secure_radius=0.0)
    self.dof = description.dof
    self.num_capsules = self.reach.num_capsules
    if not max_step > 0:
      raise ValueError(f'max_step: expected > 0, got {max_step}')
    self.max_step = float(max_step)
    self._setup_boxes(extra_boxes, floor, float(tool_table_allowance),
                      table)
    self._setup_levers()
    self._setup_pairs(int(exclusion_samples), seed)
    # The compiled plan sweep's fixed groups (collision_kernels), as it takes
    # them (kernels.as_fields).
    fixed, points = self.reach.kernel_model
    self._sweep_groups = kernels.as_fields((
        collision_kernels.SweepSettings(
            self.levers, self._kernel_pair_levers, self.max_step,
            _REFINE_OFFSETS, REFINE_LEVELS, SWEEP_RUN),
        collision_kernels.RobotCapsules(
            fixed, points, self.reach.kernel_frames, self.reach.kernel_radii),
        collision_kernels.CollisionTests(
            self.box_min, self.box_max, self._box_checked,
            self._box_allowance, self._kernel_pairs)))
    self.num_checks = 0
    self.num_replacements = 0

  # -- Construction ---------------------------------------------------------

  def _setup_boxes(self, extra_boxes, floor, tool_table_allowance, table):
    boxes = workcell_boxes(floor, layout.robot_mount(self.description.name),
                           table)
    for i, box in enumerate(extra_boxes):
      try:
        lo, hi = (np.asarray(x, dtype=float) for x in box)
      except (TypeError, ValueError):
        raise ValueError(f'extra_boxes[{i}]: expected (min (3,), max (3,)), '
                         f'got {box!r}') from None
      if lo.shape != (3,) or hi.shape != (3,) or np.any(lo > hi):
        raise ValueError(f'extra_boxes[{i}]: expected min <= max, both (3,),'
                         f' got {box!r}')
      boxes[f'extra_{i}'] = (lo, hi)
    self.box_names = tuple(boxes)
    self.box_min = np.array([boxes[n][0] for n in self.box_names], dtype=float)
    self.box_max = np.array([boxes[n][1] for n in self.box_names], dtype=float)
    # Which capsule is checked against which box, and allowed penetration.
    checked = np.ones((len(self.box_names), self.num_capsules), dtype=bool)
    checked[self.box_names.index('pedestal'), 0] = False
    allowance = np.zeros(checked.shape)
    if self.reach.has_tool:
      allowance[self.box_names.index('table'), -1] = tool_table_allowance
    self._box_checked = checked
    self._box_allowance = allowance

  def _setup_levers(self):
    """Motion bounds: lever[k, c] >= distance of any point of capsule c from
    joint k's origin (0 if joint k does not move capsule c)."""
    self.levers = self.reach.joint_levers(with_radius=True)

  def _setup_pairs(self, samples, seed):
    """Non-adjacent capsule pairs to check, with their tolerances."""
    count = self.num_capsules
    last_link = self.dof - 1
    candidates = []
    for i in range(count):
      for j in range(i + 2, count):
        candidates.append((i, j))
    if self.reach.has_tool:  # The tool is adjacent to the last link only.
      candidates = [p for p in candidates if p != (last_link, count - 1)]
    pairs = np.array(candidates, dtype=int).reshape(-1, 2)
    limits = self.description.limits
    rs = np.random.RandomState(seed)
    q = np.vstack([self.description.q_home[None],
                   rs.uniform(limits.q_min, limits.q_max,
                              (samples, self.dof))])
    p1, p2, r = self.reach.capsules(q)
    i, j = pairs[:, 0], pairs[:, 1]
    dist = geometry.capsule_distance(p1[:, i], p2[:, i], r[i], p1[:, j],
                                     p2[:, j], r[j])               # (S, P)
    always = (dist < 0).mean(axis=0) >= _ALWAYS_FRACTION
    at_home = dist[0] < 0
    exempt = np.array([tuple(p) in self.description.self_collision_exempt
                       for p in pairs.tolist()], dtype=bool)
    excluded = always | at_home | exempt
    self.excluded_pairs = tuple((int(a), int(b)) for a, b in pairs[excluded])
    self.home_overlap_pairs = tuple(
        (int(a), int(b)) for a, b in pairs[at_home & ~always])
    self.pairs = pairs[~excluded]
    # Relative motion of a pair: capsule j moves in capsule i's frame only
    # through the joints after capsule i's frame.
    frames = self.reach.frame_index
    after = (np.arange(self.dof)[:, None] > frames[self.pairs[:, 0]][None])
    self._pair_levers = self.levers[:, self.pairs[:, 1]] * after   # (dof, P)
    # Contiguous arguments of the compiled check
    # (`collision_kernels.colliding`).
    self._kernel_pairs = np.ascontiguousarray(self.pairs, dtype=np.int64)
    self._kernel_pair_levers = np.ascontiguousarray(self._pair_levers)
    self._no_box_mask = np.zeros((0, 0, 0), dtype=bool)
    self._no_pair_mask = np.zeros((0, 0), dtype=bool)

  # -- Checks ---------------------------------------------------------------

  def _colliding(self, q, capsule_margin=None, pair_margin=None,
                 ignore_boxes=None, ignore_pairs=None):
    """Collision flags (N,) of configurations q (N, dof). Capsules are
    inflated by capsule_margin (N, L) against boxes, and pairs need a
    clearance of pair_margin (N, P) (both default 0). ignore_boxes (N, Bx,
    L) and ignore_pairs (N, P) leave elements out (escape, `paths_free`)."""
    if not self.compiled:
      return self._colliding_reference(q, capsule_margin, pair_margin,
                                       ignore_boxes, ignore_pairs)
    count = q.shape[0]
    pairs = (count, len(self.pairs))
    def margin(x, shape):
      if x is None:
        return np.zeros(shape)
      # Writeable C arrays: one kernel signature (broadcast views are
      # read-only).
      return np.require(np.broadcast_to(x, shape), float, ('C', 'W'))
    def mask(x, empty):
      # An empty mask stands for "none" (the kernel's convention).
      return empty if x is None else np.require(x, bool, ('C', 'W'))
    return collision_kernels.colliding(
        np.ascontiguousarray(q, dtype=float), *self.reach.kernel_model,
        self.reach.kernel_frames, self.reach.kernel_radii,
        margin(capsule_margin, (count, self.num_capsules)),
        margin(pair_margin, pairs), self.box_min, self.box_max,
        self._box_checked, self._box_allowance, self._kernel_pairs,
        mask(ignore_boxes, self._no_box_mask),
        mask(ignore_pairs, self._no_pair_mask))

  def _colliding_reference(self, q, capsule_margin=None, pair_margin=None,
                           ignore_boxes=None, ignore_pairs=None):
    """NumPy reference of `_colliding` (same arguments)."""
    p1, p2, r = self.reach.capsules(q)                             # (N, L, 3)
    radius = (np.broadcast_to(r, q.shape[:1] + r.shape) if capsule_margin is
              None else r + capsule_margin)
    # Boxes: a capsule's bounding box must overlap the box first.
    lo = np.minimum(p1, p2) - radius[..., None]
    hi = np.maximum(p1, p2) + radius[..., None]
    overlap = np.all((lo[:, None] <= self.box_max[None, :, None]) &
                     (hi[:, None] >= self.box_min[None, :, None]), axis=-1)
    overlap &= self._box_checked[None]                             # (N, Bx, L)
    if ignore_boxes is not None:
      overlap &= ~ignore_boxes
    hit = np.zeros(q.shape[0], dtype=bool)
    if overlap.any():
      n, b, l = np.nonzero(overlap)
      dist = geometry.capsule_box_distance(p1[n, l], p2[n, l], radius[n, l],
                                           self.box_min[b], self.box_max[b])
      colliding = dist < -self._box_allowance[b, l]
      hit[n[colliding]] = True
    if len(self.pairs):
      i, j = self.pairs[:, 0], self.pairs[:, 1]
      dist = geometry.capsule_distance(p1[:, i], p2[:, i], r[i],
                                       p1[:, j], p2[:, j], r[j])   # (N, P)
      pair_hit = dist < (0.0 if pair_margin is None else pair_margin)
      if ignore_pairs is not None:
        pair_hit &= ~ignore_pairs
      hit |= np.any(pair_hit, axis=-1)
    return hit

  def penetrations(self, q: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Penetration depths (m) of configurations: > 0 is a collision, <= 0
    clearance (unchecked capsule-box combinations: -inf).

    A capsule in a box: its radius minus its axis' distance to the box,
    plus how deep the deeper axis end lies inside the box (so a deeper
    capsule keeps counting deeper once its axis enters), minus the allowed
    penetration. A pair: minus its capsule distance.

    Args:
      q: configurations (N, dof) (or one, (dof,)).

    Returns:
      (boxes (N, Bx, L), pairs (N, P)).
    """
    q = np.asarray(q, dtype=float).reshape(-1, self.dof)
    p1, p2, r = self.reach.capsules(q)
    n = q.shape[0]
    a0 = np.broadcast_to(p1[:, None], (n, len(self.box_names)) + p1.shape[1:])
    a1 = np.broadcast_to(p2[:, None], a0.shape)
    lo = self.box_min[None, :, None]
    hi = self.box_max[None, :, None]
    axis = geometry.segment_box_distance(a0, a1, lo, hi)          # (N, Bx, L)
    inside = np.maximum(
        np.minimum(a0 - lo, hi - a0).min(axis=-1),
        np.minimum(a1 - lo, hi - a1).min(axis=-1))
    boxes = r - axis + np.maximum(inside, 0.0) - self._box_allowance[None]
    boxes = np.where(self._box_checked[None], boxes, -np.inf)
    pairs = np.zeros((n, 0))
    if len(self.pairs):
      i, j = self.pairs[:, 0], self.pairs[:, 1]
      pairs = -geometry.capsule_distance(p1[:, i], p2[:, i], r[i],
                                         p1[:, j], p2[:, j], r[j])
    return boxes, pairs

  def in_collision(self, q: np.ndarray) -> np.ndarray:
    """Exact collision flags of configurations.

    Args:
      q: configurations (..., dof).

    Returns:
      Flags (...,): True where a configuration collides.

    Raises:
      ValueError: q's last axis is not dof.
    """
    q = np.asarray(q, dtype=float)
    if q.ndim == 0 or q.shape[-1] != self.dof:
      raise ValueError(f'q: expected shape (..., {self.dof}), got {q.shape}')
    flat = q.reshape(-1, self.dof)
    return self._colliding(flat).reshape(q.shape[:-1])

  def _path_samples(self, q_start, q_goal):
    """Number of steps for the straight path (no point moves > max_step)."""
    travel = (np.abs(np.subtract(q_goal, q_start)) @ self.levers).max()
    return max(1, int(np.ceil(travel / self.max_step)))

  def _check_start(self, q_start):
    q_start = np.asarray(q_start, dtype=float)
    if q_start.shape != (self.dof,):
      raise ValueError(f'q_start: expected shape ({self.dof},), got '
                       f'{q_start.shape}')
    return q_start

  def _within(self, q_goals):
    limits = self.description.limits
    if self.compiled:
      return collision_kernels.within_limits(
          np.ascontiguousarray(q_goals), limits.q_min, limits.q_max)
    return np.all((q_goals >= limits.q_min) & (q_goals <= limits.q_max),
                  axis=-1)

  def paths_free(self, q_start: np.ndarray, q_goals: np.ndarray
                 ) -> np.ndarray:
    """Which goals are within the joint limits and have collision-free
    straight paths from q_start.

    Each sample stands for the path within half a step around it: against
    boxes each capsule is inflated by its largest motion over half a step,
    and each pair needs the clearance of its largest relative motion.
    Samples flagged that way are refined (REFINE sub-samples with REFINE
    times smaller margins, up to REFINE_LEVELS times) before a collision is
    declared, so near-touching capsules are not rejected by the margins
    alone; a sample colliding without margins ends its path at once.

    A start already in collision does not trap the robot (escape rule): a
    path is accepted if every capsule-box or capsule pair in collision at
    the start has a penetration that never increases from sample to sample
    (exact, 1e-9 m slack) until it is free, and is checked like the others
    (margins and refinement) from the sample after that on; all other
    elements are checked along the whole path. Between the start and that
    sample only the samples are checked for these elements.

    Args:
      q_start: the start's joint positions (dof,).
      q_goals: the goals (G, dof).

    Returns:
      Flags (G,).

    Raises:
      ValueError: q_start is not dof joint positions.
    """
    q_start = self._check_start(q_start)
    q_goals = np.asarray(q_goals, dtype=float).reshape(-1, self.dof)
    delta = q_goals - q_start
    motion = np.abs(delta) @ self.levers                           # (G, L)
    pair_motion = np.abs(delta) @ self._pair_levers                # (G, P)
    steps = np.maximum(1, np.ceil(motion.max(axis=-1) / self.max_step))
    steps = steps.astype(int)

    def evaluate(owner, fraction, half):
      q = q_start + fraction[:, None] * delta[owner]
      return (q, motion[owner] * half[:, None],
              pair_motion[owner] * half[:, None])

    counts = steps + 1
    owner = np.repeat(np.arange(len(q_goals)), counts)
    index = np.arange(owner.size) - np.repeat(np.cumsum(counts) - counts,
                                              counts)
    fraction = index / steps[owner]
    half = 0.5 / steps[owner]                   # Half a step, in path units.
    collided = self._sweep(q_start, len(q_goals), owner, fraction, half,
                           evaluate)
    self.num_checks += len(q_goals)
    return self._within(q_goals) & ~collided

  def _sweep(self, q_start, num_paths, owner, param, half, evaluate):
    """Collision flags (num_paths,) of paths given by base samples (owner,
    path parameter `param` increasing along each path, half-width `half`);
    evaluate(owner, param, half) -> (q, capsule margins, pair margins)
    covering the path within `half` of each sample. The start q_start is
    not a sample: paths starting in collision follow the escape rule."""
    escaping = bool(self._colliding(q_start[None])[0])
    collided = np.zeros(num_paths, dtype=bool)
    free_box = free_pair = None
    if escaping:
      boxes, pairs = self.penetrations(q_start[None])
      start_boxes, start_pairs = boxes[0] > 0.0, pairs[0] > 0.0
      collided, free_box, free_pair = self._escape(
          num_paths, owner, param, half, evaluate, boxes[0], pairs[0],
          start_boxes, start_pairs)
    offsets = _REFINE_OFFSETS
    for level in range(REFINE_LEVELS + 1):
      keep = ~collided[owner]
      owner, param, half = owner[keep], param[keep], half[keep]
      if not owner.size:
        break
      ignore_boxes = ignore_pairs = None
      if escaping:   # Elements in collision at the start, until free.
        ignore_boxes = (param[:, None, None] - half[:, None, None]
                        <= free_box[owner])
        ignore_pairs = (param[:, None] - half[:, None] <= free_pair[owner])
      q, capsule_margin, pair_margin = evaluate(owner, param, half)
      hit = self._colliding(q, capsule_margin, pair_margin, ignore_boxes,
                            ignore_pairs)
      if not hit.any():
        break
      if level == REFINE_LEVELS:
        collided[owner[hit]] = True
        break
      exact = self._colliding(
          q[hit], None, None,
          None if ignore_boxes is None else ignore_boxes[hit],
          None if ignore_pairs is None else ignore_pairs[hit])
      collided[owner[hit][exact]] = True
      owner, centre, half = owner[hit], param[hit], half[hit]
      param = (centre[:, None] + offsets * half[:, None]).ravel()
      owner = np.repeat(owner, REFINE)
      half = np.repeat(half / REFINE, REFINE)
    return collided

  def _escape(self, num_paths, owner, param, half, evaluate, start_box,
              start_pair, colliding_box, colliding_pair):
    """Escape rule of `paths_free`: (collided (G,), free_box (G, Bx, L),
    free_pair (G, P)), the free_* being the path parameter of the sample
    at which each element in collision at the start is free (-inf for the
    others; inf if never: then the path is collided)."""
    q = evaluate(owner, param, half)[0]
    boxes, pairs = self.penetrations(q)
    depth = np.concatenate([boxes[:, colliding_box], pairs[:, colliding_pair]],
                           axis=1)                                 # (S, E0)
    start = np.concatenate([start_box[colliding_box],
                            start_pair[colliding_pair]])
    collided = np.zeros(num_paths, dtype=bool)
    free_at = np.full((num_paths, depth.shape[1]), np.inf)
    bounds = np.flatnonzero(np.diff(owner)) + 1
    for g, rows in zip(np.unique(owner), np.split(np.arange(owner.size),
                                                  bounds)):
      path = np.vstack([start[None], depth[rows]])     # (1 + S_g, E0)
      free = path <= 0.0
      first = np.where(free.any(axis=0), free.argmax(axis=0), path.shape[0])
      rising = np.diff(path, axis=0) > _ESCAPE_SLACK  # Sample k -> k + 1.
      before = np.arange(1, path.shape[0])[:, None] <= first[None]
      if np.any(rising & before) or np.any(first == path.shape[0]):
        collided[g] = True
        continue
      free_at[g] = param[rows][first - 1]
    free_box = np.full((num_paths,) + start_box.shape, -np.inf)
    free_pair = np.full((num_paths,) + start_pair.shape, -np.inf)
    count = int(colliding_box.sum())
    free_box[:, colliding_box] = free_at[:, :count]
    free_pair[:, colliding_pair] = free_at[:, count:]
    return collided, free_box, free_pair

  def planned_paths_free(self, q_goals: np.ndarray, plan_from: PlanStart
                         ) -> np.ndarray:
    """Which goals have collision-free long-term plans from the shield's
    current command (what the robot really does: a moving robot overshoots
    before it turns to the goal).

    The plan is `long_term_plan.plan_to_goal` from plan_from's command with
    its limits, exactly the shield's next candidate. Each plan cycle is
    covered by samples of the shield's own Taylor polynomial (at most
    max_step of capsule motion apart, margins from the polynomial's
    derivatives over half a sample spacing), refined like `paths_free`; the
    escape rule applies. A plan that cannot be made (it would leave the
    joint limits) is not free. If the command cannot start a plan now
    (braking harder than the planning limits; the shield then keeps braking
    on its verified path and plans later), the straight path from the
    command is checked instead.

    Args:
      q_goals: the goals (G, dof).
      plan_from: the `Shield` that will execute the goal.

    Returns:
      Flags (G,).
    """
    return self._planned(q_goals, plan_from)[0]

  def _planned(self, q_goals, plan_from):
    """(`planned_paths_free`'s flags, the plans made: a `LongTermPlan` or
    None per goal)."""
    q_goals = np.asarray(q_goals, dtype=float).reshape(-1, self.dof)
    q0, dq0, ddq0 = (np.asarray(x, dtype=float) for x in (
        plan_from.q, plan_from.dq, plan_from.ddq))
    q0 = self._check_start(q0)
    limits, cycle = plan_from.limits, float(plan_from.cycle_time)
    start_time = float(plan_from.s)
    try:
      ltp.check_start_state(q0, dq0, ddq0, limits)
    except ltp.PlanningError:
      return self.paths_free(q0, q_goals), [None] * len(q_goals)
    plans, feasible = [], np.zeros(len(q_goals), dtype=bool)
    for g, goal in enumerate(q_goals):
      try:
        plans.append(ltp.plan_to_goal(q0, dq0, ddq0, goal, limits, cycle,
                                      start_time))
        feasible[g] = True
      except ltp.PlanningError:
        plans.append(None)
    collided = np.zeros(len(q_goals), dtype=bool)
    start_free = self.compiled
    if self.compiled:
      start = np.ascontiguousarray(q0[None])
      for g, plan in enumerate(plans):
        verdict = 0 if plan is None else self._plan_collides(plan, start)
        start_free = verdict >= 0
        if not start_free:
          break
        collided[g] = verdict > 0
    if not start_free:   # The reference, and the escape rule.
      collided = self._planned_sweep(q0, plans, cycle)
    self.num_checks += len(q_goals)
    return self._within(q_goals) & feasible & ~collided, plans

  def _plan_collides(self, plan, start):
    """1 if a plan from start (1, dof) collides, 0 if not, -1 if the start
    collides (then `_planned_sweep` decides): the compiled sweep of
    `_planned_sweep` (collision_kernels.planned_path_collides)."""
    return collision_kernels.planned_path_collides(
        start, _polynomial_fields(plan), *self._sweep_groups)

  def _planned_sweep(self, q0, plans, cycle):
    """Collision flags of plans (None: not made, not flagged) from q0, by
    `_sweep` (the reference, and the escape rule)."""
    owners, params, halves = [], [], []
    for g, plan in enumerate(plans):
      if plan is None:
        continue
      # Cycles needing more than one sample: the polynomial's motion over
      # a whole cycle, per capsule, against max_step.
      c = np.abs(plan.nominal(plan.start_time + cycle * np.arange(
          plan.num_samples))[1:])          # v, a, j at the samples.
      travel = c[0] * cycle + c[1] * cycle ** 2 / 2 + c[2] * cycle ** 3 / 6
      pieces = np.maximum(1, np.ceil(
          _lever_sum(travel, self.levers).max(axis=-1) / self.max_step))
      pieces = pieces.astype(int)
      cycle_index = np.repeat(np.arange(plan.num_samples), pieces)
      within = (np.arange(cycle_index.size)
                - np.repeat(np.cumsum(pieces) - pieces, pieces))
      width = cycle / pieces[cycle_index]
      params.append(plan.start_time + cycle_index * cycle
                    + (within + 0.5) * width)
      halves.append(0.5 * width)
      owners.append(np.full(cycle_index.size, g))
    if not owners:
      return np.zeros(len(plans), dtype=bool)

    def evaluate(owner, param, half):
      q = np.empty((owner.size, self.dof))
      reach = np.empty((owner.size, self.dof))
      for g in np.unique(owner):
        rows = owner == g
        q[rows], v, a, j = plans[g].nominal(param[rows])
        h = half[rows][:, None]
        reach[rows] = h * (np.abs(v) + h * (np.abs(a) / 2
                                            + h * np.abs(j) / 6))
      return (q, _lever_sum(reach, self.levers),
              _lever_sum(reach, self._pair_levers))
    return self._sweep(q0, len(plans), np.concatenate(owners),
                       np.concatenate(params), np.concatenate(halves),
                       evaluate)

  def is_safe(self, q_start: np.ndarray, q_goal: np.ndarray) -> bool:
    """Whether q_goal is within the joint limits and the straight path to
    it is collision-free (`paths_free`).

    Args:
      q_start: the start's joint positions (dof,).
      q_goal: the goal's (dof,).

    Returns:
      True iff both.
    """
    return bool(self.paths_free(q_start, np.asarray(q_goal)[None])[0])

  # -- Replacement ----------------------------------------------------------

  def filter_action(
      self, action: np.ndarray, q_current: np.ndarray,
      action_to_goal: Callable[[np.ndarray], Optional[np.ndarray]],
      policy: str = 'zero', num_samples: int = DEFAULT_NUM_SAMPLES,
      action_low: Union[float, np.ndarray] = -1.0,
      action_high: Union[float, np.ndarray] = 1.0,
      random_state: Union[None, int, np.random.RandomState] = None,
      zero_action: Optional[np.ndarray] = None,
      plan_from: Optional[PlanStart] = None) -> FilteredAction:
    """The action if its goal is safe, else a replacement chosen by
    `policy`: 'zero': the zero action and q_current (stay); 'resample': the
    first safe of up to num_samples uniform actions in [action_low,
    action_high]; 'closest': the safe sample closest to the proposed
    action. Without a safe sample the zero action is used.

    Args:
      action: the proposed action.
      q_current: the robot's joint positions (dof,).
      action_to_goal: action -> its goal q_goal (dof,), or None (e.g. IK
        failed: unsafe).
      policy: one of POLICIES.
      num_samples: the replacement samples drawn, >= 1.
      action_low: the samples' lower bound.
      action_high: their upper bound.
      random_state: np.random.RandomState or seed (required for 'resample'
        and 'closest').
      zero_action: the zero action (None: zeros like action).
      plan_from: the `Shield` that will execute the goal; if given, goals
        are checked along its long-term plan from its command
        (`planned_paths_free`), else along the straight path from
        q_current.

    Returns:
      FilteredAction(action, q_goal, replaced, plan): `plan` is the
      returned goal's long-term plan made for the check (`Shield.new_goal`
      takes it as its first candidate), None where none was made (no
      plan_from, the zero action, a start braking too hard).

    Raises:
      ValueError: an unknown policy, num_samples < 1, or no random_state
        for 'resample' or 'closest'.
    """
    if policy not in POLICIES:
      raise ValueError(f'policy: expected one of {POLICIES}, got {policy!r}')
    action = np.asarray(action, dtype=float)
    q_current = np.asarray(q_current, dtype=float)
    if plan_from is None:
      check = lambda goals: (self.paths_free(q_current, goals),
                             [None] * len(goals))
    else:
      check = lambda goals: self._planned(goals, plan_from)
    goal = action_to_goal(action)
    if goal is not None:
      goal = np.asarray(goal, dtype=float)
      free, plans = check(goal[None])
      if free[0]:
        return FilteredAction(action, goal, False, plans[0])
    self.num_replacements += 1
    zero = (np.zeros_like(action) if zero_action is None
            else np.asarray(zero_action, dtype=float))
    if policy == 'zero':
      return FilteredAction(zero, q_current.copy(), True, None)
    if random_state is None:
      raise ValueError(f'policy {policy!r} needs a random_state')
    if not isinstance(random_state, np.random.RandomState):
      random_state = np.random.RandomState(random_state)
    if int(num_samples) < 1:
      raise ValueError(f'num_samples: expected >= 1, got {num_samples}')
    samples = random_state.uniform(action_low, action_high,
                                   (int(num_samples),) + action.shape)
    goals = [action_to_goal(s) for s in samples]
    valid = [i for i, g in enumerate(goals) if g is not None]
    safe = np.zeros(len(samples), dtype=bool)
    plans = [None] * len(samples)
    if valid:
      free, made = check(np.array([goals[i] for i in valid], dtype=float))
      safe[valid] = free
      for i, plan in zip(valid, made):
        plans[i] = plan
    if not safe.any():
      return FilteredAction(zero, q_current.copy(), True, None)
    if policy == 'resample':
      pick = int(np.argmax(safe))
    else:
      gaps = np.linalg.norm((samples - action).reshape(len(samples), -1),
                            axis=-1)
      pick = int(np.argmin(np.where(safe, gaps, np.inf)))
    return FilteredAction(samples[pick], np.asarray(goals[pick], dtype=float),
                          True, plans[pick])
