"""Every task plays the real recordings (tests/conftest.py; the module is
marked `recordings`) on two robots, and the speed model's opt-out is
counted."""

import numpy as np
import pytest

from hrc_suite import experts
from hrc_suite import layout
from hrc_suite import suite
from hrc_suite.experts import adversary
from hrc_suite.human import clip as clip_lib
from hrc_suite.human import recording_cache
from hrc_suite.tasks import stacking

pytestmark = pytest.mark.recordings

# Each reference folder's task, as suite (domain, task) names.
FOLDER_TASKS = {
    'RobotHumanHandover': ('handover', 'robot_to_human'),
    'HumanRobotHandover': ('handover', 'human_to_robot'),
    'CollaborativeLifting': ('lifting', 'default'),
    'CollaborativeStacking': ('stacking', 'default'),
    # The reference's roles (its robot hammers): hammering/default refuses
    # these clips (tests/tasks/test_hammering_robot.py).
    'CollaborativeHammering': ('hammering', 'robot_hammers'),
    'ObjectInspection': ('inspection', 'default'),
    'PickPlaceCloseHuman': ('pick_place', 'close'),
}
ROBOTS = ('schunk', 'panda')
CASES = [(folder, robot) for folder in FOLDER_TASKS for robot in ROBOTS]


@pytest.fixture(autouse=True)
def cache(tmp_path_factory, monkeypatch):
  monkeypatch.setenv(recording_cache.CACHE_ENV,
                     str(tmp_path_factory.getbasetemp() / 'recordings'))


def _load(motions, folder, robot, seed=0, **kwargs):
  """`folder`'s task on `robot` playing the recordings under `motions`."""
  domain, task = FOLDER_TASKS[folder]
  kwargs = dict({'robot': robot, 'seed': seed, 'motions': motions,
                 'outside_human_model': 'allow'}, **kwargs)
  return suite.load(domain, task, task_kwargs=kwargs)


@pytest.mark.parametrize('folder,robot', CASES)
def test_recordings_play_in_their_task(folder, robot, recordings_dir):
  env = _load(recordings_dir, folder, robot)
  clips = env.task.player.clips
  assert len(clips) == len(list((recordings_dir / folder).glob('*.bvh')))
  assert all(c.metadata['source'] == 'bvh' for c in clips)
  policy = experts.make(env)
  timestep = env.reset()
  for _ in range(20):
    timestep = env.step(policy(timestep))
    if timestep.last():
      break
  metrics = env.task.episode_metrics
  assert metrics['steps'] >= 1
  assert metrics['contacts_human_critical'] == 0


def test_fast_recordings_are_refused_by_default(recordings_dir):
  """pick_place's recordings move hands at 3-12 m/s (over the shield's
  2 m/s model): refused unless allowed, then counted."""
  with pytest.raises(clip_lib.ClipError, match='over the shield.s human '
                     "model.*'outside_human_model': 'allow'"):
    _load(recordings_dir, 'PickPlaceCloseHuman', 'panda',
          outside_human_model='refuse')
  env = _load(recordings_dir, 'PickPlaceCloseHuman', 'panda')
  env.reset()
  outside = 0
  for _ in range(150):
    env.step(np.zeros(env.action_spec().shape))
    outside = env.task.episode_metrics['steps_outside_human_model']
    if outside:
      break
  assert outside > 0



def test_critical_contacts_split_by_the_human_model(recordings_dir):
  """Without the shield the chaser strikes a recorded person who at times
  moves faster than the shield's human model: each RL step's critical
  contacts count as outside the model exactly when the person was, and
  the episode has contacts on both sides."""
  env = _load(recordings_dir, 'PickPlaceCloseHuman', 'panda', seed=2,
              shield='off')
  policy = adversary.PersonChaser(env)
  timestep = env.reset()
  for _ in range(300):
    timestep = env.step(policy(timestep))
    step = env.task.step_metrics
    expected = (step['contacts_human_critical']
                if step['steps_outside_human_model'] else 0)
    assert step['contacts_human_critical_outside_model'] == expected
    if timestep.last():
      break
  episode = env.task.episode_metrics
  outside = episode['contacts_human_critical_outside_model']
  assert 0 < outside < episode['contacts_human_critical'], episode

def test_stacking_people_bring_their_cubes_and_set_them_down(
    recordings_dir):
  """Both human cubes start in the recorded person's hands and travel with
  them; cube 1 is let go over the table and set down on it, upright."""
  env = _load(recordings_dir, 'CollaborativeStacking', 'panda', seed=2)
  env.reset()
  task = env.task
  held = [task.cubes[i] for i in stacking.HUMAN_CUBES]
  start = [env.physics.bind(c.body).xpos.copy() for c in held]
  assert [task._human_state[i] for i in stacking.HUMAN_CUBES] == [
      stacking.HELD] * 2
  for _ in range(60):   # 6 s: the person walks in and puts cube 1 down.
    env.step(np.zeros(env.action_spec().shape))
    if task._human_state[0] == stacking.RELEASED:
      break
  assert task._human_state[0] == stacking.RELEASED
  moved = [np.linalg.norm(env.physics.bind(c.body).xpos - p)
           for c, p in zip(held, start)]
  assert min(moved) > 0.5, moved
  cube = env.physics.bind(held[0].body)
  assert cube.xpos[2] == pytest.approx(
      layout.TABLE_TOP_Z + held[0].size / 2, abs=2e-3)
  assert task.stacked[0]


@pytest.mark.slow
@pytest.mark.parametrize('folder,robot', CASES)
def test_full_expert_episode_on_recordings(folder, robot, recordings_dir):
  env = _load(recordings_dir, folder, robot, seed=1)
  policy = experts.make(env)
  timestep = env.reset()
  while not timestep.last():
    timestep = env.step(policy(timestep))
  metrics = env.task.episode_metrics
  assert metrics['contacts_human_critical'] == 0, metrics
