"""The task's self-collision check: compiled (collision prevention's
capsule kernel) against its NumPy reference, on every robot."""

import numpy as np
import pytest

from hrc_suite import robot_description
from hrc_suite.safety import collision_prevention
from hrc_suite.tasks.runtime import self_collision

SAMPLES = 2000
FOLDING = ('schunk', 'panda')


@pytest.mark.parametrize('name', robot_description.ROBOT_NAMES)
def test_compiled_check_decides_as_the_reference(name):
  description = robot_description.load(name)
  checker = collision_prevention.CollisionPrevention(description)
  check = self_collision.SelfCollision(checker, compiled=True)
  limits = description.limits
  rng = np.random.RandomState(0)
  q = rng.uniform(limits.q_min, limits.q_max, (SAMPLES, description.dof))
  compiled = [check(row) for row in q]
  reference = [check.reference(row) for row in q]
  assert compiled == reference
  # Both outcomes occur on the benchmark's robots (the test can fail both
  # ways; random configurations of the iiwa never self-collide).
  if name in FOLDING:
    assert 0 < sum(reference) < SAMPLES


def test_reference_path_uses_the_numpy_check():
  description = robot_description.load('panda')
  checker = collision_prevention.CollisionPrevention(description,
                                                     compiled=False)
  check = self_collision.SelfCollision(checker, compiled=False)
  q = description.q_home
  assert check(q) == check.reference(q) is False
