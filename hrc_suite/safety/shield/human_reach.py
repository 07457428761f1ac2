"""The human's reachable set: per-keypoint balls and body capsules over time.

Implements docs/shield_maths.md, 8 on hrc_suite's keypoints (defects B2,
L2, L5: its section 10):
* measurement processing by finite differences or a constant-velocity
  Kalman filter whose dt is measured from the PREVIOUS sample (fixes B2);
* the VEL (maximal velocity), ACCEL (acceleration) and POS (arm extremity)
  models, or the single COMBINED model;
* body capsules enclosing the balls of both keypoints at both ends of every
  interval (also for ball bodies: fixes L5).

Velocity-dependent models (ACCEL, COMBINED) need a velocity: until two
measurements exist (or after `reset`) they fall back to the VEL ball, which
holds for any initial velocity within v_max (fixes L2: the human is never
assumed to be at rest). With finite differences the velocity is the mean over
the last sample period, which differs from the current velocity by at most
a_max dt / 2; that is added to the velocity error.

The POS model covers each arm's bodies by the extremity ball around the
shoulder; the other bodies (head, torso, pelvis, legs) use VEL capsules, so
every model over-approximates every body (each must: SSM accepts an interval
as soon as one model is collision-free).
"""

import dataclasses
import json
import pathlib
from typing import Optional

import numpy as np

from hrc_suite.human import keypoints as keypoint_set
from hrc_suite.safety import geometry
from hrc_suite.safety import kernels

DEFAULT_MODEL_PATH = (pathlib.Path(__file__).resolve().parents[2] / 'assets' /
                      'human' / 'shield_human_model.json')

# Speeds below this (m/s) have no direction; the combined model then shifts
# along x by a zero amount (docs/shield_maths.md, 8.3).
_MIN_SPEED = 1e-12
# Sample periods below this (s) do not update velocities
# (docs/shield_maths.md, 8.1).
MIN_SAMPLE_PERIOD = 1e-7

POS, VEL, ACCEL = 0, 1, 2


@dataclasses.dataclass(frozen=True)
class Body:
  name: str
  proximal: str
  distal: str
  thickness: float  # Diameter, m.


@dataclasses.dataclass(frozen=True)
class Extremity:
  name: str
  base: str
  end: str
  length: float     # m, upper bound of the base-to-end distance.
  thickness: float  # Diameter, m.
  covers: tuple     # Names of the bodies the extremity ball stands for.


@dataclasses.dataclass(frozen=True)
class HumanModelConfig:
  """The shield's human model (see shield_human_model.json)."""
  keypoint_names: tuple
  v_max: np.ndarray          # (N_kp,) m/s
  a_max: np.ndarray          # (N_kp,) m/s^2
  bodies: tuple
  extremities: tuple
  measurement_error_pos: float
  measurement_error_vel: float
  delay: float
  use_combined_model: bool
  kalman_s_w: float
  kalman_s_v: float
  kalman_initial_pos_var: float
  kalman_initial_vel_var: float

  @classmethod
  def load(cls, path=None):
    """Reads and validates a model file (default: the shipped one)."""
    path = pathlib.Path(DEFAULT_MODEL_PATH if path is None else path)
    try:
      data = json.loads(path.read_text())
    except FileNotFoundError:
      raise ValueError(f'{path}: no such human model file') from None
    except json.JSONDecodeError as e:
      raise ValueError(f'{path}: not valid JSON: {e}') from None

    def fail(field, message):
      raise ValueError(f'{path}: field {field!r}: {message}')

    def number(value, field, minimum=0.0):
      try:
        value = float(value)
      except (TypeError, ValueError):
        fail(field, f'expected a number, got {value!r}')
      if not np.isfinite(value) or value < minimum:
        fail(field, f'expected a finite number >= {minimum}, got {value}')
      return value

    def name(value, field):
      if value not in keypoint_set.KEYPOINT_INDEX:
        fail(field, f'unknown keypoint {value!r}; expected one of '
             f'{", ".join(keypoint_set.KEYPOINT_NAMES)}')
      return value

    raw = data.get('keypoints')
    if not isinstance(raw, dict) or set(raw) != set(
        keypoint_set.KEYPOINT_NAMES):
      fail('keypoints', 'expected an entry for every keypoint: '
           f'{", ".join(keypoint_set.KEYPOINT_NAMES)}')
    names = keypoint_set.KEYPOINT_NAMES
    v_max = np.array([number(raw[n].get('v_max'), f'keypoints.{n}.v_max',
                             1e-9) for n in names])
    a_max = np.array([number(raw[n].get('a_max'), f'keypoints.{n}.a_max',
                             1e-9) for n in names])
    bodies = []
    for i, b in enumerate(data.get('bodies') or fail('bodies', 'missing')):
      f = f'bodies[{i}]'
      bodies.append(Body(str(b.get('name')), name(b.get('proximal'),
                                                   f + '.proximal'),
                         name(b.get('distal'), f + '.distal'),
                         number(b.get('thickness'), f + '.thickness')))
    body_names = [b.name for b in bodies]
    if len(set(body_names)) != len(body_names):
      fail('bodies', f'duplicate body names in {body_names}')
    extremities = []
    for i, e in enumerate(data.get('extremities', [])):
      f = f'extremities[{i}]'
      covers = tuple(e.get('covers', ()))
      for c in covers:
        if c not in body_names:
          fail(f + '.covers', f'unknown body {c!r}; expected one of '
               f'{body_names}')
      extremities.append(Extremity(
          str(e.get('name')), name(e.get('base'), f + '.base'),
          name(e.get('end'), f + '.end'),
          number(e.get('length'), f + '.length', 1e-9),
          number(e.get('thickness'), f + '.thickness'), covers))
    kalman = data.get('kalman', {})
    return cls(
        keypoint_names=names, v_max=v_max, a_max=a_max, bodies=tuple(bodies),
        extremities=tuple(extremities),
        measurement_error_pos=number(data.get('measurement_error_pos', 0.0),
                                     'measurement_error_pos'),
        measurement_error_vel=number(data.get('measurement_error_vel', 0.0),
                                     'measurement_error_vel'),
        delay=number(data.get('delay', 0.0), 'delay'),
        use_combined_model=bool(data.get('use_combined_model', True)),
        kalman_s_w=number(kalman.get('s_w', 200.0), 'kalman.s_w'),
        kalman_s_v=number(kalman.get('s_v', 1e-6), 'kalman.s_v', 1e-12),
        kalman_initial_pos_var=number(kalman.get('initial_pos_var', 0.003),
                                      'kalman.initial_pos_var'),
        kalman_initial_vel_var=number(kalman.get('initial_vel_var', 0.5),
                                      'kalman.initial_vel_var'))


@dataclasses.dataclass(frozen=True)
class HumanState:
  """The measurement record of a `HumanReach` (docs/shield_maths.md, 8.1):
  what a measurement reads and changes. Arrays are replaced, never changed
  in place, so a record is a snapshot."""
  positions: Optional[np.ndarray]     # (N_kp, 3); None before a measurement.
  velocities: np.ndarray              # (N_kp, 3) m/s.
  last_measurement_time: Optional[float]  # s, of the last velocity update.
  last_period: float                  # s, its sample period (0 before).
  num_measurements: int               # Velocity updates, the first included.
  covariance: np.ndarray              # (2, 2) the Kalman filter's.
  extremity_lengths: np.ndarray       # (E,) m, the POS model's arm lengths.
  # Positions whose arm lengths are not in extremity_lengths yet (those of
  # the last velocity update; None: none).
  length_positions: Optional[np.ndarray]


def combined_balls(p, v, v_max, a_max, t):
  """COMBINED model balls (docs/shield_maths.md, 8.3) without measurement
  errors.

  p, v (N, 3); v_max, a_max (N,); t (T,) prediction times >= 0. Returns
  centres (T, N, 3) and core radii (T, N). Keypoints measured faster than
  v_max keep their speed (a ball of radius speed * t).
  """
  speed = np.sqrt(np.vecdot(v, v))
  direction = v / np.maximum(speed, _MIN_SPEED)[:, None]  # 0 when at rest.
  t = np.asarray(t, dtype=float)[:, None]
  # Phase ends clipped to t: accelerating to v_max along the velocity,
  # braking, and reversing to v_max (negative only when speed > v_max, where
  # the result is replaced below).
  t_up = np.minimum((v_max - speed) / a_max, t)
  t_m = np.minimum(v_max / a_max, t)
  t_dn = np.minimum((v_max + speed) / a_max, t)
  up_sq, dn_sq = t_up * t_up, t_dn * t_dn
  along = t_m * (t - 0.5 * t_m)
  across = 0.25 * (t * (t_up + t_dn) - 0.5 * (up_sq + dn_sq))
  simple = (t_dn < t) | (t_up >= t)
  core = a_max * np.where(simple, along,
                          np.sqrt(across * across + along * along))
  shift = speed * t + 0.5 * a_max * (t * (t_up - t_dn) - 0.5 * (up_sq - dn_sq))
  fast = speed > v_max
  if fast.any():
    core = np.where(fast, speed * t, core)
    shift = np.where(fast, 0.0, shift)
  return p + shift[..., None] * direction, core


class HumanReach:
  """Human measurements in, reachable body capsules out.

  Attributes:
    kernel_ends: (2B,) int64, the keypoint ends of every body, proximal
      ends then distal ends.
    kernel_v_max, kernel_a_max: (K,) float64, the keypoints' maximal speeds
      and accelerations (HumanModelConfig).
    half_thickness: (B,) half of every body's thickness.

  These arrays are contiguous, built once, and read-only by convention:
  the compiled kernels and the shield's cycle constants share them.
  """

  def __init__(self, config=None, use_kalman_filter=False,
               use_combined_model=None):
    if config is None or isinstance(config, (str, pathlib.Path)):
      config = HumanModelConfig.load(config)
    self.config = config
    self.use_kalman_filter = bool(use_kalman_filter)
    self.use_combined_model = (config.use_combined_model
                               if use_combined_model is None
                               else bool(use_combined_model))
    self.num_models = 1 if self.use_combined_model else 3
    self.num_keypoints = len(config.keypoint_names)
    self.num_bodies = len(config.bodies)
    self.body_names = tuple(b.name for b in config.bodies)
    index = keypoint_set.KEYPOINT_INDEX
    # Keypoint ends of every body: proximal then distal, (2B,).
    self._ends = np.array([index[b.proximal] for b in config.bodies] +
                          [index[b.distal] for b in config.bodies])
    self.half_thickness = np.array([b.thickness / 2 for b in config.bodies])
    # Extremities: which bodies each covers, chain keypoints for the length.
    body_index = {b.name: i for i, b in enumerate(config.bodies)}
    self._ext_base = np.array([index[e.base] for e in config.extremities],
                              dtype=int)
    self._ext_end = np.array([index[e.end] for e in config.extremities],
                             dtype=int)
    self._ext_length = np.array([e.length for e in config.extremities])
    self._ext_speed = np.array([
        max(config.v_max[index[e.base]], config.v_max[index[e.end]])
        for e in config.extremities])
    self._ext_radius = np.array([
        max([e.thickness] + [config.bodies[body_index[c]].thickness
                             for c in e.covers]) / 2
        for e in config.extremities])
    self._ext_bodies = [np.array([body_index[c] for c in e.covers], dtype=int)
                        for e in config.extremities]
    self._ext_chains = [self._chain(e) for e in config.extremities]
    # Contiguous arguments of the compiled velocity-model kernel.
    self.kernel_ends = np.ascontiguousarray(self._ends, dtype=np.int64)
    self.kernel_v_max = np.ascontiguousarray(config.v_max, dtype=float)
    self.kernel_a_max = np.ascontiguousarray(config.a_max, dtype=float)
    # Caches derived from the record: the extremity lengths of its
    # length positions, the velocity errors of a sample period.
    self._lengths = (None, None)
    self._error_vel = (None, None)
    self.reset()

  def _chain(self, extremity):
    """Pairs of keypoints (a, b) along the covered bodies (for lengths)."""
    pairs = [(keypoint_set.KEYPOINT_INDEX[b.proximal],
              keypoint_set.KEYPOINT_INDEX[b.distal])
             for b in self.config.bodies if b.name in extremity.covers]
    return np.array(pairs, dtype=int).reshape(-1, 2)

  def initial_state(self):
    """The measurement record before any measurement (`reset`)."""
    return HumanState(
        positions=None, velocities=np.zeros((self.num_keypoints, 3)),
        last_measurement_time=None, last_period=0.0, num_measurements=0,
        covariance=np.diag([self.config.kalman_initial_pos_var,
                            self.config.kalman_initial_vel_var]),
        extremity_lengths=self._ext_length.copy(), length_positions=None)

  def reset(self):
    """Forgets all measurements."""
    self._state = self.initial_state()

  @property
  def state(self):
    """The measurement record (`HumanState`); settable (the shield's
    state carries it, safety/shield/shield_state.py)."""
    return self._state

  @state.setter
  def state(self, state):
    if not isinstance(state, HumanState):
      raise TypeError(f'HumanReach.state: expected a HumanState, got '
                      f'{type(state).__name__}')
    self._state = state

  @property
  def positions(self):
    """Keypoint positions (N_kp, 3) of the last measurement (None: none)."""
    return self._state.positions

  @property
  def velocities(self):
    """Keypoint velocities (N_kp, 3) (zero until two measurements)."""
    return self._state.velocities

  @property
  def last_measurement_time(self):
    """Time (s) of the last measurement that updated the velocities."""
    return self._state.last_measurement_time

  @property
  def last_period(self):
    """The sample period (s) of the last velocity update (0 before)."""
    return self._state.last_period

  @property
  def num_measurements(self):
    """Measurements that updated the velocities, the first included."""
    return self._state.num_measurements

  def get_state(self):
    """The measurement state as arrays and scalars (for .npz / JSON):
    `set_state` restores it exactly."""
    state = self._state
    none = np.zeros((self.num_keypoints, 3))
    lengths_pending = state.length_positions is not None
    return {
        'has_positions': state.positions is not None,
        'positions': (none if state.positions is None
                      else state.positions.copy()),
        'velocities': state.velocities.copy(),
        'last_measurement_time': (0.0 if state.last_measurement_time is None
                                  else state.last_measurement_time),
        'num_measurements': state.num_measurements,
        'last_period': state.last_period,
        'covariance': state.covariance.copy(),
        'extremity_lengths': state.extremity_lengths.copy(),
        'lengths_pending': lengths_pending,
        'length_positions': (state.length_positions.copy() if lengths_pending
                             else none),
    }

  def set_state(self, state):
    """Restores a `get_state` (arrays may be lists, as after JSON)."""
    def array(name, shape):
      value = np.array(state[name], dtype=float)
      if value.shape != shape:
        raise ValueError(f'human state {name!r}: expected shape {shape}, '
                         f'got {value.shape}')
      return value
    points = (self.num_keypoints, 3)
    has_positions = bool(state['has_positions'])
    self._state = HumanState(
        positions=array('positions', points) if has_positions else None,
        velocities=array('velocities', points),
        last_measurement_time=(float(state['last_measurement_time'])
                               if has_positions else None),
        last_period=float(state['last_period']),
        num_measurements=int(state['num_measurements']),
        covariance=array('covariance', (2, 2)),
        extremity_lengths=array('extremity_lengths', self._ext_length.shape),
        length_positions=(array('length_positions', points)
                          if bool(state['lengths_pending']) else None))

  @property
  def has_velocity(self):
    return self._state.num_measurements >= 2

  def measure(self, keypoints, t):
    """Takes one measurement of all keypoints (N_kp, 3) at time t (s)."""
    self._state = self.measured(self._state, keypoints, t)

  def measured(self, state, keypoints, t):
    """The record `state` (`HumanState`) after a measurement of all
    keypoints (N_kp, 3) at time t (s); `state` is not changed."""
    keypoints = np.asarray(keypoints, dtype=float)
    if keypoints.shape != (self.num_keypoints, 3):
      raise ValueError(f'keypoints: expected shape ({self.num_keypoints}, 3),'
                       f' got {keypoints.shape}')
    if not np.all(np.isfinite(keypoints)):
      raise ValueError('keypoints: expected finite positions')
    t = float(t)
    if state.positions is None:
      positions = keypoints.copy()
      # The POS model's lengths come from the positions of the last
      # velocity update, computed when first needed
      # (`_extremity_lengths_now`).
      return dataclasses.replace(
          state, positions=positions,
          velocities=np.zeros((self.num_keypoints, 3)),
          last_measurement_time=t, num_measurements=1,
          length_positions=positions)
    dt = t - state.last_measurement_time
    if dt < 0:
      raise ValueError(f'measurement time {t} is before the previous one '
                       f'({state.last_measurement_time}); call reset() first')
    if dt < MIN_SAMPLE_PERIOD:
      return dataclasses.replace(state, positions=keypoints.copy())
    covariance = state.covariance
    if self.use_kalman_filter:
      positions, velocities, covariance = self._kalman_update(state,
                                                              keypoints, dt)
    else:
      velocities = (keypoints - state.positions) / dt
      positions = keypoints.copy()
    return HumanState(
        positions=positions, velocities=velocities,
        last_measurement_time=t,   # dt of the next sample from here (B2).
        last_period=dt, num_measurements=state.num_measurements + 1,
        covariance=covariance, extremity_lengths=state.extremity_lengths,
        length_positions=positions)

  def _kalman_update(self, state, z, dt):
    """Constant-velocity KF per coordinate (docs/shield_maths.md, 8.1); all
    share the same 2x2 covariance, so it is propagated once. Returns
    positions, velocities and covariance."""
    cfg = self.config
    velocities = state.velocities
    if state.num_measurements == 1:  # State (p, 0) from the first sample.
      velocities = np.zeros_like(z)
    transition = np.array([[1.0, dt], [0.0, 1.0]])
    noise = cfg.kalman_s_w * np.array([[dt ** 3 / 3, dt ** 2 / 2],
                                       [dt ** 2 / 2, dt]])
    cov = transition @ state.covariance @ transition.T + noise
    predicted = state.positions + dt * velocities
    gain = cov[:, 0] / (cov[0, 0] + cfg.kalman_s_v)
    innovation = z - predicted
    return (predicted + gain[0] * innovation,
            velocities + gain[1] * innovation,
            cov - np.outer(gain, cov[0]))

  def _extremity_lengths_now(self):
    """Arm extremity lengths: the model's, or longer if the arm measured
    at the last velocity update was longer. A cache of this object,
    derived from the record's positions kept for the lengths."""
    state = self._state
    p = state.length_positions
    if p is None:
      return state.extremity_lengths
    if self._lengths[0] is not p:
      lengths = state.extremity_lengths.copy()
      for e, chain in enumerate(self._ext_chains):
        if len(chain):
          length = np.linalg.norm(p[chain[:, 1]] - p[chain[:, 0]],
                                  axis=-1).sum()
          lengths[e] = max(self._ext_length[e], length)
      self._lengths = (p, lengths)
    return self._lengths[1]

  def body_capsules(self, keypoints):
    """Real-size body capsules: p1 (B, 3), p2 (B, 3), r (B,)."""
    keypoints = np.asarray(keypoints, dtype=float)
    ends = keypoints[..., self._ends, :]
    b = self.num_bodies
    return ends[..., :b, :], ends[..., b:, :], self.half_thickness

  def _velocity_error(self):
    error = self.config.measurement_error_vel
    if not self.use_kalman_filter:
      error = error + self.config.a_max * (0.5 * self.last_period)
    return error

  def keypoint_balls(self, t):
    """VEL balls (radii (T, N) around the last positions) and, if a
    velocity is known, the velocity model's balls (centres (T, N, 3), radii
    (T, N): COMBINED or ACCEL) at prediction times t (T,) (time since the
    last measurement, delay included); else None for those."""
    cfg = self.config
    t = np.asarray(t, dtype=float)
    e_p = cfg.measurement_error_pos
    vel_radius = e_p + t[:, None] * cfg.v_max
    if not self.has_velocity:
      return vel_radius, None, None
    e_v = self._velocity_error()
    if self.use_combined_model:
      centre, core = combined_balls(self.positions, self.velocities,
                                    cfg.v_max, cfg.a_max, t)
    else:
      centre = self.positions + t[:, None, None] * self.velocities
      core = 0.5 * cfg.a_max * (t * t)[:, None]
    return vel_radius, centre, core + e_p + e_v * t[:, None]

  def reach_capsules(self, t_cycle, t_edges, compiled=True):
    """Body capsules over K intervals: c1, c2 (M, K, B, 3), r (M, K, B).

    t_edges (K+1,) are relative to t_cycle (the interval [t_cycle + t_k,
    t_cycle + t_{k+1}]). Models: [COMBINED] or [POS, VEL, ACCEL].
    compiled=False computes the velocity model with NumPy (the reference)
    instead of the kernel.
    """
    if self.positions is None:
      raise RuntimeError('HumanReach.reach_capsules: no measurement yet; '
                         'call measure(keypoints, t) first')
    t_edges = np.asarray(t_edges, dtype=float)
    if t_edges.ndim != 1 or t_edges.shape[0] < 2:
      raise ValueError(f't_edges: expected shape (K+1,) with K >= 1, got '
                       f'{t_edges.shape}')
    t = (t_cycle - self.last_measurement_time) + t_edges + self.config.delay
    if t[0] < 0:
      raise ValueError(f'reach_capsules: interval starts at {t_cycle} + '
                       f'{t_edges[0]}, before the last measurement '
                       f'({self.last_measurement_time})')
    k = t.shape[0] - 1
    b = self.num_bodies
    ends = self._ends
    if compiled and self.has_velocity:
      if self._error_vel[0] != self.last_period:
        self._error_vel = (self.last_period, np.array(
            np.broadcast_to(self._velocity_error(), (self.num_keypoints,)),
            dtype=float))   # A writeable copy: one kernel signature.
      error_vel = self._error_vel[1]
      c1, c2, r = kernels.human_velocity_capsules(
          self.positions, self.velocities, self.kernel_v_max,
          self.kernel_a_max, t, self.config.measurement_error_pos,
          error_vel, self.kernel_ends, self.half_thickness,
          self.use_combined_model)
      if self.use_combined_model:
        return c1[None], c2[None], r[None]
      kp_centre, kp_r = np.concatenate([c1, c2], axis=1), r
      vel_radius = self.config.measurement_error_pos + (
          t[:, None] * self.config.v_max)
    else:
      vel_radius, centre, radius = self.keypoint_balls(t)
    # VEL balls grow about a fixed centre: the t_b ball encloses the t_a one.
    vel_r = vel_radius[1:, ends]                                  # (K, 2B)
    vel_r = np.maximum(vel_r[:, :b], vel_r[:, b:]) + self.half_thickness
    vel_ends = np.broadcast_to(self.positions[ends], (k, 2 * b, 3))
    if compiled and self.has_velocity:
      pass   # The velocity model's capsules come from the kernel above.
    elif centre is None:  # No velocity yet: the velocity model is VEL too.
      kp_centre, kp_r = vel_ends, vel_r
    else:   # The NumPy reference of the kernel.
      c, r = geometry.enclosing_ball(centre[:-1], radius[:-1], centre[1:],
                                     radius[1:])                  # (K, N)
      kp_centre = c[:, ends]
      r = r[:, ends]
      kp_r = np.maximum(r[:, :b], r[:, b:]) + self.half_thickness
    if self.use_combined_model:
      return (kp_centre[None, :, :b], kp_centre[None, :, b:], kp_r[None])
    centres = np.empty((3, k, 2 * b, 3))
    centres[POS] = vel_ends
    centres[VEL] = vel_ends
    centres[ACCEL] = kp_centre
    radii = np.empty((3, k, b))
    radii[POS] = vel_r
    radii[VEL] = vel_r
    radii[ACCEL] = kp_r
    t_b = t[1:]
    lengths = self._extremity_lengths_now()
    for e, bodies in enumerate(self._ext_bodies):
      centres[POS][:, bodies] = self.positions[self._ext_base[e]]
      centres[POS][:, bodies + b] = self.positions[self._ext_base[e]]
      ball = (self._ext_speed[e] * t_b + lengths[e]
              + self._ext_radius[e] + self.config.measurement_error_pos)
      radii[POS][:, bodies] = ball[:, None]
    return centres[:, :, :b], centres[:, :, b:], radii
