"""Cover times by sampling a model's own chain (docs/model.md §20a): the hot loop.

A run is a path of the model's delay chain (:class:`~planners.coverage.event_flights.StartedChain`)
stepped one step at a time: each robot of a team is inside one flight (the flight's index
and the offset of its next step); the step is counted in the flight's cell at that offset
(or in none: a dropped step); after a flight's last step (the bump step) the robot lands,
turns by its current angle (a row of the angle's turn matrix) and picks its next flight
(by weight). The team's visited cells are one set; what a run reports is read off it at
given steps. Two robots of the team *meet* at a step when both count it in the same cell
(§20a): a run also reports its first meeting and how many (pair, step) meetings it had.
Compiled with numba: a step of one robot costs a few nanoseconds, and the runs are spread
over the cores (``numba.prange``), each from its own seed.

The tables are flat arrays (CSR-like) built once per chain by :class:`SampleTables`.
"""

from __future__ import annotations

import os
import threading
from dataclasses import dataclass
from typing import NamedTuple

import numba
import numpy as np
import scipy.sparse as sp

__all__ = ["SampleTables", "SampledRuns", "sample_runs", "turn_tables"]

# numba's built-in thread pool unless the user chose one: GNU OpenMP (numba's "omp" layer,
# picked first where libgomp is installed) kills every child a process forks after it ran
# a parallel loop, and the sweeps fork worker processes. The built-in pool takes one
# parallel call at a time, hence the lock.
if "NUMBA_THREADING_LAYER" not in os.environ:
    numba.config.THREADING_LAYER = "workqueue"
_PARALLEL = threading.Lock()


@dataclass(frozen=True, eq=False)
class SampleTables:
    """A :class:`~planners.coverage.event_flights.StartedChain` as flat arrays for
    :func:`sample_runs`.

    Attributes
    ----------
    fptr : (n+1,) int64      flights of state s are ``fidx[fptr[s]:fptr[s+1]]``
    fidx : (F,) int64
    fcum : (F,) float64      cumulative weights within each state's block (last = 1)
    dst, delay : (F,) int64  landing state and steps of each flight
    cptr : (F,) int64        flight f's steps are ``cells[cptr[f]:cptr[f] + delay[f]]``
    cells : int32            cell of each step of each flight, −1 for a dropped step
    """

    fptr: np.ndarray
    fidx: np.ndarray
    fcum: np.ndarray
    dst: np.ndarray
    delay: np.ndarray
    cptr: np.ndarray
    cells: np.ndarray

    @classmethod
    def of(cls, started) -> "SampleTables":
        """The tables of a :class:`~planners.coverage.event_flights.StartedChain`."""
        ch, st = started.chain, started.steps
        n = ch.n
        order = np.argsort(ch.src, kind="stable")
        fptr = np.zeros(n + 1, dtype=np.int64)
        fptr[1:] = np.cumsum(np.bincount(ch.src, minlength=n))
        fcum = _block_cumsum(np.asarray(ch.weight, dtype=float)[order], fptr)
        delay = np.asarray(ch.delay, dtype=np.int64)
        cptr = np.zeros(delay.size, dtype=np.int64)
        cptr[1:] = np.cumsum(delay)[:-1]
        cells = np.full(int(delay.sum()), -1, dtype=np.int32)
        cells[cptr[st.flight] + st.offset] = st.cell
        return cls(fptr=fptr, fidx=order.astype(np.int64), fcum=fcum,
                   dst=np.asarray(ch.dst, dtype=np.int64), delay=delay, cptr=cptr,
                   cells=cells)


@numba.njit(cache=True)
def _block_cumsum(w: np.ndarray, ptr: np.ndarray) -> np.ndarray:
    """Cumulative sums of ``w`` restarted at every block of ``ptr``, normalised to end at 1
    (a block of zero weight is left unnormalised), each block's last entry set to 1 exactly
    (so a uniform draw below 1 always finds an entry).
    """
    c = np.empty(w.size)
    for b in range(ptr.size - 1):
        lo, hi = ptr[b], ptr[b + 1]
        if hi == lo:
            continue
        s = 0.0
        for i in range(lo, hi):
            s += w[i]
            c[i] = s
        if s > 0:
            for i in range(lo, hi):
                c[i] /= s
        c[hi - 1] = 1.0
    return c


def turn_tables(turns) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The angles' turn matrices (each n × n, row-stochastic) stacked for :func:`sample_runs`:
    (tptr (m, n+1), tcol, tcum), row s of angle a at ``tptr[a, s]:tptr[a, s+1]``.
    """
    ptrs, cols, cums, base = [], [], [], 0
    for W in turns:
        W = sp.csr_matrix(W)
        W.sum_duplicates()
        ptr = W.indptr.astype(np.int64)
        ptrs.append(ptr + base)
        cols.append(W.indices.astype(np.int64))
        cums.append(_block_cumsum(W.data.astype(float), ptr))
        base += int(W.nnz)
    return np.stack(ptrs), np.concatenate(cols), np.concatenate(cums)


@numba.njit(cache=True)
def _pick(cum, lo, hi, u):
    """Index in [lo, hi) of the first cumulative weight above ``u`` (hi − 1 at the end)."""
    i = lo + np.searchsorted(cum[lo:hi], u, side="right")
    return min(i, hi - 1)


@numba.njit(cache=True, parallel=True)
def _kernel(fptr, fidx, fcum, dst, delay, cptr, cells, tptr, tcol, tcum, acum, epoch,
            sstate, scum, P, robots, runs, horizon, times, kneed, seed):
    G, nk = times.size, kneed.size
    counts = np.zeros((runs, G), dtype=np.int32)
    reach = np.full((runs, nk), -1, dtype=np.int64)
    idle = np.zeros(runs, dtype=np.int64)
    first = np.empty((runs, P), dtype=np.int32)
    meet = np.full(runs, -1, dtype=np.int64)
    pairs = np.zeros(runs, dtype=np.int64)
    for run in numba.prange(runs):
        counts[run], reach[run], idle[run], first[run], meet[run], pairs[run] = _run(
            fptr, fidx, fcum, dst, delay, cptr, cells, tptr, tcol, tcum, acum, epoch,
            sstate, scum, P, robots, horizon, times, kneed, seed + run)
    return counts, reach, idle, first, meet, pairs


@numba.njit(cache=True)
def _run(fptr, fidx, fcum, dst, delay, cptr, cells, tptr, tcol, tcum, acum, epoch,
         sstate, scum, P, robots, horizon, times, kneed, seed):
    """One run of the team from its own seed (the thread's generator is seeded for it, so a
    run is the same whichever thread samples it).
    """
    np.random.seed(seed)
    G, nk = times.size, kneed.size
    counts = np.zeros(G, dtype=np.int32)
    reach = np.full(nk, -1, dtype=np.int64)
    first = np.full(P, -1, dtype=np.int32)
    last = np.full(P, -1, dtype=np.int64)
    here = np.zeros(P, dtype=np.int64)         # robots counted in the cell at step last[c]
    meet, pairs = -1, 0
    fl = np.empty(robots, dtype=np.int64)
    pos = np.empty(robots, dtype=np.int64)
    cur = np.zeros(robots, dtype=np.int64)
    m = acum.size
    covered, gi, ki, worst = 0, 0, 0, 0
    for r in range(robots):
        s = sstate[_pick(scum, 0, scum.size, np.random.random())]
        fl[r] = fidx[_pick(fcum, fptr[s], fptr[s + 1], np.random.random())]
        pos[r] = 0
    for t in range(horizon):
        while gi < G and times[gi] == t:
            counts[gi] = covered
            gi += 1
        if m > 1 and t % epoch == 0:
            for r in range(robots):
                cur[r] = _pick(acum, 0, m, np.random.random())
        for r in range(robots):
            f, j = fl[r], pos[r]
            c = cells[cptr[f] + j]
            if c >= 0:
                if first[c] < 0:
                    first[c] = t
                    covered += 1
                    while ki < nk and covered >= kneed[ki]:
                        reach[ki] = t + 1
                        ki += 1
                if last[c] == t:                   # another robot counted this step here
                    pairs += here[c]
                    here[c] += 1
                    if meet < 0:
                        meet = t
                else:
                    here[c] = 1
                gap = t - last[c] - 1
                if gap > worst:
                    worst = gap
                last[c] = t
            j += 1
            if j == delay[f]:                      # the bump step: land, turn, fly on
                s = dst[f]
                a = cur[r]
                s = tcol[_pick(tcum, tptr[a, s], tptr[a, s + 1], np.random.random())]
                f = fidx[_pick(fcum, fptr[s], fptr[s + 1], np.random.random())]
                j = 0
            fl[r], pos[r] = f, j
    while gi < G:
        counts[gi] = covered
        gi += 1
    for c in range(P):
        gap = horizon - 1 - last[c]
        if gap > worst:
            worst = gap
    return counts, reach, worst, first, meet, pairs


class SampledRuns(NamedTuple):
    """What :func:`sample_runs` returns, per run (see there)."""

    counts: np.ndarray
    reach: np.ndarray
    idle: np.ndarray
    first: np.ndarray
    meet: np.ndarray
    pairs: np.ndarray


def sample_runs(tables: SampleTables, turns, alpha, epoch: int | None, start_states,
                start_weights, P: int, robots: int, runs: int, horizon: int, times, kneed,
                seed: int):
    """``runs`` independent runs of a team of ``robots`` robots over ``horizon`` steps.

    Parameters
    ----------
    tables : SampleTables
    turns : sequence of (n, n) sparse   each angle's turn matrix (row-stochastic), or their
                                        :func:`turn_tables` (built once for several calls)
    alpha : (m,) array                  probabilities of the angles (one angle: [1])
    epoch : int or None                 steps per epoch: every robot draws its own angle at
                                        steps 0, τ, 2τ, … (None: one angle for the whole run)
    start_states, start_weights        states that depart at step −1, and their probabilities
    P : int                             position cells
    times : (G,) int, sorted            steps t ≥ 1 at which to read the visited cells
    kneed : (k,) int, non-decreasing    cell counts whose first step to record
    seed : int                          run i draws from the compiled generator seeded with
                                        ``seed + i`` (the runs are shared among the cores;
                                        the result does not depend on how many)

    Returns
    -------
    counts (runs, G) int32     cells visited in steps 0 … t−1 for every t of ``times``
    reach (runs, k) int64      the first t with at least ``kneed[i]`` cells visited in steps
                               0 … t−1, −1 when not within the horizon
    idle (runs,) int64         longest stretch of steps in [0, horizon) in which some cell is
                               not visited by any robot of the team
    first (runs, P) int32      the step at which each cell is first visited by the team
                               (−1: not within the horizon)
    meet (runs,) int64         the first step at which two robots of the team are counted in
                               one cell (−1: none within the horizon)
    pairs (runs,) int64        the (pair of robots, step) meetings in [0, horizon)
    """
    tptr, tcol, tcum = turns if isinstance(turns, tuple) else turn_tables(turns)
    a = np.asarray(alpha, dtype=float)
    acum = np.cumsum(a / a.sum())
    acum[-1] = 1.0
    w = np.asarray(start_weights, dtype=float)
    scum = np.cumsum(w / w.sum())
    scum[-1] = 1.0
    ep = int(epoch) if epoch is not None and a.size > 1 else int(horizon) + 1
    with _PARALLEL:
        return SampledRuns(*_kernel(tables.fptr, tables.fidx, tables.fcum, tables.dst, tables.delay,
                       tables.cptr, tables.cells, tptr, tcol, tcum, acum, ep,
                       np.asarray(start_states, dtype=np.int64), scum, int(P), int(robots),
                       int(runs), int(horizon), np.asarray(times, dtype=np.int64),
                       np.asarray(kneed, dtype=np.int64), int(seed)))
