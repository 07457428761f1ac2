"""What an algorithm is: a builder of its networks, learner, actor and replay.

An `agents.agent.Agent` composes what a builder makes (Acme's
ActorLearnerBuilder); a second learner is a new builder and a new loss, not
a new agent. The algorithms by name:

* 'sac': soft actor-critic (agents/sac/);
* 'sac_lag': SAC-Lagrangian, SAC under a per-episode cost limit
  (agents/sac_lag/).
"""

from typing import Any, Mapping, Protocol

from agents.sac import builder as sac_builder
from agents.sac_lag import builder as sac_lag_builder


class ActorLearnerBuilder(Protocol):
  """Makes one algorithm's parts (the agent wires them together)."""

  name: str          # The algorithm's name (a key of BUILDERS).
  config: Any        # Its config dataclass (to_dict / from_dict).
  needs_cost: bool   # Whether its learner reads the transitions' cost.

  def make_networks(self, observation_size: int, action_size: int) -> Any:
    """The networks (policy first: `policy_init`, `policy_apply`).

    Args:
      observation_size: the flat observation's size.
      action_size: the action's size.

    Returns:
      The networks.
    """

  def make_learner(self, networks: Any, observation_size: int,
                   action_size: int, seed: int) -> Any:
    """The learner.

    Args:
      networks: of `make_networks`.
      observation_size: the flat observation's size.
      action_size: the action's size.
      seed: the learner's random seed.

    Returns:
      A variable source ('policy') with update, update_steps,
      compile_in_background, steps, state and restore; optionally
      observe_episode_cost(cost).
    """

  def make_replay(self, observation_size: int, action_size: int) -> Any:
    """The replay buffer the adder writes and the agent samples.

    Args:
      observation_size: the flat observation's size.
      action_size: the action's size.

    Returns:
      The buffer (e.g. `agents.replay.ReplayBuffer`).
    """

  def make_actor(self, networks: Any, variables: Any, seed: int,
                 evaluation: bool = False) -> Any:
    """An actor reading the policy from `variables.params`.

    Args:
      networks: of `make_networks`.
      variables: holds the policy's parameters as `params`
        (agents/variable_utils.py).
      seed: the actor's random seed.
      evaluation: act deterministically.

    Returns:
      The actor, with select_action(observation).
    """


BUILDERS = {'sac': sac_builder.SACBuilder,
            'sac_lag': sac_lag_builder.SACLagrangianBuilder}


def config_class(name: str) -> type:
  """The config dataclass of an algorithm.

  Args:
    name: a key of BUILDERS.

  Returns:
    The class.

  Raises:
    ValueError: an unknown name.
  """
  return _builder_class(name).CONFIG_CLASS


def make_builder(name: str,
                 config: Mapping[str, Any]) -> ActorLearnerBuilder:
  """The builder of an algorithm with its config from a dict.

  Args:
    name: a key of BUILDERS.
    config: the config's fields (`from_dict`).

  Returns:
    The builder.

  Raises:
    ValueError: an unknown name or a bad config.
  """
  return _builder_class(name)(config_class(name).from_dict(config))


def _builder_class(name):
  if name not in BUILDERS:
    raise ValueError(f'Unknown agent algorithm {name!r}: expected one of '
                     f'{", ".join(BUILDERS)}')
  return BUILDERS[name]
