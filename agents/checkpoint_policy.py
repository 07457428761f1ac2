"""Trained checkpoints as `hrc_suite.rendering.episode` policies.

Registered in setup.py under the entry-point group
`hrc_suite.checkpoint_policies` (name `sac`), so that

  python -m hrc_suite.rendering.episode --policy=runs/reach_dense/seed0 --out=x.mp4

renders a training run's latest checkpoint (or a given one) while hrc_suite
never imports agents. The episode runs in the run's evaluation environment
(domain, task, robot, action space, task arguments) with the deterministic
policy, as `agents.evaluate` does.
"""

import os

from agents import checkpoints
from agents import agent_checkpoint
from hrc_suite.rendering import episode as render


def load(path: str) -> render.TrainedPolicy:
  """The policy of a training run's checkpoint, for rendering.

  Args:
    path: a run directory, its checkpoints/ folder or a checkpoint.

  Returns:
    The TrainedPolicy: the run's environment and its deterministic policy.

  Raises:
    ValueError: if `path` holds no checkpoint.
  """
  directory = checkpoints.resolve(path)
  loop_state, _ = checkpoints.load_loop_state(directory)
  run_config = loop_state['run_config']
  agent_directory = os.path.join(directory, checkpoints.AGENT_DIR)

  def factory(env, seed):
    return agent_checkpoint.load_policy(agent_directory, env, deterministic=True,
                                 seed=seed)

  factory.__name__ = f'checkpoint {directory}'
  return render.TrainedPolicy(
      domain=run_config['domain'], task=run_config['task'],
      robot=run_config['robot'],
      task_kwargs=dict(run_config['task_kwargs'],
                       action_space=run_config['action_space']),
      factory=factory)
