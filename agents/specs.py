"""Environment specs in Acme's shape (`acme.specs.EnvironmentSpec`)."""

import collections

EnvironmentSpec = collections.namedtuple(
    'EnvironmentSpec', ['observations', 'actions', 'rewards', 'discounts'])


def make_environment_spec(environment):
  """EnvironmentSpec of a dm_env.Environment."""
  return EnvironmentSpec(observations=environment.observation_spec(),
                         actions=environment.action_spec(),
                         rewards=environment.reward_spec(),
                         discounts=environment.discount_spec())
