"""The rows of an expert evaluation's table: one per task, robot, action
space, policy, people and shield, from its episodes
(evaluation_episodes.run_job), with the success rate's bootstrap
confidence interval, means per episode and the bar each row must reach.
"""

import collections
from typing import Any, Iterable, Mapping, Optional, Sequence

import numpy as np

from hrc_suite import statistics
from hrc_suite.experts import evaluation_episodes as episodes_lib
from hrc_suite.safety.shield import modes as modes_lib

# --shield values: the task's default (DEFAULT_SHIELD) or a registered
# shield mode (hrc_suite/safety/shield/modes.py).
DEFAULT_SHIELD = 'default'
# The bar every expert must reach: success in at least 80 % of
# the episodes of its task, with no critical human contact while the
# person was inside the shield's human model (`critical_inside_model`).
SUCCESS_BAR = 0.8
# Seed of every row's bootstrap resampling (rows are reproducible alone).
BOOTSTRAP_SEED = 0
# Per-episode metrics reported as means per episode, in table order
# (hrc_suite/tasks/runtime/metrics.py).
CONTACT_COLUMNS = (('static', 'contacts_static'), ('self', 'self_collisions'),
                   ('human safe', 'contacts_human_allowed'),
                   ('human critical', 'contacts_human_critical'),
                   ('human pushed', 'contacts_human_pushed'))
SAFETY_COLUMNS = (('steps outside human model', 'steps_outside_human_model'),
                  ('human critical outside model',
                   'contacts_human_critical_outside_model'),
                  ('shield resyncs', 'shield_resyncs'),
                  ('physics errors', 'physics_errors'))
# A table row (`summarise`), JSON-able.
Row = dict[str, Any]


def critical_inside_model(metrics: Mapping[str, float]) -> float:
  """An episode's critical human contacts while the person was inside the
  shield's human model, where its guarantee holds (docs/tasks.md,
  "Metrics").

  Args:
    metrics: the episode's metrics.

  Returns:
    contacts_human_critical less contacts_human_critical_outside_model
    (all of them for episodes run before that metric existed).
  """
  return (metrics['contacts_human_critical']
          - metrics.get('contacts_human_critical_outside_model', 0))


def success_ci(successes: Sequence[float],
               seed: int = BOOTSTRAP_SEED) -> tuple[float, float, float]:
  """The success rate and its 95 % percentile-bootstrap CI (10^4
  resamples, seeded).

  Args:
    successes: 0/1 outcomes.
    seed: the resampling's seed.

  Returns:
    (rate, low, high).
  """
  return statistics.bootstrap_ci(np.asarray(successes, dtype=float),
                                 np.random.RandomState(seed))


def _values(results, name):
  values = [r['metrics'].get(name) for r in results if r['metrics']]
  return [v for v in values if v is not None]


def _mean(results, name):
  values = _values(results, name)
  return float(np.mean(values)) if values else float('nan')


def _episodes_with(results, name):
  """How many episodes have a nonzero `name`; None if none recorded it."""
  values = _values(results, name)
  return sum(1 for v in values if v) if values else None


def summarise(results: Sequence[Mapping[str, Any]]) -> list[Row]:
  """The table's rows.

  Args:
    results: episode results (`evaluation_episodes.run_job`).

  Returns:
    One row per (task, robot, action space, policy, people, shield), in
    first-seen order.
  """
  groups = collections.OrderedDict()
  for result in results:
    choice = episodes_lib.job_fields(result.get('job', ()))[8]
    key = (result['domain'], result['task'], result['robot'],
           result['action_space'], result['policy'],
           episodes_lib.people(result), choice)
    groups.setdefault(key, []).append(result)
  rows = []
  for (domain, task, robot, space, policy, who, choice), group in (
      groups.items()):
    done = [r for r in group if r['metrics']]
    errors = [r for r in group if not r['metrics']]
    # An episode that raised counts as a failure.
    success = [r['metrics']['success'] if r['metrics'] else 0.0
               for r in group]
    rate, low, high = success_ci(success)
    steps = _mean(group, 'steps')
    timestep = next((r['control_timestep'] for r in done), float('nan'))
    distances = _values(group, 'min_human_distance')
    row = {
        'domain': domain, 'task': task, 'robot': robot,
        'action_space': space, 'policy': policy, 'people': who,
        'shield': done[0]['shield'] if done else choice,
        'shield_choice': choice or DEFAULT_SHIELD,
        'episodes': len(group), 'errors': len(errors),
        'first_error': errors[0]['error'] if errors else None,
        'success': rate, 'success_low': low, 'success_high': high,
        'return': _mean(group, 'return'), 'steps': steps,
        'seconds': steps * timestep,
        'shield_interventions': _mean(group, 'shield_interventions'),
        'critical_episodes': sum(
            1 for r in done if r['metrics']['contacts_human_critical']),
        'critical_inside_model_episodes': sum(
            1 for r in done if critical_inside_model(r['metrics'])),
        'pushed_episodes': _episodes_with(group, 'contacts_human_pushed'),
        'physics_error_episodes': _episodes_with(group, 'physics_errors'),
        # m, robot capsules at the command to the person's, over episodes.
        'min_human_distance': min(distances) if distances else float('nan'),
        'wall_time': float(np.mean([r['wall_time'] for r in group])),
    }
    for _, name in CONTACT_COLUMNS + SAFETY_COLUMNS:
      row[name] = _mean(group, name)
    rows.append(row)
  return rows


def shield_gates(shield: Optional[str]) -> bool:
  """Whether a row's shield mode decides the robot's motion.

  Args:
    shield: the row's shield mode; None (a row whose episodes raised
      before reporting it) counts as on.

  Returns:
    True unless the mode does not gate the motion ('off').
  """
  return shield is None or modes_lib.get(shield).gates


def below_bar(row: Mapping[str, Any]) -> list[str]:
  """Reasons a row misses the bar: experts must succeed (SUCCESS_BAR);
  with the shield on no policy may touch the person critically while the
  person is inside the shield's human model; no episode may raise.

  Args:
    row: a row of `summarise`.

  Returns:
    The reasons, empty if it passes.
  """
  reasons = []
  if (row['policy'] in episodes_lib.EXPERT_POLICIES
      and row['success'] < SUCCESS_BAR):
    reasons.append(f'success {row["success"]:.2f} < {SUCCESS_BAR:.2f}')
  inside = row.get('critical_inside_model_episodes',
                   row['critical_episodes'])
  if shield_gates(row['shield']) and inside:
    reasons.append(f'critical human contacts inside the human model in '
                   f'{inside} of {row["episodes"]} episodes')
  if row['errors']:
    reasons.append(f'{row["errors"]} episodes raised ({row["first_error"]})')
  return reasons


def bar_text(rows: Iterable[Mapping[str, Any]]) -> str:
  """The bar of the rows' policies, in words.

  Args:
    rows: rows of `summarise`.

  Returns:
    The text.
  """
  policies = {row['policy'] for row in rows}
  parts = []
  if policies & set(episodes_lib.EXPERT_POLICIES):
    parts.append(f'experts: success >= {SUCCESS_BAR:.0%} and no critical '
                  'human contact inside the human model with the shield on')
  tests = sorted(policies & set(episodes_lib.TEST_POLICIES))
  if tests:
    parts.append(f'{" and ".join(tests)} policy: zero critical human '
                 'contacts inside the human model with the shield on')
  return '; '.join(parts)


def title(rows: Sequence[Mapping[str, Any]]) -> str:
  """The table's title: its policies and, if not synthetic, its people.

  Args:
    rows: the table's rows.

  Returns:
    The title.
  """
  policies = {row['policy'] for row in rows}
  if policies <= set(episodes_lib.EXPERT_POLICIES):
    text = 'Expert baseline'
  elif policies <= set(episodes_lib.TEST_POLICIES):
    text = 'Test-policy safety check'
  else:
    text = 'Expert baseline and test-policy safety check'
  who = list(dict.fromkeys(row['people'] for row in rows))
  if who and who != [episodes_lib.SYNTHETIC]:
    text += f' (people: {", ".join(who)})'
  return text


def row_name(row: Mapping[str, Any]) -> str:
  """A row's name in the text.

  Args:
    row: a row of `summarise`.

  Returns:
    'domain/task robot policy', with its people and shield unless they
    are the synthetic library and the task's default.
  """
  name = f'{row["domain"]}/{row["task"]} {row["robot"]} {row["policy"]}'
  if (row['people'] != episodes_lib.SYNTHETIC
      or row['shield_choice'] != DEFAULT_SHIELD):
    name += f' ({row["people"]} people, shield {row["shield"]})'
  return name


def row_key(result: Mapping[str, Any]) -> str:
  """The table row an episode belongs to.

  Args:
    result: the episode's result (`evaluation_episodes.run_job`).

  Returns:
    'domain/task robot policy action_space' (the job's action space:
    'default' for the task's default), then ' people=<label>' unless
    synthetic and ' shield=<mode>' if chosen.
  """
  (domain, task, robot, space, policy, _, _, motions,
   shield) = episodes_lib.job_fields(result['job'])
  key = f'{domain}/{task} {robot} {policy} {space or "default"}'
  if motions is not None:
    key += f' people={motions[0]}'
  if shield is not None:
    key += f' shield={shield}'
  return key


def task_key(domain: str, task: str,
             motions: episodes_lib.Motions = None) -> str:
  """The key of a task not evaluated.

  Args:
    domain: the task's domain.
    task: the task.
    motions: the people, (label, folder), or None.

  Returns:
    'domain/task', then ' people=<label>' with motions.
  """
  key = f'{domain}/{task}'
  return key if motions is None else f'{key} people={motions[0]}'
