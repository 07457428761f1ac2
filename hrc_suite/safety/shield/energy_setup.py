"""Energy PFL's inputs of a shield (docs/shield_maths.md, 9.4): the arm's
energy model with its payload, the allowed energies per body, what a body
can be clamped against, and a plan's energy tables.

Each is made when a mode first needs it (only `pfl_energy` reads them);
a new payload makes a new energy model, and with it new plan tables.
"""

from typing import Mapping, Optional, Sequence, Tuple

import numpy as np

from hrc_suite import layout
from hrc_suite import robot_description as robot_description_lib
from hrc_suite.safety import arm_energy
from hrc_suite.safety import clamping
from hrc_suite.safety import collision_prevention
from hrc_suite.safety import long_term_plan as ltp
from hrc_suite.safety import robot_energy
from hrc_suite.safety.shield import energy_table_kernels
from hrc_suite.safety.shield import energy_verification
from hrc_suite.safety.shield import human_reach as human_reach_lib
from hrc_suite.safety.shield import pfl_tables


class EnergySetup:
  """Energy PFL's models of one shield, made when first asked.

  Args:
    description: the robot's description.
    human_config: the human model's configuration (its bodies).
    frame_index: the link frame of each robot capsule
      (robot_reach.RobotReach.frame_index).
    cycle_time: the shield's cycle (s): the plans' sample period.
    payload: what the last link carries (None: the gripper,
      robot_energy.gripper_payload).
    static_boxes: the boxes a body can be clamped against: name -> (min
      (3,), max (3,)), world frame (None: the workcell's,
      collision_prevention.workcell_boxes).
  """

  def __init__(
      self, description: robot_description_lib.RobotDescription,
      human_config: human_reach_lib.HumanModelConfig,
      frame_index: Sequence[int], cycle_time: float,
      payload: Optional[robot_energy.Payload] = None,
      static_boxes: Optional[Mapping[str, Tuple[Sequence[float],
                                                Sequence[float]]]] = None):
    self._description = description
    self._human_config = human_config
    self._frame_index = frame_index
    self._cycle_time = cycle_time
    self._payload = payload
    self._static_boxes = static_boxes
    self._made = {}   # 'model', 'limits', 'clamp' -> made when first asked.

  @property
  def model(self) -> arm_energy.ArmEnergyModel:
    """The arm's energy model with its payload
    (`arm_energy.ArmEnergyModel`; made when first asked)."""
    if 'model' not in self._made:
      payload = self._payload
      if payload is None:
        payload = robot_energy.gripper_payload(self._description.name)
      self._made['model'] = arm_energy.ArmEnergyModel(self._description,
                                                      payload)
      energy_table_kernels.warm_up()   # Its plans' tables.
    return self._made['model']

  def set_payload(self, payload: Optional[robot_energy.Payload]) -> None:
    """Sets what the last link carries from now on: the plan tables
    follow it.

    Args:
      payload: the gripper and an object grasped, or the gripper alone
        after a release (None: the gripper,
        robot_energy.gripper_payload).

    Raises:
      TypeError: payload is neither a robot_energy.Payload nor None.
    """
    if payload is not None and not isinstance(payload, robot_energy.Payload):
      raise TypeError(f'payload: expected a robot_energy.Payload or None, '
                      f'got {type(payload).__name__}')
    self._payload = payload
    self._made.pop('model', None)

  @property
  def limits(self) -> energy_verification.EnergyLimits:
    """The allowed energies per body of the human model
    (`energy_verification.EnergyLimits`)."""
    if 'limits' not in self._made:
      self._made['limits'] = energy_verification.energy_limits(
          self._human_config)
    return self._made['limits']

  @property
  def clamp_geometry(self) -> clamping.ClampGeometry:
    """What a body can be clamped against (`clamping.ClampGeometry` of the
    robot's capsules and the static boxes)."""
    if 'clamp' not in self._made:
      boxes = self._static_boxes
      if boxes is None:
        boxes = collision_prevention.workcell_boxes(
            mount=layout.robot_mount(self._description.name))
      self._made['clamp'] = clamping.clamp_geometry(
          self._description, self._frame_index, boxes)
    return self._made['clamp']

  def plan_energies(self, plan: ltp.LongTermPlan
                    ) -> Tuple[np.ndarray, np.ndarray]:
    """Energy PFL tables of a plan (docs/shield_maths.md, 9.4). Kept on the
    plan for the energy model (a new payload makes new ones), as
    `Shield.plan_speeds`.

    Args:
      plan: a plan of the shield.

    Returns:
      (window (N, dof), suffix (N,)), J: per link the largest contact
      energy bound at nominal path speed over the next PFL_WINDOW samples,
      and of any link from each sample to the end.
    """
    model = self.model
    return plan.derived('pfl_energy_tables', model,
                        lambda: energy_table_kernels.plan_energy_tables(
                            plan.samples(), model.kernel_arrays,
                            float(self._cycle_time),
                            pfl_tables.PFL_WINDOW))
