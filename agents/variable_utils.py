"""How actors read a learner's parameters (Acme's variable source and client).

A variable source (a learner) answers `get_variables(names)` with the
current value of each named variable ('policy': the policy parameters). An
actor never holds the learner itself: it reads `.params` of one of

* `VariableClient`: a copy taken from the source when `update_and_wait()`
  is called (the training actor: the agent refreshes it at chosen moments,
  so what the actor acts with is deterministic);
* `LatestVariables`: the source's current value at every read (evaluation
  with the learner's latest parameters);
* `FixedVariables`: parameters given once (a policy loaded from a
  checkpoint).
"""

from typing import Any, Protocol, Sequence


class VariableSource(Protocol):
  """Anything that serves named variables, e.g. a learner."""

  def get_variables(self, names: Sequence[str]) -> list:
    """The current values of variables.

    Args:
      names: the variables' names.

    Returns:
      Their values, in order.
    """


class VariableClient:
  """A copy of one variable of a source, refreshed on request.

  Args:
    source: the `VariableSource`.
    key: the variable's name (e.g. 'policy').
  """

  def __init__(self, source: VariableSource, key: str):
    self._source = source
    self._key = key
    self._params = source.get_variables([key])[0]

  @property
  def params(self) -> Any:
    """The copy taken at the last `update_and_wait` (or construction)."""
    return self._params

  def update_and_wait(self) -> None:
    """Takes the source's current value."""
    self._params = self._source.get_variables([self._key])[0]

  def restore(self, params: Any) -> None:
    """Sets the copy.

    Args:
      params: the variable's value (from a checkpoint).
    """
    self._params = params


class LatestVariables:
  """The source's current value of one variable at every read.

  Args:
    source: the `VariableSource`.
    key: the variable's name (e.g. 'policy').
  """

  def __init__(self, source: VariableSource, key: str):
    self._source = source
    self._key = key

  @property
  def params(self) -> Any:
    """The source's current value."""
    return self._source.get_variables([self._key])[0]


class FixedVariables:
  """Parameters given once.

  Args:
    params: the parameters.
  """

  def __init__(self, params: Any):
    self._params = params

  @property
  def params(self) -> Any:
    """The parameters given."""
    return self._params
