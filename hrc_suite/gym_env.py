"""Every hrc_suite task as a Gymnasium environment, with the safety cost.

  import gymnasium
  import hrc_suite.gym_env   # registers hrc_suite/<domain>-<task>-v0

  env = gymnasium.make('hrc_suite/reach-dense-v0', robot='panda',
                       shield='off')
  observation, info = env.reset(seed=0)
  observation, reward, terminated, truncated, info = env.step(
      env.action_space.sample())
  info['cost'], info['cost_separation_deficit']   # tasks/runtime/cost.py

(`gymnasium.make('hrc_suite.gym_env:hrc_suite/reach-dense-v0')` imports
the module itself.) A thin layer over the dm_env environment of
`suite.load`, which stays the primary interface:

* make's kwargs are the task's kwargs (docs/tasks.md), but for
  `flatten` (default True: one float64 Box, the observables concatenated
  in the observation's order; False: a Dict of Boxes), `render_mode`
  (None or 'rgb_array', from `camera` at `render_size`) and
  `environment_kwargs` (suite.load's);
* the task is built with a cost (`cost=True` unless given): info holds
  `cost` and every `cost_<component>` of the RL step, and at an
  episode's last step `episode_metrics` (the task's, all of them);
* `terminated` is the task ending the episode (success, failure: discount
  0), `truncated` the time limit; Gymnasium's own TimeLimit is not added;
* `reset(seed=s)` seeds the environment's random state, so the same seed
  gives the same episode.
"""

import collections
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

import gymnasium
from gymnasium import spaces
import numpy as np

from hrc_suite import suite
from hrc_suite.tasks import base
from hrc_suite.tasks.runtime import cost as cost_lib

NAMESPACE = 'hrc_suite'
VERSION = 0
RENDER_MODES = ('rgb_array',)


def env_id(domain: str, task: str) -> str:
  """The Gymnasium id of a task: hrc_suite/<domain>-<task>-v0.

  Args:
    domain: the task's domain.
    task: the task's name in the domain.

  Returns:
    The id.
  """
  return f'{NAMESPACE}/{domain}-{task}-v{VERSION}'


def _box(spec):
  shape = tuple(spec.shape)
  dtype = np.dtype(spec.dtype)
  if dtype == np.uint8:
    return spaces.Box(0, 255, shape, np.uint8)
  return spaces.Box(-np.inf, np.inf, shape, np.float64)


class HrcEnv(gymnasium.Env):
  """A registered task as a Gymnasium environment (module docstring)."""

  metadata = {'render_modes': list(RENDER_MODES), 'render_fps': 10}

  def __init__(self, domain: str, task: str, flatten: bool = True,
               render_mode: Optional[str] = None, camera: str = 'front',
               render_size: Sequence[int] = (240, 320),
               environment_kwargs: Optional[Dict[str, Any]] = None,
               **task_kwargs: Any):
    """Builds the task.

    Args:
      domain: a registered domain (suite.ALL_TASKS).
      task: its task.
      flatten: one Box observation (True) or a Dict of Boxes (False).
      render_mode: None or 'rgb_array'.
      camera: the workcell camera `render` draws from.
      render_size: (height, width) of rendered frames, pixels.
      environment_kwargs: suite.load's environment_kwargs.
      **task_kwargs: the task's kwargs (docs/tasks.md); cost defaults to
        True.

    Raises:
      ValueError: an unknown render_mode, a flatten that is not a bool, a
        task without a cost (cost=False), flatten=True with camera
        observables, or what suite.load rejects.
    """
    if render_mode is not None and render_mode not in RENDER_MODES:
      raise ValueError(f'Unknown render_mode {render_mode!r}: expected None '
                       f'or one of {", ".join(RENDER_MODES)}')
    if not isinstance(flatten, bool):
      raise ValueError(f'flatten must be True or False, got {flatten!r}')
    task_kwargs.setdefault('cost', True)
    if cost_lib.CostSpec.of(task_kwargs['cost']) is None:
      raise ValueError('The Gymnasium environments report info["cost"]: '
                       f'cost={task_kwargs["cost"]!r} turns it off')
    self._env = suite.load(domain, task, task_kwargs=task_kwargs,
                           environment_kwargs=environment_kwargs)
    # The first reset compiles the model and draws random numbers of its
    # own: done here, so that every reset(seed=s) starts alike.
    self._env.reset()
    self._closed = False
    self.render_mode = render_mode
    self._camera = camera
    self._render_size = tuple(render_size)
    self._flatten = flatten
    specs = self._env.observation_spec()
    self._names = list(specs)
    boxes = collections.OrderedDict(
        (name, _box(spec)) for name, spec in specs.items())
    if flatten:
      if any(box.dtype == np.uint8 for box in boxes.values()):
        raise ValueError('flatten=True cannot join camera images with '
                         'vectors: pass flatten=False')
      size = sum(int(np.prod(box.shape)) for box in boxes.values())
      self.observation_space = spaces.Box(-np.inf, np.inf, (size,),
                                          np.float64)
    else:
      self.observation_space = spaces.Dict(boxes)
    action = self._env.action_spec()
    self.action_space = spaces.Box(
        np.asarray(action.minimum, np.float32),
        np.asarray(action.maximum, np.float32), tuple(action.shape),
        np.float32)

  @property
  def dm_env(self) -> suite.Environment:
    """The wrapped dm_env environment (suite.load's)."""
    return self._env

  @property
  def task(self) -> base.HrcTask:
    """The task of the wrapped environment."""
    return self._env.task

  def _observation(self, observation):
    if self._flatten:
      return np.concatenate([np.asarray(observation[name], np.float64)
                             .ravel() for name in self._names])
    return collections.OrderedDict(
        (name, np.asarray(observation[name],
                          self.observation_space[name].dtype))
        for name in self._names)

  def _info(self, last):
    step = self._env.task.step_metrics
    info = {name: float(step.get(name, 0.0))
            for name in cost_lib.metric_names()}
    if last:
      info['episode_metrics'] = dict(self._env.task.episode_metrics)
    return info

  def reset(self, *, seed: Optional[int] = None,
            options: Optional[dict] = None
            ) -> Tuple[Union[np.ndarray, Dict[str, np.ndarray]],
                       Dict[str, Any]]:
    """Starts an episode.

    Args:
      seed: None or an integer >= 0 that seeds the environment's random
        state (the same seed gives the same episode).
      options: none are taken (None or empty).

    Returns:
      (observation, info): info holds the cost metrics, all 0.

    Raises:
      ValueError: if options are given.
    """
    super().reset(seed=seed)
    if options:
      raise ValueError(f'reset takes no options, got {options!r}')
    if seed is not None:
      self._env.random_state.seed(int(seed))
    timestep = self._env.reset()
    return self._observation(timestep.observation), self._info(False)

  def step(self, action: np.ndarray
           ) -> Tuple[Union[np.ndarray, Dict[str, np.ndarray]], float, bool,
                      bool, Dict[str, Any]]:
    """Steps the environment.

    Args:
      action: an action of `action_space`'s shape.

    Returns:
      (observation, reward, terminated, truncated, info): terminated where
      the task ends the episode (discount 0), truncated at the time limit;
      info holds the RL step's cost metrics and, at the last step,
      'episode_metrics'.

    Raises:
      ValueError: an action of another shape.
    """
    action = np.asarray(action, np.float64)
    if action.shape != self.action_space.shape:
      raise ValueError(f'action of shape {action.shape}: expected '
                       f'{self.action_space.shape}')
    timestep = self._env.step(action)
    last = timestep.last()
    terminated = bool(last and timestep.discount == 0.0)
    truncated = bool(last and not terminated)
    return (self._observation(timestep.observation), float(timestep.reward),
            terminated, truncated, self._info(last))

  def render(self) -> Optional[np.ndarray]:
    """The current frame from `camera`, or None without a render_mode.

    Returns:
      None, or a (height, width, 3) uint8 image.
    """
    if self.render_mode is None:
      return None
    height, width = self._render_size
    return self._env.physics.render(height=height, width=width,
                                    camera_id=self._camera)

  def close(self) -> None:
    """Frees the physics; closing twice is allowed."""
    if not self._closed:
      self._closed = True
      self._env.close()


def make_env(**kwargs: Any) -> HrcEnv:
  """gymnasium.make's entry point: HrcEnv(**kwargs).

  Args:
    **kwargs: HrcEnv's arguments.

  Returns:
    The environment.
  """
  return HrcEnv(**kwargs)


def register_envs() -> List[str]:
  """Registers every task of the suite (extensions included) with Gymnasium.

  Returns:
    The ids, hrc_suite/<domain>-<task>-v0, of every registered task.
  """
  ids = []
  for domain, task in suite.ALL_TASKS:
    name = env_id(domain, task)
    if name not in gymnasium.registry:
      gymnasium.register(id=name, entry_point=f'{__name__}:make_env',
                         kwargs={'domain': domain, 'task': task},
                         disable_env_checker=True)
    ids.append(name)
  return ids


ENV_IDS = tuple(register_envs())
