"""absl flags that name registered things (tasks, robots, shield modes),
checked against the registries when the command line is parsed, so that
what an extension registers (docs/extending.md) is accepted by every
binary and a bad name fails at once, listing the valid ones."""

import os

from absl import flags

from hrc_suite import robot_description
from hrc_suite.safety.shield import modes


def _values(value):
  if value is None:
    return []
  return [value] if isinstance(value, str) else list(value)


def _robot_ok(name):
  return name in robot_description.names() or (
      name.endswith('.json') and os.path.isfile(name))


def check_robot(flag_name, flag_values=flags.FLAGS):
  """--flag_name (one robot or a list) names robots or description files."""
  def check(value):
    bad = [v for v in _values(value) if not _robot_ok(v)]
    if bad:
      raise flags.ValidationError(
          f'unknown robot {bad[0]!r}: expected one of '
          f'{", ".join(robot_description.names())} or the path of a .json '
          'description file')
    return True
  flags.register_validator(flag_name, check, flag_values=flag_values)


def check_shield(flag_name, flag_values=flags.FLAGS, extra=()):
  """--flag_name (one mode or a list) names shield modes or `extra`."""
  def check(value):
    valid = tuple(extra) + modes.names()
    bad = [v for v in _values(value) if v not in valid]
    if bad:
      raise flags.ValidationError(f'unknown shield mode {bad[0]!r}: expected '
                                  f'one of {", ".join(valid)}')
    return True
  flags.register_validator(flag_name, check, flag_values=flag_values)


def check_task(domain_flag, task_flag, flag_values=flags.FLAGS):
  """--domain_flag/--task_flag name a registered task (None: unset)."""
  def check(values):
    from hrc_suite import suite  # pylint: disable=g-import-not-at-top
    domain, task = values[domain_flag], values[task_flag]
    tasks = suite.all_tasks()
    if domain is not None and domain not in {d for d, _ in tasks}:
      raise flags.ValidationError(
          f'unknown domain {domain!r}: expected one of '
          f'{", ".join(sorted({d for d, _ in tasks}))}')
    if domain is not None and task is not None and (domain, task) not in (
        tasks):
      raise flags.ValidationError(
          f'unknown task {task!r} of domain {domain!r}: expected one of '
          f'{", ".join(t for d, t in tasks if d == domain)}')
    return True
  flags.register_multi_flags_validator([domain_flag, task_flag], check,
                                       flag_values=flag_values)
