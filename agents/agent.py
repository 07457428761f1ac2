"""An actor, a learner and their replay on one machine (Acme's local layout).

  agent = Agent(specs.make_environment_spec(env), SACBuilder(config), seed=0)
  timestep = env.reset()
  agent.observe_first(timestep)
  while ...:
    action = agent.select_action(timestep.observation)
    timestep = env.step(action)
    agent.observe(action, timestep)
    agent.update()

What an algorithm is lives in its builder (agents/builders.py): the
networks, the learner (its losses), the actor and the replay. The agent
composes them the same way for every algorithm:

* the actor reads the policy through a `VariableClient` on the learner
  (agents/variable_utils.py);
* transitions, the step's safety cost included, reach the replay through
  one `TransitionAdder` (agents/adders.py); a learner that constrains the
  cost also hears each finished episode's cost;
* checkpoints are written and read by agents/agent_checkpoint.py.

Bootstrapping uses the environment's discount: 0 at a termination, 1 at a
time-limit truncation (dm_env's convention), times the config's gamma.
Updates start once the replay holds `min_replay_size` transitions; from
then on each observed step adds `updates_per_step` gradient steps to a
credit (fractional ratios accumulate), and `update()` dispatches one
learner call of `fused_steps` gradient steps (one compiled lax.scan on
fused_steps fresh minibatches) whenever the credit holds that many.

Overlap and lag: JAX runs a call asynchronously, so the call dispatched
before an environment step computes while the environment steps. The actor
does not wait for it: it runs the policy in NumPy (a jitted action would
queue behind the call on the device), and each call moves it to the policy
the learner had before that call (the previous call's result, computed in
the meantime). A call's gradient steps therefore reach the actions one call
later, fused_steps / updates_per_step environment steps after its dispatch,
and act until the call after that. A call learns only from transitions
observed before its dispatch: its minibatches are sampled then, from
everything observed so far (up to fused_steps / updates_per_step - 1
transitions more than the same gradient steps would have seen dispatched
one at a time). The policy the actor uses is deterministic (it never
depends on how fast the call ran) and part of a checkpoint; evaluation
(`policy`) uses the learner's latest parameters.

The observation entries that are signals rather than state (the cost
observables, agents/adders.py COST_OBSERVATIONS) are not part of the
policy's input.
"""

from typing import Optional

import dm_env
import numpy as np

from agents import action_scaler
from agents import adders
from agents import observations
from agents import replay as replay_lib
from agents import variable_utils

# Slack on the update credit, a float sum of updates_per_step, before it
# counts as holding fused_steps gradient steps (0.1 added ten times is
# 0.9999999999999999).
_CREDIT_TOLERANCE = 1e-9
POLICY = 'policy'   # The variable the actor reads.


def derive_seeds(seed, count):
  """`count` independent 31-bit seeds derived from one seed."""
  if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or (
      seed < 0):
    raise ValueError(f'seed={seed!r}: expected an integer >= 0')
  state = np.random.SeedSequence(int(seed)).generate_state(count, np.uint32)
  return [int(s) >> 1 for s in state]


class Agent:
  """One algorithm's actor, learner and replay, composed by its builder.

  Args:
    environment_spec: `agents.specs.EnvironmentSpec` of the environment.
    builder: an `agents.builders.ActorLearnerBuilder` (e.g. SACBuilder).
    seed: integer >= 0; the learner, the actor's sampling and the replay's
      sampling draw from independent seeds derived from it.
    images: what the observation flattener does with image observations
      (agents/observations.py).
  """

  def __init__(self, environment_spec, builder, seed: int = 0,
               images: str = 'error'):
    learner_seed, actor_seed, replay_seed = derive_seeds(seed, 3)
    self._builder = builder
    self._config = builder.config
    self._seed = int(seed)
    self._images = images
    observation_spec = environment_spec.observations
    self._flattener = observations.ObservationFlattener(
        observation_spec, images=images, exclude=adders.COST_OBSERVATIONS)
    self._scaler = action_scaler.ActionScaler(environment_spec.actions)
    cost_key = (adders.COST_KEY if adders.COST_KEY in observation_spec
                else None)
    if builder.needs_cost and cost_key is None:
      raise ValueError(
          f'{builder.name} learns from the safety cost, which the '
          f'environment does not observe (observations '
          f'{list(observation_spec)}): build the task with the cost '
          "observables, task_kwargs {'observations': 'safe_rl'}")
    observation_size = self._flattener.size
    action_size = self._scaler.size
    self._networks = builder.make_networks(observation_size, action_size)
    self._learner = builder.make_learner(self._networks, observation_size,
                                         action_size, learner_seed)
    self._replay = builder.make_replay(observation_size, action_size)
    self._variable_client = variable_utils.VariableClient(self._learner,
                                                          POLICY)
    self._actor = builder.make_actor(self._networks, self._variable_client,
                                     actor_seed)
    self._adder = adders.TransitionAdder(
        self._replay, self._flatten, self._scaler.to_normalised,
        cost_key=cost_key,
        on_episode_cost=getattr(self._learner, 'observe_episode_cost', None))
    self._sample_random_state = np.random.RandomState(replay_seed)
    self._flat_cache = (None, None)   # (observation dict, its flat vector).
    self._env_steps = 0
    self._steps_since_update = 0
    self._update_credit = 0.0

  def _flatten(self, observation):
    cached_dict, cached_vector = self._flat_cache
    if observation is cached_dict:
      return cached_vector
    vector = self._flattener(observation)
    self._flat_cache = (observation, vector)
    return vector

  # Acme's actor interface.

  def select_action(self, observation) -> np.ndarray:
    """float64 action within the action spec (sampled from the policy)."""
    return self._scaler.to_environment(
        self._actor.select_action(self._flatten(observation)))

  def observe_first(self, timestep: dm_env.TimeStep) -> None:
    self._adder.add_first(timestep)

  def observe(self, action, next_timestep: dm_env.TimeStep) -> None:
    """Adds the transition that led to next_timestep."""
    self._adder.add(action, next_timestep)
    self._env_steps += 1
    self._steps_since_update += 1

  def update(self):
    """Dispatches the learner calls due; the last one's mean metrics (read
    lazily: learning.UpdateMetrics), or None."""
    config = self._config
    if len(self._replay) < max(config.min_replay_size, 1):
      self._steps_since_update = 0
      return None
    self._update_credit += config.updates_per_step * self._steps_since_update
    self._steps_since_update = 0
    calls = int((self._update_credit + _CREDIT_TOLERANCE)
                // config.fused_steps)
    if calls == 0:
      return None
    self._update_credit = max(
        0.0, self._update_credit - calls * config.fused_steps)
    for _ in range(calls):
      metrics = self.learn(config.fused_steps)
    return metrics

  def learn(self, num_steps: int = 1):
    """One learner call of `num_steps` gradient steps on fresh replay
    samples, dispatched asynchronously; its mean metrics. The actor moves
    to the policy from before this call (module docstring)."""
    if len(self._replay) == 0:
      raise ValueError('Cannot learn from an empty replay buffer')
    batch = self._replay.sample(num_steps * self._config.batch_size,
                                self._sample_random_state)
    self._variable_client.update_and_wait()
    if num_steps == 1:
      return self._learner.update(batch)
    batches = replay_lib.Transition(*(
        field.reshape((num_steps, self._config.batch_size) + field.shape[1:])
        for field in batch))
    return self._learner.update_steps(batches)

  def compile_update_in_background(self):
    """Starts compiling the learner call `update` makes (fused_steps
    gradient steps on batches of batch_size) on a background thread
    (the learner's compile_in_background); returns the thread."""
    config = self._config
    leading = (config.batch_size,)
    if config.fused_steps > 1:
      leading = (config.fused_steps,) + leading
    sizes = {'observation': (self._flattener.size,),
             'action': (self._scaler.size,),
             'next_observation': (self._flattener.size,)}
    batches = replay_lib.Transition(**{
        field: np.zeros(leading + sizes.get(field, ()), np.float32)
        for field in replay_lib.Transition._fields})
    return self._learner.compile_in_background(batches)

  # Evaluation.

  def policy(self, deterministic: bool = True, seed: int = 0):
    """Callable timestep -> action with the agent's current parameters.

    Deterministic: tanh(mean). Otherwise samples with its own RandomState
    seeded by `seed` (the training actor's is left alone).
    """
    actor = self._builder.make_actor(
        self._networks,
        variable_utils.LatestVariables(self._learner, POLICY), seed,
        evaluation=deterministic)
    return TimestepPolicy(self._flattener, actor, self._scaler)

  # Components (read by agents/agent_checkpoint.py and the tests).

  @property
  def builder(self):
    return self._builder

  @property
  def config(self):
    return self._config

  @property
  def seed(self) -> int:
    return self._seed

  @property
  def images(self) -> str:
    return self._images

  @property
  def networks(self):
    return self._networks

  @property
  def learner(self):
    return self._learner

  @property
  def replay(self):
    return self._replay

  @property
  def actor(self):
    return self._actor

  @property
  def adder(self):
    return self._adder

  @property
  def variable_client(self):
    return self._variable_client

  @property
  def sample_random_state(self) -> np.random.RandomState:
    """The replay sampling's RandomState."""
    return self._sample_random_state

  @property
  def flattener(self):
    return self._flattener

  @property
  def action_scaler(self):
    return self._scaler

  @property
  def acting_policy_params(self):
    """The policy parameters the actor samples with (module docstring)."""
    return self._variable_client.params

  @property
  def env_steps(self) -> int:
    """Transitions observed."""
    return self._env_steps

  def counters(self) -> dict:
    """The update schedule's counters (for checkpoints)."""
    return {'env_steps': self._env_steps,
            'steps_since_update': self._steps_since_update,
            'update_credit': self._update_credit,
            'learner_steps': self._learner.steps}

  def restore_counters(self, counters: dict, seed: Optional[int]) -> None:
    """Restores `counters()` (and the seed the agent was built with)."""
    self._env_steps = int(counters['env_steps'])
    self._steps_since_update = int(counters['steps_since_update'])
    self._update_credit = float(counters['update_credit'])
    self._flat_cache = (None, None)
    if seed is not None:
      self._seed = int(seed)


class TimestepPolicy:
  """timestep -> environment action, through a flattener and an actor."""

  def __init__(self, flattener, actor, scaler):
    self._flattener = flattener
    self._actor = actor
    self._scaler = scaler

  def __call__(self, timestep):
    return self._scaler.to_environment(
        self._actor.select_action(self._flattener(timestep.observation)))
