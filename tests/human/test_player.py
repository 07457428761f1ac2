"""Tests for the clip player: idle phases, continuity, sequences, state."""

import json
import math

import numpy as np
import pytest

from hrc_suite import layout
from hrc_suite.human import bvh_import
from hrc_suite.human import clip as clip_lib
from hrc_suite.human import keypoints
from hrc_suite.human import player as player_lib

DT = 0.004          # physics step, s.
SPEED = 0.2         # m/s of every keypoint along x in the ramp clips.
LIMIT_STEP = clip_lib.MAX_KEYPOINT_SPEED * DT
K = keypoints.NUM_KEYPOINTS


def ramp_clip(name='ramp', seconds=4.0, fps=50.0, start=(0.0, 0.0),
              phases=(), task='other', keyframes=None, targets=None):
  """Every keypoint moves along +x at SPEED: x encodes clip time exactly."""
  frames = int(round(seconds * fps)) + 1
  t = np.arange(frames) / fps
  base = np.stack([np.full(K, start[0]), np.full(K, start[1]),
                   np.linspace(0.1, 1.7, K)], axis=1)
  positions = base[None] + SPEED * t[:, None, None] * np.array([1.0, 0, 0])
  return clip_lib.Clip(
      name=name, task=task, fps=fps, positions=positions.astype(np.float32),
      keyframes=keyframes or (frames // 4, 3 * frames // 5),
      idle_phases=phases, targets=targets or {})


def phase(keyframe, event, amplitudes=(0.5, 0.05), speeds=(0.6, 0.3),
          factor=1.1):
  return clip_lib.IdlePhase(keyframe, event, np.array(amplitudes),
                            np.array(speeds), factor, factor)


def clip_time_from_x(x, start=0.0):
  return (x - start) / SPEED


def run(player, seconds, triggers=None):
  """Steps the player; records positions and clip times; fires triggers."""
  triggers = dict(triggers or {})
  positions, times, waits = [], [], []
  for step in range(int(round(seconds / DT))):
    event = triggers.pop(step, None)
    if event is not None:
      assert player.trigger(event)
    player.advance(DT)
    positions.append(player.positions.copy())
    times.append(player.clip_time)
    waits.append(player.waiting_for)
  return np.array(positions), np.array(times), waits


def test_linear_playback_interpolates_and_differentiates():
  clip = ramp_clip()
  player = player_lib.Player([clip])
  player.reset(np.random.RandomState(0))
  positions, times, _ = run(player, 0.5)
  np.testing.assert_allclose(times, DT * np.arange(1, 126), atol=1e-12)
  np.testing.assert_allclose(positions[:, 0, 0], SPEED * times, atol=1e-6)
  np.testing.assert_allclose(player.velocities[:, 0], SPEED, atol=1e-5)
  np.testing.assert_allclose(player.velocities[:, 1:], 0, atol=1e-6)


def test_idle_phase_follows_the_sine_formula_and_runs_backwards():
  clip = ramp_clip(phases=(phase(0, 'go'),))
  player = player_lib.Player([clip])
  player.reset(np.random.RandomState(3))
  (u, s), = player.idle_parameters
  base = clip.idle_phases[0]
  ratio_u, ratio_s = u / base.amplitudes, s / base.speeds
  for ratio in (ratio_u, ratio_s):
    assert np.all(ratio >= 1.1**-3 - 1e-12) and np.all(ratio <= 1.1**3 + 1e-12)
    assert not np.allclose(ratio, 1.0)
  positions, times, waits = run(player, 12.0)
  episode = DT * np.arange(1, len(times) + 1)
  t_i = clip.keyframe_time(0)
  waiting = episode >= t_i
  assert all(w == 'go' for w, on in zip(waits, waiting) if on)
  assert all(w is None for w, on in zip(waits, waiting) if not on)
  omega = s / u
  expected = t_i + (u[None] * np.sin((episode[waiting, None] - t_i) * omega)
                    ).sum(axis=1)
  expected = np.clip(expected, 0.0, clip.duration)
  np.testing.assert_allclose(times[waiting], expected, atol=1e-9)
  # The body really shows the warped time (x encodes clip time).
  np.testing.assert_allclose(clip_time_from_x(positions[waiting, 3, 0]),
                             expected, atol=1e-4)
  assert np.any(np.diff(times[waiting]) < 0), 'replay never ran backwards'
  assert np.max(np.abs(np.diff(positions, axis=0))) < LIMIT_STEP


def test_event_ends_the_wait_without_a_jump_and_playback_continues():
  clip = ramp_clip(phases=(phase(0, 'go'),))
  player = player_lib.Player([clip])
  player.reset(np.random.RandomState(5))
  run(player, 2.345)
  assert player.waiting_for == 'go'
  assert not player.trigger('other_event')
  before_time, before = player.clip_time, player.positions.copy()
  assert player.trigger('go')
  assert player.waiting_for is None
  assert player.clip_time == pytest.approx(before_time, abs=1e-12)
  np.testing.assert_allclose(player.positions, before, atol=1e-12)
  positions, times, _ = run(player, 0.4)
  np.testing.assert_allclose(np.diff(times), DT, atol=1e-9)
  assert np.linalg.norm(positions[0] - before, axis=1).max() < LIMIT_STEP
  assert not player.trigger('go')   # no longer waiting.


def test_two_idle_phases_in_order():
  clip = ramp_clip(phases=(phase(0, 'second_cube_placed'),
                           phase(1, 'fourth_cube_placed')), task='stacking')
  player = player_lib.Player([clip], sequence_length=1)
  player.reset(np.random.RandomState(1))
  seen = []
  rs = np.random.RandomState(2)
  previous = player.positions.copy()
  for _ in range(int(20.0 / DT)):
    waiting = player.waiting_for
    if not seen or seen[-1] != waiting:
      seen.append(waiting)
    if waiting and rs.rand() < 0.002:
      assert player.trigger(waiting)
    player.advance(DT)
    assert np.linalg.norm(player.positions - previous, axis=1).max() < (
        LIMIT_STEP)
    previous = player.positions.copy()
  assert seen == [None, 'second_cube_placed', None, 'fourth_cube_placed',
                  None]
  assert player.motion_finished
  np.testing.assert_allclose(player.velocities, 0.0)
  np.testing.assert_allclose(player.positions, clip.positions[-1], atol=1e-6)


def test_clip_switch_blends_without_jumps():
  clips = [ramp_clip('a', seconds=1.0),
           ramp_clip('b', seconds=1.0, start=(0.6, -0.5))]
  player = player_lib.Player(clips, station=(1.0, 2.0, 0.5))
  player.reset(np.random.RandomState(0))
  names, blends = [], 0
  previous = player.positions.copy()
  for _ in range(int(12.0 / DT)):
    player.advance(DT)
    step = np.linalg.norm(player.positions - previous, axis=1).max()
    assert step < LIMIT_STEP
    if player.in_transition:
      blends += 1
      speed = np.linalg.norm(player.velocities, axis=1).max()
      assert speed <= player_lib.TRANSITION_SPEED + 1e-9
      assert step <= player_lib.TRANSITION_SPEED * DT + 1e-9
    previous = player.positions.copy()
    if not names or names[-1] != player.clip.name:
      names.append(player.clip.name)
  assert len(names) >= 3 and blends > 0
  assert not player.motion_finished


def test_velocities_match_finite_differences():
  clip = ramp_clip(phases=(phase(0, 'go'),))
  player = player_lib.Player([clip], station=(0.3, -0.2, 1.0))
  player.reset(np.random.RandomState(4))
  dt = 1e-4
  for _ in range(20):
    player.advance(0.137)
    before = player.positions.copy()
    velocity = player.velocities.copy()
    player.advance(dt)
    np.testing.assert_allclose((player.positions - before) / dt, velocity,
                               atol=2e-3)


def test_placement_station_and_random_ranges():
  clip = ramp_clip(targets={'handover_point': np.array([0.5, 0.0, 1.0])})
  station = (1.45, 0.0, math.pi)
  player = player_lib.Player([clip], station=station)
  player.reset(np.random.RandomState(0))
  assert player.placement == station
  local = clip.positions[0].astype(np.float64)
  expected = np.stack([1.45 - local[:, 0], -local[:, 1], local[:, 2]], axis=1)
  np.testing.assert_allclose(player.positions, expected, atol=1e-6)
  np.testing.assert_allclose(player.targets_world['handover_point'],
                             [0.95, 0.0, 1.0], atol=1e-12)
  ranged = player_lib.Player([clip], station=station,
                             placement_range=(0.02, 0.1, 0.1))
  draws = []
  for seed in range(50):
    ranged.reset(np.random.RandomState(seed))
    draws.append(np.array(ranged.placement) - station)
  draws = np.array(draws)
  assert np.all(np.abs(draws) <= [0.02, 0.1, 0.1])
  assert np.all(draws.std(axis=0) > [0.005, 0.03, 0.03])


def sequence(seed, steps=3000, trigger_every=400):
  clips = [ramp_clip('a', seconds=2.0, phases=(phase(0, 'go'),),
                     keyframes=(25, 60)),
           ramp_clip('b', seconds=1.5, start=(0.4, 0.3))]
  player = player_lib.Player(clips, station=(1.0, 0.0, 3.0),
                             placement_range=(0.1, 0.1, 0.2))
  player.reset(np.random.RandomState(seed))
  out = []
  for step in range(steps):
    if step % trigger_every == 0 and player.waiting_for:
      player.trigger(player.waiting_for)
    player.advance(DT)
    out.append(player.positions.copy())
  return np.array(out), player


def test_deterministic_given_the_random_state():
  first, _ = sequence(7)
  second, _ = sequence(7)
  np.testing.assert_array_equal(first, second)
  other, _ = sequence(8)
  assert not np.array_equal(first, other)


@pytest.mark.parametrize('steps', [150, 600, 1000, 2200])
def test_get_and_set_state_restore_exactly(steps):
  _, player = sequence(11, steps=steps)
  state = json.loads(json.dumps(player.get_state()))
  clips = player._clips   # the same prepared clips, as a task would reuse.
  restored = player_lib.Player([c.clip for c in clips],
                               station=(1.0, 0.0, 3.0),
                               placement_range=(0.1, 0.1, 0.2))
  restored.set_state(state)
  np.testing.assert_array_equal(restored.positions, player.positions)
  np.testing.assert_array_equal(restored.velocities, player.velocities)
  assert restored.waiting_for == player.waiting_for
  assert restored.clip.name == player.clip.name
  for step in range(800):
    for p in (player, restored):
      if step % 300 == 0 and p.waiting_for:
        p.trigger(p.waiting_for)
      p.advance(DT)
    np.testing.assert_array_equal(restored.positions, player.positions)
  assert restored.episode_time == player.episode_time


def test_resampling_to_fps_out_keeps_the_motion():
  clip = ramp_clip(phases=(phase(0, 'go'),))
  player = player_lib.Player([clip], fps_out=250)
  player.reset(np.random.RandomState(0))
  assert player.clip.fps == 250
  assert player.clip.keyframes == tuple(k * 5 for k in clip.keyframes)
  _, times, _ = run(player, 0.5)
  np.testing.assert_allclose(player.positions[0, 0], SPEED * times[-1],
                             atol=1e-6)


def test_bad_use_is_reported():
  with pytest.raises(ValueError, match='at least one clip'):
    player_lib.Player([])
  player = player_lib.Player([ramp_clip()])
  with pytest.raises(RuntimeError, match='before reset'):
    player.advance(DT)
  player.reset(np.random.RandomState(0))
  with pytest.raises(ValueError, match='dt must be >= 0'):
    player.advance(-1.0)
  with pytest.raises(ValueError, match='placement_range'):
    player_lib.Player([ramp_clip()], placement_range=(-1, 0, 0))
  with pytest.raises(ValueError, match='Bad player state'):
    player.set_state({'seed': 1})


@pytest.mark.recordings
def test_real_recordings_have_no_jump_at_events_and_switches(recordings_dir):
  files = sorted((recordings_dir / 'HumanRobotHandover').glob('*.bvh'))
  clips = [bvh_import.import_clip(f) for f in files[:3]]
  player = player_lib.Player(clips, station=layout.HUMAN_STATION_ACROSS,
                             placement_range=(0.0, 0.2, 0.1),
                             sequence_length=3)
  player.reset(np.random.RandomState(0))
  rs = np.random.RandomState(1)
  events = switches = 0
  previous, name = player.positions.copy(), player.clip.name
  while not player.motion_finished:
    if player.waiting_for and rs.rand() < 0.001:
      before = player.positions.copy()
      player.trigger(player.waiting_for)
      np.testing.assert_array_equal(player.positions, before)
      events += 1
      player.advance(DT)
      assert np.linalg.norm(player.positions - before, axis=1).max() < (
          LIMIT_STEP)
    else:
      player.advance(DT)
    if player.clip.name != name or player.in_transition:
      switches += 1
      assert np.linalg.norm(player.positions - previous, axis=1).max() < (
          LIMIT_STEP)
    previous, name = player.positions.copy(), player.clip.name
  assert events == 6 and switches > 0


@pytest.mark.parametrize('seed', [0, 3, 11])
def test_advance_many_equals_advance_steps(seed):
  """advance_many writes, bit for bit, what advance step by step gives,
  through idle phases, events, clip switches and blends."""
  def make():
    clips = [ramp_clip('a', seconds=0.5, phases=(phase(0, 'go'),),
                       keyframes=(5, 15)),
             ramp_clip('b', seconds=0.3, start=(0.4, 0.3)),
             ramp_clip('c', seconds=0.2)]
    player = player_lib.Player(clips, station=(1.0, 0.0, 3.0),
                               placement_range=(0.1, 0.1, 0.2),
                               transition_speed=5.0)
    player.reset(np.random.RandomState(seed))
    return player
  single, batched = make(), make()
  # Every way of advance_many is taken: whole blocks within one clip or
  # waiting in an idle phase (compiled) and blocks with waits that end,
  # switches or blends (step loop).
  within_clip, waiting = [], []
  whole_block = batched._advance_within_clip
  batched._advance_within_clip = lambda *args: within_clip.append(
      whole_block(*args)) or within_clip[-1]
  whole_wait = batched._advance_waiting
  batched._advance_waiting = lambda *args: waiting.append(
      whole_wait(*args)) or waiting[-1]
  n, blends = 25, 0
  positions, times, clips = np.zeros((n, K, 3)), np.zeros(n), [None] * n
  for block in range(60):
    expected = []
    for _ in range(n):
      single.advance(DT)
      blends += single.in_transition
      expected.append((single.positions.copy(), single.episode_time,
                       single.clip))
    batched.advance_many(DT, positions, times, clips)
    np.testing.assert_array_equal(positions, [e[0] for e in expected])
    assert list(times) == [e[1] for e in expected]
    assert [c.name for c in clips] == [e[2].name for e in expected]
    np.testing.assert_array_equal(batched.velocities, single.velocities)
    assert batched.get_state() == single.get_state()
    if block % 3 == 0 and single.waiting_for:
      assert single.trigger('go') and batched.trigger('go')
  assert blends > 0 and single.clip_index > 3
  assert any(within_clip) and not all(within_clip)
  # Blocks waiting in an idle phase (compiled), and blocks neither way.
  assert any(waiting) and not all(waiting)


def test_advance_many_needs_room_for_every_step():
  player = player_lib.Player([ramp_clip()])
  player.reset(np.random.RandomState(0))
  with pytest.raises(ValueError, match='times and clips need 4'):
    player.advance_many(DT, np.zeros((4, K, 3)), np.zeros(3), [None] * 4)


def test_uncompiled_player_plays_the_same_without_kernels(monkeypatch):
  """compiled=False runs advance_many's Python path (the kernels'
  reference): no kernel call, the same bits as the compiled player."""
  clips = [ramp_clip('a', seconds=0.5, phases=(phase(0, 'go'),),
                     keyframes=(5, 15)), ramp_clip('b', seconds=0.3)]
  players = [player_lib.Player(clips, station=(1.0, 0.0, 3.0),
                               compiled=compiled)
             for compiled in (True, False)]
  for player in players:
    player.reset(np.random.RandomState(5))
  n = 25
  rows = [(np.zeros((n, K, 3)), np.zeros(n), [None] * n) for _ in players]
  compiled_rows, reference_rows = rows
  for block in range(30):
    players[0].advance_many(DT, *compiled_rows)
    with monkeypatch.context() as patch:
      for name in ('play_within_clip', 'play_waiting'):
        patch.setattr(player_lib.player_kernels, name, None)
      players[1].advance_many(DT, *reference_rows)
    np.testing.assert_array_equal(reference_rows[0], compiled_rows[0])
    np.testing.assert_array_equal(reference_rows[1], compiled_rows[1])
    assert players[0].get_state() == players[1].get_state()
    if block % 4 == 0 and players[0].waiting_for:
      assert all(player.trigger('go') for player in players)
