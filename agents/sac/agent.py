"""SACAgent: soft actor-critic's builder in the shared agent layout.

  agent = SACAgent(specs.make_environment_spec(env), config, seed=0)

is `agents.agent.Agent(spec, SACBuilder(config), seed)`: the interaction,
update schedule and policy lag are the agent's (agents/agent.py), the
checkpoints agents/agent_checkpoint.py's (its load_policy rebuilds a
saved policy).
"""

from typing import Optional

from agents import agent as agent_lib
from agents import config as config_lib
from agents import specs
from agents.sac import builder as builder_lib


class SACAgent(agent_lib.Agent):
  """Soft actor-critic agent on a dm_env environment spec.

  Args:
    environment_spec: `agents.specs.EnvironmentSpec`.
    config: `agents.config.SACConfig` (None: `default_config()`).
    seed: integer >= 0.
    images: what to do with image observations (agents/observations.py).
  """

  def __init__(self, environment_spec: specs.EnvironmentSpec,
               config: Optional[config_lib.SACConfig] = None, seed: int = 0,
               images: str = 'error'):
    config = config or config_lib.default_config()
    if not isinstance(config, config_lib.SACConfig):
      raise TypeError(f'config must be a SACConfig, got '
                      f'{type(config).__name__}')
    super().__init__(environment_spec, builder_lib.SACBuilder(config),
                     seed=seed, images=images)
