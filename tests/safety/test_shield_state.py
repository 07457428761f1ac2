"""Shield snapshots (get_state / set_state through .npz and JSON) and the
cheap unshielded mode."""

import io
import json

import numpy as np
import pytest

from hrc_suite import robot_description
from hrc_suite.safety.shield import path_check
from hrc_suite.safety.shield import shield as shield_lib

import shield_harness as harness

CYCLE = shield_lib.DEFAULT_CYCLE_TIME


def _shield(name, **kwargs):
  description = robot_description.load(name)
  return shield_lib.Shield(description,
                           tool_capsule=harness.tool_capsule(description),
                           **kwargs)


def _drive(shield, human, goals, first, last, read=True):
  """Cycles [first, last) with a new goal every 12 cycles; returns commands
  (q, dq, ddq) and read-outs per cycle."""
  out = []
  for i in range(first, last):
    if i % 12 == 0:
      shield.new_goal(goals[i // 12])
    t = i * CYCLE
    q, dq, ddq = shield.step(human(t), t)
    row = [q.copy(), dq.copy(), ddq.copy(), shield.intervened]
    if read:
      row += [shield.is_safe, shield.first_unsafe_interval]
    out.append(row)
  return out


def _same(a, b):
  assert len(a) == len(b)
  for x, y in zip(a, b):
    for u, v in zip(x, y):
      assert np.array_equal(u, v), (u, v)   # Bit for bit.


def _through_npz(state):
  buffer = io.BytesIO()
  np.savez(buffer, **state)
  buffer.seek(0)
  with np.load(buffer, allow_pickle=False) as data:
    return {k: data[k] for k in data.files}


def _through_json(state):
  text = json.dumps({k: v.tolist() if isinstance(v, np.ndarray) else v
                     for k, v in state.items()})
  return json.loads(text)


@pytest.mark.parametrize('name, mode, kalman', [
    ('panda', 'ssm', False), ('ur5e', 'pfl', True), ('panda', 'off', False)])
def test_restored_shield_continues_identically(name, mode, kalman):
  shield = _shield(name, mode=mode, use_kalman_filter=kalman)
  description = shield.description
  goals = [harness.random_goals(description, np.random.RandomState(5))()
           for _ in range(40)]
  human = harness.walk_in(start=0.1, from_x=1.3)   # Brakes the robot.
  _drive(shield, human, goals, 0, 101)  # Braking, a goal pending.
  state = shield.get_state()
  assert state['goal_pending'] == (mode != 'off')
  for key, value in state.items():
    assert isinstance(value, (np.ndarray, str, bool, int, float)), key
  copies = []
  for transport in (_through_npz, _through_json):
    other = _shield(name, mode=mode, use_kalman_filter=kalman)
    other.set_state(transport(state))
    copies.append(other)
  expected = _drive(shield, human, goals, 101, 330)
  assert any(row[3] for row in expected) or mode == 'off'   # It braked.
  for other in copies:
    _same(_drive(other, human, goals, 101, 330), expected)


def test_set_state_names_a_mismatch():
  state = _shield('panda').get_state()
  with pytest.raises(ValueError, match="mode: expected 'pfl'"):
    _shield('panda', mode='pfl').set_state(state)
  with pytest.raises(ValueError, match="robot: expected 'ur5e'"):
    _shield('ur5e').set_state(state)


def test_off_mode_checks_only_when_a_read_out_is_asked(monkeypatch):
  """Unshielded: no verification per cycle; the read-outs, when read, are
  those of a shield that checks every cycle on the same commands."""
  calls = []
  verify = path_check.PathCheck.verify

  def counting(self, *args):
    calls.append(args[6].mode)   # The shield.
    return verify(self, *args)
  monkeypatch.setattr(path_check.PathCheck, 'verify', counting)
  lazy, eager = _shield('panda', mode='off'), _shield('panda', mode='off')
  goals = [harness.random_goals(lazy.description,
                                np.random.RandomState(2))() for _ in range(20)]
  human = harness.walk_in(start=0.0, from_x=1.3)
  quiet = _drive(lazy, human, goals, 0, 200, read=False)
  assert not calls
  assert not any(row[3] for row in quiet)      # Never intervenes.
  assert lazy.min_distance < np.inf and not calls
  read = _drive(eager, human, goals, 0, 200)
  assert len(calls) == 200
  _same([row[:4] for row in read], quiet)      # Same commands.
  assert not all(row[4] for row in read)       # The human got close.
  # Asking now runs the check of the last cycle once.
  assert lazy.is_safe == read[-1][4]
  assert lazy.first_unsafe_interval == read[-1][5]
  assert lazy.reach_distance == eager.reach_distance
  assert len(calls) == 201
