"""The human's grips on task objects, as the task loop and snapshots see them.

`Human.hold` / `release` change the model, not the physics state: the weld's
relative pose (eq_data) and the collision bits of the object and the hand.
A snapshot therefore keeps, per holdable object, which hand holds it and
the eq_data rows of its welds (tasks may set a weld's anchors themselves,
e.g. lifting's two-handed hold); restoring releases everything, re-holds
at the saved poses and writes the rows back. Whether a weld is active is
physics state (mjSTATE_EQ_ACTIVE), restored with it.

A task owns one (`self._grips`): `add` makes an object holdable (in
`_build_task`), `hold` / `release` grab and let go of it. `changed`
records a grip change (or a task's own model change, e.g. weld data it
writes: `mark_changed`) since the last `clear`, so the step loop calls
physics.forward() then, as a restore does, and a restored snapshot starts
from the same derived quantities.
"""

import numpy as np


class HumanGrips:
  """Holdable objects of one task and the human's grips on them."""

  def __init__(self, human):
    self._human = human
    self._holdables = []      # (object body, {hand: weld element})
    self.changed = False

  def add(self, body):
    """Makes `body` holdable (before compiling); returns {hand: weld}."""
    welds = self._human.add_holdable(body)
    self._holdables.append((body, welds))
    return welds

  def hold(self, physics, body, hand, relative_pose=None):
    """The human's `hand` grabs `body` (`Human.hold`)."""
    self._human.hold(physics, body, hand, relative_pose)
    self.changed = True

  def release(self, physics, body):
    """The human lets go of `body` (nothing if not held)."""
    if self._human.holding(body) is not None:
      self.changed = True
    self._human.release(physics, body)

  def release_all(self, physics):
    """The human lets go of everything."""
    for body, _ in self._holdables:
      self.release(physics, body)

  def mark_changed(self):
    """The task changed the model (e.g. weld data): forward after the step."""
    self.changed = True

  def clear(self):
    """Forgets the changes so far (an RL step's start of the task logic)."""
    self.changed = False

  def state(self, physics):
    """Per holdable: (holding hand or None, {hand: weld eq_data row})."""
    eq_data = physics.model.eq_data
    return [(self._human.holding(body),
             {hand: eq_data[physics.bind(weld).element_id].copy()
              for hand, weld in welds.items()})
            for body, welds in self._holdables]

  def restore(self, physics, state):
    """Restores `state` from `state(physics)` (same task configuration)."""
    if len(state) != len(self._holdables):
      raise ValueError(f'snapshot has grips of {len(state)} objects, this '
                       f'task has {len(self._holdables)} holdable objects')
    for body, _ in self._holdables:
      self._human.release(physics, body)
    eq_data = physics.model.eq_data
    for (body, welds), (hand, rows) in zip(self._holdables, state):
      if hand is not None:
        row = np.asarray(rows[hand], dtype=float)
        self._human.hold(physics, body, hand, (row[3:6], row[6:10]))
      for weld_hand, weld in welds.items():
        eq_data[physics.bind(weld).element_id] = rows[weld_hand]
