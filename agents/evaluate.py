r"""Deterministic evaluation episodes of a training checkpoint, as a table.

  python -m agents.evaluate --checkpoint=runs/reach_dense/seed0 --episodes=20

--checkpoint is a run's log directory (its latest checkpoint), its
checkpoints/ folder or one checkpoint directory. The environment is the
run's task and robot, seeded from --seed (by default the run seed, through a
stream distinct from training and the training run's evaluations). Prints
the success rate with a 95 % bootstrap confidence interval over episodes,
the return, the episode length, shield interventions and contacts; --output
writes the per-episode metrics and the summary as JSON. --motions=DIR
evaluates on other people than the run's (task_kwargs['motions']: clips,
BVH recordings or one sub-folder per task, docs/motion_library.md), played
with outside_human_model='allow' as experts.evaluate plays them.
"""

import math
import os
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple

from absl import app
from absl import flags
import numpy as np

from agents import checkpoints
from agents import loop as loop_lib
from hrc_suite import statistics
from agents import train as train_lib
from agents import agent_checkpoint

# Seed purpose of evaluate's environment (train uses 0, 1, 2).
_EVALUATE_ENV = 3

# Rows of the table: (label, metric, kind); kind 'rate' gets a bootstrap CI.
_TABLE = (
    ('success rate', 'success', 'rate'),
    ('return', 'episode_return', 'mean'),
    ('episode length', 'episode_length', 'mean'),
    ('shield interventions', 'shield_interventions', 'mean'),
    ('action replacements', 'action_replacements', 'mean'),
    ('static contacts', 'contacts_static', 'mean'),
    ('allowed human contacts', 'contacts_human_allowed', 'mean'),
    ('critical human contacts', 'contacts_human_critical', 'mean'),
    ('pushed human contacts', 'contacts_human_pushed', 'mean'),
    ('shield resyncs', 'shield_resyncs', 'mean'),
    ('physics errors', 'physics_errors', 'mean'),
    ('self collisions', 'self_collisions', 'mean'),
    ('min human distance [m]', 'min_human_distance', 'min'),
)


def summary(episodes: Sequence[Mapping[str, float]],
            random_state: np.random.RandomState
            ) -> Dict[str, Dict[str, float]]:
  """The table's statistics over the episodes.

  Args:
    episodes: per-episode metrics (loop.evaluate's).
    random_state: the bootstrap's random numbers.

  Returns:
    {metric: {'mean', 'low', 'high'} (rates, a 95 % bootstrap CI),
    {'mean', 'std'} or {'min'}}.
  """
  result = {}
  for _, name, kind in _TABLE:
    if name not in episodes[0]:
      continue
    values = np.array([e[name] for e in episodes], dtype=float)
    if kind == 'min':
      result[name] = {'min': float(values.min())}
    elif kind == 'rate':
      mean, low, high = statistics.bootstrap_ci(values, random_state)
      result[name] = {'mean': mean, 'low': low, 'high': high}
    else:
      result[name] = {'mean': float(values.mean()),
                      'std': float(values.std())}
  return result


def format_table(result: Mapping[str, Mapping[str, float]],
                 episodes: int) -> str:
  """The summary as a text table.

  Args:
    result: of `summary`.
    episodes: the number of episodes.

  Returns:
    The table's lines.
  """
  lines = [f'{"metric":<26} {"value":>30}', '-' * 57]
  for label, name, kind in _TABLE:
    if name not in result:
      continue
    entry = result[name]
    if kind == 'min':
      value = f'{entry["min"]:.3f}'
    elif kind == 'rate':
      value = (f'{entry["mean"]:.2f} [{entry["low"]:.2f}, '
               f'{entry["high"]:.2f}] 95% CI')
    else:
      value = f'{entry["mean"]:.3f} +- {entry["std"]:.3f}'
    lines.append(f'{label:<26} {value:>30}')
  lines.append(f'({episodes} deterministic episodes)')
  return '\n'.join(lines)


def run(checkpoint: str, episodes: int, seed: Optional[int] = None,
        motions: Optional[str] = None
        ) -> Tuple[List[Dict[str, float]], Dict[str, Dict[str, float]]]:
  """Evaluates a checkpoint with deterministic episodes.

  Args:
    checkpoint: a run's log directory, its checkpoints/ folder or a
      checkpoint directory.
    episodes: episodes to run.
    seed: the environment's seed (None: derived from the run seed).
    motions: None (the run's people) or a folder of motions for the task
      (task_kwargs['motions'], played with outside_human_model='allow').

  Returns:
    (per-episode metrics, summary).

  Raises:
    ValueError: a path that holds no checkpoint.
  """
  directory = checkpoints.resolve(checkpoint)
  loop_state, _ = checkpoints.load_loop_state(directory)
  run_config = loop_state['run_config']
  if motions is not None:
    if not os.path.isdir(motions):
      raise ValueError(f'motions={motions!r}: expected a folder of motions')
    run_config = dict(run_config, task_kwargs=dict(
        run_config['task_kwargs'], motions=motions,
        outside_human_model='allow'))
  if seed is None:
    seed = train_lib.derived_seed(run_config['seed'], _EVALUATE_ENV)
  env = train_lib.make_environment(run_config, seed)
  policy = agent_checkpoint.load_policy(
      os.path.join(directory, checkpoints.AGENT_DIR), env,
      deterministic=True)
  results = loop_lib.evaluate(env, policy, episodes)
  return results, summary(results, np.random.RandomState(seed))


def define_flags(flag_values: flags.FlagValues = flags.FLAGS) -> None:
  """Defines the binary's flags (only when run as a program).

  Args:
    flag_values: where to define them.
  """
  fv = flag_values
  flags.DEFINE_string('checkpoint', None, 'Checkpoint or run directory.',
                      required=True, flag_values=fv)
  flags.DEFINE_integer('episodes', 20, 'Episodes to run.', flag_values=fv)
  flags.DEFINE_integer('seed', None, 'Environment seed (default: derived '
                       'from the run seed).', flag_values=fv)
  flags.DEFINE_string('output', None, 'JSON file for the results.',
                      flag_values=fv)
  flags.DEFINE_string('motions', None, "A folder of people for the task "
                      "(task_kwargs['motions']: clips, BVH recordings or one "
                      "sub-folder per task), played with outside_human_model="
                      "'allow' (default: the run's).", flag_values=fv)


def main(argv: Sequence[str],
         flag_values: flags.FlagValues = flags.FLAGS) -> None:
  """Evaluates --checkpoint, prints the table, writes --output.

  Args:
    argv: the command line (unused).
    flag_values: the parsed flags.
  """
  del argv
  f = flag_values
  if f.motions is not None and not os.path.isdir(f.motions):
    raise app.UsageError(f'--motions={f.motions}: not a folder')
  results, table = run(f.checkpoint, f.episodes, f.seed, f.motions)
  print(f'checkpoint: {checkpoints.resolve(f.checkpoint)}')
  if f.motions:
    print(f'motions: {f.motions}')
  print(format_table(table, len(results)))
  if f.output:
    checkpoints.write_json(f.output, finite({'summary': table,
                                             'episodes': results}))


def finite(value: Any) -> Any:
  """A copy with non-finite floats as None (strict JSON).

  Args:
    value: nested dicts, lists and scalars.

  Returns:
    The copy.
  """
  if isinstance(value, dict):
    return {k: finite(v) for k, v in value.items()}
  if isinstance(value, list):
    return [finite(v) for v in value]
  if isinstance(value, float) and not math.isfinite(value):
    return None
  return value


if __name__ == '__main__':
  define_flags()
  app.run(main)
