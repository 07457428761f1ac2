r"""Collects an expert dataset (format: docs/datasets.md).

  python -m agents.collect_expert --domain=pick_place --task=default \
      --robot=schunk --policy=noisy_expert --episodes=100 --seed=0 \
      --out=/tmp/pick_place_schunk

Running it again with the same --out resumes: the episodes already there
are kept and collection continues at the next episode index (episode i
always uses seed + i), up to --episodes in total.
"""

import json
from typing import Sequence

from absl import app
from absl import flags

from hrc_suite.experts import dataset

def define_flags(flag_values: flags.FlagValues = flags.FLAGS) -> None:
  """Defines the command's flags (only when run as a program, so that the
  module can be imported next to other binaries).

  Args:
    flag_values: where to define them.
  """
  fv = flag_values
  flags.DEFINE_string('domain', None, 'Task domain, e.g. reach.',
                      flag_values=fv)
  flags.DEFINE_string('task', None, 'Task name, e.g. dense.', flag_values=fv)
  flags.DEFINE_string('robot', 'schunk', 'Robot name.', flag_values=fv)
  flags.DEFINE_enum('action_space', None, ['cartesian', 'joint'],
                    "Action space (default: the task's default).",
                    flag_values=fv)
  flags.DEFINE_enum('policy', 'noisy_expert', list(dataset.POLICIES),
                    'Expert with or without Ornstein-Uhlenbeck noise.',
                    flag_values=fv)
  flags.DEFINE_integer('episodes', 10, 'Episodes the dataset holds when '
                       'done.', lower_bound=0, flag_values=fv)
  flags.DEFINE_integer('seed', 0, 'Episode i uses seed + i.', lower_bound=0,
                       flag_values=fv)
  flags.DEFINE_string('out', None, 'Dataset directory.', flag_values=fv)
  flags.DEFINE_float('time_limit', None, 'Episode length in s (default: the '
                     "task's horizon).", flag_values=fv)
  flags.DEFINE_string('task_kwargs', '{}', 'Further task kwargs as a JSON '
                      'object, e.g. \'{"shield": "pfl", "observations": '
                      '"full"}\'.', flag_values=fv)
  flags.DEFINE_string('noise', '{}', 'Overrides of the reference OU noise '
                      'parameters as a JSON object (alpha, sigma, dt, mu, '
                      'weight, start).', flag_values=fv)
  flags.DEFINE_bool('progress', True, 'Show progress bars.', flag_values=fv)
  flags.mark_flags_as_required(['domain', 'task', 'out'], flag_values=fv)


def _json_object(flag):
  try:
    value = json.loads(flag.value)
  except json.JSONDecodeError as e:
    raise app.UsageError(f'--{flag.name} is not valid JSON: {e}') from e
  if not isinstance(value, dict):
    raise app.UsageError(f'--{flag.name} must be a JSON object, got '
                         f'{flag.value!r}')
  return value


def main(argv: Sequence[str],
         flag_values: flags.FlagValues = flags.FLAGS) -> None:
  """Collects (or extends) the dataset the flags describe.

  Args:
    argv: the command line (no arguments).
    flag_values: the parsed flags.

  Raises:
    app.UsageError: arguments, or a flag that is not a JSON object.
  """
  f = flag_values
  if len(argv) > 1:
    raise app.UsageError(f'Unexpected arguments: {argv[1:]}')
  task_kwargs = _json_object(f['task_kwargs'])
  task_kwargs['robot'] = f.robot
  if f.action_space is not None:
    task_kwargs['action_space'] = f.action_space
  if f.time_limit is not None:
    task_kwargs['time_limit'] = f.time_limit
  noise = _json_object(f['noise']) or None
  data = dataset.collect(
      f.out, f.domain, f.task, task_kwargs,
      policy=f.policy, episodes=f.episodes, seed=f.seed,
      noise_kwargs=noise, progress=f.progress)
  episodes = data.metadata['episodes']
  if episodes:
    success = sum(e['success'] for e in episodes) / len(episodes)
    steps = sum(e['steps'] for e in episodes)
    print(f'{data.directory}: {len(episodes)} episodes, {steps} steps, '
          f'success rate {success:.2f}')


if __name__ == '__main__':
  define_flags()
  app.run(main)
