"""Distances between distributions over cells, shared by the models, the simulators and the
experiments.

>>> tv_distance([1, 0], [0.5, 0.5]), tv_distance([2, 2], [1, 1])
(0.5, 0.0)
>>> tv_distance([0.5, 0.5], [0.25, 0.75], normalise=False)
0.25
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["tv_distance"]


def tv_distance(a: ArrayLike, b: ArrayLike, *, normalise: bool = True) -> float:
    """Total-variation distance ½ Σ |a − b| between two non-negative vectors.

    Parameters
    ----------
    a, b : array_like
        Counts or probabilities over the same cells.
    normalise : bool
        Divide each by its sum first (default), so counts and probabilities mix freely;
        ``False`` takes them as they are (both already sum to 1).
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    if normalise:
        a, b = a / a.sum(), b / b.sum()
    return 0.5 * float(np.abs(a - b).sum())
