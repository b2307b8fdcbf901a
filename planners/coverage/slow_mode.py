"""The slowest mode of a horizon run (docs/model.md §20): once the faster modes have died
out, the share of each step in each cell differs from the limit by u·λ^t of one direction,
so every later horizon's counts follow in closed form. :mod:`planners.coverage.to_limit`
extrapolates steps_to_limit with it; :mod:`planners.coverage.horizon` predicts with it when
a run settles at its limit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["SlowMode", "at_end", "slow_mode"]

_WINDOW = 0.5               # the fit uses the segments that start at or after 0.5·T_last
_MIN_SEGMENTS = 3           # ... at least this many
_MIN_COSINE = 0.9           # ... whose deviations point the same way (one mode)


@dataclass(frozen=True, eq=False)
class SlowMode:
    """A run's counts beyond its last horizon T, from its slowest mode (see :func:`slow_mode`).

    Attributes
    ----------
    T : int                 last horizon of the run [steps]
    counts : (P,) ndarray   counted steps per cell of its first T steps
    rate : float            counted steps per step at T
    q : (P,) ndarray        the limit
    u : (P,) ndarray        deviation of the per-step share from q at step T
    lam : float             the mode's factor per step (0 < λ < 1)
    """

    T: int
    counts: np.ndarray
    rate: float
    q: np.ndarray
    u: np.ndarray
    lam: float

    @property
    def relaxation(self) -> float:
        """1/(1 − λ) [steps]: the deviation shrinks by e in this many steps."""
        return 1.0 / (1.0 - self.lam)

    def counts_at(self, T: int) -> np.ndarray:
        """Counted steps per cell of the first ``T`` ≥ :attr:`T` steps:
        counts + rate·((T − T_L)·q + u·(1 − λ^(T − T_L))/(1 − λ)).
        """
        dt = int(T) - self.T
        if dt < 0:
            raise ValueError("a slow mode extrapolates forwards only.")
        return self.counts + self.rate * (dt * self.q
                                          + self.u * -math.expm1(dt * math.log(self.lam))
                                          * self.relaxation)


def slow_mode(history, limit_q) -> SlowMode | None:
    """The slowest mode of a run from its counts at increasing horizons (docs/model.md §20).

    ``history``: (T, counts) pairs, T increasing. Each segment between two horizons gives the
    per-step share in each cell, s_k (normalised), and its deviation e_k = s_k − q from the
    limit. Over the segments that start at or after half the last T (at least three), log ‖e_k‖₁
    is fitted against the segment's middle step by least squares: the slope is log λ. None
    when that is no single decaying mode: fewer than three segments, λ ≥ 1 (not yet
    decaying: the limit is not in sight), or deviations whose directions differ (cosine
    below 0.9 between the first and the last: several modes of similar speed).
    """
    q = np.asarray(limit_q, dtype=float)
    if len(history) < 2:
        return None
    T_last = history[-1][0]
    devs, mids = [], []
    for (t0, c0), (t1, c1) in zip(history, history[1:]):
        if t0 < _WINDOW * T_last:
            continue
        s = (np.asarray(c1, dtype=float) - c0) / (t1 - t0)
        if not s.sum() > 0:
            return None
        devs.append(s / s.sum() - q)
        mids.append(0.5 * (t0 + t1))
    if len(devs) < _MIN_SEGMENTS:
        return None
    norms = np.array([np.abs(e).sum() for e in devs])
    first, last = devs[0], devs[-1]
    cos = float(first @ last) / max(float(np.linalg.norm(first) * np.linalg.norm(last)), 1e-300)
    if not (norms > 0).all() or cos < _MIN_COSINE:
        return None
    slope = float(np.polyfit(mids, np.log(norms), 1)[0])
    lam = math.exp(slope)
    if not 0.0 < lam < 1.0:
        return None
    return at_end(history, q, last * lam ** (history[-1][0] - mids[-1]), lam)


def at_end(history, limit_q, u, lam: float) -> SlowMode:
    """The :class:`SlowMode` of deviation ``u`` and factor ``lam`` at the end of ``history``
    (at least two horizons): its counts there and the counted steps per step of its last
    segment.
    """
    (t0, c0), (t1, c1) = history[-2], history[-1]
    c1 = np.asarray(c1, dtype=float)
    return SlowMode(T=int(t1), counts=c1, rate=float(np.sum(c1 - c0)) / (t1 - t0),
                    q=np.asarray(limit_q, dtype=float), u=np.asarray(u, dtype=float), lam=lam)
