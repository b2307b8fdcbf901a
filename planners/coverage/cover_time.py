"""Coverage-time metrics from a model's own chain (docs/model.md §20a).

How fast a bouncing policy covers the map, for one robot or a team of K robots that ignore
each other, predicted from the coverage model's delay chain (:mod:`planners.coverage.timeshare`,
with every flight's steps counted where §20 counts them):

- the covered fraction C(t): the share of the P position cells visited at least once in the
  first t steps (mean, 10th and 90th percentiles over runs);
- T_X, the first t with C(t) ≥ X, for X in :data:`LEVELS`;
- each cell's mean return time (Kac: 1 / its share of the steps in the limit) and the worst
  idleness (the longest stretch of steps in which some cell is not visited);
- for a team, its robots' meetings (two robots counted in one cell at the same step): the
  first one, how often, and how often in the limit (closed form).

Exactly (:mod:`.cover_exact`: the chain on (unit, visited set)) when that chain is small,
otherwise by sampling runs of the chain (:mod:`.cover_sample`), with the standard error.

Three cells in a row at K = 4 with φ = 90° (the corridor of docs/model.md §16) in the step
model, from configuration 0 (cell 0 facing east): steps 0, 1, 2 are in cells 0, 1, 2, so all
three are covered after 3 steps:

>>> import envs
>>> from planners.cells import CellSpace
>>> from planners.coverage import model_for
>>> env = envs.Environment.from_dict({"boundary": [[0, 0], [1.1, 0], [1.1, 0.4], [0, 0.4]],
...     "robot_radius": 0.17, "discretization": {"cell_size": 0.34, "orientations": 4}})
>>> m, = coverage_metrics(model_for(CellSpace(env), "step"), 90, horizon=8, start=0,
...                       times=[1, 2, 3])
>>> m.method, m.covered_mean.round(3).tolist(), m.T["1.0"]["mean"]
('exact', [0.333, 0.667, 1.0], 3.0)
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from envs import UserError

from ..noise import TurnNoise
from ..plan import PolicyMix
from .cover_exact import (
    EXACT_MAX,
    MEET_EXACT_MAX,
    exact_distribution,
    exact_size,
    meeting_size,
    meeting_survival,
    subset_union,
)
from .cover_sample import SampleTables, sample_runs, turn_tables
from .event_flights import started_chain
from .horizon import start_distribution

__all__ = ["LEVELS", "CoverMetrics", "coverage_metrics", "metric_times", "return_times"]

LEVELS = (0.5, 0.8, 0.9, 1.0)   # the X of T_X
RUNS = 1000                      # default runs (teams) of the sampled path
_EXACT = TurnNoise()


def metric_times(horizon: int) -> list[int]:
    """The steps at which C(t) is reported: round(100·2^(k/4)) up to ``horizon``, and
    ``horizon`` itself.

    >>> metric_times(300)
    [100, 119, 141, 168, 200, 238, 283, 300]
    """
    out, k = [], 0
    while (t := int(round(100 * 2 ** (k / 4)))) < horizon:
        if not out or t > out[-1]:
            out.append(t)
        k += 1
    return out + [int(horizon)]


@dataclass(frozen=True, eq=False)
class CoverMetrics:
    """Coverage-time metrics of one policy and team size (docs/model.md §20a).

    Attributes
    ----------
    angle : float or None     bouncing angle [deg]; None for a mix
    robots : int              team size K
    horizon : int             steps per robot [steps]
    t : (G,) int              the steps at which C(t) is given
    covered_mean, covered_p10, covered_p90 : (G,)   mean and percentiles of C(t)
    covered_se : (G,)         standard error of covered_mean (0 when exact)
    T : dict                  "0.5", "0.8", "0.9", "1.0" → {"mean", "median", "not_reached"}
                              (and "mean_se"): the mean over the runs that reach X within the
                              horizon, the median over all runs (None when half do not reach
                              it), the share that does not [steps]
    return_time : (P,)        mean return time of each cell [steps], inf when never visited
                              in the limit
    idleness_worst : float    mean over runs of the worst idleness [steps] (always sampled)
    idleness_se : float
    method : str              "exact" or "sampled" (C(t) and T)
    runs : int                sampled runs (teams), for the idleness too
    seed : int                seed of the sampler
    details : dict            policy (angles, alpha, epoch), noise, start, seconds
    cell_visited : (G, P)     the share of runs in which the team has visited cell p in
                              steps 0 … t−1, for every t of :attr:`t` (always sampled; not in
                              ``metrics.json``): which places a run is likely to miss
    meeting : dict or None    a team's meetings (None for one robot): "first" (the first
                              step with two robots counted in one cell: "mean", "median",
                              "not_reached", "mean_se", and "method": exact for two robots
                              on a small chain, else sampled), "per_1000" and its "per_1000_se"
                              (meetings per 1000 steps of one robot within the horizon,
                              sampled: a pair's meeting counts for both), "per_1000_limit"
                              (the same in the limit, 1000 (K − 1) Σ_p s_p², closed form)
    """

    angle: float | None
    robots: int
    horizon: int
    t: np.ndarray
    covered_mean: np.ndarray
    covered_p10: np.ndarray
    covered_p90: np.ndarray
    covered_se: np.ndarray
    T: dict
    return_time: np.ndarray
    idleness_worst: float
    idleness_se: float
    method: str
    runs: int
    seed: int
    details: dict = field(default_factory=dict)
    cell_visited: np.ndarray | None = None
    meeting: dict | None = None

    def covered_at(self, t: int) -> float:
        """covered_mean at a step of :attr:`t`."""
        return float(self.covered_mean[list(self.t).index(int(t))])

    def to_json(self) -> dict:
        """The record of ``metrics.json`` (inf and missing values as null)."""
        return {"angle": "mix" if self.angle is None else _num(self.angle),
                "robots": self.robots, "horizon": self.horizon, "method": self.method,
                "t": [int(x) for x in self.t],
                "covered_mean": _list(self.covered_mean), "covered_p10": _list(self.covered_p10),
                "covered_p90": _list(self.covered_p90), "covered_se": _list(self.covered_se),
                "T": {k: {kk: _val(vv) for kk, vv in v.items()} for k, v in self.T.items()},
                "return_time_mean": _list(self.return_time),
                "idleness_worst": self.idleness_worst, "idleness_se": self.idleness_se,
                **({} if self.meeting is None else {"meeting": {
                    k: {kk: _val(vv) if kk != "method" else vv for kk, vv in v.items()}
                    if isinstance(v, dict) else _val(v) for k, v in self.meeting.items()}}),
                "runs": self.runs, "seed": self.seed, **self.details}


def _num(x):
    x = float(x)
    return int(round(x)) if abs(x - round(x)) < 1e-9 else x


def _val(x):
    return None if x is None or not math.isfinite(x) else float(x)


def _list(a) -> list:
    return [_val(x) for x in np.asarray(a, dtype=float)]


class _Prepared:
    """A model's started chain and its sampling tables (per noise's kind of flights)."""

    def __init__(self, model, noise: TurnNoise, angles=None) -> None:
        self.sc = started_chain(model, noise, angles)
        self.tables = SampleTables.of(self.sc)


def return_times(model, noise: TurnNoise, policy, epoch: int | None = None,
                 limit=None) -> np.ndarray:
    """Mean return time [steps] of every position cell (Kac): 1 / s_p, s_p the share of all
    steps (dropped ones included) counted in cell p in the limit; inf where s_p = 0.

    ``policy``: an angle, or a :class:`PolicyMix`. ``limit``: the angle's
    :class:`~planners.coverage.base.AngleCoverage`, or (q, counted fraction), when already
    known; for a mix executed in epochs pass §19's time-shared (q, counted fraction) when it
    is known (``epoch`` is then not used). Without it a mix's shares are Σ α_a s_a over its
    angles (the limit of long epochs, docs/model.md §16): the time-shared recursion can take
    minutes on maps whose rooms exchange the robot rarely.
    """
    if limit is None and isinstance(policy, PolicyMix):
        al = np.asarray(policy.alpha, dtype=float) / sum(policy.alpha)
        s = sum(a / return_times(model, noise, ang) for a, ang in zip(al, policy.angles)
                if a > 0)
        limit = (s, 1.0)
    elif limit is None or hasattr(limit, "pi"):
        cov = limit if limit is not None else model.analyse(float(policy), noise)
        ch = _prepared(model, noise, [float(policy)]).sc.chain
        nb = cov.pi.size
        length = np.bincount(ch.src, weights=ch.weight * ch.delay, minlength=ch.n)[:nb]
        counted = float(np.asarray(ch.reward[:nb].sum(axis=1)).ravel() @ cov.pi)
        limit = (cov.q, counted / float(length @ cov.pi))
    q, c = limit
    s = np.asarray(q, dtype=float) * float(c)
    with np.errstate(divide="ignore"):
        return np.where(s > 0, 1.0 / np.where(s > 0, s, 1.0), np.inf)


_CACHE: dict = {}


def _prepared(model, noise: TurnNoise, angles) -> _Prepared:
    """The started chain of ``model`` for bumps by ``angles`` under ``noise``, kept per kind
    of flights (Gaussian or not, and the body's rest turn in the sense they spin, §11b).
    """
    key = (id(model), bool(noise.gaussian) and model.steps_in_flights,
           noise.rest_for(angles) if model.steps_in_flights else 0.0)
    hit = _CACHE.get(key)
    if hit is None or hit[0] is not model:
        if len(_CACHE) >= 4:
            _CACHE.pop(next(iter(_CACHE)))
        hit = _CACHE[key] = (model, _Prepared(model, noise, angles))
    return hit[1]


def coverage_metrics(model, policy, noise: TurnNoise | None = None, *, robots=1,
                     horizon: int = 20_000, epoch: int | None = None, start=None,
                     runs: int = RUNS, rng=None, exact: bool | None = None, times=None,
                     limits=None, progress=None) -> list[CoverMetrics]:
    """Coverage-time metrics of bouncing policies (docs/model.md §20a).

    Parameters
    ----------
    model : CoverageModel         any of :data:`planners.coverage.MODELS`
    policy : float, sequence of float or PolicyMix
                                  one record per angle, or one for the mix (executed in epochs)
    noise : TurnNoise, optional   rotation noise (default: the mix's, else exact)
    robots : int or sequence      team sizes K (one record per policy and K)
    horizon : int                 steps per robot T
    epoch : int, optional         steps per epoch of a mix (default 1000)
    start : optional              start of every robot: None (uniform over the N
                                  configurations), a configuration z, or N weights
    runs : int                    sampled runs (teams) per record
    rng : numpy.random.Generator or int, optional
    exact : bool, optional        True: exactly (at most 20 cells), False: by sampling;
                                  None (default): exactly when the chain on (unit, visited
                                  set) has at most :data:`EXACT_MAX` entries
    times : sequence of int, optional   steps at which C(t) is given (default
                                  :func:`metric_times`)
    limits : sequence, optional   per policy its limit, when known: an AngleCoverage or
                                  (q, counted fraction) (see :func:`return_times`)
    progress : callable, optional wraps the iterable of records (tqdm)
    """
    cs = model.cs
    T = int(horizon)
    if T < 1:
        raise UserError(f"the horizon must be at least one step, got {horizon}.")
    ks = [int(k) for k in np.atleast_1d(robots)]
    if not ks or min(ks) < 1:
        raise UserError("a team needs at least one robot.")
    if int(runs) < 2:
        raise UserError(f"the sampled metrics need at least two runs, got {runs}.")
    rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
    if isinstance(policy, PolicyMix):
        noise = noise if noise is not None else TurnNoise(policy.eps, policy.r, policy.sigma)
        epoch = int(epoch) if epoch is not None else 1000
        if epoch < 1:
            raise UserError(f"an epoch must be at least one step, got {epoch}.")
        policies = [(None, list(policy.angles), np.asarray(policy.alpha, dtype=float))]
    else:
        noise = noise if noise is not None else _EXACT
        policies = [(float(a), [float(a)], np.ones(1)) for a in np.atleast_1d(policy)]
    times = metric_times(T) if times is None else sorted({int(x) for x in times})
    if not times or times[0] < 1 or times[-1] > T:
        raise UserError(f"the steps of C(t) must lie in 1 … {T}.")
    p0 = start_distribution(cs, start)
    prep = _prepared(model, noise, [a for _, angs, _ in policies for a in angs])
    z = np.flatnonzero(p0 > 0)
    sstates, sweights = prep.sc.offset + z, p0[z]
    kneed = np.array([max(1, math.ceil(x * cs.P - 1e-9)) for x in LEVELS])
    if exact is None:
        exact = exact_size(prep.tables, cs.P) <= EXACT_MAX
    if exact and cs.P > 20:
        raise UserError(f"the exact cover times need at most 20 cells; this map has {cs.P}.")
    jobs = [(i, k) for i in range(len(policies)) for k in ks]
    out, kept = [], {}
    for i, k in (progress(jobs) if progress else jobs):
        t0 = time.perf_counter()
        angle, angs, alpha = policies[i]
        if i not in kept:                        # one policy's turns serve every team size
            kept.clear()
            turns = [model.turn_matrix(a, noise) for a in angs]
            kept[i] = (turns, turn_tables(turns))
        turns, tt = kept[i]
        seed = int(rng.integers(2 ** 31 - 1))
        sampled = sample_runs(prep.tables, tt, alpha, epoch, sstates, sweights, cs.P, k,
                              int(runs), T, times, kneed, seed)
        if exact:
            cov, Ts = _exact_stats(prep.tables, turns, alpha, epoch, sstates, sweights, cs.P,
                                   k, T, times, kneed)
        else:
            cov, Ts = _sampled_stats(sampled.counts, sampled.reach, cs.P)
        pol = policy if isinstance(policy, PolicyMix) else angle
        lim = None if limits is None else limits[i]
        rt = return_times(model, noise, pol, epoch, lim)
        meeting = None
        if k > 1:
            meet_exact = (exact and k == 2 and len(angs) == 1
                          and meeting_size(prep.tables, T) <= MEET_EXACT_MAX)
            surv = meeting_survival(prep.tables, turns[0], sstates, sweights, T) \
                if meet_exact else None
            meeting = _meeting_stats(sampled, surv, k, T, rt)
        idle = sampled.idle
        details = {"angles": [_num(a) for a in angs], "alpha": [float(a) for a in alpha],
                   "epoch": epoch if angle is None else None, "noise": str(noise),
                   "start": "uniform" if start is None else (
                       int(start) if np.ndim(start) == 0 else "distribution"),
                   "model": model.name, "P": cs.P,
                   "seconds": round(time.perf_counter() - t0, 3)}
        out.append(CoverMetrics(angle=angle, robots=k, horizon=T, t=np.asarray(times), **cov,
                                T=Ts, return_time=rt, idleness_worst=float(idle.mean()),
                                idleness_se=float(idle.std(ddof=1) / math.sqrt(idle.size)),
                                method="exact" if exact else "sampled", runs=int(runs),
                                seed=seed, details=details,
                                cell_visited=visited_by(sampled.first, times),
                                meeting=meeting))
    return out


def visited_by(first, times) -> np.ndarray:
    """(G, P) the share of runs whose first visit of each cell (``first`` (runs, P), −1:
    none) falls in steps 0 … t−1, for every t of ``times``.
    """
    f = np.where(first < 0, np.iinfo(np.int64).max, first.astype(np.int64))
    return np.stack([(f < int(t)).mean(axis=0) for t in times])


def _sampled_stats(counts, reach, P: int) -> tuple[dict, dict]:
    """C(t) and T_X from sampled runs (percentiles as the inverted CDF)."""
    frac = counts / P
    n = frac.shape[0]
    cov = {"covered_mean": frac.mean(axis=0),
           "covered_p10": np.quantile(frac, 0.1, axis=0, method="inverted_cdf"),
           "covered_p90": np.quantile(frac, 0.9, axis=0, method="inverted_cdf"),
           "covered_se": frac.std(axis=0, ddof=1) / math.sqrt(n)}
    return cov, {_key(x): _time_stats(col) for x, col in zip(LEVELS, reach.T)}


def _time_stats(col: np.ndarray) -> dict:
    """The mean over the runs whose time ``col`` was reached (not −1), the median over all
    (None when half were not), the share not reached and the mean's standard error.
    """
    ok = col[col >= 0].astype(float)
    med = np.quantile(np.where(col >= 0, col, np.inf), 0.5, method="inverted_cdf")
    return {"mean": float(ok.mean()) if ok.size else None,
            "median": float(med) if np.isfinite(med) else None,
            "not_reached": float(1 - ok.size / col.size),
            "mean_se": float(ok.std(ddof=1) / math.sqrt(ok.size)) if ok.size > 1 else None}


def _cdf_stats(F: np.ndarray) -> dict:
    """:func:`_time_stats` of an exact distribution: ``F[t]`` = Pr(time ≤ t), t = 0, 1, …
    (the horizon's end: what is left is not reached); the standard error is 0.
    """
    F = np.maximum.accumulate(np.clip(F, 0.0, 1.0))
    pmf = np.diff(np.concatenate([[0.0], F]))
    got = float(F[-1])
    med = np.flatnonzero(F >= 0.5 - 1e-12)
    return {"mean": float(pmf @ np.arange(F.size)) / got if got > 1e-12 else None,
            "median": float(med[0]) if med.size else None,
            "not_reached": max(0.0, 1.0 - got), "mean_se": 0.0}


def _meeting_stats(sampled, survival, K: int, T: int, return_time) -> dict:
    """The ``meeting`` record of a team of K (:class:`CoverMetrics`): the first meeting exactly
    from the product chain's ``survival`` (Pr(τ > t)) when given, else from the sampled runs;
    the meetings per 1000 steps sampled, and in the limit from the cells' shares s = 1/return
    time.
    """
    first = (dict(_cdf_stats(1.0 - survival), method="exact") if survival is not None
             else dict(_time_stats(sampled.meet), method="sampled"))
    per = 2000.0 * sampled.pairs / (K * T)          # each pair's meeting counts for both
    s = np.where(np.isfinite(return_time), 1.0 / return_time, 0.0)
    return {"first": first, "per_1000": float(per.mean()),
            "per_1000_se": float(per.std(ddof=1) / math.sqrt(per.size)),
            "per_1000_limit": 1000.0 * (K - 1) * float(s @ s)}


def _key(x: float) -> str:
    return f"{x:.1f}"


def _exact_stats(tables, turns, alpha, epoch, sstates, sweights, P, K, T, times,
                 kneed) -> tuple[dict, dict]:
    """C(t) and T_X of a team of K exactly (:mod:`.cover_exact`)."""
    pop = np.array([bin(s).count("1") for s in range(1 << P)])
    want = set(times)
    G = len(times)
    cov: dict[str, Any] = {k: np.zeros(G) for k in ("covered_mean", "covered_p10",
                                                    "covered_p90", "covered_se")}
    reach_cdf = np.zeros((len(kneed), T + 1))
    gi = 0
    for t, g in exact_distribution(tables, turns, alpha, epoch, sstates, sweights, P, T):
        pc = np.bincount(pop, weights=subset_union(g, K), minlength=P + 1)
        cdf = np.cumsum(pc)
        tail = 1.0 - np.concatenate([[0.0], cdf[:-1]])      # Pr(count ≥ c)
        reach_cdf[:, t] = tail[kneed]
        if t in want:
            cov["covered_mean"][gi] = float(pc @ np.arange(P + 1)) / P
            cov["covered_p10"][gi] = _inv_cdf(cdf, 0.1) / P
            cov["covered_p90"][gi] = _inv_cdf(cdf, 0.9) / P
            gi += 1
    return cov, {_key(x): _cdf_stats(F) for x, F in zip(LEVELS, reach_cdf)}


def _inv_cdf(cdf: np.ndarray, p: float) -> float:
    """The smallest count whose CDF reaches p (the inverted CDF, as the sampled path)."""
    return float(np.flatnonzero(cdf >= p - 1e-12)[0])
