"""The stationary distributions of the event model's large contact chains (docs/model.md §17).

Closed classes of up to 20 000 states are solved directly (sparse LU,
:func:`planners.coverage.markov.stationary_distributions`). Larger ones by BiCGSTAB
(:func:`_krylov_stationary`), or the damped power iteration where it fails
(:func:`_power_stationary`), checked by iterative aggregation–disaggregation over the contact
bins (:func:`_aggregated_stationary`) and, if that does not converge, the direct solve:
:func:`analyse_contact_chain`.
"""

from __future__ import annotations

import threading
from contextlib import contextmanager

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as sla
from threadpoolctl import threadpool_limits

from .markov import (
    ChainAnalysis,
    absorption_probabilities,
    assemble,
    check_stochastic,
    closed_classes,
    stationary_distributions,
)

__all__ = ["analyse_contact_chain"]

_DIRECT_MAX = 20000      # closed classes up to this size are solved directly (sparse LU)
_POWER_TOL = 1e-6        # L1 error bound at which the power iteration stops
_POWER_MAX = 200000      # iterations cap
_POWER_FIRST = 3000      # power iterations tried before the aggregation (docs/model.md §17)
_LAZY = 0.05             # weight of the current iterate (damps periodic modes)
_AGG_SWEEPS = 10         # damped power steps per aggregation-disaggregation cycle
_AGG_MAX = 20000         # cycles cap
_AGG_BLEND = 1e-9        # share of uniform weights inside an aggregate (keeps C irreducible)
_KRYLOV_RTOL = 1e-8      # BiCGSTAB's relative residual (2-norm) for a large class
_KRYLOV_MAX = 1500       # BiCGSTAB iterations (two products each) before the fallback
_KRYLOV_RES = 1e-7       # L1 residual ‖Tᵀx − x‖₁ a Krylov answer must meet to be taken
_BLAS = [threading.Lock(), 0, None]   # one BLAS thread while any solve runs (see below)


@contextmanager
def _one_blas_thread():
    """Limit BLAS to one thread while any Krylov solve of this process runs. BiCGSTAB's
    inner products are BLAS calls on long vectors: a threaded BLAS on a 2-core machine where
    the analyses already run on threads of their own made them many times slower. The
    limit is process-wide (threadpoolctl), so concurrent solves count their users.
    """
    lock = _BLAS[0]
    with lock:
        if _BLAS[1] == 0:
            _BLAS[2] = threadpool_limits(limits=1, user_api="blas")
        _BLAS[1] += 1
    try:
        yield
    finally:
        with lock:
            _BLAS[1] -= 1
            if _BLAS[1] == 0:
                _BLAS[2].restore_original_limits()
                _BLAS[2] = None


def _krylov_stationary(Tg: sp.csr_matrix) -> tuple[np.ndarray | None, int]:
    """Stationary distribution of one irreducible class by BiCGSTAB (docs/model.md §17):
    (I − Tᵀ + 1·1ᵀ/n) x = 1/n, which π solves (1ᵀ(I − Tᵀ) = 0 and 1ᵀπ = 1) and which is
    non-singular for an irreducible T; periodic classes need no damping here. Float64,
    from the uniform vector, to a relative residual of 1e-8. Returns (π, products), or
    (None, products) when it did not converge or its L1 residual ‖Tᵀπ − π‖₁ (after
    clipping round-off negatives) exceeds 1e-7: the caller then takes the power iteration.
    A small residual does not bound the error where the class mixes slowly (the caller's
    aggregation cycle checks it).
    """
    TT = sp.csr_matrix(Tg.T, dtype=float)
    n = TT.shape[0]
    count = [0]

    def matvec(x):
        count[0] += 1
        return x - TT @ x + x.sum() / n

    b = np.full(n, 1.0 / n)
    op = sla.LinearOperator((n, n), matvec=matvec, dtype=float)
    with _one_blas_thread():
        x, info = sla.bicgstab(op, b, x0=b.copy(), rtol=_KRYLOV_RTOL, atol=0.0,
                               maxiter=_KRYLOV_MAX)
    if info != 0 or not np.all(np.isfinite(x)):
        return None, count[0]
    x = np.clip(x, 0.0, None)
    if not x.sum() > 0:
        return None, count[0]
    x /= x.sum()
    if np.abs(TT @ x - x).sum() > _KRYLOV_RES:
        return None, count[0]
    return x, count[0]


def _power_stationary(Tg: sp.csr_matrix, max_iter: int | None = None
                      ) -> tuple[np.ndarray, int]:
    """Stationary distribution of one irreducible class by damped power iteration (the
    benchmark's reference): x ← (1 − β) Tᵀx + βx with β = 0.05 (same fixed point; eigenvalues
    on the unit circle other than 1 move inside it, so periodic classes converge). Stops when
    d·ρ/(1 − ρ) < 1e-6 in L1 (d the last change, ρ the observed contraction over 20
    iterations). Products in float32 (memory bound: 1.5 times faster; ~2e-6 from float64 in
    L1 on ``complex``), sums and the stopping test in float64. Returns (π, iterations).
    """
    TT = sp.csr_matrix(Tg.T).astype(np.float32)
    n = TT.shape[0]
    x = np.full(n, 1.0 / n, dtype=np.float32)
    a, b = np.float32(1.0 - _LAZY), np.float32(_LAZY)
    prev = None
    y, it = x, 0
    for it in range(1, (_POWER_MAX if max_iter is None else max_iter) + 1):
        y = a * (TT @ x) + b * x
        if it % 20 == 0:
            d = float(np.abs(y - x).sum(dtype=np.float64))
            if d == 0.0:
                break
            if prev is not None and d < prev:
                rho = (d / prev) ** (1.0 / 20)
                if rho < 1 and d * rho / (1 - rho) < _POWER_TOL:
                    break
            prev = d
        x = y
    y = y.astype(float)
    return y / y.sum(), it


def _aggregated_stationary(Tg: sp.csr_matrix, agg: np.ndarray, x0=None
                           ) -> tuple[np.ndarray, int]:
    """Stationary distribution of one irreducible class by iterative aggregation–
    disaggregation (Takahashi's method; docs/model.md §17).

    ``agg`` maps every state of the class to an aggregate (its contact bin). One cycle: the
    coarse chain C_IJ = Σ_{i∈I} x_i T_ij(J) / X_I over the aggregates, weighted by the current
    iterate x, is solved exactly (sparse LU, a few hundred to a few thousand unknowns); x is
    rescaled inside each aggregate to the coarse solution, then smoothed by 10 damped power
    steps x ← 0.95·Tᵀx + 0.05·x. π is a fixed point of the cycle. The coarse solve carries
    mass between weakly coupled regions (two rooms joined by a door few flights pass), the
    slow modes that stall the plain power iteration; the smoothing removes the fast ones.
    Stops when d·ρ/(1 − ρ) < 1e-6 in L1 (d: the change over a cycle, ρ: its contraction).
    """
    n = Tg.shape[0]
    _, agg = np.unique(np.asarray(agg), return_inverse=True)
    m = int(agg.max()) + 1
    A = sp.csr_matrix((np.ones(n), (np.arange(n), agg)), shape=(n, m))
    TA = sp.csr_matrix(Tg @ A)                              # state -> aggregate
    TT = sp.csr_matrix(Tg.T)
    size = np.bincount(agg, minlength=m)
    x = np.full(n, 1.0 / n) if x0 is None else np.asarray(x0, dtype=float) / np.sum(x0)
    prev = None
    cycles = 0
    while cycles < _AGG_MAX:
        cycles += 1
        X = np.bincount(agg, weights=x, minlength=m)
        # weights inside each aggregate, blended with 1e-9 of the uniform weights: states the
        # class visits with vanishing probability (masses that underflow to 0) would
        # otherwise drop edges of the coarse chain and make it reducible (a singular solve)
        empty = X <= 0.0
        w = np.where(empty[agg], 0.0, x / np.where(empty, 1.0, X)[agg])
        w = (1.0 - _AGG_BLEND) * w + _AGG_BLEND / size[agg]
        w[empty[agg]] = 1.0 / size[agg][empty[agg]]
        C = sp.csr_matrix(A.T @ sp.diags(w) @ TA)
        xi = np.clip(stationary_distributions(C, [np.arange(m)]), 0.0, None)
        y = w * xi[agg]
        for _ in range(_AGG_SWEEPS):
            y = (1.0 - _LAZY) * (TT @ y) + _LAZY * y
        y /= y.sum()
        d = float(np.abs(y - x).sum())
        x = y
        if d == 0.0 or (cycles >= 500 and d > 1e-3):   # or stalled: the caller solves directly
            break
        if x0 is not None and cycles == 1 and d < 10 * _POWER_TOL:   # x0 was its fixed point
            break
        if prev is not None and d < prev:
            rho = d / prev
            if d * rho / (1 - rho) < _POWER_TOL:
                break
        prev = d
    return x, cycles


def analyse_contact_chain(T, start, aggregates=None, method: str = "krylov"
                          ) -> ChainAnalysis:
    """:func:`planners.coverage.markov.analyse_chain` for large contact chains.

    Closed classes and absorption (from ``start``, only needed with several classes) as in
    :mod:`planners.coverage.markov`. Classes of up to 20000 states are solved directly
    (:func:`planners.coverage.markov.stationary_distributions`). Larger ones (docs/model.md §17):

    - ``"krylov"`` (default): BiCGSTAB (:func:`_krylov_stationary`; where it fails, the
      damped power iteration, ≤ 3000 iterations), then aggregation–disaggregation over
      ``aggregates`` (the contact bins) from that iterate: one cycle if it was the fixed
      point, more where it was not (a small residual does not mean a small error on two
      rooms joined by rare edges); a result whose residual ‖Tᵀx − x‖₁ exceeds 1e-6 is
      replaced by the direct solve.
    - ``"aggregation"``: the same with the damped power iteration first (the method before).
    - ``"power"`` (or no aggregates): the first stage alone (BiCGSTAB, or the damped power
      iteration for ``"power"``), unchecked; the power iteration stalls on slowly mixing
      classes (two rooms joined by a door: docs/model.md §17).
    """
    if method not in ("krylov", "aggregation", "power"):
        raise ValueError(f"method must be 'krylov', 'aggregation' or 'power', got {method!r}.")
    T = check_stochastic(T)
    n = T.shape[0]
    _, groups = closed_classes(T)
    small = [g for g in groups if len(g) <= _DIRECT_MAX]
    stat = stationary_distributions(T, small) if small else np.zeros(n)
    for g in groups:
        if len(g) > _DIRECT_MAX:
            Tg = T[g][:, g]
            check = aggregates is not None and method != "power"   # by the aggregation
            x = _krylov_stationary(Tg)[0] if method == "krylov" else None
            if x is None:                                    # fast where the class mixes fast
                x, _ = _power_stationary(Tg, _POWER_FIRST if check else None)
            if check:
                x, _ = _aggregated_stationary(Tg, np.asarray(aggregates)[g], x0=x)  # checks x
                if np.abs(Tg.T @ x - x).sum() > _POWER_TOL:     # not converged: direct solve
                    x = stationary_distributions(Tg, [np.arange(len(g))])
            stat[g] = x
    if len(groups) > 1:
        a = absorption_probabilities(T, groups, start)
    else:
        a = np.ones(len(groups))
    return assemble(n, groups, stat, a)
