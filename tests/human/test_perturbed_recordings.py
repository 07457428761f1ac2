"""Placement and target derivation over perturbed recordings.

A "recording" here is a shipped synthetic clip's motion with the fields a
recording's `_info.json` gives (keyframes, idle phases, hands), run through
`bvh_import.clip_from_motion` as an imported BVH file is. Perturbed: the
same motion recorded further from or closer to the lab's table, raised,
slowed, mirrored to the other hand, and a person who steps back after
setting the plank down. Each must give the same task (targets moved with
the perturbation) or be refused with the documented error
(docs/motion_library.md, "Real recordings in the tasks").
"""

import dataclasses

import numpy as np
import pytest

from hrc_suite import suite
from hrc_suite import experts
from hrc_suite.human import bvh_import
from hrc_suite.human import clip as clip_lib
from hrc_suite.human import keypoints
from hrc_suite.human import placement
from hrc_suite.tasks.runtime import metrics

I = keypoints.KEYPOINT_INDEX
TASKS = ('handover_robot_to_human', 'handover_human_to_robot',
         'hammering_board', 'hammering', 'inspection')
# Targets whose height is the table's, not a keypoint's.
TABLE_HEIGHT_TARGETS = ('board_place',)
# Keypoint order with left and right swapped.
MIRROR = [I[name.replace('left_', 'right_') if name.startswith('left_')
            else name.replace('right_', 'left_')]
          for name in keypoints.KEYPOINT_NAMES]


def _fields(clip):
  return dict(keyframes=clip.keyframes, idle_phases=clip.idle_phases,
              holding_hand=clip.holding_hand, placing_hand=clip.placing_hand)


def recording(task, index=0):
  """(positions, fps, fields) of a shipped clip as a recording."""
  clip = clip_lib.shipped_library(task)[index]
  return clip.positions.astype(np.float64), clip.fps, _fields(clip)


def derive(task, positions, fps, fields):
  return bvh_import.clip_from_motion(positions, fps, fields, task,
                                     name=f'{task}_perturbed')


def shifted(positions, offset):
  return positions + np.asarray(offset, dtype=np.float64)


def slowed(positions, fields, factor):
  """The motion played `factor` (integer) times slower at the same fps."""
  frames = (len(positions) - 1) * factor + 1
  t = np.arange(frames) / factor
  lo = np.minimum(np.floor(t).astype(int), len(positions) - 2)
  frac = (t - lo)[:, None, None]
  out = positions[lo] * (1.0 - frac) + positions[lo + 1] * frac
  phases = tuple(dataclasses.replace(p, amplitudes=p.amplitudes * factor)
                 for p in fields['idle_phases'])
  return out, dict(fields, keyframes=tuple(k * factor for k in
                                           fields['keyframes']),
                   idle_phases=phases)


def mirrored(positions, fields):
  """The motion mirrored left to right (y -> -y, sides swapped)."""
  out = positions[:, MIRROR] * np.array([1.0, -1.0, 1.0])
  swap = {'left': 'right', 'right': 'left', None: None}
  return out, dict(fields, holding_hand=swap[fields['holding_hand']],
                   placing_hand=swap[fields['placing_hand']])


@pytest.mark.parametrize('task', TASKS)
@pytest.mark.parametrize('offset', [(-0.6, 0.0, 0.0), (0.35, 0.0, 0.0),
                                    (-0.2, 0.4, 0.0)])
def test_where_the_person_stood_does_not_matter(task, offset):
  positions, fps, fields = recording(task)
  base = derive(task, positions, fps, fields)
  moved = derive(task, shifted(positions, offset), fps, fields)
  np.testing.assert_allclose(moved.positions, base.positions, atol=1e-5)
  assert moved.targets.keys() == base.targets.keys()
  for name, point in base.targets.items():
    np.testing.assert_allclose(moved.targets[name], point, atol=2e-4)


@pytest.mark.parametrize('task', TASKS)
def test_a_raised_recording_raises_its_targets(task):
  rise = 0.12
  positions, fps, fields = recording(task)
  base = derive(task, positions, fps, fields)
  raised = derive(task, shifted(positions, (0.0, 0.0, rise)), fps, fields)
  for name, point in base.targets.items():
    expected = point + [0.0, 0.0, 0.0 if name in TABLE_HEIGHT_TARGETS
                        else rise]
    np.testing.assert_allclose(raised.targets[name], expected, atol=2e-4)


@pytest.mark.parametrize('task', TASKS)
def test_a_slowed_recording_keeps_its_targets(task):
  positions, fps, fields = recording(task)
  base = derive(task, positions, fps, fields)
  slow_positions, slow_fields = slowed(positions, fields, 2)
  slow = derive(task, slow_positions, fps, slow_fields)
  assert slow.duration == pytest.approx(2 * base.duration, abs=0.1)
  for name, point in base.targets.items():
    np.testing.assert_allclose(slow.targets[name], point, atol=0.01)


@pytest.mark.parametrize('task', TASKS)
def test_a_mirrored_recording_mirrors_its_targets(task):
  positions, fps, fields = recording(task)
  base = derive(task, positions, fps, fields)
  mirror_positions, mirror_fields = mirrored(positions, fields)
  mirror = derive(task, mirror_positions, fps, mirror_fields)
  if base.holding_hand:
    assert mirror.holding_hand != base.holding_hand
  for name, point in base.targets.items():
    np.testing.assert_allclose(mirror.targets[name],
                               point * [1.0, -1.0, 1.0], atol=2e-4)


def _step_back_after(positions, start, end, distance, frames=40):
  """The person steps `distance` back (-x; forward if negative) after frame
  `start` and returns by frame `end` (smooth ramps of `frames`)."""
  out = positions.copy()
  index = np.arange(len(positions))
  up = np.clip((index - start) / frames, 0.0, 1.0)
  down = np.clip((end - index) / frames, 0.0, 1.0)
  ramp = np.minimum(up, down)
  ramp = ramp * ramp * (3.0 - 2.0 * ramp)
  out[..., 0] -= distance * ramp[:, None]
  return out


@pytest.mark.parametrize('distance', [-0.3, -0.15, 0.3])
def test_board_set_down_close_to_the_body_is_placed_not_refused(distance):
  """A person who steps in after setting the plank down (it lies close to
  where they wait: placed by the wait, the plank would land short of the
  table) or back (beyond the robot's reach) is placed by the set-down: the
  plank lands in bvh_import.BOARD_REACH, the pelvis within its lean
  allowance. One who steps in 0.3 m would pass the lean allowance with
  the plank in the band: they step up as far as it allows."""
  positions, fps, fields = recording('hammering_board')
  keys = fields['keyframes']
  moved = _step_back_after(positions, keys[0] + 5, keys[-1] - 5, distance)
  clip = derive('hammering_board', moved, fps, fields)
  low, high = bvh_import.BOARD_REACH
  lean = placement.lean_allowance('hammering_board')
  pelvis = clip.positions[:, I['pelvis'], 0]
  assert pelvis.max() <= lean + 1e-5
  place = clip.targets['board_place'][0]
  if distance < -0.2:
    assert place < low and pelvis.max() == pytest.approx(lean, abs=1e-5)
  else:
    assert low - 1e-3 <= place <= high + 1e-3


def test_board_never_over_the_table_is_refused():
  """A person whose hands never come over the table sets nothing down on
  it: refused with the documented error."""
  positions, fps, fields = recording('hammering_board')
  arms = [I[f'{side}_{part}'] for side in ('left', 'right')
          for part in ('elbow', 'wrist', 'hand')]
  held = positions.copy()
  held[:, arms, 0] = held[:, [I['pelvis']], 0] + 0.05
  with pytest.raises(clip_lib.ClipError,
                     match=r"cannot derive 'board_place'.*not over the "
                           r'table'):
    derive('hammering_board', held, fps, fields)


def test_a_handover_recorded_further_back_steps_up():
  """A handover person standing short of HANDOVER_REACH steps up."""
  positions, fps, fields = recording('handover_robot_to_human')
  frame = fields['keyframes'][fields['idle_phases'][0].keyframe]
  hand = I[f"{fields['holding_hand']}_hand"]
  # The arm held 0.1 m closer to the body during the whole clip.
  short = positions.copy()
  for part in ('elbow', 'wrist', 'hand'):
    short[:, I[f"{fields['holding_hand']}_{part}"], 0] -= 0.1
  clip = derive('handover_robot_to_human', short, fps, fields)
  x = clip.positions[frame, hand, 0]
  at_limit = clip.positions[:, I['pelvis'], 0].max() > (
      placement.LEAN_ALLOWANCE - 1e-5)
  assert x == pytest.approx(bvh_import.HANDOVER_REACH, abs=1e-4) or at_limit


@pytest.mark.parametrize('task,robot', [('robot_to_human', 'panda'),
                                        ('human_to_robot', 'schunk')])
def test_expert_completes_a_perturbed_handover(task, robot):
  """The expert hands over with a person recorded elsewhere in the lab,
  mirrored to the other hand and 5 cm taller."""
  clip_task = suite.task_class('handover', task).MOTIONS
  positions, fps, fields = recording(clip_task)
  positions, fields = mirrored(shifted(positions, (-0.5, 0.3, 0.05)),
                               fields)
  clip = derive(clip_task, positions, fps, fields)
  env = suite.load('handover', task, task_kwargs={
      'robot': robot, 'motions': [clip]}, environment_kwargs={
          'random_state': 0})
  episode = metrics.run_episode(env, experts.make(env))
  assert episode['success'] == 1.0
  assert episode['contacts_human_critical'] == 0
