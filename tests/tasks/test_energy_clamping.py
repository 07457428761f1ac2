"""A hand resting on the table under the gripper, in the pick-and-place
task: unshielded, the descending gripper clamps it with more energy than
the hand's clamped limit allows (ISO/TS 15066 Annex A, docs/safety.md,
"Energy limits of body regions"); with the shield in 'pfl_energy' the
gripper still comes down onto the hand, within the limit.

The person is still: the shipped pick-and-place clip's frame in which the
left hand reaches a pick point on the table, lowered so that the hand's
capsule rests on the table top (clamped against it). The policy is
scripted: the TCP goes above the hand at full Cartesian steps, then
straight down."""

import numpy as np
import pytest

from hrc_suite import layout
from hrc_suite import suite
from hrc_suite.entities import human as human_lib
from hrc_suite.human import clip as clip_lib
from hrc_suite.human import keypoints
from hrc_suite.tasks.runtime import actions
from hrc_suite.tasks.runtime import contact_energies

# The pick-and-place clip and frame with the left hand on a pick point.
CLIP, FRAME, HAND = 7, 137, 'left_hand'
# The keypoints at the hand capsule's ends (human/keypoints.py, SEGMENTS).
HAND_ENDS = ('left_wrist', 'left_hand')
# m the capsule's lowest point lies below the table top: the soft tissue
# of a hand laid on a table (and a capsule touching the table's box counts
# as touching it, tasks/runtime/contact_energies.py).
SINK = 0.005
ABOVE = 0.25          # m above the hand: the TCP's approach height
APPROACH_STEPS = 15   # RL steps to get above the hand
RATIO = f'contact_energy_ratio/{HAND}'


def _lowest(physics, geom):
  """m: the lowest point of a capsule geom."""
  bound = physics.bind(geom)
  radius, half = bound.size[0], bound.size[1]
  return bound.xpos[2] - half * abs(bound.xmat[8]) - radius


def _hand_on_table_clip(radius):
  """The still person, the hand capsule (of `radius`) on the table."""
  shipped = clip_lib.shipped_library('pick_place')[CLIP]
  frame = shipped.positions[FRAME:FRAME + 1].astype(np.float64)
  ends = frame[0, [keypoints.KEYPOINT_INDEX[k] for k in HAND_ENDS], 2]
  frame = frame + np.array([0.0, 0.0, layout.TABLE_TOP_Z - SINK + radius
                            - ends.min()])
  return shipped.replace(name='hand_on_table',
                         positions=np.repeat(frame, 100, axis=0),
                         keyframes=(), idle_phases=(), fast_phases=(),
                         targets={})


def _press_on_hand(shield, seconds):
  """Runs the scripted descent onto the hand; returns the episode
  metrics."""
  index = contact_energies.BODIES.index(HAND)
  radius = human_lib.Human().geoms[index].size[0]
  env = suite.load('pick_place', 'default', task_kwargs=dict(
      robot='panda', shield=shield, motions=[_hand_on_table_clip(radius)],
      collision_prevention='off', done_at_success=False,
      time_limit=seconds), environment_kwargs={'random_state': 0})
  timestep = env.reset()
  task, physics = env.task, env.physics
  geom = task.human.geoms[index]
  assert _lowest(physics, geom) == pytest.approx(
      layout.TABLE_TOP_Z - SINK, abs=1e-3)
  hand = physics.bind(geom).xpos.copy()
  action = np.zeros(env.action_spec().shape)
  action[-1] = 1.0   # Gripper closed.
  steps = 0
  while not timestep.last():
    tcp = physics.bind(task.robot.tcp_site).xpos
    aim = hand + [0.0, 0.0, ABOVE if steps < APPROACH_STEPS else -ABOVE]
    action[:3] = np.clip((aim - tcp) / actions.CARTESIAN_STEP, -1.0, 1.0)
    timestep = env.step(action)
    steps += 1
  return task.episode_metrics


def test_unshielded_gripper_clamps_the_hand_over_its_limit():
  metrics = _press_on_hand('off', seconds=4.0)
  assert metrics['contacts_human_critical'] > 0
  assert metrics[RATIO] > 1.0
  assert metrics['max_contact_energy_ratio'] == metrics[RATIO]


def test_pfl_energy_clamps_the_hand_within_its_limit():
  metrics = _press_on_hand('pfl_energy', seconds=8.0)
  assert metrics['contacts_human_allowed'] > 0   # It touches the hand...
  assert 0.0 < metrics[RATIO] <= 1.0             # ... within the limit.
  assert metrics['max_contact_energy_ratio'] <= 1.0
  assert metrics['contacts_human_critical'] == 0
