"""Shared checks of the expert tests (imported as `expert_checks`)."""

import numpy as np

from hrc_suite import experts


def expert_actions(env):
  """The actions of the environment's expert over one episode, (T, n)."""
  expert = experts.make(env)
  timestep, actions = env.reset(), []
  while not timestep.last():
    actions.append(expert(timestep))
    timestep = env.step(actions[-1])
  return np.array(actions)


def assert_same_seed_same_actions(make_env):
  """Two environments from make_env() give the expert identical actions."""
  np.testing.assert_array_equal(expert_actions(make_env()),
                                expert_actions(make_env()))
