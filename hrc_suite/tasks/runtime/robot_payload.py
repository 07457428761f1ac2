"""What the robot's gripper carries, told to the shield and the contact monitor.

Energy-based PFL bounds a contact's energy by the kinetic energy of the
arm with what its last link carries, the gripper and a held object
(docs/safety.md, "Energy limits of body regions"; docs/shield_maths.md,
9.4). A task decides when its gripper holds an object (both fingers on it,
`ParallelGripper.is_grasping`, as its own progress logic reads it);
`CarriesPayload`, a mixin of `base.HrcTask`, turns that decision, the
task's `_held_bodies()`, into a `robot_energy.Payload` and gives it to
the shield's `energy` (`EnergySetup.set_payload`: the `pfl_energy` mode's
energy model) and to the
contact monitor's energy meter (tasks/runtime/contact_energies.py) whenever the
held objects change: at an episode's start and after every RL step. A
grasp or release within an RL step takes effect from the next one.

The payload is `robot_energy.payload_from_physics` of the gripper and the
held objects' bodies (each with its sub-bodies, e.g. a board's nail) at
the RL step the grasp is first seen, in the last link's frame; it is kept
while the same objects are held, and snapshots carry it, so a restored
episode continues with the same payload. Nothing held: the shield's
default (the gripper, `robot_energy.gripper_payload`).

Other shield modes do not read the shield's payload: their episodes are
unchanged. The monitor measures every robot-human contact's energy with
the payload in every mode (the episode's contact_energy maxima).
"""

from typing import Any, Optional, Sequence

from dm_control import mjcf
import numpy as np

from hrc_suite.safety import robot_energy

# The key of the payload in the task's own snapshot state.
STATE_KEY = 'robot_payload'


def held_payload(physics: mjcf.Physics, robot, bodies: Sequence[mjcf.Element]
                 ) -> Optional[robot_energy.Payload]:
  """The payload of the robot's last link holding `bodies`.

  Args:
    physics: the environment's physics, after a forward pass or a step.
    robot: the `hrc_suite.entities.robot.Robot` (with its gripper).
    bodies: the MJCF bodies the gripper holds (each with its sub-bodies).

  Returns:
    The gripper and the held bodies as one `robot_energy.Payload`, or None
    when nothing is held (the shield's default, the gripper).
  """
  if not bodies:
    return None
  extra = []
  for body in bodies:
    extra += [body] + list(body.find_all('body'))
  return robot_energy.payload_from_physics(physics, robot, extra)


def payload_state(payload: Optional[robot_energy.Payload]) -> Any:
  """A payload as snapshot values (None, or a dict of a float and arrays)."""
  if payload is None:
    return None
  return {'mass': float(payload.mass),
          'center_of_mass': np.array(payload.center_of_mass, dtype=float),
          'inertia': np.array(payload.inertia, dtype=float)}


def payload_from_state(state: Any) -> Optional[robot_energy.Payload]:
  """The payload of `payload_state`'s values."""
  if state is None:
    return None
  return robot_energy.Payload(
      mass=float(state['mass']),
      center_of_mass=np.array(state['center_of_mass'], dtype=float),
      inertia=np.array(state['inertia'], dtype=float).reshape(3, 3))


class CarriesPayload:
  """Mixin of `base.HrcTask` for tasks whose gripper holds objects: the
  payload follows what `_held_bodies` names (module docstring). List it
  before `base.HrcTask` among the bases."""

  _held_ids = ()          # element ids of the held bodies, told last
  _held_payload = None    # the payload told last (None: the gripper)
  # (model, {bodies: element ids}) of the compiled model they were bound in
  _held_id_cache = None

  def _held_bodies(self) -> Sequence[mjcf.Element]:
    """The MJCF bodies the gripper holds now, by the task's own decision
    (its gripped flags of the last RL step)."""
    raise NotImplementedError

  @property
  def robot_payload(self) -> Optional[robot_energy.Payload]:
    """What the gripper holds, as the shield's payload (None: nothing,
    the shield's default payload, the gripper)."""
    return self._held_payload

  def initialize_episode(self, physics: mjcf.Physics,
                         random_state: np.random.RandomState) -> None:
    """Starts an episode (base.HrcTask.initialize_episode), then reads the
    payload of what the gripper holds at the start.

    Args:
      physics: the environment's physics.
      random_state: the episode's random numbers.
    """
    super().initialize_episode(physics, random_state)
    if self._held_ids:
      self._held_ids = None   # A held object's grasp is read anew.
    self._follow_held(physics)

  def after_step(self, physics: mjcf.Physics,
                 random_state: np.random.RandomState) -> None:
    """Ends an RL step (base.HrcTask.after_step), then follows a grasp or
    release the task saw in it.

    Args:
      physics: the environment's physics.
      random_state: unused.
    """
    super().after_step(physics, random_state)
    self._follow_held(physics)

  def _follow_held(self, physics):
    bodies = tuple(self._held_bodies())
    ids = self._element_ids(physics, bodies)
    if ids != self._held_ids:
      self._tell(ids, held_payload(physics, self._robot, bodies))

  def _element_ids(self, physics, bodies):
    """The element ids of `bodies` in the physics' model: bound once per
    compiled model and set of bodies (called after every RL step)."""
    if not bodies:
      return ()
    model = physics.model.ptr
    cache = self._held_id_cache
    if cache is None or cache[0] is not model:
      cache = self._held_id_cache = (model, {})
    ids = cache[1].get(bodies)
    if ids is None:
      ids = cache[1][bodies] = tuple(
          int(i) for i in physics.bind(bodies).element_id)
    return ids

  def _tell(self, ids, payload):
    """Gives `payload` to the shield and the contact monitor's meter."""
    self._held_ids, self._held_payload = ids, payload
    self._shield.energy.set_payload(payload)
    energies = self._stepper.monitor.energies
    if energies is not None:
      energies.meter.set_payload(
          payload if payload is not None
          else robot_energy.gripper_payload(self._robot.description.name))

  def _task_state(self, physics):
    state = super()._task_state(physics)
    state[STATE_KEY] = {'bodies': list(self._held_ids or ()),
                        'payload': payload_state(self._held_payload)}
    return state

  def _set_task_state(self, physics, state):
    super()._set_task_state(physics, state)
    saved = state.get(STATE_KEY)
    if saved is None:   # A snapshot without it: read from the physics.
      self._held_ids = None
      self._follow_held(physics)
      return
    ids = tuple(int(i) for i in saved['bodies'])
    payload = payload_from_state(saved['payload'])
    if ids != self._held_ids or not _same(payload, self._held_payload):
      self._tell(ids, payload)


def _same(a, b):
  """Whether two payloads (or None) are equal bit for bit."""
  if a is None or b is None:
    return a is b
  return (a.mass == b.mass
          and np.array_equal(a.center_of_mass, b.center_of_mass)
          and np.array_equal(a.inertia, b.inertia))
