r"""Tables comparing shield modes on the same episodes, from a results file
of `python -m hrc_suite.experts.evaluate` (docs/results/pfl_energy.md).

  python scripts/shield_comparison.py docs/results/pfl_energy.json \
      --baseline=pfl --other=pfl_energy

Prints, per task, one row per robot, people and shield: episodes, success
with its 95 % bootstrap interval, episode length, the time of the task's
first event (its first counter's first count: time_to/<counter> of
experts/pace.py, the mean over the episodes that have one, and how many
do), shield interventions per episode, episodes with a critical human
contact, the largest contact energy ratio, the robot's mean speed and its
mean and largest speed near the person, and the number of RL steps near
the person per episode; then, per task, robot and people, what --other
changes against --baseline (ratios of the means).
"""

import argparse
import collections
import json
import math
import os
import pathlib
import sys

import numpy as np

# The checkout this script belongs to, before an installed hrc_suite.
sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(
    __file__))))
# pylint: disable=wrong-import-position
from hrc_suite import suite
from hrc_suite.experts import evaluation_report
from hrc_suite.experts import evaluation_rows
from hrc_suite.experts import results_file

COLUMNS = ('robot', 'people', 'shield', 'episodes', 'success [95 % CI]',
           'length (s)', 'first {event} (s)', 'episodes with {event}',
           'interventions', 'critical-contact episodes',
           'max contact energy ratio', 'speed mean (m/s)',
           'speed near person mean (m/s)', 'speed near person max (m/s)',
           'steps near person')


def load(path):
  """The episodes of a results JSON or of its .partial.jsonl."""
  path = pathlib.Path(path)
  if path.suffix == '.jsonl':
    return [json.loads(line) for line in path.read_text().splitlines()
            if line.strip()]
  return results_file.episodes(json.loads(path.read_text()))


def first_event(domain, task):
  """The task's first counter (EXTRA_COUNTERS), e.g. handovers."""
  counters = suite.task_class(domain, task).defaults().extra_counters
  return counters[0] if counters else None


def _mean(values):
  values = [v for v in values if v is not None and math.isfinite(v)]
  return float(np.mean(values)) if values else math.nan


def summarise(episodes):
  """{(domain, task): [row dict]} in first-seen order."""
  groups = collections.OrderedDict()
  for e in episodes:
    key = (e['domain'], e['task'], e['robot'], e['people'], e['shield'])
    groups.setdefault(key, []).append(e)
  tables = collections.OrderedDict()
  for (domain, task, robot, people, shield), group in groups.items():
    event = first_event(domain, task)
    metrics = [e['metrics'] or {} for e in group]
    def values(name):
      return [m.get(name) for m in metrics]
    rate, low, high = evaluation_rows.success_ci(
        [m.get('success') or 0.0 for m in metrics])
    times = [v for v in values(f'time_to/{event}') if v is not None]
    step = group[0]['control_timestep'] or math.nan
    tables.setdefault((domain, task), []).append({
        'robot': robot, 'people': people, 'shield': shield,
        'event': event, 'episodes': len(group),
        'errors': sum(1 for e in group if e['metrics'] is None),
        'success': (rate, low, high),
        'length': _mean(values('steps')) * step,
        'first_event': _mean(times), 'event_episodes': len(times),
        'interventions': _mean(values('shield_interventions')),
        'critical': sum(1 for v in values('contacts_human_critical')
                        if v),
        'energy_ratio': max((v for v in values('max_contact_energy_ratio')
                             if v is not None), default=math.nan),
        'speed': _mean(values('robot_speed_mean')),
        'near_speed': _mean([m.get('robot_speed_near_mean') for m in metrics
                             if m.get('near_steps')]),
        'near_max': max((v for v in values('robot_speed_near_max')
                         if v is not None), default=math.nan),
        'near_steps': _mean(values('near_steps'))})
  return tables


def _cell(value, digits=2):
  return evaluation_report.MISSING if not math.isfinite(value) else (
      f'{value:.{digits}f}')


def markdown(tables):
  lines = []
  for (domain, task), rows in tables.items():
    event = rows[0]['event'] or 'event'
    lines += [f'### {domain}/{task}', '',
              '| ' + ' | '.join(c.format(event=event) for c in COLUMNS)
              + ' |', '|' + '---|' * len(COLUMNS)]
    for r in rows:
      rate, low, high = r['success']
      lines.append('| ' + ' | '.join([
          r['robot'], r['people'], r['shield'], str(r['episodes']),
          f'{rate:.2f} [{low:.2f}, {high:.2f}]', _cell(r['length'], 1),
          _cell(r['first_event'], 1), str(r['event_episodes']),
          _cell(r['interventions'], 1), str(r['critical']),
          _cell(r['energy_ratio']), _cell(r['speed'], 3),
          _cell(r['near_speed'], 3), _cell(r['near_max'], 3),
          _cell(r['near_steps'], 1)]) + ' |')
    lines.append('')
  return '\n'.join(lines)


def changes(tables, baseline, other):
  """Markdown: per task, robot and people, other / baseline."""
  lines = [f'| task | robot | people | length | first event | '
           f'speed mean | speed near person mean |',
           '|---|---|---|---|---|---|---|']
  for (domain, task), rows in tables.items():
    by = {(r['robot'], r['people'], r['shield']): r for r in rows}
    for (robot, people, shield), base in by.items():
      if shield != baseline or (robot, people, other) not in by:
        continue
      new = by[(robot, people, other)]
      ratio = [new[k] / base[k] if base[k] else math.nan
               for k in ('length', 'first_event', 'speed', 'near_speed')]
      lines.append(f'| {domain}/{task} | {robot} | {people} | '
                   + ' | '.join(f'x{_cell(x)}' for x in ratio) + ' |')
  return '\n'.join(lines)


def main(argv=None):
  parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
  parser.add_argument('results', help='results JSON (or .partial.jsonl)')
  parser.add_argument('--baseline', default='pfl')
  parser.add_argument('--other', default='pfl_energy')
  args = parser.parse_args(argv)
  tables = summarise(load(args.results))
  print(markdown(tables))
  print(changes(tables, args.baseline, args.other))


if __name__ == '__main__':
  main()
