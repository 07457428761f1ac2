"""Where the CPU time of an RL step goes: `python -m hrc_suite.benchmark
--section=profile` (docs/benchmarks.md, "Where the time of an RL step goes").

Times the parts of the step loop by wrapping them (CPU time,
time.process_time, summed per part and divided by the RL steps; the
wrappers are removed afterwards). Parts nest: collision prevention holds
the IK it calls, the task's hooks hold the shield, the person, the
controller and the contact monitor. Top-level parts count their own time
without the top-level parts they call: on the fast path the task's
run_physics_steps runs the RL step's L physics steps (composer's one
substep, tasks/runtime/substeps.py), most in one compiled call
(tasks/runtime/physics_loop.py, which holds their physics, mocap, controller,
tracking and contacts); steps it hands back to Python count as physics
and after_substep. "composer
and the rest" is the RL step's total minus the top-level parts
(dm_control's environment loop, observables, the action spec check,
numpy glue).
"""

import contextlib
import time

import numpy as np

from hrc_suite.tasks.runtime import motions as task_motions

# (label, module, class or None, attribute, top level): top-level parts are
# disjoint and add up to the measured step with "composer and the rest".
PARTS = (
    ('physics in Python (mj_step2, mj_step1, warnings, entity hooks)',
     'dm_control.mujoco.engine', 'Physics', 'step', True),
    ('physics in Python (mj_step2, mj_step1, warnings, entity hooks)',
     'hrc_suite.tasks.runtime.substeps', 'PhysicsSteps', 'step', True),
    ('task before_step (action, goal, shield.new_goal, playback)',
     'hrc_suite.tasks.base', 'HrcTask', 'before_step', True),
    ('  collision prevention (plan and capsule checks of the goal)',
     'hrc_suite.safety.collision_prevention.prevention',
     'CollisionPrevention', 'filter_action', False),
    ('    IK (Cartesian actions)', 'hrc_suite.control.ik',
     'InverseKinematics', 'solve', False),
    ('  person: playback of the RL step (25 poses, segment frames)',
     'hrc_suite.entities.human_playback', 'HumanPlayback', 'advance', False),
    ('task run_physics_steps: the RL step\'s physics steps',
     'hrc_suite.tasks.base', 'HrcTask', 'run_physics_steps', True),
    ('  shield: 25 cycles (safety.shield.batch.step_many)',
     'hrc_suite.safety.shield.batch', None, 'step_many', False),
    ('  compiled physics steps (physics_loop.run: mocap, controller, '
     'mj_step2, mj_step1, tracking, contacts)',
     'hrc_suite.tasks.runtime.physics_loop', 'CompiledSteps', 'run', False),
    ('  person: mocap of one pose, Python steps',
     'hrc_suite.entities.human_playback', 'HumanPlayback', 'apply', False),
    ('  controller, Python steps', 'hrc_suite.control.controller',
     'JointTrackingController', '__call__', False),
    ('task after_substep: tracking, contacts, Python steps',
     'hrc_suite.tasks.base', 'HrcTask', 'after_substep', True),
    ('  contact monitor, Python steps', 'hrc_suite.tasks.runtime.contacts',
     'ContactMonitor', 'update', False),
    ('task after_step: self-collision, task logic, reward, metrics',
     'hrc_suite.tasks.base', 'HrcTask', 'after_step', True),
)


@contextlib.contextmanager
def _timed(totals):
  """Wraps every part of PARTS, adding its CPU time to totals[label]
  (a top-level part's without the top-level parts inside it)."""
  import importlib
  restore = []
  inner = []   # Per active top-level part: time of top-level parts inside.
  try:
    for label, module_name, class_name, attribute, top in PARTS:
      module = importlib.import_module(module_name)
      owner = module if class_name is None else getattr(module, class_name)
      original = getattr(owner, attribute)
      def wrapper(*args, _original=original, _label=label, _top=top,
                  **kwargs):
        if _top:
          inner.append(0.0)
        start = time.process_time()
        try:
          return _original(*args, **kwargs)
        finally:
          elapsed = time.process_time() - start
          if _top:
            totals[_label] += elapsed - inner.pop()
            if inner:
              inner[-1] += elapsed
          else:
            totals[_label] += elapsed
      setattr(owner, attribute, wrapper)
      restore.append((owner, attribute, original))
    yield
  finally:
    for owner, attribute, original in reversed(restore):
      setattr(owner, attribute, original)


def profile(domain, task, robot, rl_steps, action_space=None, seed=0,
            motions=None):
  """{label: µs per RL step} of PARTS, 'composer and the rest' and
  'total' for random actions (resets excluded); motions: a folder of
  people (motions.recorded_people_kwargs; None: the shipped library)."""
  from hrc_suite import suite
  kwargs = dict(robot=robot, seed=seed,
                **task_motions.recorded_people_kwargs(motions))
  if action_space:
    kwargs['action_space'] = action_space
  env = suite.load(domain, task, task_kwargs=kwargs)
  spec = env.action_spec()
  rng = np.random.RandomState(seed)
  timestep = env.reset()
  totals = {label: 0.0 for label, *_ in PARTS}
  total = 0.0
  with _timed(totals):
    for step in range(rl_steps + 30):
      if step == 30:   # Warm-up steps are not counted.
        for label in totals:
          totals[label] = 0.0
        total = 0.0
      if timestep.last():
        timestep = env.reset()
      action = rng.uniform(spec.minimum, spec.maximum, spec.shape)
      start = time.process_time()
      timestep = env.step(action.astype(spec.dtype))
      total += time.process_time() - start
  env.close()
  out = {label: 1e6 * value / rl_steps for label, value in totals.items()}
  top = sum(out[label] for label in {label for label, *_, is_top in PARTS
                                     if is_top})
  out['composer and the rest'] = 1e6 * total / rl_steps - top
  out['total'] = 1e6 * total / rl_steps
  return out
