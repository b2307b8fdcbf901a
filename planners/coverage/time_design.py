"""A policy mix designed for time, not only for shape (docs/model.md §20b): the α that
minimises the time to cover 90 % of the room, or the worst idleness, predicted by the
coverage-time metrics of the model's own chain (:mod:`planners.coverage.cover_time`).

The objective of a mix α executed in epochs:

- ``"cover90"``: E[min(T_90, T)], the mean over runs of the first step at which 90 % of the
  position cells have been visited, a run that does not get there within the horizon T
  counting T (so the objective is finite and a mix that rarely covers is penalised by how
  often it fails);
- ``"idleness"``: the mean over runs of the worst idleness within T (§20a).

How it is optimised: both objectives come from sampled runs of the chain, so they are noisy
and not smooth in α. The search is exhaustive over the simplex grid of step 1/n
(:func:`simplex_grid`: every α with Σα = 1 and α_i a multiple of 1/n, the pure angles among
them), each candidate evaluated with the same sampler seed (common random numbers: the
differences between candidates are far less noisy than each value). The ``refine`` best
are then sampled again with ``refine_factor`` times the runs and a fresh seed, and the best
of those is returned with its standard error and every candidate's value. For three angles
and n = 10 that is 66 candidates.

(:func:`planners.coverage.design_mix` with ``objective="cover90"`` or ``"idleness"`` calls
:func:`design_for_time`; its default ``"tv"`` is §16's fit of the shape.)

>>> simplex_grid(3, 2).tolist()   # doctest: +NORMALIZE_WHITESPACE
[[0.0, 0.0, 1.0], [0.0, 0.5, 0.5], [0.0, 1.0, 0.0], [0.5, 0.0, 0.5], [0.5, 0.5, 0.0],
 [1.0, 0.0, 0.0]]
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from envs import UserError

from ..noise import TurnNoise
from ..plan import PolicyMix
from .cover_time import coverage_metrics, return_times

__all__ = ["OBJECTIVES", "TimeDesign", "design_for_time", "objective_value", "simplex_grid"]

OBJECTIVES = ("tv", "cover90", "idleness")
"""What :func:`planners.coverage.design_mix` optimises: the TV of the long-run shape to a
target (§16), the time to cover 90 % of the room, or the worst idleness."""


def simplex_grid(m: int, n: int) -> np.ndarray:
    """Every α over ``m`` angles with Σα = 1 and each α_i a multiple of 1/``n`` (rows)."""
    rows = [c for c in itertools.product(range(n + 1), repeat=m) if sum(c) == n]
    return np.array(rows, dtype=float) / n


def objective_value(metrics, objective: str) -> tuple[float, float]:
    """(value, standard error) of one :class:`~planners.coverage.cover_time.CoverMetrics`
    record for ``objective`` ("cover90" or "idleness") [steps].
    """
    if objective == "idleness":
        return metrics.idleness_worst, metrics.idleness_se
    t90 = metrics.T["0.9"]
    miss = float(t90["not_reached"])
    if t90["mean"] is None or miss >= 1.0:
        return float(metrics.horizon), 0.0
    value = (1.0 - miss) * float(t90["mean"]) + miss * metrics.horizon
    se = t90.get("mean_se")                 # None when a single run got there
    return value, (1.0 - miss) * float(se) if se is not None else math.nan


@dataclass(frozen=True, eq=False)
class TimeDesign:
    """A mix designed for a time objective.

    Attributes
    ----------
    objective : str           "cover90" or "idleness"
    angles : tuple of float   bouncing angles [deg]
    noise : TurnNoise
    alpha : ndarray (m,)      the best candidate
    value, value_se : float   its objective [steps] and standard error
    candidates : ndarray (c, m)   every α tried
    values, values_se : ndarray (c,)   the screening values (``runs`` runs, ``seed``)
    refined : dict            candidate index -> (value, se) of the second stage
    horizon, epoch, robots, runs, seed : int   how the objective was sampled
    """

    objective: str
    angles: tuple
    noise: TurnNoise
    alpha: np.ndarray
    value: float
    value_se: float
    candidates: np.ndarray
    values: np.ndarray
    values_se: np.ndarray
    refined: dict
    horizon: int
    epoch: int
    robots: int
    runs: int
    seed: int

    @property
    def mix(self) -> PolicyMix:
        """The :class:`PolicyMix` to execute."""
        return PolicyMix(tuple(self.angles), tuple(float(a) for a in self.alpha),
                         self.noise.eps_deg, self.noise.r, self.noise.sigma_deg)


def design_for_time(model, angles, noise: TurnNoise, objective: str = "cover90", *,
                    horizon: int = 20_000, epoch: int = 1000, robots: int = 1,
                    runs: int = 300, grid: int = 10, refine: int = 5,
                    refine_factor: int = 5, rng=None, progress=None) -> TimeDesign:
    """The α over ``angles`` that minimises ``objective`` (module docstring).

    Parameters
    ----------
    model : CoverageModel
    angles : sequence of float     bouncing angles [deg]
    noise : TurnNoise
    objective : {"cover90", "idleness"}
    horizon : int                  steps per robot T
    epoch : int                    steps per epoch of the executed mix
    robots : int                   team size K the objective is for
    runs : int                     sampled runs per candidate
    grid : int                     n of the simplex grid (step 1/n)
    refine, refine_factor : int    the best ``refine`` candidates are sampled again with
                                   ``refine_factor`` × ``runs`` runs and a new seed (0: no
                                   second stage)
    rng : numpy.random.Generator or int   draws the one sampler seed all candidates share
    progress : callable, optional  wraps the iterable of candidates (tqdm)
    """
    if objective not in OBJECTIVES[1:]:
        raise UserError(f"unknown time objective {objective!r}; use cover90 or idleness.")
    angles = tuple(float(a) for a in angles)
    if int(grid) < 1:
        raise UserError(f"the simplex grid needs n >= 1, got {grid}.")
    rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
    seed, seed2 = (int(v) for v in rng.integers(2 ** 31 - 1, size=2))
    cands = simplex_grid(len(angles), int(grid))

    # each angle's long-run shares, once: a candidate's record needs Σ α_a s_a for its
    # return times (cover_time.return_times), which would otherwise re-solve every angle's
    # limit for every candidate (98 % of the search's time)
    shares = [1.0 / return_times(model, noise, a) for a in angles]

    def evaluate(alpha, n, s):
        mix = PolicyMix(angles, tuple(alpha), noise.eps_deg, noise.r, noise.sigma_deg)
        limit = (sum(a * sh for a, sh in zip(alpha, shares) if a > 0), 1.0)
        rec, = coverage_metrics(model, mix, noise, robots=int(robots), horizon=int(horizon),
                                epoch=int(epoch), runs=int(n), rng=s, exact=False,
                                times=[int(horizon)], limits=[limit])
        return objective_value(rec, objective)

    values, ses = np.empty(len(cands)), np.empty(len(cands))
    for i in (progress(range(len(cands))) if progress else range(len(cands))):
        values[i], ses[i] = evaluate(cands[i], runs, seed)
    refined = {int(i): evaluate(cands[i], int(runs) * int(refine_factor), seed2)
               for i in np.argsort(values, kind="stable")[:max(int(refine), 0)]}
    if refined:
        best = min(refined, key=lambda i: refined[i][0])
        value, se = refined[best]
    else:
        best = int(np.argmin(values))
        value, se = values[best], ses[best]
    return TimeDesign(objective, angles, noise, cands[best], float(value), float(se), cands,
                      values, ses, refined, int(horizon), int(epoch), int(robots), int(runs),
                      seed)
