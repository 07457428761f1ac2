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

  def make_networks(self, observation_size: int, action_size: int):
    """The networks (policy first: `policy_init`, `policy_apply`)."""

  def make_learner(self, networks, observation_size: int, action_size: int,
                   seed: int):
    """The learner: a variable source ('policy') with update, update_steps,
    compile_in_background, steps, state and restore; optionally
    observe_episode_cost(cost)."""

  def make_replay(self, observation_size: int, action_size: int):
    """The replay buffer the adder writes and the agent samples."""

  def make_actor(self, networks, variables, seed: int,
                 evaluation: bool = False):
    """An actor reading the policy from `variables.params`."""


BUILDERS = {'sac': sac_builder.SACBuilder,
            'sac_lag': sac_lag_builder.SACLagrangianBuilder}


def config_class(name: str):
  """The config dataclass of the algorithm `name`."""
  return _builder_class(name).CONFIG_CLASS


def make_builder(name: str, config: Mapping[str, Any]):
  """The builder of algorithm `name` with its config from a dict."""
  return _builder_class(name)(config_class(name).from_dict(config))


def _builder_class(name):
  if name not in BUILDERS:
    raise ValueError(f'Unknown agent algorithm {name!r}: expected one of '
                     f'{", ".join(BUILDERS)}')
  return BUILDERS[name]
