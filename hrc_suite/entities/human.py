"""The human co-worker: kinematic capsules driven by keypoint positions.

Each body segment (keypoints.SEGMENTS plus the pelvis between the hips) is a
capsule on its own mocap body, and each keypoint has a site on a tiny mocap
body of its own. MuJoCo only accepts mocap bodies that are children of the
world, while composer's `attach` nests an entity's bodies in an attachment
body; so the capsules and sites are built as small MJCF parts that
`attach_to(arena)` attaches directly to the arena, turning each attachment
frame into the mocap body. Use `human.attach_to(arena)` instead of
`arena.attach(human)`.

The capsules collide with the robot and objects only (collision_groups), so
contacts with the robot are detected and the human never collides with itself
or the table. `set_keypoints` moves everything in one vectorised write;
`resize` sets capsule lengths to a clip's segment lengths (size, rbound and
aabb); `hold` / `release` weld an object to a hand (at its current relative
pose or a given one, changeable while held with `set_grip`).

While a hand holds an object, contacts between that hand's capsule and the
object are off (the capsule encloses a gripped handle and would push the
object out of the hand against the weld): `hold` moves the object's geoms
from the OBJECT collision bit to HELD_OBJECT_BIT and takes that bit out of
the holding hand's conaffinity; every human capsule has it otherwise, so the
held object still collides with the rest of the body, the robot, the table
and other objects. `release` restores the bits. (One bit for all held
objects: a hand that holds one object does not collide with another held
object either.)
"""

from typing import Dict, Optional, Sequence, Tuple, Union

import numpy as np
from dm_control import composer
from dm_control import mjcf
from dm_control.composer.observation import observable

from hrc_suite import rotations
from hrc_suite.entities import collision_groups
from hrc_suite.entities import element_ids
from hrc_suite.entities import human_playback
from hrc_suite.entities import human_segments
from hrc_suite.human import body as body_lib
from hrc_suite.human import clip as clip_lib
from hrc_suite.human import keypoints
from hrc_suite.human import player as player_lib

# Capsule radii (m) at the reference stature, scaled with stature: about half
# the limb's breadth/depth (head ~0.19 m breadth, chest depth ~0.24 m, upper
# arm ~0.10 m, thigh ~0.15 m diameters for an adult of about 1.75 m).
REFERENCE_STATURE = 1.75
CAPSULE_RADII = {
    'head': 0.095, 'torso': 0.13, 'pelvis': 0.11,
    'upper_arm': 0.05, 'forearm': 0.04, 'hand': 0.045,
    'thigh': 0.075, 'shin': 0.055,
}
# The capsules' segments and frames (entities/human_segments.py).
SEGMENTS = human_segments.SEGMENTS
segment_frames = human_segments.segment_frames
HANDS = ('left', 'right')
_SKIN = (0.85, 0.65, 0.5, 1.0)
# Collision bit of a held object (unused by collision_groups' scheme): every
# capsule but the holding hand has it in its conaffinity.
HELD_OBJECT_BIT = 16
assert not HELD_OBJECT_BIT & (collision_groups.STATIC | collision_groups.ROBOT
                              | collision_groups.OBJECT
                              | collision_groups.HUMAN)
_SITE_RGBA = (0.1, 0.3, 0.9, 1.0)


def _part(name):
  return name.split('_', 1)[-1] if name.startswith(('left_', 'right_')) \
      else name


def row_norms(vectors: np.ndarray) -> np.ndarray:
  """np.linalg.norm of each row, each exactly as on one row.

  np.linalg.norm takes a row's dot product through BLAS; a stacked
  np.matmul does the same row by row, where a sum of squares would round
  differently.

  Args:
    vectors: (n, k) rows.

  Returns:
    (n,) their norms.
  """
  return np.sqrt(np.matmul(vectors[:, None, :], vectors[:, :, None])[:, 0, 0])


class Human(composer.Entity):
  """Kinematic human: capsules and keypoint sites on mocap bodies."""

  def _build(self, name: str = 'human',
             anthropometrics: Optional[body_lib.Anthropometrics] = None):
    """Builds the capsules and keypoint sites (attach with `attach_to`).

    Args:
      name: the MJCF model's name, the stem of its parts' names.
      anthropometrics: the body's measures, which size the capsules
        (default: proportional to REFERENCE_STATURE); `resize` sets
        a clip's.
    """
    self._mjcf_root = mjcf.RootElement(model=name)
    self._name = name
    self._anthropometrics = (anthropometrics or
                             body_lib.proportional_body(REFERENCE_STATURE))
    lengths = self._anthropometrics.segment_lengths()
    lengths['pelvis'] = self._anthropometrics.hip_width
    scale = self._anthropometrics.stature / REFERENCE_STATURE
    self._segment_parts = []
    self._segment_geoms = []
    for seg_name, _, _ in SEGMENTS:
      part = mjcf.RootElement(model=f'{name}_{seg_name}')
      radius = CAPSULE_RADII[_part(seg_name)] * scale
      geom = part.worldbody.add(
          'geom', name='capsule', type='capsule',
          size=(radius, lengths[seg_name] / 2), rgba=_SKIN, mass=1.0)
      collision_groups.set_human(geom)
      geom.conaffinity = collision_groups.HUMAN_CONAFFINITY | HELD_OBJECT_BIT
      self._segment_parts.append(part)
      self._segment_geoms.append(geom)
    self._keypoint_parts = []
    self._sites = []
    for kp in keypoints.KEYPOINT_NAMES:
      part = mjcf.RootElement(model=f'{name}_kp_{kp}')
      self._sites.append(part.worldbody.add(
          'site', name='site', size=(0.012,), rgba=_SITE_RGBA, group=4))
      self._keypoint_parts.append(part)
    seg_index = {s[0]: i for i, s in enumerate(SEGMENTS)}
    self._hand_segment = {h: seg_index[f'{h}_hand'] for h in HANDS}
    self._proximal = np.array(keypoints.index([s[1] for s in SEGMENTS]))
    self._distal = np.array(keypoints.index([s[2] for s in SEGMENTS]))
    self._radii = np.array([CAPSULE_RADII[_part(s[0])] for s in SEGMENTS])
    self._segment_frames = None
    self._keypoint_frames = None
    self._holdables = {}      # object body -> {hand: weld element}
    self._held = {}           # object body -> hand
    self._held_bits = {}      # object body -> (geom ids, contype, conaff.)
    self._cache = None
    self._player = None
    self._playback = None   # follow's HumanPlayback

  def _build_observables(self):
    return HumanObservables(self)

  @property
  def mjcf_model(self) -> mjcf.RootElement:
    """The human's MJCF model (its parts attach to the arena)."""
    return self._mjcf_root

  # ------------------------------------------------------------- assembly

  def attach_to(self, arena: composer.Entity) -> 'Human':
    """Attaches the human to `arena`, its parts as mocap bodies.

    Args:
      arena: the arena (e.g. the workcell).

    Returns:
      The human.

    Raises:
      RuntimeError: if it is already attached.
    """
    if self._segment_frames is not None:
      raise RuntimeError(f'Human {self._name!r} is already attached')
    arena.attach(self)
    frames = []
    for part in self._segment_parts + self._keypoint_parts:
      frame = arena.mjcf_model.attach(part)
      frame.mocap = 'true'
      frames.append(frame)
    n = len(self._segment_parts)
    self._segment_frames = tuple(frames[:n])
    self._keypoint_frames = tuple(frames[n:])
    self._root = arena.mjcf_model
    return self

  def add_holdable(self, object_body: mjcf.Element
                   ) -> Dict[str, mjcf.Element]:
    """Prepares weld constraints from each hand to `object_body` (off).

    Args:
      object_body: the body of a free prop, before compiling.

    Returns:
      The welds, {hand: weld element}.

    Raises:
      RuntimeError: if the human is not attached.
    """
    self._require_attached()
    welds = {}
    for hand in HANDS:
      welds[hand] = self._root.equality.add(
          'weld', name=f'{self._name}_{hand}_hand_holds_'
          f'{object_body.full_identifier.replace("/", "_")}',
          body1=self._segment_frames[self._hand_segment[hand]],
          body2=object_body, active='false', solref=(0.01, 1.0))
    self._holdables[object_body] = welds
    return welds

  def _require_attached(self):
    if self._segment_frames is None:
      raise RuntimeError(f'Human {self._name!r} is not attached: call '
                         'human.attach_to(arena) first')

  @property
  def anthropometrics(self) -> body_lib.Anthropometrics:
    """The body's measures at construction."""
    return self._anthropometrics

  @property
  def geoms(self) -> Tuple[mjcf.Element, ...]:
    """The capsules, in SEGMENTS' order."""
    return tuple(self._segment_geoms)

  @property
  def keypoint_sites(self) -> Tuple[mjcf.Element, ...]:
    """The keypoint sites, in keypoints.KEYPOINT_NAMES' order."""
    return tuple(self._sites)

  @property
  def segment_bodies(self) -> Tuple[mjcf.Element, ...]:
    """The capsules' mocap bodies (attachment frames), in SEGMENTS' order.

    Raises:
      RuntimeError: if the human is not attached.
    """
    self._require_attached()
    return self._segment_frames

  # ------------------------------------------------------------ per step

  def _bound(self, physics):
    """Index arrays for this physics, computed once per physics."""
    if self._cache is not None and self._cache[0] is physics:
      return self._cache[1]
    self._require_attached()
    model = physics.model
    # Mocap bodies bind in dm_control's 'mocap_body' namespace, which has no
    # element_id; look their body ids up by name instead.
    body_id = lambda f: model.name2id(f.full_identifier, 'body')
    seg_bodies = np.array([body_id(f) for f in self._segment_frames])
    kp_bodies = np.array([body_id(f) for f in self._keypoint_frames])
    cache = {
        'segment_mocap': model.body_mocapid[seg_bodies].copy(),
        'keypoint_mocap': model.body_mocapid[kp_bodies].copy(),
        'geoms': physics.bind(self._segment_geoms).element_id.copy(),
        'sites': physics.bind(self._sites).element_id.copy(),
        # Per segment: the line its frame's x axis follows (arms, head and
        # torso the shoulder line, legs the hip line; the pelvis capsule,
        # which lies along the hips, world z).
        'reference': np.tile([0.0, 0.0, 1.0], (len(SEGMENTS), 1)),
        'hand_bodies': {h: int(seg_bodies[self._hand_segment[h]])
                        for h in HANDS},
    }
    self._cache = (physics, cache)
    return cache

  def set_keypoints(self, physics: mjcf.Physics, positions: np.ndarray
                    ) -> None:
    """Moves capsules and sites to keypoint positions.

    Args:
      physics: the physics.
      positions: (NUM_KEYPOINTS, 3) world positions.

    Raises:
      ValueError: positions of another shape.
    """
    positions = np.asarray(positions, dtype=np.float64)
    if positions.shape != (keypoints.NUM_KEYPOINTS, 3):
      raise ValueError(f'Expected keypoint positions of shape '
                       f'({keypoints.NUM_KEYPOINTS}, 3), got {positions.shape}')
    cache = self._bound(physics)
    k = keypoints.KEYPOINT_INDEX
    reference = cache['reference']
    reference[:8] = (positions[k['left_shoulder']]
                     - positions[k['right_shoulder']])
    reference[8:12] = positions[k['left_hip']] - positions[k['right_hip']]
    mid, _, quat = human_segments.segment_frames(positions, self._proximal, self._distal,
                                  reference)
    data = physics.data
    data.mocap_pos[cache['segment_mocap']] = mid
    data.mocap_quat[cache['segment_mocap']] = quat
    data.mocap_pos[cache['keypoint_mocap']] = positions

  def resize(self, physics: mjcf.Physics,
             clip_or_positions: Union[clip_lib.Clip, np.ndarray]
             ) -> Dict[str, float]:
    """Sets capsule lengths to the segment lengths of a clip (or positions).

    Each length is the median over the frames; the radii scale with the
    clip's stature (its metadata's, else estimated from the first frame).

    Args:
      physics: the physics (its model is changed).
      clip_or_positions: a clip, or keypoint positions (T, NUM_KEYPOINTS,
        3) or (NUM_KEYPOINTS, 3).

    Returns:
      {segment name: capsule length between its keypoints, m}.
    """
    positions = getattr(clip_or_positions, 'positions', clip_or_positions)
    positions = np.asarray(positions, dtype=np.float64)
    if positions.ndim == 2:
      positions = positions[None]
    lengths = np.linalg.norm(positions[:, self._distal]
                             - positions[:, self._proximal], axis=-1)
    half = 0.5 * np.median(lengths, axis=0)
    metadata = getattr(clip_or_positions, 'metadata', {}) or {}
    stature = metadata.get('anthropometrics', {}).get('stature')
    if not isinstance(stature, (int, float)) or not 1.0 < stature < 2.5:
      stature = _stature_from(positions[0])
    radius = self._radii * stature / REFERENCE_STATURE
    cache = self._bound(physics)
    geoms = cache['geoms']
    model = physics.model
    model.geom_size[geoms, 0] = radius
    model.geom_size[geoms, 1] = half
    model.geom_rbound[geoms] = half + radius
    model.geom_aabb[geoms, 3:5] = radius[:, None]
    model.geom_aabb[geoms, 5] = half + radius
    model.geom_aabb[geoms, :3] = 0.0
    return dict(zip([s[0] for s in SEGMENTS], 2 * half))

  def keypoint_positions(self, physics: mjcf.Physics) -> np.ndarray:
    """World positions of the keypoint sites.

    Args:
      physics: the physics.

    Returns:
      (NUM_KEYPOINTS, 3) a copy.
    """
    return physics.data.site_xpos[self._bound(physics)['sites']].copy()

  # ---------------------------------------------------------------- driving

  def follow(self, player: Optional[player_lib.Player]) -> None:
    """Lets `player` drive the human in an episode.

    At episode start the player is reset with the episode's random_state;
    before every physics step it advances by the physics timestep and the
    capsules move to its keypoints (resized whenever the clip changes), by
    the tasks' own playback (entities/human_playback.py, one substep at a
    time). The task triggers the player's events itself.

    Args:
      player: the clip player, or None to stop following.
    """
    self._player = player
    self._playback = (None if player is None else
                      human_playback.HumanPlayback(self, player, substeps=1))

  @property
  def player(self) -> Optional[player_lib.Player]:
    """The player the human follows, or None."""
    return self._player

  def initialize_episode(self, physics: mjcf.Physics,
                         random_state: np.random.RandomState) -> None:
    """Resets the followed player and shows its pose (composer's hook).

    Args:
      physics: the physics.
      random_state: the episode's random numbers (the player's reset).
    """
    if self._player is not None:
      self._player.reset(random_state)
      self._playback.bind(physics)
      self._playback.forget_clip()
      self._playback.show_current(physics)

  @property
  def substep_hooks_idle(self) -> bool:
    """Whether before_substep does nothing (no player to follow):
    tasks/runtime/substeps.py may then skip it."""
    return self._player is None

  def before_substep(self, physics: mjcf.Physics,
                     random_state: np.random.RandomState) -> None:
    """Advances the followed player by a physics step (composer's hook).

    Args:
      physics: the physics.
      random_state: unused.
    """
    if self._player is not None:
      self._playback.advance(physics.timestep())
      self._playback.apply(physics, 0)

  # ---------------------------------------------------------------- holding

  def hold(self, physics: mjcf.Physics, object_body: mjcf.Element,
           hand: str,
           relative_pose: Optional[Sequence[np.ndarray]] = None) -> None:
    """Welds `object_body` to `hand`.

    Contacts between that hand and the object are off until `release`
    (module doc).

    Args:
      physics: the physics (its model is changed).
      object_body: a body made holdable with `add_holdable`.
      hand: 'left' or 'right'.
      relative_pose: None (keep the current pose relative to the hand) or
        (position (3,), quaternion (4,) w first) of the object in the hand
        capsule's frame.

    Raises:
      ValueError: an unknown hand, a body that is not holdable, or a bad
        relative pose.
    """
    if hand not in HANDS:
      raise ValueError(f'Unknown hand {hand!r}: expected "left" or "right"')
    if object_body not in self._holdables:
      raise ValueError(f'{object_body.full_identifier!r} is not holdable: '
                       'call human.add_holdable(body) before compiling')
    self.release(physics, object_body)
    if relative_pose is None:
      relative_pose = self.relative_pose(physics, object_body, hand)
    self._held[object_body] = hand
    self.set_grip(physics, object_body, *relative_pose)
    eq_id = physics.bind(self._holdables[object_body][hand]).element_id
    physics.data.eq_active[eq_id] = 1
    model = physics.model
    body_id = physics.bind(object_body).element_id
    geoms = np.flatnonzero(model.geom_bodyid == body_id)
    self._held_bits[object_body] = (geoms, model.geom_contype[geoms].copy(),
                                    model.geom_conaffinity[geoms].copy())
    model.geom_contype[geoms] = HELD_OBJECT_BIT
    model.geom_conaffinity[geoms] &= ~collision_groups.HUMAN
    hand_geom = self._bound(physics)['geoms'][self._hand_segment[hand]]
    model.geom_conaffinity[hand_geom] &= ~HELD_OBJECT_BIT

  def relative_pose(self, physics: mjcf.Physics, object_body: mjcf.Element,
                    hand: str) -> Tuple[np.ndarray, np.ndarray]:
    """The pose of `object_body` in `hand`'s capsule frame.

    Args:
      physics: the physics.
      object_body: an MJCF body.
      hand: 'left' or 'right'.

    Returns:
      (position (3,), quaternion (4,) w first).
    """
    hand_body = self._bound(physics)['hand_bodies'][hand]
    obj = physics.bind(object_body)
    data = physics.data
    r1 = data.xmat[hand_body].reshape(3, 3)
    rel_pos = r1.T @ (obj.xpos - data.xpos[hand_body])
    rel_quat = rotations.quat_mul(
        rotations.quat_conj(data.xquat[hand_body]), obj.xquat)
    return rel_pos, rel_quat

  def set_grip(self, physics: mjcf.Physics, object_body: mjcf.Element,
               position: np.ndarray, quaternion: np.ndarray) -> None:
    """Changes the pose at which a held object is welded to the hand.

    Args:
      physics: the physics (its model is changed).
      object_body: a held body.
      position: (3,) in the hand capsule's frame.
      quaternion: (4,) w first, non-zero (normalised here).

    Raises:
      ValueError: a body that is not held, or a bad pose.
    """
    target, index = self.grip_slots(physics, object_body)
    target[index] = self.grip_values(position, quaternion)

  def grip_slots(self, physics: mjcf.Physics, object_body: mjcf.Element
                 ) -> Tuple[np.ndarray, np.ndarray]:
    """Where the held object's weld keeps its relative pose.

    Args:
      physics: the physics.
      object_body: a held body.

    Returns:
      (MjModel's eq_data, flat, and the 10 indices in it that
      `grip_values` fills).

    Raises:
      ValueError: a body that is not held.
    """
    hand = self._held.get(object_body)
    if hand is None:
      name = getattr(object_body, 'full_identifier', object_body)
      raise ValueError(f'{name!r} is not held')
    eq_id = physics.bind(self._holdables[object_body][hand]).element_id
    eq_data = physics.model.eq_data
    return eq_data.reshape(-1), eq_id * eq_data.shape[1] + np.arange(10)

  @staticmethod
  def grip_values(position: np.ndarray, quaternion: np.ndarray
                  ) -> np.ndarray:
    """The weld's eq_data[0:10] holding an object at a pose in the hand's
    frame (anchor 0, the unit quaternion).

    Args:
      position: (3,) finite.
      quaternion: (4,) w first, finite and non-zero.

    Returns:
      (10,) the weld's data.

    Raises:
      ValueError: a bad position or quaternion.
    """
    position = np.asarray(position, dtype=np.float64)
    quaternion = np.asarray(quaternion, dtype=np.float64)
    if position.shape != (3,) or quaternion.shape != (4,):
      raise ValueError('relative pose must be a finite position (3,) and a '
                       f'non-zero quaternion (4,), got {position!r}, '
                       f'{quaternion!r}')
    return Human.grip_rows(position[None], quaternion[None])[0]

  @staticmethod
  def grip_rows(positions: np.ndarray, quaternions: np.ndarray
                ) -> np.ndarray:
    """grip_values of n poses, each row as grip_values gives it.

    Args:
      positions: (n, 3) finite.
      quaternions: (n, 4) w first, finite and non-zero.

    Returns:
      (n, 10) the welds' data.

    Raises:
      ValueError: bad positions or quaternions.
    """
    positions = np.asarray(positions, dtype=np.float64)
    quaternions = np.asarray(quaternions, dtype=np.float64)
    norms = np.full(len(quaternions), np.nan)
    if quaternions.ndim == 2 and quaternions.shape[1] == 4:
      norms = row_norms(quaternions)
    bad = ~(np.isfinite(norms) & (norms > 0))
    if (positions.shape != (len(norms), 3) or not np.isfinite(positions).all()
        or bad.any()):
      raise ValueError('relative poses must be finite positions (n, 3) and '
                       f'non-zero quaternions (n, 4), got {positions!r}, '
                       f'{quaternions!r}')
    values = np.zeros((len(norms), 10))
    values[:, 3:6] = positions
    values[:, 6:10] = quaternions / norms[:, None]
    return values

  def grip(self, physics: mjcf.Physics, object_body: mjcf.Element
           ) -> Optional[Tuple[np.ndarray, np.ndarray]]:
    """The pose at which a held object is welded to its hand.

    Args:
      physics: the physics.
      object_body: a holdable body.

    Returns:
      (position (3,), quaternion (4,)) in the hand capsule's frame, or
      None if it is not held.
    """
    hand = self._held.get(object_body)
    if hand is None:
      return None
    eq_id = physics.bind(self._holdables[object_body][hand]).element_id
    data = physics.model.eq_data[eq_id]
    return data[3:6].copy(), data[6:10].copy()

  def release(self, physics: mjcf.Physics, object_body: mjcf.Element
              ) -> None:
    """Releases `object_body` from whichever hand holds it.

    Args:
      physics: the physics (its model is changed).
      object_body: a holdable body (nothing happens if it is not held).

    Raises:
      ValueError: a body that is not holdable.
    """
    if object_body not in self._holdables:
      name = getattr(object_body, 'full_identifier', object_body)
      raise ValueError(f'{name!r} is not holdable')
    for weld in self._holdables[object_body].values():
      physics.data.eq_active[physics.bind(weld).element_id] = 0
    hand = self._held.pop(object_body, None)
    bits = self._held_bits.pop(object_body, None)
    if bits is not None:
      geoms, contype, conaffinity = bits
      model = physics.model
      model.geom_contype[geoms] = contype
      model.geom_conaffinity[geoms] = conaffinity
      if hand not in self._held.values():
        hand_geom = self._bound(physics)['geoms'][self._hand_segment[hand]]
        model.geom_conaffinity[hand_geom] |= HELD_OBJECT_BIT

  def holding(self, object_body: mjcf.Element) -> Optional[str]:
    """The hand holding `object_body`.

    Args:
      object_body: an MJCF body.

    Returns:
      'left', 'right', or None.
    """
    return self._held.get(object_body)

  # ----------------------------------------------------------- observables

  def add_relative_observables(
      self, site: mjcf.Element,
      subset: Sequence[str] = ('head', 'left_hand', 'right_hand'),
      name: Optional[str] = None
  ) -> Tuple[observable.Generic, observable.Generic]:
    """Observables of keypoints in `site`'s frame and their distances.

    Args:
      site: the MJCF site whose frame the keypoints are taken in.
      subset: keypoint names.
      name: the observables' name suffix (default: the site's name).

    Returns:
      ('keypoints_in_{name}_frame' (len(subset), 3),
      'keypoint_distances_to_{name}' (len(subset),)), both added to the
      human's observables.
    """
    name = name or site.name
    # The frame's site, then the subset's keypoint sites.
    site_ids = element_ids.ElementIds(
        [site] + [self._sites[i] for i in keypoints.index(subset)])

    def relative(physics):
      ids = site_ids(physics)
      data = element_ids.synced_data(physics)   # The binding's values.
      origin = ids[0]
      return ((data.site_xpos[ids[1:]] - data.site_xpos[origin])
              @ data.site_xmat[origin].reshape(3, 3))

    def distance(physics):
      return np.linalg.norm(relative(physics), axis=-1)

    rel = observable.Generic(relative)
    dist = observable.Generic(distance)
    self.observables.add_observable(f'keypoints_in_{name}_frame', rel)
    self.observables.add_observable(f'keypoint_distances_to_{name}', dist)
    return rel, dist


def _stature_from(positions):
  """Rough stature from one frame: head keypoint height over eye fraction."""
  k = keypoints.KEYPOINT_INDEX
  spine = np.linalg.norm(positions[k['neck']] - positions[k['pelvis']])
  # neck - pelvis = (0.83 - 0.53) H in body.py's proportions.
  neck_fraction = (body_lib.SHOULDER_HEIGHT_FRACTION
                   + body_lib.NECK_ABOVE_SHOULDER_FRACTION
                   - body_lib.HIP_HEIGHT_FRACTION)
  return float(np.clip(spine / neck_fraction, 1.3, 2.1))


class HumanObservables(composer.Observables):
  """Keypoint positions in the world frame."""

  @composer.observable
  def keypoint_positions(self) -> observable.Generic:
    """The keypoints' world positions (NUM_KEYPOINTS, 3)."""
    return observable.Generic(self._entity.keypoint_positions)
