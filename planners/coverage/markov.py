"""Finite Markov chains with sparse transition matrices: closed classes, limiting distributions.

This module knows nothing about robots: it takes a row-stochastic transition matrix
(``scipy.sparse``, any format) and answers docs/model.md §16's questions about it.

- :func:`closed_classes`: the persistent groups (closed communicating classes) = strongly
  connected components with no transition leaving them, read off the condensation graph
  (no transitive closure).
- :func:`stationary_distributions`: the unique stationary distribution π_g of every group
  (periodic groups included: π_g solves π (P − I) = 0, Σ π = 1; for a periodic group it is
  the long-run time average, not a limit of P^t).
- :func:`absorption_probabilities`: a_g = probability of ending in group g from a start
  distribution (default: uniform over all states).
- :func:`analyse_chain`: all of the above in one :class:`ChainAnalysis` record, with the
  limiting distribution π = Σ_g a_g π_g.
- :func:`analyse_run_chain`: the same record for chains whose non-branching states form
  deterministic runs (the bouncing robot's forward moves), computed on the much smaller
  chain of branching states (the *censored* chain) and expanded back exactly.

Everything stays sparse: the largest objects are the transition matrix and a few vectors of
length N. Linear systems are solved with ``scipy.sparse.linalg.spsolve`` (SuperLU, COLAMD
ordering).

Examples
--------
A two-cell cycle (periodic, period 2) fed by one transient state:

>>> import numpy as np, scipy.sparse as sp
>>> P = sp.csr_matrix(np.array([[0, 1, 0], [1, 0, 0], [0.5, 0, 0.5]]))
>>> res = analyse_chain(P)
>>> [g.tolist() for g in res.groups], res.transient_fraction
([[0, 1]], 0.3333333333333333)
>>> res.pi.round(6).tolist()
[0.5, 0.5, 0.0]
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.sparse.linalg import LinearOperator, gmres, spilu, spsolve

__all__ = ["ChainAnalysis", "closed_classes", "stationary_distributions",
           "absorption_probabilities", "absorption_matrix", "analyse_chain",
           "analyse_run_chain", "assemble", "run_ends", "check_stochastic", "sparse_solve"]

_ROW_TOL = 1e-9
_DIRECT_MAX = 2000          # systems up to this size go straight to SuperLU


def sparse_solve(M, rhs, rtol: float = 1e-12, accept: float = 1e-10) -> np.ndarray:
    """Solve the sparse non-singular system M x = rhs.

    Small systems (n <= 2000) use a direct sparse LU (SuperLU). Larger ones use GMRES
    preconditioned by an incomplete LU (drop tolerance 1e-4): the chains here are
    expander-like, so a complete LU fills in to a large fraction of a dense matrix, while
    the ILU-preconditioned GMRES converges in a handful of iterations. GMRES aims at
    ‖M x − rhs‖ ≤ rtol ‖rhs‖ (at most 200 iterations; on ill-conditioned transient blocks
    it can stall just above that) and the answer is accepted when
    ‖M x − rhs‖ ≤ accept ‖rhs‖; otherwise, or if the ILU breaks down, a tighter ILU (drop
    tolerance 1e-6) is tried, and then the direct solver.
    """
    M = sp.csc_matrix(M)
    rhs = np.asarray(rhs, dtype=float)
    n = M.shape[0]
    if n <= _DIRECT_MAX:
        return np.atleast_1d(spsolve(M, rhs))
    bnorm = float(np.linalg.norm(rhs))
    if bnorm == 0:
        return np.zeros(n)
    for drop_tol, fill in ((1e-4, 20), (1e-6, 50)):      # a tighter ILU if the first fails
        try:
            ilu = spilu(M, drop_tol=drop_tol, fill_factor=fill)
            pre = LinearOperator(M.shape, ilu.solve)
            x, _ = gmres(M, rhs, M=pre, rtol=rtol, atol=0.0, restart=40, maxiter=5)
        except RuntimeError:           # singular pivot in the ILU
            continue
        if np.all(np.isfinite(x)) and np.linalg.norm(M @ x - rhs) <= accept * bnorm:
            return x
    return np.atleast_1d(spsolve(M, rhs))


@dataclass(frozen=True, eq=False)
class ChainAnalysis:
    """Closed classes and the limiting distribution of a finite Markov chain.

    Attributes
    ----------
    groups : tuple of ndarray
        State indices of each persistent group (closed communicating class), each sorted;
        groups are ordered by their smallest state.
    group_sizes : ndarray of int, shape (G,)
    absorption : ndarray, shape (G,)
        a_g: probability of ending in group g from the start distribution.
    stationary : ndarray, shape (N,)
        Every group's stationary distribution π_g on its own states (each sums to 1 over
        its group); 0 on transient states.
    pi : ndarray, shape (N,)
        Limiting (long-run average) distribution π = Σ_g a_g π_g; sums to 1.
    transient_fraction : float
        Fraction of the N states that belong to no persistent group.
    """

    groups: tuple
    group_sizes: np.ndarray
    absorption: np.ndarray
    stationary: np.ndarray
    pi: np.ndarray
    transient_fraction: float

    @property
    def n_states(self) -> int:
        """Number of states of the chain."""
        return int(self.pi.shape[0])

    @property
    def n_groups(self) -> int:
        """Number of persistent groups."""
        return len(self.groups)

    def group_labels(self) -> np.ndarray:
        """(N,) int array: group index of each state, or -1 for transient states."""
        lab = np.full(self.n_states, -1, dtype=np.int64)
        for g, idx in enumerate(self.groups):
            lab[idx] = g
        return lab


# ---------------------------------------------------------------------------- helpers
def check_stochastic(P, tol: float = _ROW_TOL) -> sp.csr_matrix:
    """Return P as CSR (explicit zeros removed) after checking it is row-stochastic.

    Raises ValueError for a non-square matrix, a negative entry or a row that does not sum
    to 1 within ``tol``.
    """
    P = sp.csr_matrix(P, dtype=float, copy=True)
    if P.shape[0] != P.shape[1]:
        raise ValueError(f"a transition matrix must be square, got shape {P.shape}.")
    P.sum_duplicates()
    P.eliminate_zeros()
    if P.nnz and P.data.min() < 0:
        raise ValueError("a transition matrix has a negative entry.")
    rows = np.asarray(P.sum(axis=1)).ravel()
    bad = np.flatnonzero(np.abs(rows - 1.0) > tol)
    if bad.size:
        raise ValueError(f"row {bad[0]} of the transition matrix sums to {rows[bad[0]]!r}, "
                         "not 1.")
    return P


def _groups_from_labels(labels: np.ndarray, keep: np.ndarray) -> tuple:
    """Group the state indices by component label for the components in ``keep``."""
    if keep.size == 0:
        return ()
    member = np.isin(labels, keep)
    idx = np.flatnonzero(member)
    lab = labels[idx]
    order = np.argsort(lab, kind="stable")          # stable: members stay sorted
    idx, lab = idx[order], lab[order]
    cuts = np.flatnonzero(np.diff(lab)) + 1
    groups = np.split(idx, cuts)
    groups.sort(key=lambda g: int(g[0]))
    return tuple(groups)


def closed_classes(P) -> tuple[np.ndarray, tuple]:
    """Persistent groups of the chain: SCCs with no edge leaving them.

    Parameters
    ----------
    P : sparse matrix (N, N)
        Transition matrix; only its non-zero pattern is used.

    Returns
    -------
    labels : ndarray of int, shape (N,)
        Strongly connected component of every state.
    groups : tuple of ndarray
        Sorted state indices of each closed class, ordered by smallest member.

    Notes
    -----
    A component is closed when no edge (i, j) with P[i, j] > 0 joins it to another
    component; that is one pass over the edges of the condensation graph.

    >>> import scipy.sparse as sp
    >>> P = sp.csr_matrix([[0.5, 0.5, 0], [0, 1, 0], [0, 0, 1]])
    >>> [g.tolist() for g in closed_classes(P)[1]]
    [[1], [2]]
    """
    A = sp.csr_matrix(P)
    A.eliminate_zeros()
    n = A.shape[0]
    if n == 0:
        return np.zeros(0, dtype=np.int64), ()
    ncomp, labels = connected_components(A, directed=True, connection="strong")
    labels = labels.astype(np.int64)
    rows = np.repeat(np.arange(n), np.diff(A.indptr))
    leaving = labels[rows] != labels[A.indices]
    is_open = np.zeros(ncomp, dtype=bool)
    is_open[labels[rows[leaving]]] = True
    return labels, _groups_from_labels(labels, np.flatnonzero(~is_open))


def stationary_distributions(P, groups) -> np.ndarray:
    """Stationary distribution of every closed class, solved as one sparse system.

    Parameters
    ----------
    P : sparse matrix (N, N)
        Row-stochastic transition matrix.
    groups : sequence of int arrays
        Closed classes (as from :func:`closed_classes`).

    Returns
    -------
    ndarray, shape (N,)
        π_g on each group's states (summing to 1 over the group), 0 elsewhere.

    Notes
    -----
    Restricted to the union R of the groups, P is block diagonal (the groups are closed), so
    all groups are solved together: the system (P_RR)ᵀ x − x = 0 with, in each group, the
    equation of its first state replaced by the normalisation Σ_{i∈g} x_i = 1. For an
    irreducible block the n−1 remaining balance equations are independent and the
    normalisation fixes the scale, so the system is non-singular; periodic groups need no
    special care. Round-off negatives (|x| ~ 1e-17) are clipped to 0 and each group is
    renormalised.
    """
    P = sp.csr_matrix(P)
    n = P.shape[0]
    out = np.zeros(n)
    if not len(groups):
        return out
    rec = np.concatenate([np.asarray(g, dtype=np.int64) for g in groups])
    sizes = np.array([len(g) for g in groups])
    gid = np.repeat(np.arange(len(groups)), sizes)
    m = rec.size
    local = np.full(n, -1, dtype=np.int64)
    local[rec] = np.arange(m)
    Prr = P[rec][:, rec].tocoo()
    # M = Prr^T - I, as COO triplets (row = destination state, column = source state).
    r = np.concatenate([Prr.col, np.arange(m)])
    c = np.concatenate([Prr.row, np.arange(m)])
    v = np.concatenate([Prr.data, -np.ones(m)])
    first = np.concatenate([[0], np.cumsum(sizes)[:-1]])   # local index of each group's 1st
    replaced = np.zeros(m, dtype=bool)
    replaced[first] = True
    keep = ~replaced[r]
    r = np.concatenate([r[keep], np.repeat(first, sizes)])
    c = np.concatenate([c[keep], np.arange(m)])
    v = np.concatenate([v[keep], np.ones(m)])
    M = sp.csc_matrix((v, (r, c)), shape=(m, m))
    rhs = replaced.astype(float)
    x = sparse_solve(M, rhs)
    x[x < 0] = 0.0
    tot = np.bincount(gid, weights=x, minlength=len(groups))
    x = x / tot[gid]
    out[rec] = x
    return out


def _start_vector(n: int, start) -> np.ndarray:
    if start is None:
        return np.full(n, 1.0 / n) if n else np.zeros(0)
    mu = np.asarray(start, dtype=float).ravel()
    if mu.shape != (n,) or (mu < 0).any() or not mu.sum() > 0:
        raise ValueError("start must be a non-negative vector of length N with positive sum.")
    return mu / mu.sum()


def _group_indicator(n: int, groups) -> tuple[np.ndarray, sp.csr_matrix]:
    """Labels (N,) with -1 for transient states and the (N, G) 0/1 indicator matrix."""
    lab = np.full(n, -1, dtype=np.int64)
    for g, idx in enumerate(groups):
        lab[np.asarray(idx, dtype=np.int64)] = g
    rec = np.flatnonzero(lab >= 0)
    ind = sp.csr_matrix((np.ones(rec.size), (rec, lab[rec])), shape=(n, len(groups)))
    return lab, ind


def absorption_probabilities(P, groups, start=None) -> np.ndarray:
    """Probability a_g of ending in each closed class from a start distribution.

    Parameters
    ----------
    P : sparse matrix (N, N)
        Row-stochastic transition matrix.
    groups : sequence of int arrays
        All closed classes of P.
    start : array_like (N,), optional
        Start distribution μ (default uniform over all N states); it is normalised.

    Returns
    -------
    ndarray, shape (G,), summing to 1.

    Notes
    -----
    With T the transient states, Q = P_TT and R = P_T· summed into group columns, the
    absorption matrix is X = (I − Q)⁻¹ R (:func:`absorption_matrix`) and
    a = μ_G + μ_Tᵀ X. Instead of solving for the G columns of X this solves the one
    adjoint system (I − Q)ᵀ y = μ_T and takes a = μ_G + yᵀ R (same numbers, one solve).
    """
    P = sp.csr_matrix(P)
    n = P.shape[0]
    G = len(groups)
    if G == 0:
        return np.zeros(0)
    mu = _start_vector(n, start)
    lab, ind = _group_indicator(n, groups)
    a = np.asarray(ind.T @ mu).ravel()
    T = np.flatnonzero(lab < 0)
    if T.size and mu[T].any():
        PT = P[T]
        Q = PT[:, T]
        R = PT @ ind                                   # (T, G)
        IQ = (sp.identity(T.size, format="csc") - Q).T.tocsc()
        y = sparse_solve(IQ, mu[T])
        a = a + np.asarray(R.T @ y).ravel()
    a = np.clip(a, 0.0, None)
    return a / a.sum()


def absorption_matrix(P, groups) -> tuple[np.ndarray, np.ndarray]:
    """Per-start absorption probabilities X = (I − Q)⁻¹ R of the transient states.

    Returns
    -------
    transient : ndarray of int, shape (T,)
        The transient states.
    X : ndarray, shape (T, G)
        X[t, g] = probability of ending in group g when starting in ``transient[t]``.
        (Dense in G only; meant for inspection and tests on modest chains.)
    """
    P = sp.csr_matrix(P)
    n = P.shape[0]
    lab, ind = _group_indicator(n, groups)
    T = np.flatnonzero(lab < 0)
    if T.size == 0 or not len(groups):
        return T, np.zeros((T.size, len(groups)))
    PT = P[T]
    IQ = (sp.identity(T.size, format="csc") - PT[:, T]).tocsc()
    R = (PT @ ind).toarray()
    X = spsolve(IQ, R).reshape(T.size, len(groups))
    return T, np.asarray(X)


def analyse_chain(P, start=None, check: bool = True) -> ChainAnalysis:
    """Persistent groups, stationary distributions and the limiting distribution of P.

    Parameters
    ----------
    P : sparse matrix (N, N)
        Row-stochastic transition matrix (dense arrays are accepted and converted).
    start : array_like (N,), optional
        Start distribution (default uniform over the N states).
    check : bool
        Verify that P is row-stochastic (ValueError otherwise).

    Examples
    --------
    Two absorbing states reached from a transient one with weights 1/4 and 3/4:

    >>> import scipy.sparse as sp
    >>> P = sp.csr_matrix([[0, 0.25, 0.75], [0, 1, 0], [0, 0, 1]])
    >>> res = analyse_chain(P)
    >>> res.absorption.tolist()                # (1 + 1/4) / 3, (1 + 3/4) / 3
    [0.4166666666666667, 0.5833333333333334]
    """
    P = check_stochastic(P) if check else sp.csr_matrix(P)
    n = P.shape[0]
    _, groups = closed_classes(P)
    stat = stationary_distributions(P, groups)
    a = absorption_probabilities(P, groups, start)
    return assemble(n, groups, stat, a)


def assemble(n, groups, stat, a) -> ChainAnalysis:
    """The :class:`ChainAnalysis` of ``n`` states from their closed classes ``groups``, each
    class's stationary distribution ``stat`` and the absorption weights ``a``.
    """
    sizes = np.array([len(g) for g in groups], dtype=np.int64)
    pi = np.zeros(n)
    for g, idx in enumerate(groups):
        pi[idx] = a[g] * stat[idx]
    s = pi.sum()
    if s > 0:
        pi /= s
    rec = int(sizes.sum())
    return ChainAnalysis(groups=tuple(groups), group_sizes=sizes, absorption=np.asarray(a),
                         stationary=stat, pi=pi,
                         transient_fraction=float((n - rec) / n) if n else 0.0)


# ---------------------------------------------------------------------------- run chains
def _pointer_jump_end(succ: np.ndarray) -> np.ndarray:
    """End of every deterministic run: follow ``succ`` (-1 = branching state) to the end."""
    n = succ.size
    nxt = np.where(succ >= 0, succ, np.arange(n))
    for _ in range(64):                       # 2^64 > any run length
        nn = nxt[nxt]
        if np.array_equal(nn, nxt):
            return nxt
        nxt = nn
    raise ValueError("the deterministic successor table has a cycle.")


def run_ends(succ) -> np.ndarray:
    """For every state, the branching state (``succ == -1``) its deterministic run ends in.

    >>> run_ends(np.array([1, 2, -1, -1])).tolist()
    [2, 2, 2, 3]
    """
    succ = np.asarray(succ, dtype=np.int64)
    return _pointer_jump_end(succ)


def _run_prefix(succ: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Sums of ``s`` over each state and all its deterministic predecessors (list ranking).

    ``succ`` must be injective where >= 0 (every state has at most one predecessor), so the
    deterministic edges form disjoint simple paths; Wyllie's pointer jumping computes the
    inclusive prefix sums along every path in O(N log L) vectorised work.
    """
    n = succ.size
    pred = np.full(n, -1, dtype=np.int64)
    src = np.flatnonzero(succ >= 0)
    pred[succ[src]] = src
    val = np.array(s, dtype=float, copy=True)
    ptr = pred
    while True:
        has = np.flatnonzero(ptr >= 0)
        if has.size == 0:
            return val
        p = ptr[has]
        val_new = val.copy()
        val_new[has] += val[p]
        ptr_new = ptr.copy()
        ptr_new[has] = ptr[p]
        val, ptr = val_new, ptr_new


def analyse_run_chain(succ, branch, start=None) -> ChainAnalysis:
    """Analyse a chain whose non-branching states move deterministically (exact, fast).

    The chain has two kinds of state: a *run* state x moves to ``succ[x]`` with probability
    1; a *branching* state (``succ[x] == -1``) moves according to its row of ``branch``.
    The bouncing robot's chain is of this kind (forward moves are runs, bumps branch).

    Parameters
    ----------
    succ : array_like of int, shape (N,)
        Deterministic successor, or -1 for branching states. Must be injective on its
        non-negative entries and acyclic (every run ends in a branching state).
    branch : sparse matrix (N, N)
        Transition probabilities of the branching states (rows of run states are ignored);
        each branching row sums to 1.
    start : array_like (N,), optional
        Start distribution (default uniform over the N states).

    Returns
    -------
    ChainAnalysis
        The same record :func:`analyse_chain` returns for the full N-state matrix.

    Notes
    -----
    Every run ends in a branching state, so the chain *censored* to the branching states B
    (observe the chain only when it is in B) has the transitions
    C[b, b'] = Σ_c branch[b, c] · [end(c) = b'], with end(c) the branching state that c's
    run ends in. The closed classes of C are the branching parts of the closed classes of
    the full chain, and the stationary distribution of C on a class is the full one restricted
    to B (up to scale). The full stationary vector follows from the balance equations: a
    state receives the branching inflow s(x) = Σ_b π(b) branch[b, x] plus the mass of its
    unique run predecessor, so π(x) is the prefix sum of s along its run. A start state x
    enters B at end(x), so the start distribution on B is μ pushed through end().
    """
    succ = np.asarray(succ, dtype=np.int64).ravel()
    n = succ.size
    mu = _start_vector(n, start)
    runs = succ >= 0
    if runs.any() and np.bincount(succ[runs], minlength=n).max() > 1:
        raise ValueError("the deterministic successor table is not injective.")
    end = _pointer_jump_end(succ)
    B = np.flatnonzero(~runs)
    Bbr = sp.csr_matrix(sp.csr_matrix(branch)[B])
    Bbr.sum_duplicates()
    Bbr.eliminate_zeros()
    rows = np.asarray(Bbr.sum(axis=1)).ravel()
    if B.size and np.abs(rows - 1).max() > _ROW_TOL:
        raise ValueError("a branching row of the transition matrix does not sum to 1.")
    bindex = np.full(n, -1, dtype=np.int64)
    bindex[B] = np.arange(B.size)
    # Censored chain on B: columns moved to the end of their run.
    Cc = sp.csr_matrix((Bbr.data.copy(), bindex[end[Bbr.indices]], Bbr.indptr.copy()),
                       shape=(B.size, B.size))           # copies: sum_duplicates works in place
    Cc.sum_duplicates()
    _, cgroups = closed_classes(Cc)
    cstat = stationary_distributions(Cc, cgroups)
    mu_b = np.bincount(bindex[end], weights=mu, minlength=B.size)
    a = absorption_probabilities(Cc, cgroups, mu_b) if cgroups else np.zeros(0)
    # Expand to the full chain: branching inflow, prefix sums along runs.
    inflow = np.asarray(Bbr.T @ cstat).ravel()           # s(x) over all N states
    full = _run_prefix(succ, inflow)
    # Recurrent states: those with a positive inflow at or upstream of them (combinatorial,
    # so tiny stationary masses are not mistaken for zeros).
    cls = np.full(B.size, -1, dtype=np.int64)
    for g, idx in enumerate(cgroups):
        cls[idx] = g
    bsrc = np.repeat(np.arange(B.size), np.diff(Bbr.indptr))
    fed = np.zeros(n)
    fed[Bbr.indices[cls[bsrc] >= 0]] = 1.0
    reach = _run_prefix(succ, fed) > 0
    lab = np.where(reach, cls[bindex[end]], -1)
    groups = _groups_from_labels(lab, np.arange(len(cgroups)))
    full = np.where(lab >= 0, np.clip(full, 0.0, None), 0.0)
    if groups:
        tot = np.bincount(lab[lab >= 0], weights=full[lab >= 0], minlength=len(cgroups))
        full[lab >= 0] /= tot[lab[lab >= 0]]
    # The groups come sorted by smallest full-state index; reorder a to match.
    a = a[[int(lab[g[0]]) for g in groups]] if groups else a
    return assemble(n, groups, full, a)
