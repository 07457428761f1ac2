r"""Throughput of SAC training on an hrc_suite task: RL steps per second.

  python -m agents.benchmark --hidden_sizes=64,64,64   # the paper's networks

reach/dense, Schunk, Cartesian actions. Measures, after a warm-up that
fills the replay and compiles the learner:

* training: the full loop (environment with the shield and the moving
  person, the SAC actor, one SAC gradient step per environment step with
  batch 256, --fused_steps of them per learner call), timed over --steps
  environment steps;
* environment only: the same environment with uniform random actions;
* update, 1 per call / update, N per call: --steps SAC gradient steps on
  replay samples, one per learner call and --fused_steps per call (the
  learner's cost alone, independent of the environment);
* actor only: select_action on observations.

Prints wall-clock time, process CPU time (all threads: it counts the
learner's compute on the other core, and work that other processes'
preemption would hide from wall clock) and the main thread's CPU time (the
core the environment steps on). docs/benchmarks.md, "SAC training
throughput", holds the measurements and the target: at most 3 s per 1000
training RL steps with the paper's (64, 64, 64) networks.
"""

import os
import time
from typing import Dict, Mapping, Optional, Sequence, Tuple

from absl import app
from absl import flags
import jax

from agents import config as config_lib
from agents import loop as loop_lib
from agents import specs as specs_lib
from agents.sac import agent as agent_lib
from hrc_suite import suite

# The paper's cost figure: seconds per 10^3 RL steps of training on ten
# cores of an AMD EPYC 7763 (docs/reference_benchmark.md, Training and
# evaluation).
REFERENCE_SECONDS_PER_1000_STEPS = 17.61
# Training target on this 2-core machine, environment and updates included
# (docs/benchmarks.md, "SAC training throughput").
TARGET_SECONDS_PER_1000_STEPS = 3.0
# A section's (steps, wall s, process cpu s, main-thread cpu s).
Timing = Tuple[int, float, float, float]


def make_environment(robot: str = 'schunk', seed: int = 0,
                     motions: Optional[str] = None) -> suite.Environment:
  """reach/dense, Cartesian, default shield (SSM) and human motions.

  Args:
    robot: the robot.
    seed: the environment's seed.
    motions: a folder of people, played with outside_human_model='allow'
      (None: the shipped library).

  Returns:
    The environment.
  """
  task_kwargs = {'robot': robot, 'action_space': 'cartesian'}
  if motions is not None:
    task_kwargs.update(motions=motions, outside_human_model='allow')
  return suite.load('reach', 'dense', task_kwargs=task_kwargs,
                    environment_kwargs={'random_state': seed})


def _timed(function):
  """(wall s, process CPU s, this thread's CPU s) of function()."""
  wall, cpu = time.perf_counter(), time.process_time()
  thread = time.thread_time()
  function()
  return (time.perf_counter() - wall, time.process_time() - cpu,
          time.thread_time() - thread)


def measure(steps: int = 1000, warmup: int = 300, batch_size: int = 256,
            hidden_sizes: Sequence[int] = (256, 256),
            fused_steps: int = config_lib.FUSED_STEPS, robot: str = 'schunk',
            seed: int = 0, motions: Optional[str] = None
            ) -> Dict[str, Timing]:
  """Times the sections (module doc).

  Args:
    steps: timed steps per section.
    warmup: training steps before timing (> batch_size + 2 fused_steps).
    batch_size: SAC's batch size.
    hidden_sizes: the MLPs' hidden sizes.
    fused_steps: gradient steps per learner call.
    robot: the robot.
    seed: the seed.
    motions: a folder of people (`make_environment`), or None.

  Returns:
    {section: (steps, wall s, cpu s, main-thread cpu s)}.

  Raises:
    ValueError: a warmup too short to compile the updates.
  """
  if warmup < batch_size + 2 * fused_steps:
    raise ValueError(f'warmup ({warmup}) must exceed batch_size '
                     f'({batch_size}) + 2 fused_steps ({fused_steps}) so '
                     'that updates (and their compilation) happen during '
                     'the warm-up')
  env = make_environment(robot, seed, motions)
  config = config_lib.default_config(
      batch_size=batch_size, hidden_sizes=tuple(hidden_sizes),
      min_replay_size=batch_size, updates_per_step=1.0,
      fused_steps=fused_steps)
  agent = agent_lib.SACAgent(specs_lib.make_environment_spec(env), config,
                             seed=seed)
  training = loop_lib.EnvironmentLoop(env, agent)
  training.run(num_steps=warmup)   # Fills the replay, compiles the update.

  def train():
    training.run(num_steps=steps)
    # Updates are dispatched asynchronously: wait for the last one.
    jax.block_until_ready(agent.learner.training_state)
  results = {'training': (steps,) + _timed(train)}

  random_agent = loop_lib.RandomAgent(env.action_spec(), seed)
  env_loop = loop_lib.EnvironmentLoop(env, random_agent,
                                      should_update=False)
  results['environment only'] = (steps,) + _timed(
      lambda: env_loop.run(num_steps=steps))

  for per_call in sorted({1, fused_steps}):
    agent.learn(per_call)   # Compiles it (1 per call is not in training).
    jax.block_until_ready(agent.learner.training_state)

    def updates(per_call=per_call):
      for _ in range(steps // per_call):
        agent.learn(per_call)
      jax.block_until_ready(agent.learner.training_state)
    results[f'update, {per_call} per call'] = (
        steps // per_call * per_call,) + _timed(updates)

  observation = env.reset().observation
  agent.select_action(observation)   # Compiled already; one more to be sure.

  def actions():
    for _ in range(steps):
      agent.select_action(observation)
  results['actor only'] = (steps,) + _timed(actions)
  return results


def format_results(results: Mapping[str, Timing]) -> str:
  """A table of the sections, per step and per 1000 steps.

  Args:
    results: of `measure` (with 'training').

  Returns:
    The table.
  """
  lines = [f'{"section":<20} {"steps":>6} {"wall [s]":>9} {"cpu [s]":>8} '
           f'{"main cpu":>8} {"steps/s":>8} {"s/1000":>7} {"cpu/1000":>8} '
           f'{"main/1000":>9}', '-' * 92]
  for name, (steps, wall, cpu, main) in results.items():
    lines.append(f'{name:<20} {steps:>6d} {wall:>9.2f} {cpu:>8.2f} '
                 f'{main:>8.2f} {steps / wall:>8.1f} '
                 f'{1000 * wall / steps:>7.2f} {1000 * cpu / steps:>8.2f} '
                 f'{1000 * main / steps:>9.2f}')
  steps, wall, _, _ = results['training']
  lines.append(f'training: {1000 * wall / steps:.2f} s per 1000 RL steps '
               f'(target <= {TARGET_SECONDS_PER_1000_STEPS:g} s with (64, '
               f'64, 64) networks; reference '
               f'{REFERENCE_SECONDS_PER_1000_STEPS} s on ten cores)')
  return '\n'.join(lines)


def define_flags(flag_values: flags.FlagValues = flags.FLAGS) -> None:
  """Defines the binary's flags (only when run as a program).

  Args:
    flag_values: where to define them.
  """
  fv = flag_values
  flags.DEFINE_integer('steps', 1000, 'Timed steps per section.',
                       flag_values=fv)
  flags.DEFINE_integer('warmup', 300, 'Training steps before timing.',
                       flag_values=fv)
  flags.DEFINE_integer('batch_size', 256, 'SAC batch size.', flag_values=fv)
  flags.DEFINE_list('hidden_sizes', ['256', '256'], 'MLP hidden sizes.',
                    flag_values=fv)
  flags.DEFINE_integer('fused_steps', config_lib.FUSED_STEPS,
                       'Gradient steps per learner call (SACConfig).',
                       flag_values=fv)
  flags.DEFINE_string('robot', 'schunk', 'Robot.', flag_values=fv)
  flags.DEFINE_integer('seed', 0, 'Seed.', flag_values=fv)
  flags.DEFINE_string('motions', None, "A folder of people for reach/dense "
                      "(task_kwargs['motions']; docs/motion_library.md), "
                      "played with outside_human_model='allow' (default: the "
                      'shipped synthetic library).', flag_values=fv)


def main(argv: Sequence[str],
         flag_values: flags.FlagValues = flags.FLAGS) -> None:
  """Measures with the flags' settings and prints the table.

  Args:
    argv: the command line (unused).
    flag_values: the parsed flags.
  """
  del argv
  f = flag_values
  if f.motions is not None and not os.path.isdir(f.motions):
    raise app.UsageError(f'--motions={f.motions}: not a folder')
  results = measure(steps=f.steps, warmup=f.warmup, batch_size=f.batch_size,
                    hidden_sizes=[int(h) for h in f.hidden_sizes],
                    fused_steps=f.fused_steps, robot=f.robot, seed=f.seed,
                    motions=f.motions)
  print('reach/dense, {}, Cartesian, SSM shield, person moving; one SAC '
        'gradient step (batch {}, MLP {}) per RL step, {} per learner '
        'call'.format(f.robot, f.batch_size, 'x'.join(f.hidden_sizes),
                      f.fused_steps))
  print(format_results(results))


if __name__ == '__main__':
  define_flags()
  app.run(main)
