"""Stable-Baselines3's SAC on an hrc_suite task through Gymnasium (README.md,
"Training with Stable-Baselines3"): the registered environment as it is, no
wrappers. Needs `pip install -e '.[gym]' torch stable-baselines3`.

  python examples/sb3_sac.py [--steps=1000]
"""

import argparse
import time

import gymnasium
import hrc_suite.gym_env   # pylint: disable=unused-import  (registers)
from stable_baselines3 import SAC


def main():
  parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
  parser.add_argument('--steps', type=int, default=1000)
  args = parser.parse_args()
  env = gymnasium.make('hrc_suite/reach-dense-v0')
  model = SAC('MlpPolicy', env, learning_starts=100, seed=0, verbose=0)
  start = time.time()
  model.learn(total_timesteps=args.steps)
  print(f'SAC trained {args.steps} steps in {time.time() - start:.1f} s')


if __name__ == '__main__':
  main()
