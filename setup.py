"""hrc_suite: safe reinforcement learning benchmarks for human-robot collaboration."""

import warnings

import setuptools

# `pip install -e .` builds in this process; setuptools' editable_wheel then
# emits an InformationOnly warning ("Editable installation ... Please be
# careful with folders in your working directory with the same name as your
# package") on every editable install that uses its import hook, which pip
# prints as a warning box. It is a note about editable installs in general,
# not about this project: not shown.
warnings.filterwarnings('ignore', message='Editable installation')

# JAX agents (agents/): networks (flax), optimisers (optax), logs
# (tensorboardX), learning-curve plots (matplotlib), grids of runs on Ray
# (agents.sweep; the core package, no dashboard).
TRAIN_REQUIRES = ['jax>=0.4.30', 'flax', 'optax', 'tensorboardX',
                  'matplotlib', 'ray>=2.9']

setuptools.setup(
    name='hrc_suite',
    version='0.1.0',
    description=('Human-robot collaboration benchmark tasks for safe '
                 'reinforcement learning, on dm_control composer and MuJoCo.'),
    long_description=open('README.md').read(),
    long_description_content_type='text/markdown',
    # Tested versions: docs/python_versions.md. Not 3.13: dm-control
    # requires labmaze, whose last release (1.0.6) has wheels up to 3.12 and
    # whose source build needs Bazel; capped so pip refuses with a clear
    # message instead of failing in that build.
    python_requires='>=3.10,<3.13',
    # The data folders under hrc_suite/assets have no __init__.py: listed as
    # namespace packages, with their files as package data (listing them
    # only as data of hrc_suite makes setuptools warn about each folder).
    packages=setuptools.find_namespace_packages(
        include=['hrc_suite', 'hrc_suite.*', 'agents', 'agents.*'],
        exclude=['*.__pycache__']),
    package_data={'hrc_suite.assets': ['**/*.json', '**/*.npz']},
    # `python -m hrc_suite.rendering.episode --policy=<checkpoint>` finds the agents'
    # checkpoint loader here (hrc_suite does not import agents).
    entry_points={'hrc_suite.checkpoint_policies': [
        'sac = agents.checkpoint_policy:load']},
    include_package_data=True,
    install_requires=[
        # dm-control 1.0.50 crashes on mujoco 4 (MjModel.flex_vertedge).
        'dm-control==1.0.50',
        'mujoco==3.17.0',
        'pin>=3.0',          # pinocchio kinematics (wheels, with coal).
        'dm-env',
        # NumPy 2.5 deprecates setting ndarray.shape, which dm-control 1.0.50
        # does (dm_control/mujoco/index.py) with DeprecationWarnings always
        # shown (dm_control/composer/environment.py): six warnings per
        # suite.load on Python 3.12 (docs/python_versions.md).
        'numpy>=1.24,<2.5',
        'scipy>=1.10',
        'absl-py',
        'ruckig>=0.12',      # jerk-limited trajectory generation.
        'imageio>=2.30',
        'imageio-ffmpeg>=0.4.9',  # ships its own ffmpeg binary.
        # Video captions and event markers (hrc_suite/rendering/overlay.py);
        # load_default(size=...) needs Pillow >= 10.1.
        'Pillow>=10.1',
        'tqdm',
        # Compiled kernels of the shield's per-cycle geometry
        # (hrc_suite/safety/kernels.py).
        'numba>=0.60',
    ],
    extras_require={
        'train': TRAIN_REQUIRES,
        # Tests also check the gymnasium wrapper (tests/test_gym.py) and the
        # agents (tests/agents: the train extra).
        'dev': ['pytest>=7', 'pytest-xdist', 'shimmy[dm-control]',
                'gymnasium', 'packaging'] + TRAIN_REQUIRES,
        # Gymnasium's MuJoCo module, which shimmy's dm_control wrapper
        # imports, needs packaging and does not declare it.
        'gym': ['shimmy[dm-control]', 'gymnasium', 'packaging'],
    },
    classifiers=[
        'Programming Language :: Python :: 3',
        'Programming Language :: Python :: 3.10',
        'Programming Language :: Python :: 3.11',
        'Programming Language :: Python :: 3.12',
        'Topic :: Scientific/Engineering :: Artificial Intelligence',
    ],
)
