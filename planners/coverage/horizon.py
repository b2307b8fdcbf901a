"""Coverage over a horizon of T steps, and the time a policy needs to reach its limit
(docs/model.md §20).

docs/model.md §16 predicts the *limiting* coverage. On a map whose rooms exchange the robot
rarely the limit can be days of driving away; a user who runs the robot for T steps wants
the expected fraction of *those* T steps spent in each cell. This module computes it with
the model's own dynamics, step by step, through the delay chain of
:mod:`planners.coverage.timeshare` (a horizon is one run of T steps from the start, no fixed point):

- :class:`Horizon`: a model's delay chain extended for horizons: per-step rewards, so that a
  flight cut by T counts only the steps made before T, and (event model) the first flights
  from the cell-centre starts, whose steps are counted too.
- :func:`horizon_coverage`: q_T of one angle or of a mix executed in epochs (docs/model.md §21),
  from the uniform start or a given start.
- :func:`grid`: the horizons at which :mod:`planners.coverage.to_limit` reads the time to
  the limit (a geometric grid of ratio 2^(1/8) from 100); one pass serves every grid point.

Two cells in a row at K = 4 with φ = 180°: from the uniform start half of the robots shuttle
east-west, half north-south, and the step model's q_T is uniform at every T:

>>> import envs
>>> from planners.cells import CellSpace
>>> from planners.coverage import model_for
>>> env = envs.Environment.from_dict({"boundary": [[0, 0], [0.68, 0], [0.68, 0.34],
...     [0, 0.34]], "discretization": {"cell_size": 0.34, "orientations": 4}})
>>> hz = Horizon(model_for(CellSpace(env), "step"))
>>> hz.coverage([180], horizon=3).q.round(6).tolist()
[0.5, 0.5]
"""

from __future__ import annotations

import math
import time
import weakref
from dataclasses import dataclass
from functools import lru_cache, partial

import numpy as np
import scipy.sparse as sp
from scipy.optimize import minimize

from envs import UserError

from ..metrics import tv_distance
from ..noise import TurnNoise
from .event_flights import started_chain
from .mix import MixDesign, solve_mix
from .slow_mode import slow_mode
from .timeshare import DelayChain, TimeShared

__all__ = ["Horizon", "HorizonCoverage", "horizon_coverage", "horizon_of",
           "start_distribution", "fit_horizon_mix", "CAP", "LIMIT_TV", "grid", "PARALLEL_MAX",
           "SETTLED", "SETTLED_LIMIT", "STEP_CAP"]

CAP = 10_000_000        # default cap [steps] of steps_to_limit
LIMIT_TV = 0.05         # default TV at which q_T counts as at the limit
_GRID0 = 100            # first horizon of the steps_to_limit grid [steps]
STEP_CAP = 1_000_000    # steps a run beyond it steps at most (then its limit, once settled)
SETTLED = 1e-6          # TV between two segments' per-step shares that counts as settled ...
SETTLED_LIMIT = 1e-4    # ... when within this TV of the limit (the float32 recursion's own
                        # steady state lies 1.5e-5 off the float64 limit on a two-room map)
PARALLEL_MAX = 100_000  # horizons up to this run beside the limits' analyses; longer ones
                        # after them, so that the limits can settle them (design_mix)
KEPT_RUNS = 8           # runs a Horizon keeps (angle, noise, start); the oldest goes first
_GRID_RATIO = 2 ** (1 / 8)
_EXACT = TurnNoise()


@dataclass(frozen=True, eq=False)
class HorizonCoverage:
    """Expected coverage of the first T steps (docs/model.md §20).

    Attributes
    ----------
    q : (P,) ndarray            expected fraction of the counted steps in each cell (sum 1)
    horizon : int               T [steps]
    epoch : int                 steps per epoch (T for one angle)
    counted_fraction : float    expected share of the T steps counted in a free cell
    seconds : float
    """

    q: np.ndarray
    horizon: int
    epoch: int
    counted_fraction: float
    seconds: float


def grid(cap: int = CAP) -> list[int]:
    """The horizons steps_to_limit tests: round(100 · 2^(k/8)) up to ``cap``, distinct.

    >>> grid(200)
    [100, 109, 119, 130, 141, 154, 168, 183, 200]
    """
    out, k = [], 0
    while True:
        t = int(round(_GRID0 * _GRID_RATIO ** k))
        if t > cap:
            break
        if not out or t > out[-1]:
            out.append(t)
        k += 1
    return out


@lru_cache(maxsize=4)
def _grid_set(cap: int = CAP) -> frozenset:
    return frozenset(grid(cap))


def start_distribution(cs, start=None) -> np.ndarray:
    """A start as a distribution over the N configurations (docs/model.md §20).

    ``None``: uniform (docs/model.md §8); an int z: that configuration; an array of N
    non-negative weights: normalised.
    """
    if start is None:
        return np.full(cs.N, 1.0 / cs.N)
    if np.ndim(start) == 0:
        z = int(start)
        if not 0 <= z < cs.N:
            raise UserError(f"start {z} is out of range: configurations are 0 to {cs.N - 1}.")
        out = np.zeros(cs.N)
        out[z] = 1.0
        return out
    w = np.asarray(start, dtype=float).ravel()
    if w.shape != (cs.N,) or not np.all(np.isfinite(w)) or (w < 0).any() or not w.sum() > 0:
        raise UserError(f"a start distribution needs {cs.N} non-negative weights with a "
                        "positive sum.")
    return w / w.sum()


@dataclass(frozen=True, eq=False)
class _Recursion:
    """A model's delay chain extended for horizons (see :class:`Horizon`'s notes).

    Attributes
    ----------
    chain : DelayChain         with the event model's first flights on N extra states
    ts : TimeShared            its recursion
    offset : int               index of configuration 0's start state
    tailsT : csr (P, D·n)      Q_jᵀ stacked: steps a flight makes at offsets m ≥ j
    """

    chain: DelayChain
    ts: TimeShared
    offset: int
    tailsT: sp.csr_matrix

    @property
    def n(self) -> int:
        """States of the extended chain."""
        return self.chain.n

    @classmethod
    def build(cls, model, noise: TurnNoise, angles=None) -> "_Recursion":
        """The recursion of ``model`` with the flights of ``noise`` (event model: §11a)."""
        cs = model.cs
        if not model.steps_in_flights:                    # step, sampled: D = 1
            base = model.delay_chain()
            ts = TimeShared(base)
            return cls(chain=base, ts=ts, offset=0, tailsT=sp.csr_matrix(ts.RT))
        sc = started_chain(model, noise, angles)
        chain, steps, src, weight = sc.chain, sc.steps, sc.chain.src, sc.chain.weight
        nt = chain.n
        ts = TimeShared(chain)
        # Q_j: rows j·nt + src of every step at offset m ≥ j (j < D)
        rep = steps.offset + 1
        j = np.arange(rep.sum()) - np.repeat(np.cumsum(rep) - rep, rep)
        rows = j * nt + np.repeat(src[steps.flight], rep)
        tails = sp.csr_matrix((np.repeat(weight[steps.flight], rep),
                               (rows, np.repeat(steps.cell, rep))), shape=(ts.D * nt, cs.P))
        tails.sum_duplicates()
        return cls(chain=chain, ts=ts, offset=sc.offset, tailsT=sp.csr_matrix(tails.T))


class _Trajectory:
    """One angle's run from one start, kept at the last point of :func:`grid` it reached.

    Counts of the first T steps are computed on one canonical path, whatever was asked
    before: from step 0 through every grid point below T, then to T. So a later, longer
    horizon (steps_to_limit after the fit, docs/model.md §20) resumes where an earlier one
    stopped instead of starting again, with the same arithmetic as a fresh run.
    """

    def __init__(self, rec: _Recursion, WT, p0: np.ndarray) -> None:
        self.rec, self.WT, self.p0 = rec, WT, p0
        self.hist = np.zeros((rec.ts.D, rec.n), dtype=np.float32)
        self.hist[0, rec.offset:rec.offset + p0.size] = p0
        self.dep = self.hist[0].astype(float)            # v_{−1}
        self.t = 0
        self.known: dict[int, np.ndarray] = {}           # T → counts per cell (P,)
        self._next_check = 1600                          # _check_settles from this t

    def _count(self, hist: np.ndarray, dep: np.ndarray) -> np.ndarray:
        return self.rec.ts.RT @ dep - self.rec.tailsT @ hist.reshape(-1).astype(float)

    def counts(self, T: int, threads: int | None = None, limit=None) -> np.ndarray:
        """Counted steps per cell (P,) of the first T steps. ``threads``: row blocks per step
        (:meth:`~planners.coverage.timeshare.TimeShared.advance`; 1 when runs go on threads of their
        own, :func:`planners.coverage.api.analyses`); the counts do not depend on it.

        ``limit``: the run's limit q (P,). Then the run stops stepping once it has settled
        (:meth:`_settled`) and every later step counts at the limit: counts(g) +
        c·(T − g)·q. A horizon above :data:`STEP_CAP` needs it.
        """
        if T in self.known:
            return self.known[T]
        if T < self.t:                           # behind the checkpoint: a fresh run
            return _Trajectory(self.rec, self.WT, self.p0).counts(T, threads, limit)
        capped = limit is not None and T > STEP_CAP     # beyond: the limit, once settled
        for g in sorted(g for g in _grid_set() if self.t < g <= T):
            if limit is not None and self._settled(limit) is not None:
                break
            if capped:
                if g > STEP_CAP:
                    break
                self._check_settles(limit, T)
            self.hist, dd = self.rec.ts.advance(self.WT, self.hist, g - self.t, threads)
            self.dep += dd
            self.t = g
            self.known[g] = self._count(self.hist, self.dep)
        settled = None if limit is None else self._settled(limit)
        if settled is not None and T > settled[0]:
            g, rate = settled
            return self.known[g] + rate * (T - g) * np.asarray(limit, dtype=float)
        if capped:
            raise UserError(f"the model's run has not settled at its limit after {self.t} "
                            f"steps, so the coverage of the first {T} steps cannot be "
                            f"computed; use a horizon of at most {STEP_CAP:.0e} steps.")
        if T not in self.known:
            hist, dd = self.rec.ts.advance(self.WT, self.hist, T - self.t, threads)
            self.known[T] = self._count(hist, self.dep + dd)
        return self.known[T]

    def _check_settles(self, limit, T: int) -> None:
        """Refuse early a horizon beyond :data:`STEP_CAP` that the run would not settle for
        in time: from its slow mode (:func:`planners.coverage.slow_mode.slow_mode`, tried at
        every doubling of t from 1600 steps until it finds one), the step at which its
        per-step share comes within :data:`SETTLED_LIMIT` of the limit.
        """
        if self.t < self._next_check:
            return
        self._next_check = 2 * self.t
        sm = slow_mode([(t, self.known[t]) for t in self._grid_points()], limit)
        if sm is None:                          # no single mode yet: again at 2·t
            return
        self._next_check = math.inf             # one verdict
        dev = 0.5 * float(np.abs(sm.u).sum())
        at = sm.T + math.log(SETTLED_LIMIT / dev) / math.log(sm.lam) \
            if dev > SETTLED_LIMIT else sm.T
        if at > STEP_CAP:
            raise UserError(f"the model's run settles at its limit only after about "
                            f"{at:.1e} steps (relaxation time {sm.relaxation:.1e} steps), "
                            f"more than the {STEP_CAP:.0e} the recursion runs, so the "
                            f"coverage of the first {T} steps cannot be computed.")

    def _grid_points(self) -> list[int]:
        """The grid horizons this run has stepped through, in order."""
        return sorted(t for t in self.known if t <= self.t and t in _grid_set())

    def _settled(self, limit) -> tuple[int, float] | None:
        """(g, counted steps per step) when the last two segments between grid points (up to
        the run's last grid point g) spent their steps alike (within TV :data:`SETTLED` of
        each other: the recursion's steady state) and within :data:`SETTLED_LIMIT` of
        ``limit``, else None (docs/model.md §20).
        """
        pts = self._grid_points()
        if len(pts) < 3:
            return None
        (a, b, c) = pts[-3:]
        one, two = self.known[b] - self.known[a], self.known[c] - self.known[b]
        if tv_distance(one, two) <= SETTLED and tv_distance(two, limit) <= SETTLED_LIMIT:
            return c, float(two.sum()) / (c - b)
        return None


class Horizon:
    """A coverage model prepared for horizons: its delay chain with per-step rewards.

    Parameters
    ----------
    model : CoverageModel   any of :data:`planners.coverage.MODELS`

    Notes
    -----
    State of the recursion (docs/model.md §19): the departures v_{t−1} … v_{t−D}. A departure
    at t makes its flight's steps at t + 1 … t + d; so the steps 0 … T−1 are those of the
    departures at −1 … T−2, and the count of the first T steps is
    Rᵀ(v_{−1} + Σ_{t<T} v_t) − Σ_j Q_jᵀ v_{T−1−j}, with Q_j (n × P) the steps a flight makes
    at offsets m ≥ j (Q_0 = R). For the step and sampled models v_{−1} is the start
    distribution over the configurations (D = 1); for the event model it sits on N extra
    states, the first flights from the cell centres, whose steps are counted too.
    """

    def __init__(self, model) -> None:
        self.model = model
        self.seconds = 0.0                   # time spent preparing the recursions [s]
        self._prepared: dict = {}
        self._runs: dict = {}                # (angle, noise, start) → _Trajectory

    def _trajectory(self, angle: float, noise: TurnNoise, p0: np.ndarray) -> _Trajectory:
        """The kept run of one angle from start ``p0`` (:class:`_Trajectory`)."""
        key = (float(angle), noise, p0.tobytes())
        if key not in self._runs:
            if len(self._runs) >= KEPT_RUNS:            # each holds D·n floats: forget the
                self._runs.pop(next(iter(self._runs)))  # oldest (a fresh run replaces it)
            rec = self._prepare(noise, [angle])
            self._runs[key] = _Trajectory(rec, self._turns([angle], rec, noise)[0], p0)
        return self._runs[key]

    def tasks(self, angles, horizon: int, *, noise: TurnNoise = _EXACT, start=None) -> list:
        """The angles' runs over the first ``horizon`` steps as calls without arguments, for
        threads of their own (:func:`~planners.coverage.api.analyses`): the recursion and the
        runs are prepared here; each call advances one run on its calling thread (one row
        block per step) and keeps its counts, which a later :meth:`coverage` of that angle
        and horizon (and any longer one) finds.
        """
        T = int(horizon)
        if T < 1:
            raise UserError("a horizon must be at least one step.")
        p0 = start_distribution(self.model.cs, start)
        runs = {float(a): self._trajectory(float(a), noise, p0) for a in angles}
        return [partial(run.counts, T, 1) for run in runs.values()]

    def _prepare(self, noise: TurnNoise, angles) -> "_Recursion":
        """The recursion of ``noise``'s flights (the event model casts Gaussian noise's
        flights at sub-bin headings, docs/model.md §11a, and turns a bump from rest by the
        body's rest turn in the sense ``angles`` spin, §11b), built once per kind of flights.
        """
        kind = (bool(noise.gaussian) and self.model.steps_in_flights,
                noise.rest_for(angles) if self.model.steps_in_flights else 0.0)
        if kind not in self._prepared:
            t0 = time.perf_counter()
            self._prepared[kind] = _Recursion.build(self.model, noise, angles)
            self.seconds += time.perf_counter() - t0
        return self._prepared[kind]

    def _turns(self, angles, rec: "_Recursion", noise: TurnNoise) -> list:
        """The angles' turns prepared for ``rec``'s recursion (the start states do not turn)."""
        out = []
        for a in angles:
            W = self.model.turn_matrix(a, noise)
            if rec.offset:
                W = sp.block_diag((W, sp.csr_matrix((self.model.cs.N,) * 2)), format="csr")
            out.append(rec.ts.turn(W))
        return out

    @staticmethod
    def _advance(rec: "_Recursion", WT, hist: np.ndarray, steps: int):
        """``steps`` steps of m runs in lockstep: ``hist`` (D, n, m) their last D departures,
        ``WT`` their m turn matrices (transposed, float32). Returns (end state (D, n, m),
        Σ v_t (n, m) float64). Each run is one vector through
        :meth:`planners.coverage.timeshare.TimeShared.advance`: a sparse product with a block of m
        vectors costs as much as m products here (``benchmarks/bench_horizon.py``).
        """
        ends, deps = zip(*(rec.ts.advance(W, hist[:, :, j], steps) for j, W in enumerate(WT)))
        return np.stack(ends, axis=2), np.column_stack(deps)

    def _columns(self, angles, horizons, noise: TurnNoise, alpha, epoch, start, limits=None):
        """Counted steps per cell (P, m) of the first T steps of each of m runs, for every T
        in ``horizons``: the angles with α_i > 0 (all angles when ``alpha`` is None), each
        run keeping its angle, or with ``epoch`` a mix whose runs restart every epoch from
        the α-mixture of their end states (docs/model.md §20). Yields (T, counts, α of the
        runs).
        """
        cs = self.model.cs
        if alpha is None:
            alpha = np.ones(len(angles))
        alpha = np.asarray(alpha, dtype=float).ravel()
        if alpha.size != len(angles) or (alpha < 0).any() or not alpha.sum() > 0:
            raise UserError("a mix needs one non-negative α per angle, with a positive sum.")
        alpha = alpha / alpha.sum()
        use = [i for i in range(alpha.size) if alpha[i] > 0]
        a = alpha[use]
        horizons = sorted({int(t) for t in horizons})
        if not horizons or horizons[0] < 1:
            raise UserError("a horizon must be at least one step.")
        if epoch is not None and int(epoch) < 1:
            raise UserError(f"an epoch must be at least one step, got {epoch}.")
        E = int(epoch) if len(use) > 1 and epoch is not None else horizons[-1]
        p0 = start_distribution(cs, start)
        if E >= horizons[-1]:                    # every run keeps its angle: kept runs
            runs = [self._trajectory(angles[i], noise, p0) for i in use]
            lims = [None if limits is None else limits[i] for i in use]
            for T in horizons:
                yield T, np.column_stack([r.counts(T, limit=q) for r, q in zip(runs, lims)]), a
            return
        rec = self._prepare(noise, [angles[i] for i in use])
        WT = self._turns([angles[i] for i in use], rec, noise)
        D, n, m = rec.ts.D, rec.n, len(use)
        hist = np.zeros((D, n, m), dtype=np.float32)
        hist[0, rec.offset:rec.offset + cs.N] = p0[:, None]
        dep = hist[0].astype(float)
        RT = rec.ts.RT
        t, todo = 0, list(horizons)
        while todo:
            end = t + min(E - t % E, todo[-1] - t)          # m > 1 runs, in epochs here
            hs, ds = hist, dep.copy()
            stops = [T for T in todo if t < T <= end]
            if not stops or stops[-1] != end:
                stops.append(end)
            s = t
            for T in stops:
                hs, dd = self._advance(rec, WT, hs, T - s)
                ds += dd
                s = T
                if T in todo:
                    todo.remove(T)
                    yield T, RT @ ds - rec.tailsT @ hs.reshape(D * n, m).astype(float), a
            # the next epoch's runs all start from the α-mixture of the end states
            mixed = sum(np.float32(a[j]) * hs[:, :, j] for j in range(m)).astype(np.float32)
            hist = np.repeat(mixed[:, :, None], m, axis=2)
            dep = np.repeat(sum(a[j] * ds[:, j] for j in range(m))[:, None], m, axis=1)
            t = end

    def run(self, angles, horizons, *, noise: TurnNoise = _EXACT, alpha=None,
            epoch: int | None = None, start=None, stop=None, limits=None):
        """Counted steps per cell of the first T steps for every T in ``horizons``, in one pass.

        Parameters
        ----------
        angles : sequence of float   bouncing angles [deg]
        horizons : sequence of int   horizons T ≥ 1 [steps]
        noise : TurnNoise
        alpha : (m,) array, optional  the mix (default: one angle, m = 1)
        epoch : int, optional        steps per epoch of a mix (default: each run keeps one
                                     angle, drawn at step 0)
        start : see :func:`start_distribution`
        stop : callable, optional    stop(T, counts) → True ends the pass after that T
        limits : sequence, optional  each angle's limit q from this start: a run that has
                                     settled counts its later steps at its limit
                                     (:meth:`_Trajectory.counts`; not for epochs)

        Yields
        ------
        (T, counts (P,), total steps)
        """
        if alpha is None and len(angles) != 1:
            raise UserError("a mix needs one non-negative α per angle, with a positive sum.")
        for T, cols, a in self._columns(tuple(float(x) for x in angles), horizons, noise,
                                        alpha, epoch, start, limits):
            counts = sum(a[j] * cols[:, j] for j in range(a.size))
            yield T, counts, float(T)
            if stop is not None and stop(T, counts):
                return

    def coverage(self, angles, horizon: int, *, noise: TurnNoise = _EXACT, alpha=None,
                 epoch: int | None = None, start=None, limits=None) -> HorizonCoverage:
        """:class:`HorizonCoverage` of the first ``horizon`` steps (see :meth:`run`)."""
        t0 = time.perf_counter()
        if int(horizon) > STEP_CAP:
            if epoch is not None and int(epoch) < int(horizon) and len(angles) > 1:
                raise UserError(f"a mix in epochs runs at most {STEP_CAP:.0e} steps; the "
                                f"horizon is {horizon}.")
            if limits is None:
                raise UserError(f"a horizon of {horizon} steps is more than the "
                                f"{STEP_CAP:.0e} steps the recursion runs, and no limit is "
                                "known to take over from there (a start other than the "
                                "uniform one on a map with several persistent groups).")
        (T, counts, total), = self.run(angles, [horizon], noise=noise, alpha=alpha,
                                       epoch=epoch, start=start, limits=limits)
        c = float(counts.sum())
        if not c > 0:
            raise UserError("the horizon counts no step in a free cell.")
        return HorizonCoverage(q=counts / c, horizon=T, epoch=int(epoch or T),
                               counted_fraction=c / total,
                               seconds=time.perf_counter() - t0)


_SHARED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def horizon_of(model) -> Horizon:
    """The :class:`Horizon` shared by every user of ``model`` (the coverage models are
    cached per map, :func:`~planners.coverage.base.cached_build`): the α fit for a horizon
    and the steps_to_limit report after it run each angle once between them.
    """
    if model not in _SHARED:
        _SHARED[model] = Horizon(model)
    return _SHARED[model]


def horizon_coverage(model, angles, horizon: int, **kw) -> HorizonCoverage:
    """:meth:`Horizon.coverage` on a fresh :class:`Horizon` of ``model``."""
    return Horizon(model).coverage(angles, horizon, **kw)


def fit_horizon_mix(hz: Horizon, angles, noise: TurnNoise, target, horizon: int,
                    epoch: int | None, per_angle: tuple, *, start=None) -> MixDesign:
    """α for a horizon (docs/model.md §20): the mix whose expected coverage of the first
    ``horizon`` steps, executed in epochs of ``epoch`` steps, best meets ``target``.

    The angles' q_T are A's columns and :func:`~planners.coverage.mix.solve_mix` gives the
    exact linear fit, which is the answer when every run keeps one angle (``epoch`` None or
    ≥ T). With shorter epochs q_T(α) is non-linear in α: scipy's SLSQP minimises
    ‖q_T(α) − b‖₂² over the simplex from the linear α (gradient by central differences of
    step 1e-4, each q_T(α) one horizon run); ``convergence`` reports its iterations, the
    norm of the projected gradient at the end, the objective and SLSQP's status.
    """
    # the limits take over once a run settles where they are the runs' own: from the
    # uniform start, or from any start when every angle has one persistent group
    # (beyond PARALLEL_MAX only: shorter horizons are stepped all the way, as the runs
    # beside the analyses step them, so that threads do not change the numbers)
    own = start is None or all(len(p.groups) == 1 for p in per_angle)
    limits = [p.q for p in per_angle] if own and horizon > PARALLEL_MAX else None
    cols = np.column_stack([hz.coverage([a], horizon, noise=noise, start=start,
                                        limits=None if limits is None else [limits[i]]).q
                            for i, a in enumerate(angles)])
    fit = solve_mix(cols, target)
    alpha, mixed, method, conv = fit.alpha, fit.mixed, fit.method, None
    m = len(angles)
    if epoch is not None and int(epoch) < horizon and m > 1:
        def q_of(al):
            al = np.clip(al, 0.0, None)
            return hz.coverage(angles, horizon, noise=noise, alpha=al / al.sum(),
                               epoch=epoch, start=start).q

        def obj(al):
            d = q_of(al) - target
            return float(d @ d)

        def grad(al, h=1e-4):
            g = np.zeros(m)
            for i in range(m):
                e = np.zeros(m)
                e[i] = h
                g[i] = (obj(al + e) - obj(np.clip(al - e, 0.0, None))) / (2 * h)
            return g

        x0 = np.clip(fit.alpha, 1e-6, None)
        x0 /= x0.sum()
        res = minimize(obj, x0, jac=grad, method="SLSQP", bounds=[(0.0, 1.0)] * m,
                       constraints=[{"type": "eq", "fun": lambda al: al.sum() - 1.0,
                                     "jac": lambda al: np.ones_like(al)}],
                       options={"ftol": 1e-10, "maxiter": 50})
        alpha = np.clip(res.x, 0.0, None)
        alpha /= alpha.sum()
        if obj(alpha) > obj(fit.alpha):              # never worse than the linear start
            alpha = fit.alpha
        mixed = q_of(alpha)
        g = grad(alpha)
        free = alpha > 1e-6                          # projected gradient on the simplex face
        pg = g[free] - g[free].mean() if free.any() else g
        conv = {"iterations": int(res.nit), "projected_gradient_norm": float(np.linalg.norm(pg)),
                "objective": obj(alpha), "linear_objective": obj(fit.alpha),
                "status": int(res.status), "message": str(res.message)}
        method = "slsqp-horizon"
    diff = mixed - target
    return MixDesign(model=hz.model.name, angles=tuple(angles), noise=noise, space="positions",
                     per_angle=per_angle, target=target, alpha=alpha,
                     residual=float(np.linalg.norm(diff)),
                     tv=tv_distance(mixed, target, normalise=False), mixed=mixed,
                     method=method, horizon=int(horizon), epoch=None if epoch is None
                     else int(epoch), columns=cols, convergence=conv)
