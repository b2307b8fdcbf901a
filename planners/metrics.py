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

__all__ = ["SPLITS", "floors", "tv_distance"]

SPLITS = 200
"""Random balanced splits of the trials behind a mean noise floor (:func:`floors`)."""


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


def floors(counts: np.ndarray, half: np.ndarray, rng: np.random.Generator,
           splits: int = SPLITS) -> tuple[float, float]:
    """The noise floor of one policy's trials and its mean over random splits.

    Parameters
    ----------
    counts : (T, P) array       per trial, the steps counted in each position cell
    half : (T,) int array        the half (0 or 1) of each trial: trials alternate
    rng : numpy.random.Generator draws the random splits
    splits : int                 random balanced splits averaged in the second number

    Returns
    -------
    (floor, floor_splits)
        TV between the sums of the trials of half 0 and of half 1 (docs/model.md §22: two
        independent halves, since every trial is a batch of independent robots with its own
        seed), and the mean of the same TV over ``splits`` random splits of the trials into
        two groups of ⌊T/2⌋ and ⌈T/2⌉ (each split is again two independent halves; the mean
        has less of the single split's luck).
    """
    counts = np.asarray(counts, dtype=float)
    half = np.asarray(half)
    floor = float(tv_distance(counts[half == 0].sum(axis=0), counts[half == 1].sum(axis=0)))
    T = len(counts)
    vals = []
    for _ in range(splits):
        perm = rng.permutation(T)
        vals.append(tv_distance(counts[perm[:T // 2]].sum(axis=0),
                                counts[perm[T // 2:]].sum(axis=0)))
    return floor, float(np.mean(vals))
