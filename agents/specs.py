"""Environment specs in Acme's shape (`acme.specs.EnvironmentSpec`)."""

import collections

import dm_env

EnvironmentSpec = collections.namedtuple(
    'EnvironmentSpec', ['observations', 'actions', 'rewards', 'discounts'])


def make_environment_spec(environment: dm_env.Environment) -> EnvironmentSpec:
  """EnvironmentSpec of a dm_env.Environment.

  Args:
    environment: the environment.

  Returns:
    Its observation, action, reward and discount specs.
  """
  return EnvironmentSpec(observations=environment.observation_spec(),
                         actions=environment.action_spec(),
                         rewards=environment.reward_spec(),
                         discounts=environment.discount_spec())
