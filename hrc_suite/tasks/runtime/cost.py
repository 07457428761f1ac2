"""The safety cost of an RL step: a vector of components and a scalar.

A task built with `cost=True` (or a `CostSpec`, or a dict of its fields)
adds to its step metrics, every RL step, with the shield on or off:

* cost_critical_human_contact: 1 if a physics step of the RL step had a
  critical human contact (contacts.py: the robot faster than the task's
  critical speed where it touched the person), else 0;
* cost_human_contact: 1 if it had an allowed human contact (the robot slow
  enough, or the person pushing a slow robot), else 0;
* cost_static_contact: 1 if the robot touched static geometry (table,
  pedestal), else 0;
* cost_self_collision: 1 if the RL step ended in a self-colliding
  configuration, else 0;
* cost_shield_intervention: 1 if the shield overrode the agent's motion in
  the RL step (never with the shield off), else 0;
* cost_separation_deficit: m, how far the robot's reachable set of its
  failsafe stop and the person's reachable set overlap at the RL step's
  last shield check (the shield's SSM clearance, `Shield.reach_distance`,
  taken negative and clipped at 0): 0 where speed and separation
  monitoring verifies the separation, positive where the separation is
  below what SSM needs (docs/safety.md, Modes): positive exactly when the
  shield's last check of the RL step failed (it checks the plan it tries
  to adopt, so under a shield the deficit measures the overlap of the
  motion it refused); at most
  `max_separation_deficit` (a check whose path could not be checked at all
  counts as that much);

and `cost`, their combination: by default Safety-Gymnasium's convention of
a per-step cost in [0, 1], here 1 if the RL step had a critical human
contact, a static contact, a self-collision or a separation deficit, else
0; with `weights`, the weighted sum of the components instead. The
episode metrics sum every entry (`cost` is the episode's cost).

The separation deficit reads the shield's clearance, which the shield
otherwise computes only when asked: a task computes the cost only when
built with one, so tasks without it pay nothing.
"""

import dataclasses
import math
from typing import Mapping, Optional

# Components, in the order of the 'cost_components' observable.
COMPONENTS = ('critical_human_contact', 'human_contact', 'static_contact',
              'self_collision', 'shield_intervention', 'separation_deficit')
# Components whose being nonzero makes the default cost 1.
VIOLATIONS = ('critical_human_contact', 'static_contact', 'self_collision',
              'separation_deficit')
PREFIX = 'cost_'
COST = 'cost'
# m; the separation deficit's cap: about an arm's length, more than any
# overlap of a stopping robot's and a person's reach in the workcell.
MAX_SEPARATION_DEFICIT = 1.0


def metric_names():
  """The step metrics a cost adds: the components, then 'cost'."""
  return tuple(PREFIX + name for name in COMPONENTS) + (COST,)


@dataclasses.dataclass(frozen=True)
class CostSpec:
  """How an RL step's cost is computed (module docstring).

  Attributes:
    weights: None (the default: 1 if any of VIOLATIONS is nonzero, else 0)
      or {component: weight}: cost = sum of weight x component over the
      components named (the others weigh 0).
    max_separation_deficit: m, the separation deficit's cap (> 0).
  """
  weights: Optional[Mapping[str, float]] = None
  max_separation_deficit: float = MAX_SEPARATION_DEFICIT

  def __post_init__(self):
    if self.weights is not None:
      if not isinstance(self.weights, Mapping):
        raise ValueError(f'cost weights must be None or a dict of component '
                         f'-> weight, got {self.weights!r}')
      unknown = sorted(set(self.weights) - set(COMPONENTS))
      if unknown:
        raise ValueError(f'Unknown cost components {unknown}: expected some '
                         f'of {", ".join(COMPONENTS)}')
      for name, weight in self.weights.items():
        if not (isinstance(weight, (int, float)) and not isinstance(
            weight, bool) and math.isfinite(weight)):
          raise ValueError(f'cost weight of {name!r} must be a finite '
                           f'number, got {weight!r}')
      object.__setattr__(self, 'weights', {k: float(v) for k, v in
                                           self.weights.items()})
    cap = self.max_separation_deficit
    if not (isinstance(cap, (int, float)) and not isinstance(cap, bool)
            and math.isfinite(cap) and cap > 0):
      raise ValueError('cost max_separation_deficit must be a finite number '
                       f'> 0 (m), got {cap!r}')

  @classmethod
  def of(cls, value) -> Optional['CostSpec']:
    """The spec of a task's `cost` argument: None or False (no cost), True
    (the default spec), a CostSpec or a dict of its fields."""
    if value is None or value is False:
      return None
    if value is True:
      return cls()
    if isinstance(value, cls):
      return value
    if isinstance(value, Mapping):
      fields = [f.name for f in dataclasses.fields(cls)]
      unknown = sorted(set(value) - set(fields))
      if unknown:
        raise ValueError(f'Unknown cost fields {unknown}: expected some of '
                         f'{", ".join(fields)}')
      return cls(**value)
    raise ValueError('cost must be None, True, a CostSpec or a dict of '
                     f'its fields (weights, max_separation_deficit), got '
                     f'{value!r}')

  def components(self, step, clearance):
    """{component: value} of an RL step from its step metrics and the
    shield's SSM clearance (m; -inf where no path could be checked)."""
    deficit = min(max(0.0, -float(clearance)), self.max_separation_deficit)
    human = step.get('contacts_human_allowed', 0) + step.get(
        'contacts_human_pushed', 0)
    return {
        'critical_human_contact': float(step.get('contacts_human_critical',
                                                 0) > 0),
        'human_contact': float(human > 0),
        'static_contact': float(step.get('contacts_static', 0) > 0),
        'self_collision': float(step.get('self_collisions', 0) > 0),
        'shield_intervention': float(step.get('shield_interventions',
                                              0) > 0),
        'separation_deficit': deficit,
    }

  def cost(self, components):
    """The scalar cost of a components dict."""
    if self.weights is None:
      return float(any(components[name] > 0 for name in VIOLATIONS))
    return float(sum(weight * components[name]
                     for name, weight in self.weights.items()))

  def step_metrics(self, step, clearance):
    """The entries a cost adds to an RL step's metrics."""
    components = self.components(step, clearance)
    entries = {PREFIX + name: value for name, value in components.items()}
    entries[COST] = self.cost(components)
    return entries
