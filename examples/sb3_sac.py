"""Stable-Baselines3's SAC on an hrc_suite task (README.md, "Training with
Stable-Baselines3"): dm_env -> Gymnasium with Shimmy, observations
flattened. Needs `pip install torch stable-baselines3 'shimmy[dm-control]'`.

  python examples/sb3_sac.py [--steps=1000]
"""

import argparse
import time

from hrc_suite import suite   # First: its rendering default (README.md).
import gymnasium as gym
from shimmy import DmControlCompatibilityV0
from stable_baselines3 import SAC


def main():
  parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
  parser.add_argument('--steps', type=int, default=1000)
  args = parser.parse_args()
  env = suite.load('reach', 'dense', task_kwargs={'seed': 0})
  env = gym.wrappers.FlattenObservation(DmControlCompatibilityV0(env))
  model = SAC('MlpPolicy', env, learning_starts=100, seed=0, verbose=0)
  start = time.time()
  model.learn(total_timesteps=args.steps)
  print(f'SAC trained {args.steps} steps in {time.time() - start:.1f} s')


if __name__ == '__main__':
  main()
