"""The compliant hold of a tool by a kinematic (mocap) hand: tracking in a
fast swing, bounded press when blocked, aiming, snapshots."""

from dm_control import mjcf
import mujoco
import numpy as np
import pytest

from hrc_suite.tasks.runtime import tool_hold

MASS = 0.58          # kg, the hammer's
TIMESTEP = 0.004     # s, the suite's physics step
GRIP = np.array([-0.2, 0.0, 0.0])   # tool origin 0.2 m ahead of the hand
PLATE_TOP = 0.0      # m


def _physics(plate=False):
  root = mjcf.RootElement()
  root.option.timestep = TIMESTEP
  hand = root.worldbody.add('body', name='hand', mocap=True, pos=(0, 0, 0.3))
  tool = root.worldbody.add('body', name='tool', pos=(0.2, 0, 0.3))
  tool.add('freejoint')
  tool.add('geom', type='box', size=(0.1, 0.0125, 0.0125), pos=(-0.1, 0, 0),
           mass=0.13)
  tool.add('geom', type='cylinder', size=(0.0125, 0.02), mass=0.45)
  weld = root.equality.add('weld', body1=hand, body2=tool, active='false',
                           solref=(0.01, 1.0))
  if plate:
    root.worldbody.add('geom', name='plate', type='box',
                       size=(0.1, 0.1, 0.01), pos=(0.2, 0, PLATE_TOP - 0.01))
  physics = mjcf.Physics.from_mjcf_model(root)
  model = physics.model
  eq_id = physics.bind(weld).element_id
  model.eq_data[eq_id, 3:6] = -GRIP          # tool origin in the hand frame
  model.eq_data[eq_id, 6:10] = (1, 0, 0, 0)
  physics.forward()
  return physics, hand, tool, weld


def _strike(t):
  """Hand height (m) in a blow: 0.25 m down in 0.14 s (minimum jerk)."""
  s = np.clip(t / 0.14, 0.0, 1.0)
  return 0.3 - 0.25 * (10 * s ** 3 - 15 * s ** 4 + 6 * s ** 5)


def _run(physics, hand, tool, hold, heights):
  """Moves the hand through `heights` (one per step); returns the tool
  origin's distance from its target and the plate's contact force."""
  errors, forces = [], []
  mocap = physics.bind(hand).mocapid
  force = np.zeros(6)
  for height in heights:
    physics.data.mocap_pos[mocap] = (0.0, 0.0, height)
    if hold is not None:
      hold.apply(physics)
    physics.step()
    origin = physics.bind(tool).xpos
    errors.append(np.linalg.norm(origin - np.array([0.2, 0.0, height])))
    total = 0.0
    for i in range(physics.data.ncon):   # the plate's contacts only
      mujoco.mj_contactForce(physics.model.ptr, physics.data.ptr, i, force)
      total += force[0]
    forces.append(total)
  return np.array(errors), np.array(forces)


def _held(physics, tool, weld):
  hold = tool_hold.CompliantHold(physics, tool)
  hold.start(physics, weld)
  return hold


def test_follows_a_fast_swing_closely():
  physics, hand, tool, weld = _physics()
  hold = _held(physics, tool, weld)
  heights = _strike(np.arange(0, 0.4, TIMESTEP))
  errors, _ = _run(physics, hand, tool, hold, heights)
  assert errors.max() < 0.003          # peak hand speed ~3.4 m/s
  assert errors[-25:].max() < 0.002    # settles once the hand stops


def test_a_weld_to_a_mocap_hand_lags_the_swing():
  # The reason for the hold: mocap bodies have no velocity, so the weld's
  # damping pulls against the tool's own velocity.
  physics, hand, tool, weld = _physics()
  physics.data.eq_active[physics.bind(weld).element_id] = 1
  heights = _strike(np.arange(0, 0.4, TIMESTEP))
  errors, _ = _run(physics, hand, tool, None, heights)
  assert errors.max() > 0.03


def _press(hold_on):
  """Hand driven 2.5 cm below where the plate stops the tool."""
  physics, hand, tool, weld = _physics(plate=True)
  hold = None
  if hold_on:
    hold = _held(physics, tool, weld)
  else:
    physics.data.eq_active[physics.bind(weld).element_id] = 1
  blocked = PLATE_TOP + 0.0125    # tool's lowest point on the plate
  heights = np.concatenate([np.linspace(0.3, blocked - 0.025, 100),
                            np.full(150, blocked - 0.025)])
  _, forces = _run(physics, hand, tool, hold, heights)
  return forces[-50:].mean()


def test_a_blocked_tool_presses_with_the_spring_force_only():
  press = _press(hold_on=True)
  expected = tool_hold.STIFFNESS * 0.025 + MASS * 9.81
  assert press == pytest.approx(expected, rel=0.2)
  assert press < 20.0
  assert _press(hold_on=False) > 10 * press


def test_aims_at_a_point_within_the_wrists_range():
  physics, hand, tool, weld = _physics()
  hold = _held(physics, tool, weld)
  hold.aim((0.2, 0.05, 0.0))     # 14 deg to the left of the tool
  com, quat = hold.target(physics)
  hand_xy = physics.data.mocap_pos[0, :2]
  heading = np.arctan2(*(com[:2] - hand_xy)[::-1])
  assert heading == pytest.approx(np.arctan2(0.05, 0.2), abs=1e-3)
  assert quat[0] == pytest.approx(np.cos(heading / 2))
  hold.aim((0.0, 0.2, 0.0))      # 90 deg: the wrist stops at MAX_AIM
  com, _ = hold.target(physics)
  heading = np.arctan2(*(com[:2] - hand_xy)[::-1])
  assert heading == pytest.approx(tool_hold.MAX_AIM, abs=1e-3)
  with pytest.raises(ValueError, match='aim point'):
    hold.aim((0.0, np.nan, 0.0))


def test_state_round_trip_gives_the_same_forces():
  physics, hand, tool, weld = _physics()
  hold = _held(physics, tool, weld)
  heights = _strike(np.arange(0, 0.1, TIMESTEP))
  _run(physics, hand, tool, hold, heights[:10])
  spec = mujoco.mjtState.mjSTATE_INTEGRATION
  physics_state = np.empty(mujoco.mj_stateSize(physics.model.ptr, spec))
  mujoco.mj_getState(physics.model.ptr, physics.data.ptr, physics_state, spec)
  physics.forward()
  state = hold.state()
  _run(physics, hand, tool, hold, heights[10:])
  first = physics.data.xfrc_applied.copy()
  other = tool_hold.CompliantHold(physics, tool)
  other.set_state(state)
  mujoco.mj_setState(physics.model.ptr, physics.data.ptr, physics_state, spec)
  physics.forward()   # dm_control's step starts with mj_step2
  _run(physics, hand, tool, other, heights[10:])
  np.testing.assert_array_equal(physics.data.xfrc_applied, first)


def test_bad_input():
  physics, _, tool, weld = _physics()
  with pytest.raises(ValueError, match='stiffness'):
    tool_hold.CompliantHold(physics, tool, stiffness=-1.0)
  hold = tool_hold.CompliantHold(physics, tool)
  hold.apply(physics)     # not holding: no force
  assert not hold.holding and not physics.data.xfrc_applied.any()
  hold.start(physics, weld)
  assert hold.holding
  assert physics.data.eq_active[physics.bind(weld).element_id] == 0
