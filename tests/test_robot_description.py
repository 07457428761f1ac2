"""Robot description files load, are physically sensible, and bad ones fail clearly."""

import json
import pathlib

import numpy as np
import pytest

from hrc_suite import robot_description as rd

DOF = {'panda': 7, 'sawyer': 7, 'iiwa': 7, 'jaco': 7, 'kinova3': 7,
       'ur5e': 6, 'schunk': 6}


@pytest.mark.parametrize('name', rd.ROBOT_NAMES)
def test_shipped_description_loads(name):
  desc = rd.load(name)
  assert desc.dof == DOF[name]
  assert np.all(desc.limits.q_min < desc.q_home)
  assert np.all(desc.q_home < desc.limits.q_max)
  assert all(link.mass > 0 for link in desc.links)
  total_mass = sum(link.mass for link in desc.links)
  assert 3.0 < total_mass < 40.0, f'{name}: implausible arm mass {total_mass}'
  assert desc.shield.secure_radius == pytest.approx(0.02)


@pytest.mark.parametrize('name', rd.ROBOT_NAMES)
def test_chain_links_touch_their_capsules(name):
  """Each joint origin lies inside the capsules of the links it joins.

  This checks that transforms and capsules are expressed in the same frames
  (e.g. after the UR5e axis conversion).
  """
  desc = rd.load(name)
  frames = desc.forward_kinematics(desc.q_home)
  p1, p2, radius = desc.capsule_arrays()

  def gap(i, point):
    a = frames[i, :3, :3] @ p1[i] + frames[i, :3, 3]
    b = frames[i, :3, :3] @ p2[i] + frames[i, :3, 3]
    ab = b - a
    t = 0.0 if not ab.any() else np.clip((point - a) @ ab / (ab @ ab), 0, 1)
    return np.linalg.norm(a + t * ab - point) - radius[i]

  for i in range(desc.dof - 1):
    origin = frames[i + 1, :3, 3]
    # Enclosing capsules cover the joint housings; a joint may sit at the
    # surface of its housing, so allow 3 cm.
    assert min(gap(i, origin), gap(i + 1, origin)) < 0.03, (
        f'{name}: joint {i + 2} lies outside links {i + 1} and {i + 2}')


def test_ur5e_has_real_ur5e_kinematics():
  """At q = 0 the UR5e flange sits at the datasheet numbers (reach 0.817 m)."""
  desc = rd.load('ur5e')
  flange = desc.forward_kinematics(np.zeros(6))[-1] @ desc.flange_transform()
  np.testing.assert_allclose(np.abs(flange[:3, 3]), [0.817, 0.233, 0.063],
                             atol=2e-3)


def test_forward_kinematics_is_batched():
  desc = rd.load('panda')
  q = np.random.RandomState(0).uniform(desc.limits.q_min, desc.limits.q_max,
                                       size=(4, 3, desc.dof))
  batched = desc.forward_kinematics(q)
  assert batched.shape == (4, 3, desc.dof, 4, 4)
  np.testing.assert_allclose(batched[2, 1], desc.forward_kinematics(q[2, 1]))


def test_unknown_robot_lists_valid_names():
  with pytest.raises(rd.DescriptionError, match='panda.*schunk'):
    rd.load('ur10')


def _write_broken(tmp_path, mutate):
  data = json.loads((rd.ROBOTS_DIR / 'panda.json').read_text())
  mutate(data)
  path = tmp_path / 'broken.json'
  path.write_text(json.dumps(data))
  return path


@pytest.mark.parametrize('mutate, field', [
    (lambda d: d['links'][2].update(mass=-1.0), r"links\[2\]\.mass"),
    (lambda d: d['links'][1].update(inertia=[1, 0, 0, -1, 0, 1]),
     r"links\[1\]\.inertia.*positive definite"),
    (lambda d: d['links'][0]['capsule'].update(p1=[0, 0]),
     r"links\[0\]\.capsule\.p1.*shape"),
    (lambda d: d['limits'].update(q_min=[0.0] * 7, q_max=[-1.0] * 7),
     r"limits\.q_min.*below"),
    (lambda d: d['limits'].update(v_max=[1.0] * 6), r"limits\.v_max.*shape"),
    (lambda d: d['links'][3].update(fixed_rotation=[[1, 0, 0], [0, 1, 0],
                                                    [0, 0, 2]]),
     r"links\[3\]\.fixed_rotation.*rotation"),
    (lambda d: d.pop('flange'), r"'flange'.*missing"),
    (lambda d: d['limits'].update(torque=[1.0, 1.0, 'x', 1, 1, 1, 1]),
     r"limits\.torque"),
    (lambda d: d.update(self_collision_exempt=[[2, 3]]),
     r"self_collision_exempt.*non-adjacent"),
    (lambda d: d.update(self_collision_exempt=[[0, 9]]),
     r"self_collision_exempt.*\[0, 7\)"),
    (lambda d: d['shield'].update(unclampable_links=5),
     r"shield\.unclampable_links.*list of pairs.*got 5"),
    (lambda d: d['shield'].update(unclampable_links=[5]),
     r"shield\.unclampable_links.*pairs of link indices in \[0, 7\), got 5"),
    (lambda d: d['shield'].update(unclampable_links=[[0, 7]]),
     r"shield\.unclampable_links.*\[0, 7\), got \[0, 7\]"),
    (lambda d: d.update(notes=5), r"'notes'.*list of strings, got 5"),
    (lambda d: d.update(notes='one line'),
     r"'notes'.*list of strings, got 'one line'"),
])
def test_broken_description_names_file_and_field(tmp_path, mutate, field):
  path = _write_broken(tmp_path, mutate)
  with pytest.raises(rd.DescriptionError, match=field) as info:
    rd.load(path)
  assert 'broken.json' in str(info.value)


def test_invalid_json_names_file(tmp_path):
  path = tmp_path / 'bad.json'
  path.write_text('{"links": [')
  with pytest.raises(rd.DescriptionError, match='bad.json.*not valid JSON'):
    rd.load(path)
