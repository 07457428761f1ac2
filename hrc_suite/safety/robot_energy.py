"""The kinetic energy of a robot arm's links, for energy-based PFL.

A contact at link j can transfer at most the kinetic energy of the motion
that drives link j: that of joints 1..j, with every link they move (link j
and all links, gripper and held object beyond it, carried rigidly):

  E_j = 1/2 dq_{1..j}^T B_{1..j, 1..j}(q) dq_{1..j},

with B(q) the arm's joint-space inertia matrix (links' masses, centres of
mass and inertia tensors from the robot description, the gripper and a
held object as a payload of the last link, and each joint's reflected
rotor inertia, the armature, on its diagonal). E_n is the arm's whole
kinetic energy. Joints beyond j keep moving after link j stops and are
left out, as in the SaRA shield's energy check (docs/safety.md,
"Energy limits of body regions").

E_j bounds what a contact at link j can take from the arm's motion: the
contact's velocity v_u = u^T J_j dq along its direction u depends on
joints 1..j only, and with joints beyond j locked the arm's mass reflected
along u, m_u = 1 / (u^T J_j B_j^-1 J_j^T u) (Khatib 1995), gives
1/2 m_u v_u^2 <= 1/2 dq_j^T B_j dq_j = E_j (Cauchy-Schwarz in B_j's
metric); free distal joints only lower the reflected mass. The whole
kinetic energy E_n bounds every contact as well (energy conservation), so
`contact_energy_bounds` is min(E_j, E_n).

B is computed with pinocchio's composite-rigid-body algorithm on the
robot description's model (hrc_suite/control/kinematics.py);
`payload_from_physics` reads the payload's inertia from MuJoCo, so B
equals the arm's block of MuJoCo's own mass matrix (mj_fullM) with the
gripper's fingers at rest.
"""

import dataclasses
import functools
from typing import Iterable, Optional

from dm_control import mjcf
import mujoco
import numpy as np
import pinocchio as pin

from hrc_suite import robot_description
from hrc_suite.control import kinematics
from hrc_suite.entities import gripper as gripper_lib
from hrc_suite.entities import robot as robot_lib


@dataclasses.dataclass(frozen=True)
class Payload:
  """A rigid payload of the last link, in that link's frame.

  Attributes:
    mass: kg.
    center_of_mass: (3,) m.
    inertia: (3, 3) kg m^2 about the centre of mass.
  """
  mass: float
  center_of_mass: np.ndarray
  inertia: np.ndarray

  def to_pinocchio(self) -> pin.Inertia:
    return pin.Inertia(float(self.mass), np.asarray(self.center_of_mass,
                                                    float),
                       np.asarray(self.inertia, float))


def armature(description: robot_description.RobotDescription) -> np.ndarray:
  """Each joint's reflected rotor inertia (kg m^2), as the simulated robot
  has it (hrc_suite/entities/robot.py, ARMATURE_PER_NEWTON_METRE)."""
  return robot_lib.ARMATURE_PER_NEWTON_METRE * np.asarray(
      description.limits.torque, float)


class ArmInertia:
  """Joint-space inertia and link energies of one robot arm.

  Args:
    description: the robot's description.
    payload: what the last link carries rigidly (gripper, held object),
      or None.
  """

  def __init__(self, description: robot_description.RobotDescription,
               payload: Optional[Payload] = None):
    self._model = kinematics.KinematicModel(description).pin_model.copy()
    if payload is not None:
      last = self._model.njoints - 1
      self._model.inertias[last] = (self._model.inertias[last]
                                    + payload.to_pinocchio())
    self._data = self._model.createData()
    self._armature = armature(description)
    self._dof = description.dof

  @property
  def dof(self) -> int:
    return self._dof

  def mass_matrix(self, q) -> np.ndarray:
    """B(q): (dof, dof) joint-space inertia, armature included."""
    q = np.asarray(q, float)
    if q.shape != (self._dof,):
      raise ValueError(f'q has shape {q.shape}, expected ({self._dof},)')
    upper = pin.crba(self._model, self._data, q)
    matrix = np.triu(upper) + np.triu(upper, 1).T
    return matrix + np.diag(self._armature)

  def link_energies(self, q, dq) -> np.ndarray:
    """(dof,) E_j, J: the kinetic energy of joints 1..j's motion (module
    docstring); the last is the arm's whole kinetic energy."""
    dq = np.asarray(dq, float)
    if dq.shape != (self._dof,):
      raise ValueError(f'dq has shape {dq.shape}, expected ({self._dof},)')
    matrix = self.mass_matrix(q)
    return np.array([0.5 * dq[:j] @ matrix[:j, :j] @ dq[:j]
                     for j in range(1, self._dof + 1)])


  def contact_energy_bounds(self, q, dq) -> np.ndarray:
    """(dof,) J: min(E_j, E_n), what a contact at link j can take from the
    arm's motion at most (module docstring)."""
    energies = self.link_energies(q, dq)
    return np.minimum(energies, energies[-1])


def payload_from_physics(physics, robot, extra_bodies: Iterable = ()
                         ) -> Payload:
  """The inertia of what the robot's last link carries, read from MuJoCo.

  Args:
    physics: the environment's physics, after a forward pass.
    robot: the `hrc_suite.entities.robot.Robot` (its gripper's bodies are
      the last link's subtree).
    extra_bodies: further MJCF bodies moving with the gripper (a held
      object, welded to it).

  Returns:
    The Payload in the last link's frame: the bodies of the last link's
    subtree other than the link itself, and extra_bodies.
  """
  model, data = physics.model, physics.data
  last = int(physics.bind(robot.link_bodies[-1]).element_id)
  bodies = [b for b in range(model.nbody)
            if b != last and _in_subtree(model, b, last)]
  bodies += [int(physics.bind(body).element_id) for body in extra_bodies]
  link_position = data.xpos[last]
  link_rotation = data.xmat[last].reshape(3, 3)
  total = pin.Inertia.Zero()
  for body in bodies:
    mass = float(model.body_mass[body])
    if mass == 0.0:
      continue
    rotation = link_rotation.T @ data.ximat[body].reshape(3, 3)
    inertia = rotation @ np.diag(model.body_inertia[body]) @ rotation.T
    centre = link_rotation.T @ (data.xipos[body] - link_position)
    total = total + pin.Inertia(mass, centre, inertia)
  return Payload(mass=float(total.mass), center_of_mass=np.array(total.lever),
                 inertia=np.array(total.inertia))


@functools.lru_cache(maxsize=None)
def gripper_payload(name: str) -> Payload:
  """The Payload of the tasks' gripper (entities.gripper.ParallelGripper,
  fingers as built) on the named robot's last link: payload_from_physics
  of the robot with its gripper alone (computed once per robot; the
  shield's default payload)."""
  robot = robot_lib.make_robot(name)
  robot.attach_gripper(gripper_lib.ParallelGripper())
  physics = mjcf.Physics.from_mjcf_model(robot.mjcf_model)
  physics.forward()
  return payload_from_physics(physics, robot)


def _in_subtree(model, body, root):
  while body > 0:
    if body == root:
      return True
    body = int(model.body_parentid[body])
  return root == 0


def mujoco_mass_matrix(physics, robot) -> np.ndarray:
  """The arm's (dof, dof) block of MuJoCo's mass matrix (mj_fullM)."""
  model, data = physics.model.ptr, physics.data.ptr
  full = np.zeros((model.nv, model.nv))
  mujoco.mj_fullM(model, data, full)
  dofs = np.asarray(physics.bind(robot.joints).dofadr, int)
  return full[np.ix_(dofs, dofs)]
