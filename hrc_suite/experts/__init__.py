"""Hand-crafted experts per task, and noisy experts.

  env = suite.load('pick_place', 'default', task_kwargs={'robot': 'schunk'})
  expert = experts.make(env)                  # deterministic
  noise = experts.noise.OrnsteinUhlenbeckNoise.reference(4, 'cartesian')
  noisy = experts.make(env, noise=noise, seed=0)   # reference OU noise
  timestep = env.reset(); action = expert(timestep)
"""

import importlib

# (domain, task) -> 'module:Class' (modules imported on first use).
_EXPERTS = {}


def register(domain, task, path):
  _EXPERTS[(domain, task)] = path


def registered():
  """The (domain, task) pairs with an expert."""
  return tuple(_EXPERTS)


def expert_class(domain, task):
  key = (domain, task)
  if key not in _EXPERTS:
    valid = ', '.join(f'{d}/{t}' for d, t in sorted(_EXPERTS))
    raise ValueError(f'No expert for {domain}/{task}: experts exist for '
                     f'{valid}')
  module, name = _EXPERTS[key].split(':')
  return getattr(importlib.import_module(f'hrc_suite.experts.{module}'), name)


for _domain, _task, _path in (
    ('reach', 'dense', 'reach:ReachExpert'),
    ('reach', 'sparse', 'reach:ReachExpert'),
    ('pick_place', 'default', 'pick_place:PickPlaceExpert'),
    ('pick_place', 'close', 'pick_place:PickPlaceExpert'),
    ('handover', 'robot_to_human', 'handover:RobotToHumanExpert'),
    ('handover', 'human_to_robot', 'handover:HumanToRobotExpert'),
    ('inspection', 'default', 'inspection:InspectionExpert'),
    ('lifting', 'default', 'lifting:LiftingExpert'),
    ('hammering', 'default', 'hammering:HammeringExpert'),
    ('hammering', 'robot_hammers', 'hammering_robot:RobotHammersExpert'),
    ('stacking', 'default', 'stacking:StackingExpert')):
  register(_domain, _task, _path)


def make(env, noise=None, seed=0):
  """The expert of the environment's task (`env.task.suite_name`), wrapped
  in `noise.NoisyExpert` (noise seeded by `seed`) when `noise` (a noise
  process, e.g. `noise.OrnsteinUhlenbeckNoise.reference(size, space)`) is
  given."""
  name = getattr(env.task, 'suite_name', None)
  if name is None:
    raise ValueError('make(env) needs an environment from hrc_suite.suite.'
                     'load (its task carries suite_name = (domain, task))')
  expert = expert_class(*name)(env)
  if noise is None:
    return expert
  from hrc_suite.experts import noise as noise_lib   # pylint: disable=g-import-not-at-top
  return noise_lib.NoisyExpert(expert, noise, seed=seed)
