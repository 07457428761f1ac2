"""SAC-Lagrangian's parts: SAC's networks, actor and replay; the
Lagrangian learner (agents/builders.py)."""

from agents.sac import builder as sac_builder
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
    return True

  def make_learner(self, networks, observation_size, action_size, seed):
    return learning.SACLagrangianLearner(networks, self.config,
                                         observation_size, action_size, seed)
