r"""Behaviour cloning: an MLP fitted to an expert dataset's actions from the
agent's observations, evaluated in deterministic episodes.

  python -m agents.behaviour_cloning \
      --dataset=runs/datasets/pick_place_schunk --episodes=20 --seed=0

A probe and a reference point for the imitation agents: it shows how much
of the expert's behaviour the agent's observations (the dataset's
`observations`, i.e. the preset the dataset was recorded with) determine,
without any reinforcement learning. The policy is tanh(MLP(x)) on
observations standardised with the dataset's mean and deviation, fitted by
mean squared error to the recorded actions with Adam. The evaluation
episodes run the dataset's task, robot and task kwargs, seeded from --seed;
the table is agents.evaluate's.
"""

import dataclasses
from typing import Any, Dict, List, Sequence, Tuple

from absl import app
from absl import flags
import jax
import jax.numpy as jnp
import numpy as np
import dm_env
import optax

from agents import checkpoints
from agents import evaluate as evaluate_lib
from agents import loop as loop_lib
from agents import observations as observations_lib
from agents.sac import networks
from hrc_suite import suite
from hrc_suite.experts import dataset as dataset_lib


@dataclasses.dataclass(frozen=True)
class BehaviourCloningConfig:
  """Fit settings (defaults: a standard supervised MLP fit)."""
  hidden_sizes: tuple = (256, 256)
  learning_rate: float = 1e-3
  batch_size: int = 256
  steps: int = 20_000

  def __post_init__(self):
    if not self.hidden_sizes or min(self.hidden_sizes) < 1:
      raise ValueError(f'hidden_sizes must be positive, got '
                       f'{self.hidden_sizes!r}')
    for name in ('batch_size', 'steps'):
      if getattr(self, name) < 1:
        raise ValueError(f'{name} must be >= 1, got {getattr(self, name)!r}')
    if not self.learning_rate > 0:
      raise ValueError(f'learning_rate must be > 0, got '
                       f'{self.learning_rate!r}')


def environment(dataset: dataset_lib.Dataset,
                seed: int) -> suite.Environment:
  """The dataset's task (its robot, action space and task kwargs).

  Args:
    dataset: the expert dataset.
    seed: the environment's seed.

  Returns:
    The environment.
  """
  meta = dataset.metadata
  return suite.load(meta['domain'], meta['task'],
                    task_kwargs=dict(meta.get('task_kwargs', {})),
                    environment_kwargs={'random_state': int(seed)})


def training_pairs(dataset: dataset_lib.Dataset,
                   flattener: observations_lib.ObservationFlattener
                   ) -> Tuple[np.ndarray, np.ndarray]:
  """Every recorded step that has an action, as float32 arrays.

  Args:
    dataset: the expert dataset.
    flattener: of the environment's observations.

  Returns:
    (observations (n, size), actions (n, action size)).

  Raises:
    ValueError: a dataset without steps.
  """
  inputs, targets = [], []
  for episode in dataset.episodes:
    steps = len(episode.actions)
    observed = {name: np.asarray(value)[:steps]
                for name, value in episode.observations.items()}
    inputs.append(flattener.flatten_batch(observed))
    targets.append(np.asarray(episode.actions, np.float32))
  if not inputs or not sum(len(x) for x in inputs):
    raise ValueError(f'The dataset in {dataset.directory} has no steps')
  return np.concatenate(inputs), np.concatenate(targets)


class ClonedPolicy:
  """timestep -> action of a fitted MLP (deterministic).

  Args:
    module: the MLP.
    params: its parameters.
    flattener: of the environment's observations.
    mean: (size,) the observations' mean.
    scale: (size,) their deviation.
  """

  def __init__(self, module: networks.MLP, params: Any,
               flattener: observations_lib.ObservationFlattener,
               mean: np.ndarray, scale: np.ndarray):
    self._flattener = flattener
    self._mean, self._scale = mean, scale
    self._params = params
    self._apply = jax.jit(lambda p, x: jnp.tanh(module.apply(p, x)))

  def __call__(self, timestep: dm_env.TimeStep) -> np.ndarray:
    """The action for a timestep.

    Args:
      timestep: the environment's timestep.

    Returns:
      float64 action in [-1, 1].
    """
    x = (self._flattener(timestep.observation) - self._mean) / self._scale
    return np.asarray(self._apply(self._params, x[None])[0], np.float64)


def fit(inputs: np.ndarray, targets: np.ndarray,
        flattener: observations_lib.ObservationFlattener,
        config: BehaviourCloningConfig = BehaviourCloningConfig(),
        seed: int = 0) -> Tuple[ClonedPolicy, float]:
  """Fits the policy to observations and actions.

  Args:
    inputs: (n, size) observations.
    targets: (n, action size) actions in [-1, 1].
    flattener: of the environment's observations.
    config: the fit's settings.
    seed: the initial parameters' and batches' seed.

  Returns:
    (ClonedPolicy, final training loss).

  Raises:
    ValueError: actions outside [-1, 1].
  """
  if not np.all(np.abs(targets) <= 1.0):
    raise ValueError('actions must lie in [-1, 1] (the normalised action '
                     'space)')
  mean = inputs.mean(axis=0)
  scale = inputs.std(axis=0) + 1e-6   # Constant entries stay finite.
  normalised = (inputs - mean) / scale
  module = networks.MLP(tuple(config.hidden_sizes), targets.shape[1])
  params = module.init(jax.random.PRNGKey(seed), normalised[:1])
  optimiser = optax.adam(config.learning_rate)
  opt_state = optimiser.init(params)

  def loss_fn(p, x, y):
    return jnp.mean(jnp.sum(jnp.square(jnp.tanh(module.apply(p, x)) - y),
                            axis=-1))

  @jax.jit
  def update(p, state, x, y):
    loss, grads = jax.value_and_grad(loss_fn)(p, x, y)
    changes, state = optimiser.update(grads, state)
    return optax.apply_updates(p, changes), state, loss

  random_state = np.random.RandomState(seed)
  loss = None
  for _ in range(config.steps):
    batch = random_state.randint(len(normalised), size=config.batch_size)
    params, opt_state, loss = update(params, opt_state, normalised[batch],
                                     targets[batch])
  return (ClonedPolicy(module, params, flattener, mean, scale),
          float(loss))


def run(dataset_dir: str, episodes: int, seed: int = 0,
        config: BehaviourCloningConfig = BehaviourCloningConfig()
        ) -> Tuple[List[Dict[str, float]], Dict[str, Dict[str, float]],
                   float]:
  """Fits a policy to a dataset and evaluates it.

  Args:
    dataset_dir: the expert dataset's directory.
    episodes: evaluation episodes.
    seed: the fit's and the evaluation environment's seed.
    config: the fit's settings.

  Returns:
    (per-episode metrics, summary, final training loss).
  """
  dataset = dataset_lib.load_dataset(dataset_dir)
  env = environment(dataset, seed)
  flattener = observations_lib.ObservationFlattener(env.observation_spec())
  inputs, targets = training_pairs(dataset, flattener)
  policy, loss = fit(inputs, targets, flattener, config, seed)
  results = loop_lib.evaluate(env, policy, episodes)
  return (results,
          evaluate_lib.summary(results, np.random.RandomState(seed)), loss)


def define_flags(flag_values: flags.FlagValues = flags.FLAGS) -> None:
  """Defines the binary's flags (only when run as a program).

  Args:
    flag_values: where to define them.
  """
  fv = flag_values
  flags.DEFINE_string('dataset', None, 'Expert dataset directory '
                      '(python -m agents.collect_expert).', required=True,
                      flag_values=fv)
  flags.DEFINE_integer('episodes', 20, 'Evaluation episodes.',
                       lower_bound=1, flag_values=fv)
  flags.DEFINE_integer('seed', 0, 'Seed of the fit and the evaluation '
                       'environment.', flag_values=fv)
  flags.DEFINE_integer('steps', BehaviourCloningConfig.steps,
                       'Gradient steps.', lower_bound=1, flag_values=fv)
  flags.DEFINE_list('hidden_sizes', ['256', '256'], 'MLP layer sizes.',
                    flag_values=fv)
  flags.DEFINE_string('output', None, 'JSON file for the results.',
                      flag_values=fv)


def main(argv: Sequence[str],
         flag_values: flags.FlagValues = flags.FLAGS) -> None:
  """Fits and evaluates --dataset, prints the table, writes --output.

  Args:
    argv: the command line (unused).
    flag_values: the parsed flags.
  """
  del argv
  f = flag_values
  config = BehaviourCloningConfig(
      hidden_sizes=tuple(int(size) for size in f.hidden_sizes),
      steps=f.steps)
  results, table, loss = run(f.dataset, f.episodes, f.seed, config)
  print(f'dataset: {f.dataset}; final training loss {loss:.5f}')
  print(evaluate_lib.format_table(table, len(results)))
  if f.output:
    checkpoints.write_json(f.output, evaluate_lib.finite(
        {'summary': table, 'episodes': results, 'loss': loss,
         'config': dataclasses.asdict(config)}))


if __name__ == '__main__':
  define_flags()
  app.run(main)
