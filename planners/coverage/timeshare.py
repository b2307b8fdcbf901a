"""Time-shared policy mixes: the coverage a mix delivers when it runs in epochs (docs/model.md §19).

docs/model.md §16 predicts a mix's coverage as Σ α_i q_i, which holds when every epoch is long
enough for its angle's chain to reach its limiting distribution. docs/model.md §21 runs a mix in
epochs of E steps, each with one angle drawn with probabilities α, and the robot carries its
state from one epoch into the next. When an angle's chain mixes slowly (in ``fig1`` at 315°
the robot leaks into a pocket at about 1e-4 per step, so a 1000-step epoch rarely gets
there) the executed mix covers the map very differently from Σ α_i q_i. This module predicts
the executed mix.

**Delay chains.** Every coverage model is written as a *delay chain* (:class:`DelayChain`):
n states; in an angle's *turn* a state moves by the angle's random transition W_φ (n × n,
row-stochastic); then its *flight* takes a whole number d ≥ 1 of steps and lands in a state
again. Flights are sampled: flight f leaves state src_f with weight w_f (the weights of one
state sum to 1), takes delay_f steps and lands in dst_f. Every flight's counted steps are a
reward R (n × P: expected counted steps per position cell of a flight leaving each state).

- step and sampled models: the states are the N configurations, every flight is the identity
  with d = 1, W_φ is the model's one-step chain and R counts the step in its cell;
- event model: the states are the contact states (bin, heading); W_φ is the turn at the bump
  and the flights are the model's sampled bump-to-bump flights with d = forward steps + 1.

**The recursion.** In step t of an epoch that uses angle i,

    x_t = Σ_f w_f v_{t−d_f}[src_f] e_{dst_f}      (mass that bumps — lands — at step t)
    v_t = W_iᵀ x_t                                 (mass that turns and leaves at step t)

and the epoch's counted steps are (Σ_t v_t)ᵀ R (renewal–reward: a flight's steps are counted
when it leaves; over a long run the attribution does not matter). The state at an epoch
boundary is the last D = max d departures. The angle is drawn independently of the state, so
the boundary state of the next epoch is the α-mixture of the angles' epoch end states. The
recursion iterates that epoch map (damped by β = 0.05 like the event model's power iteration)
from the model's start (the uniform start, docs/model.md §22) until q settles (estimated TV error
below 1e-4); then q = Σ_i α_i (Σ_t v_t^{(i)})ᵀ R normalised over the P cells.

This is exact for the model's own dynamics: with one angle it converges to that angle's q; with
E → ∞ it tends to Σ α_i q_i. Cost: E matrix–vector products per angle and epoch iteration; the
epoch map contracts by 0.1–0.3 per epoch in the catalogue, so a handful of iterations do.

Two states counted in two cells, both turns deterministic: angle A always goes to state 1;
angle B goes from state 0 to 0 and from state 1 to either state. Alone, A covers (0, 1) and
B (1, 0), so Σ α_i q_i = (½, ½) at α = (½, ½). Switching every step (E = 1) is the chain
½(W_A + W_B) = [[½, ½], [¼, ¾]], whose stationary distribution is (⅓, ⅔); long epochs tend
to (½, ½):

>>> import scipy.sparse as sp
>>> chain = DelayChain.stepwise(sp.identity(2, format="csr"), [0.5, 0.5])
>>> WA, WB = sp.csr_matrix([[0, 1], [0, 1.]]), sp.csr_matrix([[1, 0], [0.5, 0.5]])
>>> timeshared(chain, [WA, WB], [0.5, 0.5], epoch=1, tol=1e-9).q.round(6).tolist()
[0.333333, 0.666667]
>>> timeshared(chain, [WA, WB], [0.5, 0.5], epoch=10000).q.round(3).tolist()
[0.5, 0.5]
"""

from __future__ import annotations

import math
import os
import time
import warnings
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from envs import UserError

__all__ = ["DelayChain", "TimeShared", "TimeSharedCoverage", "default_threads",
           "note_threads", "timeshared"]

_LAZY = 0.05          # weight of the previous epoch-boundary state (damps periodic modes)
TOL = 1e-4            # default tolerance on the estimated TV error of q
MAX_STEPS = 200_000   # default cap on the steps run per angle (epoch iterations × E)
MIN_EPOCHS = 200      # ... but at least this many epoch iterations
PARALLEL_MIN = 20_000  # chains of at least this many states split each step over the cores

_POOL: list = [None, 0]   # the shared ThreadPoolExecutor and its number of workers
_OWN = [1]                 # threads of this process's last step (its share of the load)
_SPLITS_KEPT = 8           # row-block splits of turns a TimeShared keeps (one per angle)


def default_threads() -> int:
    """Threads one step of a large recursion is split over: the cores this process may use
    (at most 4) that other work does not keep busy (by the 1-minute load average, less the
    threads of this process's last split step), at least 1. scipy's sparse products release
    the GIL, so the row blocks run in parallel; on a machine already busy, more threads only
    wait for each other (``benchmarks/bench_horizon.py --pipeline``). The numbers do not
    depend on it.
    """
    cores = min(4, len(os.sched_getaffinity(0)))
    busy = max(0.0, os.getloadavg()[0] - _OWN[0])
    return max(1, min(cores, int(cores - busy + 0.5)))


def note_threads(k: int) -> None:
    """Record that this process just kept ``k`` threads busy (its share of the load average
    that :func:`default_threads` discounts), e.g. after work split over threads elsewhere.
    """
    _OWN[0] = max(1, int(k))


def _pool(workers: int) -> ThreadPoolExecutor:
    """The shared pool of the recursion's extra threads (replaced by a larger one on demand)."""
    if _POOL[0] is None or _POOL[1] < workers:
        if _POOL[0] is not None:
            _POOL[0].shutdown(wait=False)
        _POOL[:] = [ThreadPoolExecutor(max_workers=workers, thread_name_prefix="timeshare"),
                    workers]
    return _POOL[0]


@dataclass(frozen=True, eq=False)
class DelayChain:
    """The angle-independent part of a model as a delay chain (see the module docstring).

    Attributes
    ----------
    src, dst : (F,) int      flight f leaves state src_f and lands in state dst_f
    delay : (F,) int         steps of flight f (≥ 1, the bump step included)
    weight : (F,) float      probability of flight f given its start state
    reward : csr (n, P)      expected counted steps per cell of a flight leaving each state
    start : (n,)             distribution of the first landing (mass that turns at step 0)
    """

    src: np.ndarray
    dst: np.ndarray
    delay: np.ndarray
    weight: np.ndarray
    reward: sp.csr_matrix
    start: np.ndarray

    @property
    def n(self) -> int:
        """Number of states of the delay chain."""
        return int(self.reward.shape[0])

    @classmethod
    def stepwise(cls, reward, start) -> "DelayChain":
        """A one-step chain (step and sampled models): every state flies to itself in 1 step."""
        n = reward.shape[0]
        z = np.arange(n)
        return cls(src=z, dst=z, delay=np.ones(n, dtype=np.int64), weight=np.ones(n),
                   reward=sp.csr_matrix(reward), start=np.asarray(start, dtype=float))

    def __post_init__(self) -> None:
        n = self.n
        d = np.asarray(self.delay)
        if d.size == 0 or d.min() < 1:
            raise ValueError("every flight of a delay chain takes at least one step.")
        out = np.bincount(self.src, weights=self.weight, minlength=n)
        if not np.allclose(out, 1.0, atol=1e-9):
            raise ValueError("the flights of every state must have weights summing to 1.")
        if np.asarray(self.start).shape != (n,):
            raise ValueError(f"the start distribution must have {n} entries.")


@dataclass(frozen=True, eq=False)
class TimeSharedCoverage:
    """Predicted coverage of a policy mix run in epochs.

    Attributes
    ----------
    q : (P,) ndarray        predicted step-sampled coverage (sum 1)
    epoch : int             steps per epoch
    epochs : int            epoch iterations run
    converged : bool        the estimated error fell below the tolerance
    error_estimate : float  geometric estimate dq·ρ/(1 − ρ) of the TV error of q (inf before
                            3 iterations; it assumes a steady contraction ρ)
    counted_fraction : float  share of the steps counted in a free cell (the rest dropped)
    seconds : float
    """

    q: np.ndarray
    epoch: int
    epochs: int
    converged: bool
    error_estimate: float
    counted_fraction: float
    seconds: float


class TimeShared:
    """The epoch recursion of one delay chain (built once, run for any α and angles).

    Parameters
    ----------
    chain : DelayChain

    Notes
    -----
    x_t is one sparse product H w_t, H: n × D·n with column (d−1)·n + src for a flight of
    d steps from src, w_t = (v_{t−1}, …, v_{t−D}). The product reads only the columns some
    flight uses, so they are numbered compactly (:attr:`Hc`, lag by lag, sources in order:
    the same products in the same order, so the same numbers): the product reads a vector
    of a few MB (the distinct columns) instead of D·n floats spread over tens of MB. The
    turn's product makes v_t on those columns directly (Wᵀ's rows of every lag's sources
    S_j, stacked: :meth:`_stacked`), into a ring of D such vectors whose segments the next
    steps copy into w; v_t on all n states is made only in a call's last D steps, for the
    boundary state, and Σ_t v_t as Wᵀ Σ_t x_t (``benchmarks/bench_horizon.py`` times both
    ways). Vectors and matrices are float32 (the
    products are memory bound), sums float64.
    """

    def __init__(self, chain: DelayChain) -> None:
        self.chain = chain
        n = chain.n
        self.D = D = int(chain.delay.max())
        cols = (np.asarray(chain.delay) - 1) * n + np.asarray(chain.src)
        self.H = sp.csr_matrix((np.asarray(chain.weight, dtype=np.float32),
                                (np.asarray(chain.dst), cols)), shape=(n, D * n))
        self.H.sum_duplicates()
        # the states mass can land in (a flight ends there, or the start puts mass there):
        # x_t is zero elsewhere, so the products skip those rows of H and columns of Wᵀ
        self.live = np.flatnonzero((np.diff(self.H.indptr) > 0)
                                   | (np.asarray(chain.start) != 0))
        H_live = sp.csr_matrix(self.H[self.live])
        # the distinct columns u of H_live, in order (lag j = u // n, source u % n), and
        # H_live on them: the flights' product on the lags' sources only (see the notes)
        u, rank = np.unique(H_live.indices, return_inverse=True)
        rank = rank.reshape(-1).astype(H_live.indices.dtype)
        self.Hc = sp.csr_matrix((H_live.data, rank, H_live.indptr),
                                shape=(self.live.size, u.size))
        cut = np.searchsorted(u, np.arange(D + 1) * n)
        self._lags = [(j, int(cut[j]), int(cut[j + 1]), u[cut[j]:cut[j + 1]] - j * n)
                      for j in range(D) if cut[j + 1] > cut[j]]
        self._src = u % n                # state of each column of Hc
        self._splits: dict = {}          # id(matrix) → (matrix, k, its k row blocks)
        self._stacks: dict = {}          # id(turn) → (turn, its rows of self._src)
        self.RT = sp.csr_matrix(chain.reward.T)
        # expected steps (counted or dropped) of a flight leaving each state
        self.length = np.bincount(chain.src, weights=np.asarray(chain.weight)
                                  * np.asarray(chain.delay), minlength=n)

    def turn(self, W) -> sp.csr_matrix:
        """An angle's turn W (n × n, row-stochastic) prepared for :meth:`advance`: Wᵀ on the
        columns of the states mass can land in (:attr:`live`), float32.
        """
        return sp.csr_matrix(sp.csr_matrix(W.T)[:, self.live]).astype(np.float32)

    def _split(self, A, k: int) -> list:
        """Row blocks (rows, A's rows) of A, k of them balanced by non-zeros (one for k = 1);
        the last few splits are kept (a run advances in many short calls).
        """
        m = A.shape[0]
        if k == 1:
            return [(slice(0, m), A)]
        kept = self._splits.get(id(A))
        if kept is not None and kept[0] is A and kept[1] == k:
            return kept[2]
        work = np.cumsum(np.diff(A.indptr) + 1)
        cuts = [0, *np.searchsorted(work, work[-1] * np.arange(1, k) / k).tolist(), m]
        blocks = [(slice(a, b), A[a:b]) for a, b in zip(cuts, cuts[1:]) if b > a]
        if len(self._splits) >= _SPLITS_KEPT:
            self._splits.pop(next(iter(self._splits)))
        self._splits[id(A)] = (A, k, blocks)            # A kept alive: its id stays its own
        return blocks

    def _stacked(self, WT) -> sp.csr_matrix:
        """WT's rows of the flights' sources, lag by lag (the layout of :attr:`Hc`'s
        columns): one product gives every lag's v_t[S_j]; kept per turn like the splits.
        """
        kept = self._stacks.get(id(WT))
        if kept is not None and kept[0] is WT:
            return kept[1]
        WS = sp.csr_matrix(WT[self._src])
        if len(self._stacks) >= _SPLITS_KEPT:
            self._stacks.pop(next(iter(self._stacks)))
        self._stacks[id(WT)] = (WT, WS)                 # WT kept alive: its id stays its own
        return WS

    def _epoch(self, WT, hist: np.ndarray, steps: int, inject=None, threads=None):
        """Run ``steps`` steps of one angle (``WT`` from :meth:`turn`) from boundary state
        ``hist`` (D, n).

        Each step's two products are split into row blocks that run on the shared threads
        (one block below :data:`PARALLEL_MIN` states); every row is computed by the same
        sparse kernel in the same order, so the result does not depend on the split
        (bitwise).

        Returns (end state (D, n), Σ_t v_t (n,) float64).
        """
        D, n = self.D, self.chain.n
        m = self.Hc.shape[1]
        ring = np.empty((D, n), dtype=np.float32)        # ring[s mod D] = v_s (last D steps)
        ring[(-1 - np.arange(D)) % D] = hist             # v_{−1−j} = hist[j]
        # U[s mod D] = v_s on the lags' sources (Hc's columns): at step t lag j reads its
        # segment of U[(t − 1 − j) mod D], v_{t−1−j}[S_j]
        U = np.empty((D, m), dtype=np.float32)
        for j, a, b, S in self._lags:
            for i in range(j + 1):
                U[(-1 - i) % D, a:b] = hist[i, S]
        w = np.empty(m, dtype=np.float32)
        x = np.zeros(self.live.size, dtype=np.float32)      # x_t on the live states
        xsum = np.zeros(self.live.size)                     # Σ_t x_t; Σ_t v_t = Wᵀ Σ_t x_t
        k = default_threads() if threads is None else max(1, int(threads))
        k = 1 if n < PARALLEL_MIN else k
        if n >= PARALLEL_MIN:
            _OWN[0] = k
        lands = self._split(self.Hc, k)
        sources, wholes = self._split(self._stacked(WT), k), self._split(WT, k)
        if inject is not None:
            inject = np.asarray(inject, dtype=np.float32)[self.live]

        def land(block, t):                  # x_t over the block's rows
            r, Hb = block
            x[r] = Hb @ w
            if inject is not None and t == 0:
                x[r] += inject[r]
            xsum[r] += x[r]

        def turn(block, t):                  # v_t on the sources (the block's rows of U)
            r, Wb = block
            U[t % D, r] = Wb @ x

        def whole(block, t):                 # v_t on every state (the last D steps)
            r, Wb = block
            ring[t % D, r] = Wb @ x

        pool = _pool(k - 1) if k > 1 else None
        for t in range(steps):
            for j, a, b, _ in self._lags:
                w[a:b] = U[(t - 1 - j) % D, a:b]
            last = t >= steps - D            # the end state needs the whole v_t
            for phase, blocks in ((land, lands), (whole, wholes) if last else (turn, sources)):
                futures = [pool.submit(phase, bl, t) for bl in blocks[1:]] if pool else ()
                phase(blocks[0], t)
                for f in futures:
                    f.result()
            if last:                         # the same rows, so the same numbers as `turn`
                np.take(ring[t % D], self._src, out=U[t % D])
        return ring[(steps - 1 - np.arange(D)) % D].copy(), WT @ xsum

    def advance(self, WT, hist: np.ndarray, steps: int, threads: int | None = None):
        """Run ``steps`` steps of one angle (``WT``: its turn prepared by :meth:`turn`) from
        the boundary state ``hist`` (D, n) = (v_{t−1}, …, v_{t−D}); returns (end state (D, n),
        Σ v_t over the steps (n,) float64). The horizons of :mod:`planners.coverage.horizon`
        run on this. ``threads``: row blocks per step (default :func:`default_threads`; the
        result is bitwise the same for any count).
        """
        return self._epoch(WT, np.asarray(hist, dtype=np.float32), int(steps), threads=threads)

    def run(self, turns, alpha, epoch: int, *, tol: float = TOL,
            max_epochs: int | None = None, progress=None) -> TimeSharedCoverage:
        """Coverage of the mix: angle i's turn matrix ``turns[i]`` (n × n) with weight α_i.

        Parameters
        ----------
        turns : sequence of sparse (n, n)   W_φ of every angle (rows sum to 1)
        alpha : (m,) array                  the mix (non-negative, normalised here)
        epoch : int                         steps per epoch E ≥ 1
        tol : float                         stop when the estimated TV error of q < tol
        max_epochs : int, optional          cap on epoch iterations (default: enough for
                                            200 000 steps per angle, at least 200)
        progress : callable, optional       wraps the iterable of epoch iterations (tqdm)
        """
        t0 = time.perf_counter()
        alpha = np.asarray(alpha, dtype=float).ravel()
        if len(turns) != alpha.size or alpha.size == 0:
            raise UserError("a mix needs one α per angle.")
        if not np.all(np.isfinite(alpha)) or (alpha < 0).any() or not alpha.sum() > 0:
            raise UserError("α must be non-negative with a positive sum.")
        epoch = int(epoch)
        if epoch < 1:
            raise UserError(f"epoch must be at least one step, got {epoch}.")
        alpha = alpha / alpha.sum()
        use = [i for i in range(alpha.size) if alpha[i] > 0]
        WT = {i: self.turn(turns[i]) for i in use}
        n = self.chain.n
        hist = np.zeros((self.D, n), dtype=np.float32)
        inject = np.asarray(self.chain.start, dtype=np.float32)
        prev_q, prev_dq, bound = None, None, math.inf
        converged = False
        q = counted = None
        if max_epochs is None:
            max_epochs = max(MIN_EPOCHS, math.ceil(MAX_STEPS / epoch))
        it_range = range(1, int(max_epochs) + 1)
        for it in (progress(it_range) if progress else it_range):
            new = np.zeros_like(hist)
            dep = np.zeros(n)
            for i in use:
                end, d = self._epoch(WT[i], hist, epoch, inject if it == 1 else None)
                new += np.float32(alpha[i]) * end
                dep += alpha[i] * d
            # the first epoch is the real first epoch; later ones are damped (same fixed point)
            hist = new if it == 1 else (np.float32(1 - _LAZY) * new + np.float32(_LAZY) * hist)
            cells = self.RT @ dep
            counted = float(cells.sum())
            if not counted > 0:
                raise UserError("the mix counts no step in a free cell.")
            q = cells / counted
            if prev_q is not None:
                dq = 0.5 * float(np.abs(q - prev_q).sum())
                if dq == 0.0:
                    bound, converged = 0.0, True
                elif prev_dq is not None and dq < prev_dq:
                    rho = dq / prev_dq
                    bound = dq * rho / (1 - rho)
                    converged = bound < tol
                prev_dq = dq
            prev_q = q
            if converged:
                break
        if not converged:
            warnings.warn(f"the time-shared recursion stopped after {it} epochs with a TV "
                          f"error estimate of {bound:.2g} (tolerance {tol:g}).", RuntimeWarning,
                          stacklevel=2)
        total = float(dep @ self.length)
        return TimeSharedCoverage(q=q, epoch=epoch, epochs=it, converged=converged,
                                  error_estimate=bound, counted_fraction=counted / total,
                                  seconds=time.perf_counter() - t0)


def timeshared(chain: DelayChain, turns, alpha, epoch: int, **kw) -> TimeSharedCoverage:
    """:meth:`TimeShared.run` on a fresh :class:`TimeShared` of ``chain``."""
    return TimeShared(chain).run(turns, alpha, epoch, **kw)
