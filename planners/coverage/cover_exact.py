"""Cover times computed exactly on small chains (docs/model.md §20a).

The model's delay chain (:class:`~planners.coverage.event_flights.StartedChain`) unfolded
into a one-step chain over *units* u = (flight f, offset j): at every step a robot is at the
j-th step of flight f, counted in that step's cell (or in none). From (f, j) it moves to
(f, j + 1); from a flight's last step (the bump step) it lands in dst_f, turns by the
angle's turn matrix and starts a flight f' by its weight: (f', 0). The chain on (unit,
visited set V ⊆ {0 … P−1}) is propagated exactly, for a mix in epochs as the α-mixture of
each angle's epoch (the angle is drawn independently of the state). That is 2^P·n_units
numbers per step: feasible for a handful of cells only, which is what the tests need as an
independent reference.

A team of K independent robots from the same start: the union of K independent visited
sets, whose distribution follows from one robot's by the subset (zeta) transform,
Pr(V_1 ∪ … ∪ V_K ⊆ S) = Pr(V ⊆ S)^K, and its inverse (Möbius).

Two robots meet at a step when both count it in the same cell. Their first meeting is the
absorption time of the product chain on (unit, unit), absorbed where the two units' cells
agree (:func:`meeting_survival`: n_units² numbers per step, for small chains).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

__all__ = ["EXACT_MAX", "MEET_EXACT_MAX", "exact_distribution", "exact_size", "meeting_size",
           "meeting_survival", "subset_union"]

EXACT_MAX = 1 << 18      # largest n_units · 2^P the exact path takes (method "auto")
MEET_EXACT_MAX = 1 << 30  # largest n_units² · horizon the exact first meeting takes


def _units(tables):
    """(n_units, unit of (f, 0) per flight, cell per unit) of the unfolded chain."""
    first = tables.cptr
    return int(tables.delay.sum()), first, tables.cells.astype(np.int64)


def exact_size(tables, P: int) -> int:
    """n_units · 2^P: the numbers the exact path propagates per step."""
    return int(tables.delay.sum()) << int(P)


def meeting_size(tables, horizon: int) -> int:
    """n_units² · horizon, the work of :func:`meeting_survival`; more than
    :data:`MEET_EXACT_MAX` when its joint distribution alone (n_units² numbers) would exceed
    2^24 (128 MB).
    """
    n = int(tables.delay.sum())
    return n * n * int(horizon) if n * n <= 1 << 24 else MEET_EXACT_MAX + 1


def _start_units(tables, start_states, start_weights) -> np.ndarray:
    """The distribution over units of step 0 (the first flight's first step) of a robot
    that departs from ``start_states`` with probabilities ``start_weights``.
    """
    n_units, first, _ = _units(tables)
    dist = np.zeros(n_units)
    w = np.asarray(start_weights, dtype=float)
    w = w / w.sum()
    fw = _weights(tables)
    for s, ws in zip(np.asarray(start_states).tolist(), w.tolist()):
        lo, hi = tables.fptr[s], tables.fptr[s + 1]
        np.add.at(dist, first[tables.fidx[lo:hi]], ws * fw[lo:hi])
    return dist


def meeting_survival(tables, turn, start_states, start_weights, horizon: int) -> np.ndarray:
    """Pr(τ > t) for t = 0 … horizon − 1, τ the first step at which two independent robots
    of one angle (turn matrix ``turn``), each from the start distribution, are counted in
    the same cell: the product chain on (unit, unit) propagated exactly, its meeting pairs
    absorbed at every step.
    """
    _, _, cell = _units(tables)
    n_states = tables.fptr.size - 1
    U = _unit_matrix(tables, turn, n_states)
    UT = sp.csr_matrix(U.T)
    a = _start_units(tables, start_states, start_weights)
    joint = np.outer(a, a)
    met = (cell[:, None] == cell[None, :]) & (cell[:, None] >= 0)
    out = np.empty(int(horizon))
    for t in range(int(horizon)):
        joint[met] = 0.0
        out[t] = joint.sum()
        joint = np.asarray(UT @ np.asarray(UT @ joint).T).T     # Uᵀ · joint · U
    return np.clip(out, 0.0, 1.0)


def _unit_matrix(tables, W, n_states: int) -> sp.csr_matrix:
    """One step of the unfolded chain under one angle's turn ``W`` (n_base × n)."""
    n_units, first, _ = _units(tables)
    delay, dst = tables.delay, tables.dst
    u = np.arange(n_units)
    f_of = np.repeat(np.arange(delay.size), delay)
    j_of = u - first[f_of]
    inner = j_of < delay[f_of] - 1
    rows, cols, vals = [u[inner]], [u[inner] + 1], [np.ones(int(inner.sum()))]
    # the bump step: land in dst, turn (W), start flight f' of the turned state by weight
    F = sp.csr_matrix((_weights(tables), (_srcs(tables), tables.fidx)),
                      shape=(n_states, delay.size))
    W = sp.csr_matrix(W)
    if W.shape[1] < n_states:                        # the start states: never turned into
        W = sp.hstack([W, sp.csr_matrix((W.shape[0], n_states - W.shape[1]))], format="csr")
    nxt = sp.csr_matrix(W @ F)                        # landing state → next flight
    ends = np.flatnonzero(~inner)
    block = sp.coo_matrix(nxt[dst[f_of[ends]]])
    rows.append(ends[block.row])
    cols.append(first[block.col])
    vals.append(block.data)
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                         shape=(n_units, n_units))


def _srcs(tables) -> np.ndarray:
    """The state each entry of ``tables.fidx`` belongs to."""
    return np.repeat(np.arange(tables.fptr.size - 1), np.diff(tables.fptr))


def _weights(tables) -> np.ndarray:
    """The weight of each entry of ``tables.fidx`` (from the cumulative ``fcum``)."""
    c = tables.fcum
    w = np.diff(np.concatenate([[0.0], c]))
    starts = tables.fptr[:-1][np.diff(tables.fptr) > 0]
    w[starts] = c[starts]
    return w


def exact_distribution(tables, turns, alpha, epoch, start_states, start_weights, P: int,
                       horizon: int):
    """Distribution of the visited set after every number of steps, exactly.

    Returns a generator of (t, g) for t = 1 … horizon: g (2^P,) the probability of each
    set V (bit c: cell c) of cells visited in steps 0 … t−1 by one robot.
    """
    n_units, first, cell = _units(tables)
    n_states = tables.fptr.size - 1
    alpha = np.asarray(alpha, dtype=float)
    alpha = alpha / alpha.sum()
    U = [sp.csr_matrix(_unit_matrix(tables, W, n_states).T) for W in turns]
    S = 1 << P
    dist = np.zeros((n_units, S))
    dist[:, 0] = _start_units(tables, start_states, start_weights)
    bits = np.arange(S)
    by_cell = [(c, np.flatnonzero(cell == c), bits[(bits >> c) & 1 == 0]) for c in range(P)]
    ep = int(epoch) if epoch is not None and alpha.size > 1 else int(horizon) + 1

    def visit(d):
        for c, units, without in by_cell:
            if units.size:
                b = d[units]
                b[:, without | (1 << c)] += b[:, without]
                b[:, without] = 0.0
                d[units] = b
        return d

    t = 0
    while t < horizon:
        end = min(t + ep, horizon)
        branches = [dist.copy() for _ in alpha] if alpha.size > 1 else [dist]
        out = np.zeros((end - t, S))
        for a, (al, d) in enumerate(zip(alpha, branches)):
            for i in range(end - t):
                d = visit(d)
                out[i] += al * d.sum(axis=0)
                d = U[a] @ d
            branches[a] = d
        dist = sum(al * d for al, d in zip(alpha, branches))
        for i in range(end - t):
            yield t + i + 1, out[i]
        t = end


def subset_union(g: np.ndarray, K: int) -> np.ndarray:
    """Distribution of the union of K independent sets, each distributed as ``g`` (2^P,)."""
    if K == 1:
        return g
    f = g.copy()
    P = int(f.size).bit_length() - 1
    for i in range(P):                                   # zeta: Pr(V ⊆ S)
        v = f.reshape(-1, 2, 1 << i)
        v[:, 1, :] += v[:, 0, :]
    f = f ** K
    for i in range(P):                                   # Möbius: back to Pr(V = S)
        v = f.reshape(-1, 2, 1 << i)
        v[:, 1, :] -= v[:, 0, :]
    return np.clip(f, 0.0, None)
