"""SAC-Lagrangian's parts: SAC's networks, actor and replay; the
Lagrangian learner (agents/builders.py)."""

from agents.sac import builder as sac_builder
from agents.sac import networks as networks_lib
from agents.sac_lag import config as config_lib
from agents.sac_lag import learning


class SACLagrangianBuilder(sac_builder.SACBuilder):
  """Builds SAC-Lagrangian.

  Args:
    config: `agents.sac_lag.config.SACLagrangianConfig`.
  """

  name = 'sac_lag'
  CONFIG_CLASS = config_lib.SACLagrangianConfig

  @property
  def needs_cost(self) -> bool:
    """The Lagrangian learner reads the transitions' cost."""
    return True

  def make_learner(self, networks: networks_lib.SACNetworks,
                   observation_size: int, action_size: int, seed: int
                   ) -> learning.SACLagrangianLearner:
    """The SAC-Lagrangian learner.

    Args:
      networks: of `make_networks`.
      observation_size: the flat observation's size.
      action_size: the action's size.
      seed: the learner's random seed.

    Returns:
      The learner.
    """
    return learning.SACLagrangianLearner(networks, self.config,
                                         observation_size, action_size, seed)
