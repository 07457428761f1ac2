"""SAC's parts: tanh-Gaussian policy and twin critics, SAC learner, NumPy
actor, uniform replay (agents/builders.py)."""

from agents import config as config_lib
from agents import variable_utils
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
    """Initializes the builder.

    Args:
      config: of exactly CONFIG_CLASS.

    Raises:
      TypeError: a config of another class.
    """
    if type(config) is not self.CONFIG_CLASS:   # pylint: disable=unidiomatic-typecheck
      raise TypeError(f'{type(self).__name__} needs a '
                      f'{self.CONFIG_CLASS.__name__}, got '
                      f'{type(config).__name__}')
    self.config = config

  @property
  def needs_cost(self) -> bool:
    """SAC reads the cost only as a reward penalty (config.cost_penalty)."""
    return self.config.cost_penalty > 0

  def make_networks(self, observation_size: int, action_size: int
                    ) -> networks_lib.SACNetworks:
    """The policy and twin critic (config.hidden_sizes).

    Args:
      observation_size: the flat observation's size.
      action_size: the action's size.

    Returns:
      The networks.
    """
    return networks_lib.make_networks(observation_size, action_size,
                                      self.config.hidden_sizes)

  def make_learner(self, networks: networks_lib.SACNetworks,
                   observation_size: int, action_size: int, seed: int
                   ) -> learning.SACLearner:
    """The SAC learner.

    Args:
      networks: of `make_networks`.
      observation_size: the flat observation's size.
      action_size: the action's size.
      seed: the learner's random seed.

    Returns:
      The learner.
    """
    return learning.SACLearner(networks, self.config, observation_size,
                               action_size, seed)

  def make_replay(self, observation_size: int, action_size: int
                  ) -> replay_lib.ReplayBuffer:
    """A uniform replay buffer of config.replay_capacity transitions.

    Args:
      observation_size: the flat observation's size.
      action_size: the action's size.

    Returns:
      The buffer.
    """
    return replay_lib.ReplayBuffer(self.config.replay_capacity,
                                   observation_size, action_size)

  def make_actor(self, networks: networks_lib.SACNetworks,
                 variables: variable_utils.VariableClient, seed: int,
                 evaluation: bool = False) -> actor_lib.SACActor:
    """The NumPy actor.

    Args:
      networks: of `make_networks`.
      variables: holds the policy's parameters as `params`.
      seed: the actor's random seed.
      evaluation: act deterministically (tanh of the mean).

    Returns:
      The actor.
    """
    return actor_lib.SACActor(networks, variables, seed,
                              evaluation=evaluation)
