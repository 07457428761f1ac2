"""The results file of `experts.evaluate`: episodes stored row by row.

A results JSON holds 'runs' (the commands behind the table), 'rows' (the
table's rows), 'episode_groups', 'not_evaluated' and, if any, 'notes'.
A group is a run of consecutive episodes of one job but for its seed:

  {"job": the job without its seed (evaluation_episodes.run_job; null: no job),
   "fields": {name: the value every episode of the group has},
   "columns": {name: [one value per episode]}   (seed, wall_time, clip...),
   "metrics": {name: [one value per episode]}}

Metrics keep METRIC_DIGITS significant digits and wall times
WALL_TIME_DECIMALS decimals; integral values are written without a
fraction and read back as floats. A metric is null where its episode did
not record it or it was not finite; an episode without metrics (one that
raised) has null in every metric. Files with one dict per episode (the
list 'episodes') read as well.
"""

import itertools
import json
import math
from typing import Any, Mapping, Optional, Sequence, Union

# Significant digits of a stored metric: with 6 every mean the tables of
# docs/results (experts.md, robots_sweep.md, safety_real.md) print is the
# one of the unrounded episodes; with 5 three returns of safety_real.md
# (up to -2369.6) change in their last printed digit.
METRIC_DIGITS = 6
# Decimals of a stored wall time (s): a millisecond, below the table's
# 0.1 s.
WALL_TIME_DECIMALS = 3
# Index of the seed in a job (evaluation_episodes.run_job).
_SEED_INDEX = 6
# Episode keys stored apart from 'fields' and 'columns'.
_STRUCTURED = ('job', 'metrics')


def round_metric(value: Optional[float]) -> Optional[Union[int, float]]:
  """`value` to METRIC_DIGITS significant digits (None stays None).

  Args:
    value: a number or None.

  Returns:
    The rounded float, an int if it is integral, or None.
  """
  if value is None:
    return None
  value = float(f'{float(value):.{METRIC_DIGITS}g}')
  if not math.isfinite(value):
    return None
  return int(value) if value.is_integer() else value


def round_row(row: Mapping[str, Any]) -> dict[str, Any]:
  """A table row with its floats to METRIC_DIGITS significant digits.

  Args:
    row: a row of evaluation_rows.summarise.

  Returns:
    A new dict; floats stay floats, non-finite ones become None.
  """
  rounded = {}
  for key, value in row.items():
    if isinstance(value, float):
      value = round_metric(value)
      value = None if value is None else float(value)
    rounded[key] = value
  return rounded


def _without_seed(episode, index):
  job = episode.get('job')
  if job is None:
    return None
  job = list(job)
  if len(job) <= _SEED_INDEX or job[_SEED_INDEX] != episode.get('seed'):
    raise ValueError(
        f'episode {index}: job {job!r} does not carry the episode\'s seed '
        f'{episode.get("seed")!r} at index {_SEED_INDEX}')
  return job[:_SEED_INDEX] + job[_SEED_INDEX + 1:]


def _stored(name, value):
  if name == 'wall_time' and value is not None:
    return round(float(value), WALL_TIME_DECIMALS)
  return value


def _group(job, episodes):
  keys = list(dict.fromkeys(key for episode in episodes for key in episode
                            if key not in _STRUCTURED))
  fields, columns = {}, {}
  for key in keys:
    values = [_stored(key, episode.get(key)) for episode in episodes]
    if all(v == values[0] for v in values) and all(key in episode
                                                   for episode in episodes):
      fields[key] = values[0]
    else:
      columns[key] = values
  names = list(dict.fromkeys(name for episode in episodes
                             for name in (episode.get('metrics') or {})))
  metrics = {name: [round_metric((episode.get('metrics') or {}).get(name))
                    for episode in episodes] for name in names}
  return {'job': job, 'fields': fields, 'columns': columns,
          'metrics': metrics}


def pack(episodes: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
  """The episode groups of `episodes` (evaluation_episodes.run_job results).

  Args:
    episodes: result dicts, in table order.

  Returns:
    A list of groups (module doc), in the episodes' order.

  Raises:
    ValueError: an episode whose job does not carry its seed.
  """
  keyed = [(json.dumps(_without_seed(episode, i)), episode)
           for i, episode in enumerate(episodes)]
  return [_group(json.loads(key), [episode for _, episode in run])
          for key, run in itertools.groupby(keyed, key=lambda kv: kv[0])]


def _episodes(group):
  columns = group.get('columns') or {}
  metrics = group.get('metrics') or {}
  sizes = {len(values) for values in
           itertools.chain(columns.values(), metrics.values())}
  if len(sizes) > 1:
    raise ValueError(f'group of job {group.get("job")!r}: columns of '
                     f'different lengths {sorted(sizes)}')
  count = sizes.pop() if sizes else 1
  episodes = []
  for i in range(count):
    episode = dict(group.get('fields') or {})
    episode.update({key: values[i] for key, values in columns.items()})
    values = {name: values[i] for name, values in metrics.items()}
    episode['metrics'] = (
        {name: None if v is None else float(v) for name, v in values.items()}
        if any(v is not None for v in values.values()) else None)
    if group.get('job') is not None:
      job = list(group['job'])
      episode['job'] = (job[:_SEED_INDEX] + [episode.get('seed')]
                        + job[_SEED_INDEX:])
    episodes.append(episode)
  return episodes


def unpack(groups: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
  """The episodes (one dict each, as evaluation_episodes.run_job returns) of
  `groups`.

  Args:
    groups: episode groups (module doc).

  Returns:
    The episodes, in order.

  Raises:
    ValueError: a group whose columns differ in length.
  """
  return [episode for group in groups for episode in _episodes(group)]


def episodes(payload: Mapping[str, Any]) -> list[dict[str, Any]]:
  """The episodes of a results file's payload, of either layout.

  Args:
    payload: the parsed JSON.

  Returns:
    The episodes, one dict each.

  Raises:
    KeyError: neither 'episode_groups' nor 'episodes'.
  """
  if 'episode_groups' in payload:
    return unpack(payload['episode_groups'])
  return payload['episodes']


def _flat(value):
  """Whether `value` is written on one line: no dict inside a list, no
  container inside a dict."""
  if isinstance(value, dict):
    return not any(isinstance(v, (dict, list)) for v in value.values())
  if isinstance(value, list):
    return not any(isinstance(v, dict) for v in value)
  return True


def dumps(value: Any, indent: int = 0) -> str:
  """JSON of `value`: a container of containers one item per line,
  anything flatter (_flat) on one line.

  Args:
    value: JSON-able data without NaN or infinities.
    indent: the indentation of `value`'s own line.

  Returns:
    The text, without a final newline.
  """
  if _flat(value):
    return json.dumps(value, separators=(',', ':'), allow_nan=False)
  pad = ' ' * (indent + 1)
  if isinstance(value, dict):
    items = [f'{pad}{json.dumps(key)}: {dumps(item, indent + 1)}'
             for key, item in value.items()]
    brackets = '{}'
  else:
    items = [pad + dumps(item, indent + 1) for item in value]
    brackets = '[]'
  return (brackets[0] + '\n' + ',\n'.join(items) + '\n' + ' ' * indent
          + brackets[1])
