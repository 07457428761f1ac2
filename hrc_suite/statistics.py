"""Percentile bootstrap confidence intervals of a mean.

The reference benchmark reports the mean over seeds with a 95 % bootstrap
confidence interval from 10^4 resamples (docs/reference_benchmark.md,
Training and evaluation). `bootstrap_ci` does that for one sample or,
vectorised, for many (a learning curve: seeds x evaluation points) at once.
"""

import numpy as np

# The reference's evaluation protocol (docs/reference_benchmark.md, Training
# and evaluation).
DEFAULT_RESAMPLES = 10_000
DEFAULT_CONFIDENCE = 0.95


def bootstrap_ci(samples, random_state, confidence=DEFAULT_CONFIDENCE,
                 num_resamples=DEFAULT_RESAMPLES):
  """Mean and percentile-bootstrap confidence interval along axis 0.

  Args:
    samples: array (n,) or (n, m): n observations (e.g. seeds) of m
      quantities (e.g. evaluation points); NaN is not allowed.
    random_state: np.random.RandomState drawing the resamples.
    confidence: coverage in (0, 1).
    num_resamples: bootstrap resamples (with replacement, size n each).

  Returns:
    (mean, low, high), each a float for 1-D input or an (m,) array.
  """
  samples = np.asarray(samples, dtype=float)
  if samples.ndim not in (1, 2) or samples.shape[0] < 1:
    raise ValueError('samples must be a non-empty array of shape (n,) or '
                     f'(n, m), got shape {samples.shape}')
  if not np.all(np.isfinite(samples)):
    raise ValueError('samples must be finite (no NaN or inf), got '
                     f'{samples[~np.isfinite(samples)][:5]}')
  if not 0.0 < confidence < 1.0:
    raise ValueError(f'confidence must lie in (0, 1), got {confidence!r}')
  if int(num_resamples) != num_resamples or num_resamples < 1:
    raise ValueError('num_resamples must be a positive integer, got '
                     f'{num_resamples!r}')
  if not isinstance(random_state, np.random.RandomState):
    raise ValueError('random_state must be an np.random.RandomState, got '
                     f'{type(random_state).__name__}')
  one_dimensional = samples.ndim == 1
  data = samples[:, None] if one_dimensional else samples
  n = data.shape[0]
  resamples = int(num_resamples)
  indices = random_state.randint(0, n, size=(resamples, n))
  # How often each observation is drawn in each resample: the resampled
  # means are then one (resamples, n) x (n, m) product, without a
  # (resamples, n, m) array.
  offsets = n * np.arange(resamples)[:, None]
  counts = np.bincount((indices + offsets).ravel(),
                       minlength=resamples * n).reshape(resamples, n)
  means = counts @ data / n
  tail = 100.0 * (1.0 - confidence) / 2.0
  low, high = np.percentile(means, [tail, 100.0 - tail], axis=0)
  mean = data.mean(axis=0)
  if one_dimensional:
    return float(mean[0]), float(low[0]), float(high[0])
  return mean, low, high
