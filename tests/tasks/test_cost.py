"""The safety cost (tasks/runtime/cost.py): its spec, its components against the
contact and intervention metrics on every task, shield on and off, and
that computing it changes no episode."""

import numpy as np
import pytest

from hrc_suite import suite
from hrc_suite.tasks.runtime import cost as cost_lib

STEPS = 40


def test_spec_from_a_tasks_argument():
  assert cost_lib.CostSpec.of(None) is None
  assert cost_lib.CostSpec.of(False) is None
  assert cost_lib.CostSpec.of(True) == cost_lib.CostSpec()
  spec = cost_lib.CostSpec.of({'weights': {'critical_human_contact': 10,
                                           'separation_deficit': 2.0}})
  assert spec.weights == {'critical_human_contact': 10.0,
                          'separation_deficit': 2.0}
  with pytest.raises(ValueError, match=r"Unknown cost components \['speed'\]"):
    cost_lib.CostSpec.of({'weights': {'speed': 1.0}})
  with pytest.raises(ValueError, match=r"Unknown cost fields \['limit'\]"):
    cost_lib.CostSpec.of({'limit': 25})
  with pytest.raises(ValueError, match='max_separation_deficit must be'):
    cost_lib.CostSpec(max_separation_deficit=0.0)
  with pytest.raises(ValueError, match='cost must be None, True'):
    cost_lib.CostSpec.of('yes')
  with pytest.raises(ValueError, match='cost'):
    suite.load('reach', 'dense', task_kwargs={'cost': 'yes'})


def test_components_and_combinations_by_hand():
  step = {'contacts_human_critical': 3, 'contacts_human_allowed': 0,
          'contacts_human_pushed': 2, 'contacts_static': 0,
          'self_collisions': 0, 'shield_interventions': 1}
  default = cost_lib.CostSpec()
  assert default.components(step, 0.25) == {
      'critical_human_contact': 1.0, 'human_contact': 1.0,
      'static_contact': 0.0, 'self_collision': 0.0,
      'shield_intervention': 1.0, 'separation_deficit': 0.0}
  assert default.components(step, -0.03)['separation_deficit'] == 0.03
  assert default.components(step, -np.inf)['separation_deficit'] == 1.0
  entries = default.step_metrics(step, 0.25)
  assert entries['cost'] == 1.0   # a critical contact
  calm = dict(step, contacts_human_critical=0)
  # Allowed contacts and interventions alone are no violation.
  assert default.step_metrics(calm, 0.25)['cost'] == 0.0
  assert default.step_metrics(calm, -0.01)['cost'] == 1.0
  weighted = cost_lib.CostSpec(weights={'shield_intervention': 0.5,
                                        'separation_deficit': 10.0})
  assert weighted.step_metrics(calm, -0.02)['cost'] == pytest.approx(0.7)
  assert list(entries) == list(cost_lib.metric_names())


def _episode(domain, task, steps=STEPS, **task_kwargs):
  env = suite.load(domain, task, task_kwargs=dict(
      seed=3, time_limit=steps * 0.1, **task_kwargs),
                   environment_kwargs={'random_state': 3})
  spec = env.action_spec()
  rng = np.random.RandomState(7)
  timestep = env.reset()
  steps, trace = [], []
  while not timestep.last():
    timestep = env.step(rng.uniform(spec.minimum, spec.maximum,
                                    spec.shape).astype(spec.dtype))
    steps.append(dict(env.task.step_metrics))
    trace.append((env.physics.data.qpos.copy(), timestep.reward,
                  {k: v.copy() for k, v in timestep.observation.items()}))
  return steps, dict(env.task.episode_metrics), trace


def _indicator(step, *names):
  return float(sum(step.get(name, 0) for name in names) > 0)


@pytest.mark.parametrize('shield', [None, 'off'])
@pytest.mark.parametrize('domain,task', suite.ALL_TASKS)
def test_components_equal_the_contact_and_intervention_metrics(
    domain, task, shield):
  """Step by step and summed over the episode, on every task, with the
  task's shield and without one."""
  steps, episode, _ = _episode(domain, task, shield=shield, cost=True)
  for step in steps:
    assert step['cost_critical_human_contact'] == _indicator(
        step, 'contacts_human_critical')
    assert step['cost_human_contact'] == _indicator(
        step, 'contacts_human_allowed', 'contacts_human_pushed')
    assert step['cost_static_contact'] == _indicator(step, 'contacts_static')
    assert step['cost_self_collision'] == _indicator(step, 'self_collisions')
    assert step['cost_shield_intervention'] == _indicator(
        step, 'shield_interventions')
    assert 0.0 <= step['cost_separation_deficit'] <= 1.0
    violated = any(step[f'cost_{name}'] > 0 for name in cost_lib.VIOLATIONS)
    assert step['cost'] == float(violated)
  for name in cost_lib.metric_names():
    assert episode[name] == pytest.approx(sum(s[name] for s in steps))
  assert episode['cost_shield_intervention'] == sum(
      1 for s in steps if s['shield_interventions'])
  if shield == 'off':
    assert episode['shield_interventions'] == 0


def test_the_cost_sees_what_the_shield_prevents():
  """Handover with the person close: without the shield the random
  policy's steps violate the separation far more often than with it."""
  shielded = _episode('handover', 'robot_to_human', 300, cost=True)[1]
  unshielded = _episode('handover', 'robot_to_human', 300, cost=True,
                        shield='off')[1]
  assert unshielded['cost_separation_deficit'] > shielded[
      'cost_separation_deficit']
  assert shielded['cost_shield_intervention'] > 0
  assert unshielded['cost_shield_intervention'] == 0


@pytest.mark.parametrize('domain,task', [('handover', 'robot_to_human'),
                                         ('stacking', 'default')])
def test_computing_the_cost_changes_no_episode(domain, task):
  _, _, plain = _episode(domain, task)
  _, _, costed = _episode(domain, task, cost=True)
  for (q, reward, observation), (q2, reward2, observation2) in zip(
      plain, costed):
    assert np.array_equal(q, q2) and reward == reward2
    assert observation.keys() == observation2.keys()
    for key, value in observation.items():
      assert np.array_equal(value, observation2[key])
  assert len(plain) == len(costed)


@pytest.mark.parametrize('shield', ['pfl', 'off'])
def test_fast_path_and_reference_give_the_same_cost(shield):
  fast = _episode('handover', 'robot_to_human', cost=True, shield=shield)[0]
  slow = _episode('handover', 'robot_to_human', cost=True, shield=shield,
                  fast_path=False)[0]
  assert fast == slow


def test_observables_and_the_safe_rl_preset():
  plain = suite.load('reach', 'dense')
  assert 'cost' not in plain.task.observables
  assert not any(k.startswith('cost') for k in (
      plain.step(np.zeros(plain.action_spec().shape)).observation))
  env = suite.load('reach', 'dense', task_kwargs={'observations': 'safe_rl'})
  first = env.reset().observation
  assert sorted(first) == ['cost', 'cost_components', 'goal_difference']
  assert first['cost'].tolist() == [0.0]
  timestep = env.step(np.zeros(env.action_spec().shape))
  names = cost_lib.metric_names()
  assert timestep.observation['cost_components'].tolist() == [
      env.task.step_metrics[name] for name in names[:-1]]
  assert timestep.observation['cost'][0] == env.task.step_metrics['cost']
  # 'full' holds the cost observables only where the task has a cost.
  full = suite.load('reach', 'dense', task_kwargs={'observations': 'full',
                                                   'cost': True})
  assert {'cost', 'cost_components'} <= set(full.task.observation_names)
