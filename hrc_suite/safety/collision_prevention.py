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

Path sampling: a surface point of a capsule moves at most sum_k lever_k
|dq_k| for a joint step dq, lever_k bounding the distance of any later
capsule point from joint k's origin. The path is cut into steps moving no
point more than `max_step` (1 cm); every configuration between two samples
is within half a step of a sample, so capsules are inflated by the motion
of half a step at the samples: a collision anywhere on the path is detected
(flagged samples are refined, see `paths_free`).
"""

import numpy as np

from hrc_suite import layout
from hrc_suite.safety import geometry
from hrc_suite.safety import robot_reach

POLICIES = ('zero', 'resample', 'closest')

# Default number of replacement samples (reference benchmark: 20).
DEFAULT_NUM_SAMPLES = 20
# Largest motion of any capsule point between path samples (m).
DEFAULT_MAX_STEP = 0.01
# Refinement of samples flagged with inflated capsules: sub-samples per
# sample and levels (inflation 5 mm -> 1.25 -> 0.31 -> 0.08 mm).
REFINE = 4
REFINE_LEVELS = 3
# A pair overlapping in this fraction of random configurations (and at
# q_home) overlaps by construction.
_ALWAYS_FRACTION = 1.0


def workcell_boxes(floor=True):
  """Named static boxes (min, max) of the workcell, world frame (layout)."""
  table_min = (layout.TABLE_X[0], layout.TABLE_Y[0],
               layout.TABLE_TOP_Z - layout.TABLE_THICKNESS)
  table_max = (layout.TABLE_X[1], layout.TABLE_Y[1], layout.TABLE_TOP_Z)
  cx, cy = layout.PEDESTAL_CENTER_XY
  hx, hy = layout.PEDESTAL_HALF_SIZE
  base_z = layout.ROBOT_BASE_POS[2]
  boxes = {'table': (table_min, table_max),
           'pedestal': ((cx - hx, cy - hy, 0.0), (cx + hx, cy + hy, base_z))}
  if floor:  # The floor as a thick slab below z = 0.
    boxes['floor'] = ((-10.0, -10.0, -1.0), (10.0, 10.0, 0.0))
  return boxes


class CollisionPrevention:
  """Checks goals and straight joint paths; replaces unsafe actions."""

  def __init__(self, description, base_pose=None, tool_capsule=None,
               extra_boxes=(), floor=True, tool_table_allowance=0.0,
               max_step=DEFAULT_MAX_STEP, exclusion_samples=2000, seed=0):
    self.description = description
    self.reach = robot_reach.RobotReach(description, base_pose=base_pose,
                                        tool_capsule=tool_capsule,
                                        secure_radius=0.0)
    self.dof = description.dof
    self.num_capsules = self.reach.num_capsules
    if not max_step > 0:
      raise ValueError(f'max_step: expected > 0, got {max_step}')
    self.max_step = float(max_step)
    self._setup_boxes(extra_boxes, floor, float(tool_table_allowance))
    self._setup_levers()
    self._setup_pairs(int(exclusion_samples), seed)
    self.num_checks = 0
    self.num_replacements = 0

  # -- Construction ---------------------------------------------------------

  def _setup_boxes(self, extra_boxes, floor, tool_table_allowance):
    boxes = workcell_boxes(floor)
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
    points = self.reach._points[:, :, :3]                          # (L, 2, 3)
    extent = np.linalg.norm(points, axis=-1).max(axis=-1) + self.reach.radii
    hop = np.linalg.norm(self.description.fixed_transforms()[:, :3, 3],
                         axis=-1)
    levers = np.zeros((self.dof, self.num_capsules))
    for c, frame in enumerate(self.reach.frame_index):
      for k in range(frame + 1):
        levers[k, c] = hop[k + 1:frame + 1].sum() + extent[c]
    self.levers = levers

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
    excluded = always | at_home
    self.excluded_pairs = tuple((int(a), int(b)) for a, b in pairs[excluded])
    self.home_overlap_pairs = tuple(
        (int(a), int(b)) for a, b in pairs[at_home & ~always])
    self.pairs = pairs[~excluded]
    # Relative motion of a pair: capsule j moves in capsule i's frame only
    # through the joints after capsule i's frame.
    frames = self.reach.frame_index
    after = (np.arange(self.dof)[:, None] > frames[self.pairs[:, 0]][None])
    self._pair_levers = self.levers[:, self.pairs[:, 1]] * after   # (dof, P)

  # -- Checks ---------------------------------------------------------------

  def _colliding(self, q, capsule_margin=None, pair_margin=None):
    """Collision flags (N,) of configurations q (N, dof). Capsules are
    inflated by capsule_margin (N, L) against boxes, and pairs need a
    clearance of pair_margin (N, P) (both default 0)."""
    p1, p2, r = self.reach.capsules(q)                             # (N, L, 3)
    radius = (np.broadcast_to(r, q.shape[:1] + r.shape) if capsule_margin is
              None else r + capsule_margin)
    # Boxes: a capsule's bounding box must overlap the box first.
    lo = np.minimum(p1, p2) - radius[..., None]
    hi = np.maximum(p1, p2) + radius[..., None]
    overlap = np.all((lo[:, None] <= self.box_max[None, :, None]) &
                     (hi[:, None] >= self.box_min[None, :, None]), axis=-1)
    overlap &= self._box_checked[None]                             # (N, Bx, L)
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
      hit |= np.any(dist < (0.0 if pair_margin is None else pair_margin),
                    axis=-1)
    return hit

  def in_collision(self, q):
    """Exact collision flags of configurations q (..., dof)."""
    q = np.asarray(q, dtype=float)
    if q.ndim == 0 or q.shape[-1] != self.dof:
      raise ValueError(f'q: expected shape (..., {self.dof}), got {q.shape}')
    flat = q.reshape(-1, self.dof)
    return self._colliding(flat).reshape(q.shape[:-1])

  def path_samples(self, q_start, q_goal):
    """Number of steps for the straight path (no point moves > max_step)."""
    travel = (np.abs(np.subtract(q_goal, q_start)) @ self.levers).max()
    return max(1, int(np.ceil(travel / self.max_step)))

  def paths_free(self, q_start, q_goals):
    """Flags (G,): goals (G, dof) within the joint limits whose straight
    paths from q_start are collision-free.

    Each sample stands for the path within half a step around it: against
    boxes each capsule is inflated by its largest motion over half a step,
    and each pair needs the clearance of its largest relative motion.
    Samples flagged that way are refined (REFINE sub-samples with REFINE
    times smaller margins, up to REFINE_LEVELS times) before a collision is
    declared, so near-touching capsules are not rejected by the margins
    alone; a sample colliding without margins ends its path at once. The
    start counts only if it is itself collision-free (a robot already
    touching something can move away).
    """
    q_start = np.asarray(q_start, dtype=float)
    q_goals = np.asarray(q_goals, dtype=float).reshape(-1, self.dof)
    if q_start.shape != (self.dof,):
      raise ValueError(f'q_start: expected shape ({self.dof},), got '
                       f'{q_start.shape}')
    limits = self.description.limits
    within = np.all((q_goals >= limits.q_min) & (q_goals <= limits.q_max),
                    axis=-1)
    delta = q_goals - q_start
    motion = np.abs(delta) @ self.levers                           # (G, L)
    pair_motion = np.abs(delta) @ self._pair_levers                # (G, P)
    steps = np.maximum(1, np.ceil(motion.max(axis=-1) / self.max_step))
    steps = steps.astype(int)
    first = 0 if not self._colliding(q_start[None])[0] else 1
    counts = steps + 1 - first
    owner = np.repeat(np.arange(len(q_goals)), counts)
    index = (np.arange(owner.size) - np.repeat(np.cumsum(counts) - counts,
                                               counts) + first)
    fraction = index / steps[owner]
    half = 0.5 / steps[owner]                   # Half a step, in path units.
    offsets = (2.0 * np.arange(REFINE) + 1.0) / REFINE - 1.0   # In (-1, 1).
    collided = np.zeros(len(q_goals), dtype=bool)
    for level in range(REFINE_LEVELS + 1):
      keep = ~collided[owner]
      owner, fraction, half = owner[keep], fraction[keep], half[keep]
      if not owner.size:
        break
      q = q_start + fraction[:, None] * delta[owner]
      hit = self._colliding(q, motion[owner] * half[:, None],
                            pair_motion[owner] * half[:, None])
      if not hit.any():
        break
      if level == REFINE_LEVELS:
        collided[owner[hit]] = True
        break
      exact = self._colliding(q[hit])
      collided[owner[hit][exact]] = True
      owner, centre, half = owner[hit], fraction[hit], half[hit]
      fraction = np.clip(centre[:, None] + offsets * half[:, None], 0.0,
                         1.0).ravel()
      owner = np.repeat(owner, REFINE)
      half = np.repeat(half / REFINE, REFINE)
    self.num_checks += len(q_goals)
    return within & ~collided

  def is_safe(self, q_start, q_goal):
    """True iff q_goal is within the joint limits and the straight path to
    it is collision-free."""
    return bool(self.paths_free(q_start, np.asarray(q_goal)[None])[0])

  # -- Replacement ----------------------------------------------------------

  def filter_action(self, action, q_current, action_to_goal, policy='zero',
                    num_samples=DEFAULT_NUM_SAMPLES, action_low=-1.0,
                    action_high=1.0, random_state=None, zero_action=None):
    """(action, q_goal, replaced): the action if its goal is safe, else a
    replacement chosen by `policy`.

    action_to_goal(action) -> q_goal (dof,) or None (e.g. IK failed: unsafe).
    'zero': the zero action and q_current (stay); 'resample': the first safe
    of up to num_samples uniform actions in [action_low, action_high];
    'closest': the safe sample closest to the proposed action. Without a
    safe sample the zero action is used. random_state: np.random.RandomState
    or seed (required for 'resample' and 'closest').
    """
    if policy not in POLICIES:
      raise ValueError(f'policy: expected one of {POLICIES}, got {policy!r}')
    action = np.asarray(action, dtype=float)
    q_current = np.asarray(q_current, dtype=float)
    goal = action_to_goal(action)
    if goal is not None and self.is_safe(q_current, goal):
      return action, np.asarray(goal, dtype=float), False
    self.num_replacements += 1
    zero = (np.zeros_like(action) if zero_action is None
            else np.asarray(zero_action, dtype=float))
    if policy == 'zero':
      return zero, q_current.copy(), True
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
    if valid:
      safe[valid] = self.paths_free(q_current, np.array([goals[i]
                                                         for i in valid]))
    if not safe.any():
      return zero, q_current.copy(), True
    if policy == 'resample':
      pick = int(np.argmax(safe))
    else:
      gaps = np.linalg.norm((samples - action).reshape(len(samples), -1),
                            axis=-1)
      pick = int(np.argmin(np.where(safe, gaps, np.inf)))
    return samples[pick], np.asarray(goals[pick], dtype=float), True
