"""SAC's parts: tanh-Gaussian policy and twin critics, SAC learner, NumPy
actor, uniform replay (agents/builders.py)."""

from agents import config as config_lib
from agents import replay as replay_lib
from agents.sac import actor as actor_lib
from agents.sac import learning
from agents.sac import networks as networks_lib


class SACBuilder:
  """Builds soft actor-critic.

  Args:
    config: `agents.config.SACConfig`.
  """

  name = 'sac'
  CONFIG_CLASS = config_lib.SACConfig

  def __init__(self, config: config_lib.SACConfig):
    if type(config) is not self.CONFIG_CLASS:   # pylint: disable=unidiomatic-typecheck
      raise TypeError(f'{type(self).__name__} needs a '
                      f'{self.CONFIG_CLASS.__name__}, got '
                      f'{type(config).__name__}')
    self.config = config

  @property
  def needs_cost(self) -> bool:
    """SAC reads the cost only as a reward penalty (config.cost_penalty)."""
    return self.config.cost_penalty > 0

  def make_networks(self, observation_size, action_size):
    return networks_lib.make_networks(observation_size, action_size,
                                      self.config.hidden_sizes)

  def make_learner(self, networks, observation_size, action_size, seed):
    return learning.SACLearner(networks, self.config, observation_size,
                               action_size, seed)

  def make_replay(self, observation_size, action_size):
    return replay_lib.ReplayBuffer(self.config.replay_capacity,
                                   observation_size, action_size)

  def make_actor(self, networks, variables, seed, evaluation=False):
    return actor_lib.SACActor(networks, variables, seed,
                              evaluation=evaluation)
