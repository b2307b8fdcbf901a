"""The offset distributions behind :class:`planners.noise.TurnNoise` (docs/model.md §11,
§11a): §11's stepped offsets, the Gaussian on the orientation grid, and ε in quanta; and a
body's own errors on its spins (§11b: it lags in the sense it spins, the shorter way).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.special import ndtr, ndtri

from envs import UserError

from .measures import wrap180

__all__ = ["GAUSS_TAIL", "body_errors", "gauss_support", "quanta_of", "spin_sign",
           "stepped_support"]

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


def spin_sign(rho):
    """+1 for a counter-clockwise spin ρ ≥ 0 [deg], −1 for a clockwise one (scalars or arrays)."""
    return np.where(np.asarray(rho) < 0, -1.0, 1.0) if np.ndim(rho) else (-1.0 if rho < 0 else 1.0)


def body_errors(rng: np.random.Generator, commanded, shape, sigma_deg: float,
                offset_deg: float, factor: float) -> np.ndarray:
    """A body's own errors [deg] on bumps by ``commanded`` [deg] (docs/model.md §11b): each
    spins ρ = wrap180(φ), the shorter way, and lags in its sense, sign(ρ)·O + (F − 1)·ρ plus
    N(0, S²), drawn as one array of ``shape`` from ``rng``.
    """
    rho = wrap180(np.broadcast_to(np.asarray(commanded, dtype=float), shape))
    return (spin_sign(rho) * offset_deg + (factor - 1.0) * rho
            + rng.normal(0.0, sigma_deg, size=shape))
