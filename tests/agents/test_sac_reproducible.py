"""SAC's learning, pinned: a fixed seed gives recorded parameters, bit for bit.

The digests were recorded with the versions in RECORDED; XLA's CPU code
(and so the last bits of a float) may differ under other JAX versions or
machines, where the test is skipped and says so. A change of the digest
under the recorded versions is a change of what SAC computes: record new
digests only for a change of its maths, stating it in CHANGELOG.md.
"""

import hashlib
import platform

import jax
import jaxlib
import numpy as np
import pytest

from agents import config as config_lib
from agents import specs
from agents.sac import SACAgent
from toy_tasks import PointReach

RECORDED = {'jax': '0.10.2', 'jaxlib': '0.10.2', 'machine': 'x86_64'}
# sha256 (first 16 hex digits) of the learner's state after the run.
DIGESTS = {
    'fused': 'aeb8b0217b8e421b',                 # 700 steps, 8 per call.
    'single_half': 'e58011e9cc37e2c5',           # 500 steps, 0.5 per step.
    'clipped_scaled': 'f0dee89935c130f5',        # 400 steps.
}
RUNS = {
    'fused': (700, {}),
    'single_half': (500, {'fused_steps': 1, 'updates_per_step': 0.5}),
    'clipped_scaled': (400, {'max_grad_norm': 1.0, 'reward_scale': 10.0}),
}


def _digest(arrays):
  digest = hashlib.sha256()
  for name in sorted(arrays):
    digest.update(name.encode())
    digest.update(np.ascontiguousarray(arrays[name]).tobytes())
  return digest.hexdigest()[:16]


@pytest.mark.parametrize('run', sorted(RUNS))
def test_sac_learns_the_recorded_parameters(run):
  versions = {'jax': jax.__version__, 'jaxlib': jaxlib.__version__,
              'machine': platform.machine()}
  if versions != RECORDED:
    pytest.skip(f'Digests recorded with {RECORDED}, this is {versions}')
  steps, overrides = RUNS[run]
  env = PointReach(seed=3, terminate_at=0.1)
  config = config_lib.default_config(**dict(
      dict(hidden_sizes=(64, 64), batch_size=64, min_replay_size=100),
      **overrides))
  agent = SACAgent(specs.make_environment_spec(env), config, seed=5)
  timestep = env.reset()
  agent.observe_first(timestep)
  for _ in range(steps):
    action = agent.select_action(timestep.observation)
    agent.update()
    timestep = env.step(action)
    agent.observe(action, timestep)
    if timestep.last():
      timestep = env.reset()
      agent.observe_first(timestep)
  assert _digest(agent.learner.state()) == DIGESTS[run]
