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

import threading
from typing import Any, Dict, List, Mapping, Optional

import dm_env
import numpy as np

from agents import action_scaler
from agents import adders
from agents import observations
from agents import replay as replay_lib
from agents import specs
from agents import variable_utils

# Slack on the update credit, a float sum of updates_per_step, before it
# counts as holding fused_steps gradient steps (0.1 added ten times is
# 0.9999999999999999).
_CREDIT_TOLERANCE = 1e-9
POLICY = 'policy'   # The variable the actor reads.


def derive_seeds(seed: int, count: int) -> List[int]:
  """Independent 31-bit seeds derived from one seed.

  Args:
    seed: an integer >= 0.
    count: how many.

  Returns:
    `count` seeds.

  Raises:
    ValueError: a seed that is not an integer >= 0.
  """
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

  Raises:
    ValueError: a bad seed or images mode, image observations with
      images='error', or an algorithm that learns from the cost on an
      environment without the cost observables.
  """

  def __init__(self, environment_spec: specs.EnvironmentSpec, builder: Any,
               seed: int = 0, images: str = 'error'):
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

  def select_action(self, observation: Mapping[str, Any]) -> np.ndarray:
    """An action sampled from the acting policy.

    Args:
      observation: the timestep's observation.

    Returns:
      float64 action within the action spec.
    """
    return self._scaler.to_environment(
        self._actor.select_action(self._flatten(observation)))

  def observe_first(self, timestep: dm_env.TimeStep) -> None:
    """Starts an episode.

    Args:
      timestep: the episode's first timestep.
    """
    self._adder.add_first(timestep)

  def observe(self, action: np.ndarray,
              next_timestep: dm_env.TimeStep) -> None:
    """Adds the transition that led to next_timestep.

    Args:
      action: the environment action taken.
      next_timestep: the timestep it led to.
    """
    self._adder.add(action, next_timestep)
    self._env_steps += 1
    self._steps_since_update += 1

  def update(self) -> Optional[Mapping[str, float]]:
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

  def learn(self, num_steps: int = 1) -> Mapping[str, float]:
    """One learner call of gradient steps on fresh replay samples,
    dispatched asynchronously. The actor moves to the policy from before
    this call (module docstring).

    Args:
      num_steps: gradient steps, each on batch_size samples.

    Returns:
      The call's mean metrics (read lazily).

    Raises:
      ValueError: an empty replay buffer.
    """
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

  def compile_update_in_background(self) -> threading.Thread:
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

  def policy(self, deterministic: bool = True,
             seed: int = 0) -> 'TimestepPolicy':
    """Callable timestep -> action with the agent's current parameters.

    Args:
      deterministic: tanh(mean) actions; else samples with the policy's own
        RandomState (the training actor's is left alone).
      seed: that RandomState's seed.

    Returns:
      The policy.
    """
    actor = self._builder.make_actor(
        self._networks,
        variable_utils.LatestVariables(self._learner, POLICY), seed,
        evaluation=deterministic)
    return TimestepPolicy(self._flattener, actor, self._scaler)

  # Components (read by agents/agent_checkpoint.py and the tests).

  @property
  def builder(self) -> Any:
    """The algorithm's builder (agents/builders.py)."""
    return self._builder

  @property
  def config(self) -> Any:
    """The builder's config (e.g. `agents.config.SACConfig`)."""
    return self._config

  @property
  def seed(self) -> int:
    """The seed the agent was built with."""
    return self._seed

  @property
  def images(self) -> str:
    """What the flattener does with image observations."""
    return self._images

  @property
  def networks(self) -> Any:
    """The builder's networks."""
    return self._networks

  @property
  def learner(self) -> Any:
    """The builder's learner."""
    return self._learner

  @property
  def replay(self) -> replay_lib.ReplayBuffer:
    """The replay buffer."""
    return self._replay

  @property
  def actor(self) -> Any:
    """The training actor."""
    return self._actor

  @property
  def adder(self) -> adders.TransitionAdder:
    """The writer of transitions into the replay."""
    return self._adder

  @property
  def variable_client(self) -> variable_utils.VariableClient:
    """The acting policy's copy of the learner's parameters."""
    return self._variable_client

  @property
  def sample_random_state(self) -> np.random.RandomState:
    """The replay sampling's RandomState."""
    return self._sample_random_state

  @property
  def flattener(self) -> observations.ObservationFlattener:
    """The observation flattener (the policy's input)."""
    return self._flattener

  @property
  def action_scaler(self) -> action_scaler.ActionScaler:
    """The map between [-1, 1] and the action spec."""
    return self._scaler

  @property
  def acting_policy_params(self) -> Any:
    """The policy parameters the actor samples with (module docstring)."""
    return self._variable_client.params

  @property
  def env_steps(self) -> int:
    """Transitions observed."""
    return self._env_steps

  def counters(self) -> Dict[str, Any]:
    """The update schedule's counters (for checkpoints)."""
    return {'env_steps': self._env_steps,
            'steps_since_update': self._steps_since_update,
            'update_credit': self._update_credit,
            'learner_steps': self._learner.steps}

  def restore_counters(self, counters: Mapping[str, Any],
                       seed: Optional[int]) -> None:
    """Restores `counters()` and the seed the agent was built with.

    Args:
      counters: of `counters()`.
      seed: the seed, or None to keep this agent's.
    """
    self._env_steps = int(counters['env_steps'])
    self._steps_since_update = int(counters['steps_since_update'])
    self._update_credit = float(counters['update_credit'])
    self._flat_cache = (None, None)
    if seed is not None:
      self._seed = int(seed)


class TimestepPolicy:
  """timestep -> environment action, through a flattener and an actor.

  Args:
    flattener: the observation flattener.
    actor: an actor with select_action(flat observation) -> [-1, 1] action.
    scaler: the map from [-1, 1] to the action spec.
  """

  def __init__(self, flattener: observations.ObservationFlattener,
               actor: Any, scaler: action_scaler.ActionScaler):
    self._flattener = flattener
    self._actor = actor
    self._scaler = scaler

  def __call__(self, timestep: dm_env.TimeStep) -> np.ndarray:
    """The action for a timestep.

    Args:
      timestep: the environment's timestep.

    Returns:
      float64 action within the action spec.
    """
    return self._scaler.to_environment(
        self._actor.select_action(self._flattener(timestep.observation)))
