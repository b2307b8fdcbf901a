"""The offset distributions behind :class:`planners.noise.TurnNoise` (docs/model.md §11,
§11a): §11's stepped offsets, the Gaussian on the orientation grid, and ε in quanta.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.special import ndtr, ndtri

from envs import UserError

__all__ = ["GAUSS_TAIL", "gauss_support", "quanta_of", "stepped_support"]

GAUSS_TAIL = 1e-6
"""Gaussian noise on the K grid: offsets are kept out to the smallest ±M whose two tails
beyond (M + ½)Δ hold at most this much probability; the kept ones are renormalised."""


def stepped_support(m: int, r: float) -> tuple[np.ndarray, np.ndarray]:
    """Offsets −m … m [quanta] of §11's stepped noise: 0 with r, the rest (1 − r)/(2m) each."""
    if m == 0:
        return np.array([0]), np.array([1.0])
    d = np.arange(-m, m + 1)
    return d, np.where(d == 0, r, (1.0 - r) / (2 * m))


def gauss_support(sigma: float, delta: float, mean: float = 0.0
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Offsets −M … M [quanta] and Φ(((j + ½)Δ − μ)/σ) − Φ(((j − ½)Δ − μ)/σ), renormalised
    (§11a; μ = ``mean``, 0 but for a body's own offset, §11b); σ = 0: all of it on the
    offset nearest μ (ties: the lower).
    """
    if not (math.isfinite(delta) and delta > 0):
        raise UserError(f"the noise quantum delta must be positive, got {delta:g}°.")
    if sigma == 0:
        j = math.ceil(mean / delta - 0.5)
        m = abs(j)
        d = np.arange(-m, m + 1)
        return d, (d == j).astype(float)
    z = -float(ndtri(GAUSS_TAIL / 2))                    # 2·(1 − Φ(z)) = GAUSS_TAIL
    m = max(0, math.ceil((z * sigma + abs(mean)) / delta - 0.5))
    m = min(m, 1_000_000)                                # wraps the circle many times
    d = np.arange(-m, m + 1)
    p = ndtr(((d + 0.5) * delta - mean) / sigma) - ndtr(((d - 0.5) * delta - mean) / sigma)
    return d, p / p.sum()


def quanta_of(eps_deg: float, delta_deg: float) -> int:
    """ε / Δ for an arbitrary quantum Δ [deg] > 0 (UserError unless a whole number)."""
    if not (math.isfinite(delta_deg) and delta_deg > 0):
        raise UserError(f"the noise quantum delta must be positive, got {delta_deg:g}°.")
    m = eps_deg / delta_deg
    if abs(m - round(m)) > 1e-9 * max(1.0, m):
        raise UserError(f"error range eps = {eps_deg:g}° is not a multiple of the "
                        f"orientation step {delta_deg:g}°.")
    return int(round(m))
