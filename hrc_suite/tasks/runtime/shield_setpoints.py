"""ShieldSetpoints: the shield's commands of an RL step's physics steps.

The shield is verified once per physics step (one cycle each;
tasks/runtime/shielded_stepping.py). On the reference path
(fast_path=False) every physics step runs one `Shield.step`. On the fast
path the person's poses of the whole RL step are known in advance (the
playback's frames), so the set-points of the rest of the RL step are
planned at once (`safety.shield.batch.step_many`, from a checkpoint of the
shield) at its first physics step, or again after a resync; the same
commands as one `Shield.step` each. A pushed robot or a physics error
rewinds the shield to the physics step where it happened: the checkpoint
restored and the planned cycles up to it replayed (docs/safety.md,
"Pushed robots").

Each command also says where it puts the joints after its physics step
(the tracking check's reference, `ShieldedStepper.after_physics_step`).
"""

from typing import Tuple

import numpy as np

from hrc_suite.safety.shield import batch


class ShieldSetpoints:
  """The shield's set-points of an RL step and where they put the joints:
  one `Shield.step` per physics step (reference) or planned for the rest
  of the RL step (fast path), with the checkpoint to rewind to."""

  def __init__(self, shield, playback, dof: int, fast_path: bool):
    """Set-points of `shield` for the poses of `playback`.

    Args:
      shield: the task's `safety.shield.Shield`.
      playback: the task's `entities.human_playback.HumanPlayback` (its
        `positions` and `times` of the RL step's physics steps).
      dof: the robot's joints.
      fast_path: whether the set-points are planned for the rest of the RL
        step at once (else one Shield.step per physics step).
    """
    self._shield = shield
    self._playback = playback
    self._fast_path = fast_path
    self._dt = None   # s, the physics step; `bind`
    self._expected_buffer = np.zeros(dof)
    self._expected_rows = None
    self.forget()

  def bind(self, dt: float) -> None:
    """The physics step of the bound physics.

    Args:
      dt: s, the physics' timestep.
    """
    self._dt = dt

  @property
  def setpoints(self) -> np.ndarray:
    """(n, 3, dof): the planned (q, dq, ddq) of physics steps `start`...;
    None when none are planned."""
    return self._setpoints

  @property
  def flags(self) -> np.ndarray:
    """(n,): whether the shield intervened in each planned cycle."""
    return self._setpoint_flags

  @property
  def start(self) -> int:
    """The physics step of the first planned set-point."""
    return self._setpoints_from

  @property
  def expected_rows(self) -> np.ndarray:
    """(n, dof): where each planned set-point puts the joints."""
    return self._expected_rows

  def forget(self) -> None:
    """No planned set-points (a new RL step, or a resync)."""
    self._setpoints = None
    self._setpoint_flags = None
    self._setpoints_from = 0
    self._shield_checkpoint = None

  def command(self, k: int, positions: np.ndarray,
              time: float) -> Tuple[tuple, bool, np.ndarray]:
    """The shield's command for physics step k.

    Args:
      k: the physics step's index in its RL step.
      positions: the person's keypoints at it (the playback's frame k).
      time: s, the playback time of that frame.

    Returns:
      (q, dq, ddq) the command, whether the shield intervened, and where
      the command puts the joints after the physics step (a view, valid
      until the next command).
    """
    if not self._fast_path:
      command = self._shield.step(positions, time)
      expected = self._expected(*command, self._expected_buffer)
      return command, self._shield.intervened, expected
    self.plan(k)
    i = k - self._setpoints_from
    return (self._setpoints[i], bool(self._setpoint_flags[i]),
            self._expected_rows[i])

  def plan(self, k: int) -> None:
    """The shield's set-points from physics step k to the RL step's end
    (one compiled call, `batch.step_many`) if not planned yet.

    Args:
      k: the first physics step to plan.
    """
    if self._setpoints is not None:
      return
    self._shield_checkpoint = batch.checkpoint(self._shield)
    self._setpoints_from = k
    self._setpoints, self._setpoint_flags = batch.step_many(
        self._shield, self._playback.positions[k:],
        self._playback.times[k:])
    setpoints = self._setpoints
    self._expected_rows = self._expected(
        setpoints[:, 0], setpoints[:, 1], setpoints[:, 2],
        np.empty(setpoints.shape[:1] + setpoints.shape[2:]))

  def expected_at(self, k: int) -> np.ndarray:
    """Where the planned set-point of physics step k puts the joints.

    Args:
      k: a planned physics step (`start` <= k).

    Returns:
      (dof,) a view of `expected_rows`.
    """
    return self._expected_rows[k - self._setpoints_from]

  def _expected(self, q, dq, ddq, out):
    """Where command(s) (q, dq, ddq) put the joints after a physics step,
    written into out: the controller drives the command's acceleration
    from the command's state, and MuJoCo's semi-implicit Euler moves q by
    h (dq + h ddq). (The command is the robot's state at the step's start:
    measured within ~2e-6 rad; after the step within ~2e-5 rad of this.)
    Element by element, so rows computed at once equal single ones."""
    np.multiply(ddq, self._dt, out=out)
    out += dq
    out *= self._dt
    out += q
    return out

  def rewind(self, k: int) -> None:
    """The shield back at the end of cycle k (its state when physics step
    k ran), from the checkpoint and a replay of the planned cycles
    (deterministic: checked); then no set-points are planned. Nothing to
    do when none are planned (the reference path, or already rewound).

    Args:
      k: the physics step whose cycle the shield ends at.

    Raises:
      RuntimeError: the replay differs from the planned set-points.
    """
    if self._setpoints is None:
      return
    start = self._setpoints_from
    batch.restore(self._shield, self._shield_checkpoint)
    replay, _ = batch.step_many(self._shield,
                                self._playback.positions[start:k + 1],
                                self._playback.times[start:k + 1])
    if not np.array_equal(replay, self._setpoints[:k + 1 - start]):
      raise RuntimeError('The shield replay differs from its set-points: '
                         'Shield cycles are not deterministic')
    self.forget()
