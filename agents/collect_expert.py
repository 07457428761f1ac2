r"""Collects an expert dataset (format: docs/datasets.md).

  python -m agents.collect_expert --domain=pick_place --task=default \
      --robot=schunk --policy=noisy_expert --episodes=100 --seed=0 \
      --out=/tmp/pick_place_schunk

Running it again with the same --out resumes: the episodes already there
are kept and collection continues at the next episode index (episode i
always uses seed + i), up to --episodes in total.
"""

import json

from absl import app
from absl import flags

from hrc_suite.experts import dataset

_DOMAIN = flags.DEFINE_string('domain', None, 'Task domain, e.g. reach.')
_TASK = flags.DEFINE_string('task', None, 'Task name, e.g. dense.')
_ROBOT = flags.DEFINE_string('robot', 'schunk', 'Robot name.')
_ACTION_SPACE = flags.DEFINE_enum(
    'action_space', None, ['cartesian', 'joint'],
    "Action space (default: the task's default).")
_POLICY = flags.DEFINE_enum('policy', 'noisy_expert', list(dataset.POLICIES),
                            'Expert with or without Ornstein-Uhlenbeck noise.')
_EPISODES = flags.DEFINE_integer('episodes', 10,
                                 'Episodes the dataset holds when done.',
                                 lower_bound=0)
_SEED = flags.DEFINE_integer('seed', 0, 'Episode i uses seed + i.',
                             lower_bound=0)
_OUT = flags.DEFINE_string('out', None, 'Dataset directory.')
_TIME_LIMIT = flags.DEFINE_float(
    'time_limit', None, "Episode length in s (default: the task's horizon).")
_TASK_KWARGS = flags.DEFINE_string(
    'task_kwargs', '{}', 'Further task kwargs as a JSON object, e.g. '
    '\'{"shield": "pfl", "observations": "full"}\'.')
_NOISE = flags.DEFINE_string(
    'noise', '{}', 'Overrides of the reference OU noise parameters as a JSON '
    'object (alpha, sigma, dt, mu, weight, start).')
_PROGRESS = flags.DEFINE_bool('progress', True, 'Show progress bars.')

flags.mark_flags_as_required(['domain', 'task', 'out'])


def _json_object(flag):
  try:
    value = json.loads(flag.value)
  except json.JSONDecodeError as e:
    raise app.UsageError(f'--{flag.name} is not valid JSON: {e}') from e
  if not isinstance(value, dict):
    raise app.UsageError(f'--{flag.name} must be a JSON object, got '
                         f'{flag.value!r}')
  return value


def main(argv):
  if len(argv) > 1:
    raise app.UsageError(f'Unexpected arguments: {argv[1:]}')
  task_kwargs = _json_object(_TASK_KWARGS)
  task_kwargs['robot'] = _ROBOT.value
  if _ACTION_SPACE.value is not None:
    task_kwargs['action_space'] = _ACTION_SPACE.value
  if _TIME_LIMIT.value is not None:
    task_kwargs['time_limit'] = _TIME_LIMIT.value
  noise = _json_object(_NOISE) or None
  data = dataset.collect(
      _OUT.value, _DOMAIN.value, _TASK.value, task_kwargs,
      policy=_POLICY.value, episodes=_EPISODES.value, seed=_SEED.value,
      noise_kwargs=noise, progress=_PROGRESS.value)
  episodes = data.metadata['episodes']
  if episodes:
    success = sum(e['success'] for e in episodes) / len(episodes)
    steps = sum(e['steps'] for e in episodes)
    print(f'{data.directory}: {len(episodes)} episodes, {steps} steps, '
          f'success rate {success:.2f}')


if __name__ == '__main__':
  app.run(main)
