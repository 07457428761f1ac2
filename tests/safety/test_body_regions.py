"""Body-region energy limits (hrc_suite/safety/body_regions.py) against hand
calculations of ../shared/docs/pfl-energy.md's tables."""

import json

import pytest

from hrc_suite.safety import body_regions
from hrc_suite.safety.shield import human_reach

# E_T = (2 F_QS)^2 / (2 k), J, by hand from the table's F_QS and k.
HAND_TRANSIENT = {
    'skull_forehead': 4 * 130 ** 2 / (2 * 150e3),    # 0.225
    'face': 4 * 65 ** 2 / (2 * 75e3),                 # 0.113
    'neck': 4 * 150 ** 2 / (2 * 50e3),                # 0.900
    'back_shoulders': 4 * 210 ** 2 / (2 * 35e3),      # 2.520
    'chest': 4 * 140 ** 2 / (2 * 25e3),               # 1.568
    'abdomen': 4 * 110 ** 2 / (2 * 10e3),             # 2.420
    'pelvis': 4 * 180 ** 2 / (2 * 25e3),              # 2.592
    'upper_arm_elbow': 4 * 150 ** 2 / (2 * 30e3),     # 1.500
    'lower_arm_wrist': 4 * 160 ** 2 / (2 * 40e3),     # 1.280
    'hand_fingers': 4 * 140 ** 2 / (2 * 75e3),        # 0.523
    'thigh_knee': 4 * 220 ** 2 / (2 * 50e3),          # 1.936
    'lower_leg': 4 * 130 ** 2 / (2 * 60e3),           # 0.563
}
# The document's E_T column, rounded to 3 decimals.
DOCUMENT_TRANSIENT = {
    'skull_forehead': 0.225, 'face': 0.113, 'neck': 0.900,
    'back_shoulders': 2.520, 'chest': 1.568, 'abdomen': 2.420,
    'pelvis': 2.592, 'upper_arm_elbow': 1.500, 'lower_arm_wrist': 1.280,
    'hand_fingers': 0.523, 'thigh_knee': 1.936, 'lower_leg': 0.563}
# The document's implied speeds v_max (m/s) for robot masses 2, 5, 10 kg.
DOCUMENT_SPEEDS = {
    'face': (0.40, 0.31, 0.27), 'chest': (1.28, 0.84, 0.63),
    'upper_arm_elbow': (1.58, 1.26, 1.14),
    'lower_arm_wrist': (1.60, 1.34, 1.24),
    'hand_fingers': (1.50, 1.40, 1.36), 'lower_leg': (0.76, 0.49, 0.36)}


def test_region_energies_equal_the_hand_calculation():
  table = body_regions.load()
  assert set(table.regions) == set(HAND_TRANSIENT)
  for name, region in table.regions.items():
    assert region.energy_transient == pytest.approx(HAND_TRANSIENT[name],
                                                    rel=1e-12)
    assert round(region.energy_transient, 3) == pytest.approx(
        DOCUMENT_TRANSIENT[name], abs=1e-3)
    # Clamped: half the force, a quarter of the energy.
    assert region.energy_clamped == pytest.approx(
        region.energy_transient / 4, rel=1e-12)


def test_implied_speeds_equal_the_documents_table():
  table = body_regions.load()
  for name, speeds in DOCUMENT_SPEEDS.items():
    region = table.regions[name]
    for robot_mass, expected in zip((2.0, 5.0, 10.0), speeds):
      assert region.max_relative_speed(robot_mass) == pytest.approx(
          expected, abs=0.005), (name, robot_mass)
  # A hand hit by a 5 kg arm: mu = 1 / (1/0.6 + 1/5), F_T = 280 N,
  # k = 75 N/mm.
  hand = table.regions['hand_fingers']
  mu = 1.0 / (1.0 / 0.6 + 1.0 / 5.0)
  assert hand.max_relative_speed(5.0) == pytest.approx(
      280.0 / (mu * 75e3) ** 0.5, rel=1e-12)
  assert hand.max_relative_speed(5.0, clamped=True) == pytest.approx(
      140.0 / (mu * 75e3) ** 0.5, rel=1e-12)


def test_every_shield_body_has_the_smallest_limit_of_its_regions():
  model = human_reach.HumanModelConfig.load(human_reach.DEFAULT_MODEL_PATH)
  names = tuple(body.name for body in model.bodies)
  table = body_regions.load(body_names=names)
  assert set(table.bodies) == set(names)
  head = table.limits('head')
  assert head.transient_region == 'face'
  assert head.energy_transient == pytest.approx(HAND_TRANSIENT['face'])
  assert table.limits('left_hand').energy_transient == pytest.approx(
      HAND_TRANSIENT['hand_fingers'])
  assert table.limits('torso').transient_region == 'neck'
  for limits in table.bodies.values():
    assert limits.energy_transient == min(
        table.regions[r].energy_transient for r in limits.regions)
    assert limits.energy_clamped <= limits.energy_transient
  with pytest.raises(ValueError, match="body 'tail'"):
    table.limits('tail')


@pytest.mark.parametrize('change, message', [
    (lambda raw: raw['regions']['face'].update(stiffness=0),
     'regions.face.stiffness=0'),
    (lambda raw: raw['regions']['face'].pop('effective_mass'),
     "lacks \\['effective_mass'\\]"),
    (lambda raw: raw['shield_bodies'].update(head=['snout']),
     'shield_bodies.head'),
])
def test_bad_tables_name_the_bad_value(tmp_path, change, message):
  raw = json.loads(body_regions.DEFAULT_PATH.read_text())
  change(raw)
  path = tmp_path / 'regions.json'
  path.write_text(json.dumps(raw))
  with pytest.raises(ValueError, match=message):
    body_regions.load(path)
  with pytest.raises(ValueError, match='no energy limits'):
    body_regions.load(body_names=('head', 'tail'))
