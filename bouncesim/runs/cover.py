"""Cover times measured on the kinematic twin (docs/model.md §20a, §22): the continuous
simulation that the model's coverage-time metrics (:mod:`planners.coverage.cover_time`) are
checked against.

``runs`` teams of ``robots`` robots each run ``horizon`` steps of the twin
(:class:`~bouncesim.robots.kinematic.KinematicBatch`, §8's steps, every robot from its own
uniform start over the N configurations, or from ``start``); a team's visited cells are the
union of its robots' counted steps at equal own-step t.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from planners.cells import CellSpace
from planners.coverage.cover_time import LEVELS, metric_times
from planners.noise import TurnNoise
from planners.plan import PolicyMix

__all__ = ["TwinCover", "twin_cover"]


@dataclass(frozen=True, eq=False)
class TwinCover:
    """Cover times of a simulated batch of teams.

    Attributes
    ----------
    t : (G,) int             steps at which the visited cells are read
    covered : (runs, G)      covered fraction of every team at every t (cells visited in
                             steps 0 … t−1)
    reach : (runs, 4) int    first t with C(t) ≥ X for X in LEVELS, −1 when not reached
    seconds : float
    first : (runs, P) int    the step at which each team first visits each cell (−1: not
                             within the horizon)
    """

    t: np.ndarray
    covered: np.ndarray
    reach: np.ndarray
    seconds: float
    first: np.ndarray | None = None

    @property
    def covered_mean(self) -> np.ndarray:
        """Mean covered fraction at every t."""
        return self.covered.mean(axis=0)

    @property
    def covered_se(self) -> np.ndarray:
        """Standard error of :attr:`covered_mean`."""
        return self.covered.std(axis=0, ddof=1) / math.sqrt(self.covered.shape[0])

    def T_mean(self, x: float) -> tuple[float | None, float]:
        """(mean T_X over the teams that reach X, share that does not)."""
        col = self.reach[:, list(LEVELS).index(x)]
        ok = col[col >= 0]
        return (float(ok.mean()) if ok.size else None), float(1 - ok.size / col.size)

    def T_mean_se(self, x: float) -> float | None:
        """Standard error of :meth:`T_mean`'s mean (None below two teams that reach X): how
        far a mean over the few runs that reach a rarely reached X can move by chance.
        """
        col = self.reach[:, list(LEVELS).index(x)]
        ok = col[col >= 0].astype(float)
        return float(ok.std(ddof=1) / math.sqrt(ok.size)) if ok.size > 1 else None


def twin_cover(env, policy, noise: TurnNoise, *, robots: int = 1, runs: int = 100,
               horizon: int = 20_000, epoch: int = 1000, times=None, rng=None, start=None,
               cells: CellSpace | None = None) -> TwinCover:
    """Simulate ``runs`` teams of ``robots`` twins for ``horizon`` steps each.

    Parameters
    ----------
    env : Environment
    policy : float or PolicyMix   one angle [deg], or a mix in epochs of ``epoch`` steps
                                  (every robot draws its own angle per epoch, §21)
    noise : TurnNoise             rotation noise (§11 stepped or §11a Gaussian)
    times : sequence of int       steps at which C(t) is read (default
                                  :func:`~planners.coverage.cover_time.metric_times`)
    start : int, optional         start configuration of every robot (default uniform)
    """
    from ..robots.kinematic import KinematicBatch
    from ..robots.noise import body_noise
    t0 = time.perf_counter()
    cs = cells if cells is not None else CellSpace(env)
    rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
    n = int(runs) * int(robots)
    starts = None if start is None else np.full(n, int(start))
    batch = KinematicBatch(env, n, rng, cells=cs, starts=starts)
    tw = body_noise(noise, cs.delta_deg)
    if isinstance(policy, PolicyMix):
        angles = np.asarray(policy.angles, dtype=float)
        alpha = np.asarray(policy.alpha, dtype=float) / sum(policy.alpha)
    else:
        angles, alpha = np.array([float(policy)]), np.ones(1)
    T = int(horizon)
    times = metric_times(T) if times is None else sorted({int(x) for x in times})
    want = {t: i for i, t in enumerate(times)}
    team = np.arange(n) // int(robots)
    P = cs.P
    first = np.full(int(runs) * P, -1, dtype=np.int64)
    covered = np.zeros(int(runs), dtype=np.int64)
    out = np.zeros((int(runs), len(times)))
    kneed = np.array([max(1, math.ceil(x * P - 1e-9)) for x in LEVELS])
    reach = np.full((int(runs), kneed.size), -1, dtype=np.int64)
    current = np.full(n, angles[0])
    for t in range(T + 1):
        if t in want:
            out[:, want[t]] = covered / P
        if t == T:
            break
        if angles.size > 1 and t % int(epoch) == 0:
            current = angles[rng.choice(angles.size, size=n, p=alpha)]
        cells, _ = batch.step(current, tw)
        ok = cells >= 0
        key = np.unique(team[ok] * P + cells[ok])
        new = key[first[key] < 0]
        if new.size:
            first[new] = t
            covered += np.bincount(new // P, minlength=int(runs))
            for i, k in enumerate(kneed):
                hit = (reach[:, i] < 0) & (covered >= k)
                reach[hit, i] = t + 1
    return TwinCover(t=np.asarray(times), covered=out, reach=reach,
                     seconds=time.perf_counter() - t0, first=first.reshape(int(runs), P))
