r"""Throughput of SAC training on an hrc_suite task: RL steps per second.

  python -m agents.benchmark            # reach/dense, Schunk, Cartesian

Measures, after a warm-up that fills the replay and compiles the learner:

* training: the full loop (environment with the shield and the moving
  person, the SAC actor, one SAC update per environment step with batch
  256), timed over --steps environment steps;
* environment only: the same environment with uniform random actions;
* update only: SAC gradient steps on replay samples (batch 256);
* actor only: select_action on observations.

Prints wall-clock time and process CPU time (all threads; it counts work
that other processes' preemption would hide from wall clock). The issue's
target: 1000 training RL steps in under 10 s on 2 cores, against the
reference's 17.61 s on ten cores (reference-benchmark.md).
"""

import time

from absl import app
from absl import flags
import jax
import numpy as np

from agents import config as config_lib
from agents import loop as loop_lib
from agents import specs as specs_lib
from agents.sac import agent as agent_lib
from hrc_suite import suite

# The paper's cost figure: seconds per 10^3 RL steps of training on ten
# cores of an AMD EPYC 7763 (reference-benchmark.md).
REFERENCE_SECONDS_PER_1000_STEPS = 17.61


def make_environment(robot='schunk', seed=0):
  """reach/dense, Cartesian, default shield (SSM) and human motions."""
  return suite.load('reach', 'dense',
                    task_kwargs={'robot': robot, 'action_space': 'cartesian'},
                    environment_kwargs={'random_state': seed})


def _timed(function):
  wall, cpu = time.perf_counter(), time.process_time()
  function()
  return time.perf_counter() - wall, time.process_time() - cpu


def measure(steps=1000, warmup=300, batch_size=256, hidden_sizes=(256, 256),
            robot='schunk', seed=0):
  """{section: (steps, wall s, cpu s)} of the four measurements."""
  if warmup < batch_size + 2:
    raise ValueError(f'warmup ({warmup}) must exceed batch_size '
                     f'({batch_size}) so that updates (and their compilation)'
                     ' happen during the warm-up')
  env = make_environment(robot, seed)
  config = config_lib.default_config(
      batch_size=batch_size, hidden_sizes=tuple(hidden_sizes),
      min_replay_size=batch_size, updates_per_step=1.0, update_every=1)
  agent = agent_lib.SACAgent(specs_lib.make_environment_spec(env), config,
                             seed=seed)
  training = loop_lib.EnvironmentLoop(env, agent)
  training.run(num_steps=warmup)   # Fills the replay, compiles the update.
  results = {}
  results['training'] = (steps,) + _timed(
      lambda: training.run(num_steps=steps))

  random_agent = loop_lib.RandomAgent(env.action_spec(), seed)
  env_loop = loop_lib.EnvironmentLoop(env, random_agent,
                                      should_update=False)
  results['environment only'] = (steps,) + _timed(
      lambda: env_loop.run(num_steps=steps))

  def updates():
    for _ in range(steps):
      agent.learn(1)
    # Updates are dispatched asynchronously: wait for the last one.
    jax.block_until_ready(agent.learner.training_state)
  results['update only'] = (steps,) + _timed(updates)

  observation = env.reset().observation
  agent.select_action(observation)   # Compiled already; one more to be sure.

  def actions():
    for _ in range(steps):
      agent.select_action(observation)
  results['actor only'] = (steps,) + _timed(actions)
  return results


def format_results(results):
  lines = [f'{"section":<18} {"steps":>6} {"wall [s]":>9} {"cpu [s]":>8} '
           f'{"steps/s":>8} {"s/1000":>7}', '-' * 62]
  for name, (steps, wall, cpu) in results.items():
    lines.append(f'{name:<18} {steps:>6d} {wall:>9.2f} {cpu:>8.2f} '
                 f'{steps / wall:>8.1f} {1000 * wall / steps:>7.2f}')
  steps, wall, _ = results['training']
  lines.append(f'training: {1000 * wall / steps:.2f} s per 1000 RL steps '
               f'(target < 10 s; reference {REFERENCE_SECONDS_PER_1000_STEPS}'
               ' s on ten cores)')
  return '\n'.join(lines)


def define_flags(flag_values=flags.FLAGS):
  """Defines the binary's flags (only when run as a program)."""
  fv = flag_values
  flags.DEFINE_integer('steps', 1000, 'Timed steps per section.',
                       flag_values=fv)
  flags.DEFINE_integer('warmup', 300, 'Training steps before timing.',
                       flag_values=fv)
  flags.DEFINE_integer('batch_size', 256, 'SAC batch size.', flag_values=fv)
  flags.DEFINE_list('hidden_sizes', ['256', '256'], 'MLP hidden sizes.',
                    flag_values=fv)
  flags.DEFINE_string('robot', 'schunk', 'Robot.', flag_values=fv)
  flags.DEFINE_integer('seed', 0, 'Seed.', flag_values=fv)


def main(argv, flag_values=flags.FLAGS):
  del argv
  f = flag_values
  results = measure(steps=f.steps, warmup=f.warmup, batch_size=f.batch_size,
                    hidden_sizes=[int(h) for h in f.hidden_sizes],
                    robot=f.robot, seed=f.seed)
  print('reach/dense, {}, Cartesian, SSM shield, person moving; one SAC '
        'update (batch {}, MLP {}) per RL step'.format(
            f.robot, f.batch_size, 'x'.join(f.hidden_sizes)))
  print(format_results(results))


if __name__ == '__main__':
  define_flags()
  app.run(main)
