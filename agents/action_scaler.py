"""Actions in [-1, 1]^n (a squashed policy's range) and a bounded action spec."""

from dm_env import specs
import numpy as np


class ActionScaler:
  """Affine map between [-1, 1]^n and a bounded 1-D action spec."""

  def __init__(self, action_spec: specs.BoundedArray):
    """Initializes the map.

    Args:
      action_spec: a bounded 1-D spec with finite bounds, maximum >
        minimum.

    Raises:
      ValueError: a spec without bounds, not 1-D, or with bad bounds.
    """
    minimum = getattr(action_spec, 'minimum', None)
    maximum = getattr(action_spec, 'maximum', None)
    if minimum is None or maximum is None or len(action_spec.shape) != 1:
      raise ValueError(f'Expected a bounded 1-D action spec, got '
                       f'{action_spec!r}')
    shape = action_spec.shape
    self._minimum = np.broadcast_to(np.asarray(minimum, np.float64), shape)
    self._maximum = np.broadcast_to(np.asarray(maximum, np.float64), shape)
    if not (np.all(np.isfinite(self._minimum))
            and np.all(np.isfinite(self._maximum))
            and np.all(self._maximum > self._minimum)):
      raise ValueError(f'Action bounds must be finite with maximum > minimum,'
                       f' got minimum {self._minimum} and maximum '
                       f'{self._maximum}')
    self._identity = bool(np.all(self._minimum == -1.0)
                          and np.all(self._maximum == 1.0))
    self._half_range = 0.5 * (self._maximum - self._minimum)
    self._centre = 0.5 * (self._maximum + self._minimum)

  @property
  def size(self) -> int:
    """The action's size n."""
    return self._minimum.shape[0]

  @property
  def minimum(self) -> np.ndarray:
    """(n,) the spec's lower bounds."""
    return self._minimum.copy()

  @property
  def maximum(self) -> np.ndarray:
    """(n,) the spec's upper bounds."""
    return self._maximum.copy()

  def to_environment(self, normalised: np.ndarray) -> np.ndarray:
    """The environment action of a [-1, 1] action.

    Args:
      normalised: (n,) in [-1, 1] (clipped).

    Returns:
      (n,) float64 within the spec's bounds.
    """
    normalised = np.clip(np.asarray(normalised, np.float64), -1.0, 1.0)
    if self._identity:
      return normalised
    return self._centre + self._half_range * normalised

  def to_normalised(self, action: np.ndarray) -> np.ndarray:
    """The [-1, 1] action of an environment action.

    Args:
      action: (n,) an environment action (clipped to the bounds).

    Returns:
      (n,) float64 in [-1, 1].

    Raises:
      ValueError: an action of another shape.
    """
    action = np.asarray(action, np.float64)
    if action.shape != self._minimum.shape:
      raise ValueError(f'Action has shape {action.shape}, expected '
                       f'{self._minimum.shape}')
    if not self._identity:
      action = (action - self._centre) / self._half_range
    return np.clip(action, -1.0, 1.0)
