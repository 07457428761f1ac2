"""Builds hrc_suite/assets/robots/*.json from the robot facts in shared/docs/robots.md.

Developer tool, run once when the facts change:
    python scripts/make_robot_descriptions.py ../shared/docs/robots.md

It applies the corrections that robots.md lists (Panda dynamics offset and
typos, Jaco's placeholder last link, UR5e diagonal inertias) plus the ones
found while building hrc_suite (UR5e joint axes, Panda joint-4 limit sign);
every correction is written into the description's "notes".
The torque limits, tool (flange) offsets and home poses are not in the facts
file; their sources are given below.
"""
import ast
import json
import math
import pathlib
import re
import sys

import numpy as np

# Continuous/peak joint torque limits [N m] from the manufacturers' datasheets
# (Franka Panda datasheet; Rethink Sawyer URDF effort limits; KUKA LBR iiwa 14
# R820 datasheet; Kinova JACO2 7-DoF (j2s7s300) URDF effort limits; Kinova Gen3
# user guide (large/small actuator peak torque); Universal Robots UR5e
# datasheet (size 3 / size 1 joints); Schunk LWA 4P (Powerball ERB 145/115/70)
# URDF effort limits).
TORQUE_LIMITS = {
    'panda': [87, 87, 87, 87, 12, 12, 12],
    'sawyer': [80, 80, 40, 40, 9, 9, 9],
    'iiwa': [320, 320, 176, 176, 110, 40, 40],
    'jaco': [40, 80, 40, 40, 20, 20, 20],
    'kinova3': [39, 39, 39, 39, 9, 9, 9],
    'ur5e': [150, 150, 150, 28, 28, 28],
    'schunk': [370, 370, 176, 176, 41.6, 20.1],
}

DISPLAY_NAMES = {
    'panda': 'Franka Emika Panda',
    'sawyer': 'Rethink Robotics Sawyer',
    'iiwa': 'KUKA LBR iiwa',
    'jaco': 'Kinova JACO2 (7 DoF)',
    'kinova3': 'Kinova Gen3 (7 DoF)',
    'ur5e': 'Universal Robots UR5e',
    'schunk': 'Schunk LWA 4P',
}

# Flange (tool mounting) frame relative to the last joint frame, from the
# robots' public MuJoCo/URDF models (the robosuite models the SaRA
# configurations were derived from): rotation about local axes, translation.
# Schunk and IIWA values are stated in robots.md.
FLANGES = {
    'panda': dict(translation=[0, 0, 0.107], rotation=np.eye(3)),
    'sawyer': dict(translation=[0, 0, 0.0245], rotation=np.eye(3)),
    'iiwa': dict(translation=[0, 0, 0.044], rotation=np.diag([-1.0, -1.0, 1.0])),
    'jaco': dict(translation=[0, 0, -0.16], rotation=np.diag([1.0, -1.0, -1.0])),
    'kinova3': dict(translation=[0, 0, -0.0615], rotation=np.diag([1.0, -1.0, -1.0])),
    'ur5e': dict(translation=[0, 0, 0.1], rotation=np.eye(3)),
    'schunk': dict(translation=[0, 0, 0.163], rotation=np.eye(3)),
}


# PFL safe contact speed [m/s]: hrc_suite's default for every robot
# (docs/reference_benchmark.md, Safety: the reference's code used 0.05 m/s;
# the SaRA Schunk configuration moved to 0.1 m/s in 2024-11). Configurable
# in the shield.
V_SAFE = 0.05


def _numbers(text):
  return [float(x) for x in text.split()]


def _list(text):
  value = ast.literal_eval(text.strip())
  return [float(v) for v in value]


def parse(md_text):
  robots = {}
  sections = re.split(r'^#### ', md_text, flags=re.M)[1:]
  for section in sections:
    name = section.split()[0]
    robot = {}
    for key in ('max_s_stop', 'alpha_i_max', 'v_safe',
                'reachability_set_interval_size'):
      m = re.search(key + r' = ([0-9.]+)', section)
      robot[key] = float(m.group(1))
    robot['secure_radius'] = float(
        re.search(r'secure_radius = ([0-9.]+)', section).group(1))
    for key in ('q_min', 'q_max', 'v_max', 'a_max', 'j_max', 'a_max_ltt',
                'j_max_ltt'):
      m = re.search(r'\b' + key + r' = (\[[^\]]*\])', section)
      robot[key] = _list(m.group(1))
    rows = [l for l in section.splitlines() if re.match(r'^\| \d+ \|', l)]
    transforms, capsules = [], []
    for row in rows:
      cells = [c.strip() for c in row.strip('|').split('|')]
      rot = [_numbers(r) for r in cells[1].split(';')]
      transforms.append(dict(rotation=rot, translation=_numbers(cells[2])))
      capsules.append(dict(p1=_numbers(cells[3]), p2=_numbers(cells[4]),
                           radius=float(cells[5])))
    robot['transforms'] = transforms
    robot['capsules'] = capsules
    for key in ('link_masses', 'link_inertias', 'link_centers_of_mass'):
      m = re.search(key + r'[^=]*= (\[[^\]]*\])', section)
      robot[key] = _list(m.group(1))
    m = re.search(r'unclampable_enclosures = (\[\[.*\]\])', section)
    robot['unclampable'] = ast.literal_eval(m.group(1)) if m else []
    robots[name] = robot
  return robots


def _rot_x(angle):
  c, s = math.cos(angle), math.sin(angle)
  return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def _convert_y_axis_joints(transforms, capsules, coms, inertias, y_axis):
  """Re-expresses joints that rotate about local y as z-axis joints.

  For a body frame B whose joint axis is y, the joint frame J = B·Rx(-90°)
  has z along B's y. Quantities given in B (capsules, CoM, inertia, the
  child's fixed transform) are re-expressed in J.
  """
  r_bj = _rot_x(-math.pi / 2)  # J's axes in B.
  for i, is_y in enumerate(y_axis):
    if not is_y:
      continue
    t = transforms[i]
    t['rotation'] = (np.array(t['rotation']) @ r_bj).tolist()
    to_j = r_bj.T
    for key in ('p1', 'p2'):
      capsules[i][key] = (to_j @ np.array(capsules[i][key])).tolist()
    coms[i][:3] = (to_j @ np.array(coms[i][:3])).tolist()
    inertias[i] = (to_j @ inertias[i] @ to_j.T)
    if i + 1 < len(transforms):
      child = transforms[i + 1]
      child['rotation'] = (to_j @ np.array(child['rotation'])).tolist()
      child['translation'] = (to_j @ np.array(child['translation'])).tolist()
  return to_j


def build(name, raw):
  n = len(raw['transforms'])
  notes = []
  masses = list(raw['link_masses'])
  inertia_flat = list(raw['link_inertias'])
  coms_flat = list(raw['link_centers_of_mass'])
  q_max = list(raw['q_max'])
  if name == 'panda':
    masses = masses[1:]
    inertia_flat = inertia_flat[6:]
    inertia_flat[-6:] = [0.012516, -0.000428, -0.001196, 0.010027, -0.000741,
                         0.004815]
    coms_flat = coms_flat[6:]
    notes.append('Dynamics lists start with the fixed link 0 in the source; '
                 'link i takes entry i+1 (defect B5). Last inertia row typos '
                 '(-7.41, 4.815e-34) corrected.')
    q_max[3] = -0.07
    notes.append('Joint 4 upper limit is -0.07 rad (Franka datasheet: '
                 '-0.0698 rad); the source lists +0.07, a sign slip.')
  if raw['v_safe'] != V_SAFE:
    notes.append(f'PFL v_safe set to the suite default {V_SAFE} m/s (source '
                 f'configuration: {raw["v_safe"]} m/s).')
  if name == 'jaco':
    masses[-1] = 0.5
    # Solid cylinder of 0.5 kg, radius 0.04 m, length 0.12 m about its axis z.
    m, r, h = 0.5, 0.04, 0.12
    ixx = m * (3 * r * r + h * h) / 12
    izz = m * r * r / 2
    inertia_flat[-6:] = [ixx, 0, 0, ixx, 0, izz]
    notes.append('Last link had placeholder dynamics (1e-6); set to 0.5 kg '
                 'with the inertia of a solid cylinder r=0.04 m, h=0.12 m.')
  # The last link's SaRA capsule also encloses the maker's default tool
  # (robosuite grippers), reaching 0.11-0.24 m past the flange where our
  # gripper's fingers close. hrc_suite models its gripper separately (with its
  # own enclosing capsule for the shield), so these capsules are cut back to
  # the wrist housing, ending at most a few cm past the flange.
  wrist_capsules = {
      'panda': ([0, 0, 0.0], [0, 0, 0.05], 0.06),
      'sawyer': ([0, 0.015, 0.0], [0, 0.015, 0.0], 0.0657647),
      'iiwa': ([0, 0, 0.0], [0, 0, 0.0], 0.08),
      'kinova3': ([0, 0, 0.0], [0, 0, 0.0], 0.07),
  }
  if name in wrist_capsules:
    p1, p2, radius = wrist_capsules[name]
    old = raw['capsules'][-1]
    notes.append(
        'Last link capsule cut back to the wrist housing (p1 %s, p2 %s, r %s; '
        'source p1 %s, p2 %s, r %s enclosed the default tool, which '
        'hrc_suite replaces by its own gripper and gripper capsule).'
        % (p1, p2, radius, old['p1'], old['p2'], old['radius']))
    raw['capsules'][-1] = dict(p1=p1, p2=p2, radius=radius)
  if name == 'sawyer':
    # The last fixed rotation is printed to 4 digits (0.9848, 0.1736): a
    # rotation by 10 degrees. Store it exactly so every model agrees.
    c, s = math.cos(math.radians(10)), math.sin(math.radians(10))
    rot = np.array(raw['transforms'][-1]['rotation'])
    exact = np.where(np.isclose(np.abs(rot), 0.9848, atol=1e-4),
                     np.sign(rot) * c, rot)
    exact = np.where(np.isclose(np.abs(exact), 0.1736, atol=1e-4),
                     np.sign(exact) * s, exact)
    raw['transforms'][-1]['rotation'] = exact.tolist()
    notes.append('Last fixed rotation stored with exact cos/sin of 10 deg '
                 '(source: 4 digits).')
  exempt = []
  if name == 'sawyer':
    # Measured in issue 17's sweep with these capsules (q_home's other
    # joints, and random poses with q5 in the gripper-down band).
    exempt.append([4, 6])
    notes.append(
        "self_collision_exempt [4, 6]: link5's capsule (its wrist end holds "
        "the J5 housing) and link7's sphere (the J6 housing) sit at the two "
        "ends of the 0.152 m link6. They are 0.1-5.4 mm apart for q5 in "
        "0.4-1.6 rad (q_home's other joints; the gripper-down band: q_home "
        "q5 = 0.98, robosuite's Sawyer home 0.57) and overlap by up to "
        "1.9 mm in 6.5 % of random poses with q5 in that band, so collision "
        "prevention rejected nearly every Cartesian move from home (1000 of "
        "1000 actions replaced in pick_place). The Panda's, iiwa's and "
        "Jaco's same wrist pair overlaps at home and is excluded by "
        "collision_prevention's rule; this pair overlaps only for |q5| > "
        "2.2 rad (limits 2.98 rad), the blind spot of the exemption.")
  inertias = []
  for i in range(n):
    ixx, ixy, ixz, iyy, iyz, izz = inertia_flat[6 * i:6 * i + 6]
    inertias.append(np.array([[ixx, ixy, ixz], [ixy, iyy, iyz],
                              [ixz, iyz, izz]]))
  coms = [list(coms_flat[6 * i:6 * i + 6]) for i in range(n)]
  transforms = raw['transforms']
  capsules = raw['capsules']
  if name == 'ur5e':
    y_axis = [False, True, True, True, False, True]
    _convert_y_axis_joints(transforms, capsules, coms, inertias, y_axis)
    notes.append(
        'The SaRA configuration assumes every joint turns about local z, but '
        'the UR5e body frames it was taken from turn joints 2, 3, 4 and 6 '
        'about local y (robosuite / MuJoCo Menagerie UR5e). Those joints are '
        're-expressed as z-axis joints (frame rotated by -90 deg about x), '
        'with capsules, centres of mass and inertias moved into the new '
        'frames, so the kinematics are the real UR5e\'s.')
    notes.append('Centres of mass have no orientation; inertias are diagonal.')
  links = []
  for i in range(n):
    inertia = inertias[i]
    links.append(dict(
        name=f'link{i + 1}',
        fixed_rotation=np.round(np.array(transforms[i]['rotation']), 12).tolist(),
        fixed_translation=np.round(np.array(transforms[i]['translation']), 12).tolist(),
        capsule=dict(p1=np.round(capsules[i]['p1'], 12).tolist(),
                     p2=np.round(capsules[i]['p2'], 12).tolist(),
                     radius=capsules[i]['radius']),
        mass=masses[i],
        inertia=[round(float(v), 12) for v in (
            inertia[0, 0], inertia[0, 1], inertia[0, 2], inertia[1, 1],
            inertia[1, 2], inertia[2, 2])],
        center_of_mass=[round(v, 12) for v in coms[i][:3]],
        inertia_rpy=coms[i][3:6],
    ))
  flange = FLANGES[name]
  return dict(
      name=name,
      display_name=DISPLAY_NAMES[name],
      source=('SaRA shield robot configuration numbers (robots.md), '
              'derived by their authors from the manufacturers\' URDFs.'),
      notes=notes,
      links=links,
      limits=dict(
          q_min=raw['q_min'], q_max=q_max, v_max=raw['v_max'],
          a_max=raw['a_max'], j_max=raw['j_max'], a_max_ltt=raw['a_max_ltt'],
          j_max_ltt=raw['j_max_ltt'], torque=TORQUE_LIMITS[name]),
      flange=dict(rotation=flange['rotation'].tolist(),
                  translation=flange['translation']),
      shield=dict(
          secure_radius=raw['secure_radius'], max_s_stop=raw['max_s_stop'],
          alpha_i_max=raw['alpha_i_max'], v_safe=V_SAFE,
          reachability_interval_cycles=int(
              raw['reachability_set_interval_size']),
          unclampable_links=raw['unclampable']),
      self_collision_exempt=exempt,
  )


def to_json(value):
  """JSON with every list of numbers on one line, for readable diffs."""
  text = json.dumps(value, indent=1)
  def join(match):
    return '[' + ', '.join(x.strip() for x in match.group(1).split(',')) + ']'
  for _ in range(2):  # Inner lists first, then lists of lists.
    text = re.sub(r'\[([^\[\]{}"]*)\]', join, text)
    text = re.sub(r'\[((?:\s*\[[^\[\]]*\],?)+\s*)\]', join, text)
  return text + '\n'


def main(argv):
  md = pathlib.Path(argv[1]).read_text()
  out_dir = pathlib.Path(__file__).resolve().parents[1] / 'hrc_suite/assets/robots'
  out_dir.mkdir(parents=True, exist_ok=True)
  for name, raw in parse(md).items():
    desc = build(name, raw)
    existing = out_dir / f'{name}.json'
    if existing.exists():  # Keep hand-tuned fields (home pose) across runs.
      old = json.loads(existing.read_text())
      if 'q_home' in old:
        desc['q_home'] = old['q_home']
    existing.write_text(to_json(desc))
    print('wrote', existing)


if __name__ == '__main__':
  main(sys.argv)
