r"""Digests of expert episodes: proof that a change keeps every episode.

  python scripts/episode_hashes.py --compare=scripts/episode_hashes.json
  python scripts/episode_hashes.py --out=before.json   # before a change

For every registered task with an expert (or --tasks) on every robot of
--robots, runs --episodes deterministic expert episodes from seeds 0, 1,
... (at most --steps RL steps each) and hashes, step by step, what the
episode is: the physics state (qpos, qvel, act, mocap poses, the weld
constraints' data and activity), the action, the reward, the discount,
every observation and the task's step metrics. Equal digests mean the
same episodes bit for bit; --compare lists the pairs that differ and
exits 1 if any does. scripts/episode_hashes.json holds the digests of the
current code's episodes with the defaults (the development machine's MuJoCo 3.17.0
and NumPy; another CPU or library version may change the last bits): a
change that alters episodes on purpose records new ones and says so in
CHANGELOG.md.
"""

import argparse
import hashlib
import json
import os
import sys
import time

import numpy as np

# The checkout this script belongs to, before an installed hrc_suite: the
# script proves what its own tree computes.
sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(
    __file__))))
from hrc_suite import experts   # pylint: disable=wrong-import-position
from hrc_suite import suite   # pylint: disable=wrong-import-position


def _update(digest, value):
  array = np.ascontiguousarray(np.asarray(value))
  digest.update(str(array.dtype).encode())
  digest.update(str(array.shape).encode())
  digest.update(array.tobytes())


def _physics_state(physics):
  data, model = physics.data, physics.model
  parts = [data.qpos, data.qvel, data.act, data.mocap_pos, data.mocap_quat]
  if model.neq:
    parts += [model.eq_data, data.eq_active]
  return parts


def episode_digest(domain, task, robot, seed, max_steps):
  """(sha256 hex digest, RL steps) of one expert episode."""
  env = suite.load(domain, task, task_kwargs={'robot': robot, 'seed': seed})
  expert = experts.make(env)
  digest = hashlib.sha256()
  timestep = env.reset()
  steps = 0
  while not timestep.last() and steps < max_steps:
    action = expert(timestep)
    timestep = env.step(action)
    steps += 1
    _update(digest, action)
    for value in (timestep.reward, timestep.discount):
      _update(digest, np.float64(value))
    for name in sorted(timestep.observation):
      digest.update(name.encode())
      _update(digest, timestep.observation[name])
    for value in _physics_state(env.physics):
      _update(digest, value)
    metrics = env.task.step_metrics
    for name in sorted(metrics):
      digest.update(name.encode())
      _update(digest, np.float64(metrics[name]))
  return digest.hexdigest(), steps


def main(argv=None):
  parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
  parser.add_argument('--robots', default='schunk,panda,ur5e')
  parser.add_argument('--tasks', default=None,
                      help='domain/task,... (default: every task with an '
                      'expert)')
  parser.add_argument('--episodes', type=int, default=1)
  parser.add_argument('--steps', type=int, default=300,
                      help='RL steps per episode at most')
  parser.add_argument('--out', default=None, help='write the digests here')
  parser.add_argument('--compare', default=None,
                      help='digests file to compare against')
  args = parser.parse_args(argv)
  if args.tasks:
    tasks = [tuple(name.split('/')) for name in args.tasks.split(',')]
  else:
    tasks = list(experts.registered())
  result = {}
  for domain, task in tasks:
    for robot in args.robots.split(','):
      for seed in range(args.episodes):
        key = f'{domain}/{task}/{robot}/seed{seed}'
        began = time.perf_counter()
        digest, steps = episode_digest(domain, task, robot, seed, args.steps)
        result[key] = {'digest': digest, 'steps': steps}
        print(f'{key}: {digest[:16]} ({steps} steps, '
              f'{time.perf_counter() - began:.1f} s)', flush=True)
  if args.out:
    with open(args.out, 'w') as f:
      json.dump(result, f, indent=1, sort_keys=True)
      f.write('\n')
  if args.compare:
    with open(args.compare) as f:
      reference = json.load(f)
    unknown = sorted(key for key in result if key not in reference)
    differ = sorted(key for key in result
                    if key in reference and reference[key] != result[key])
    for key in differ:
      print(f'DIFFERS {key}: {reference[key]} -> {result[key]}')
    for key in unknown:
      print(f'NOT IN {args.compare}: {key}')
    print(f'{len(result) - len(differ) - len(unknown)} of {len(result)} '
          f'episodes equal ({len(reference)} in {args.compare})')
    return 1 if differ or unknown else 0
  return 0


if __name__ == '__main__':
  sys.exit(main())
