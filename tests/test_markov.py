"""Markov-chain analysis (planners.coverage.markov) on chains small enough to solve by hand, and
against independent implementations (quantecon; dense Cesàro limits) on random chains.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from planners.coverage.markov import (
    absorption_matrix,
    absorption_probabilities,
    analyse_chain,
    analyse_run_chain,
    check_stochastic,
    closed_classes,
    run_ends,
    sparse_solve,
    stationary_distributions,
)


def groups_of(res):
    return [g.tolist() for g in res.groups]


# ---------------------------------------------------------------------------- by hand
def test_two_cell_cycle():
    res = analyse_chain(sp.csr_matrix([[0.0, 1.0], [1.0, 0.0]]))
    assert groups_of(res) == [[0, 1]]
    assert res.transient_fraction == 0.0
    np.testing.assert_allclose(res.pi, [0.5, 0.5], atol=1e-15)
    np.testing.assert_allclose(res.absorption, [1.0])


def test_periodic_group_with_transient_feeder():
    # 0 -> 1 -> 2 -> 0 is a 3-cycle (period 3); state 3 feeds it, state 4 feeds state 3.
    P = np.zeros((5, 5))
    P[0, 1] = P[1, 2] = P[2, 0] = 1
    P[3, 0], P[3, 3] = 0.5, 0.5
    P[4, 3] = 1
    res = analyse_chain(P)
    assert groups_of(res) == [[0, 1, 2]]
    assert res.transient_fraction == pytest.approx(2 / 5)
    np.testing.assert_allclose(res.pi, [1 / 3, 1 / 3, 1 / 3, 0, 0], atol=1e-14)
    np.testing.assert_allclose(res.stationary[:3], 1 / 3)


def _two_classes():
    # States: a = 0 (absorbing), b1 = 1, b2 = 2 (a 2-cycle), t0 = 3, t1 = 4 (transient).
    # t0 -> a 1/2, t1 1/2; t1 -> t0 1/2, b1 1/2. By hand: h = P(reach a):
    # h0 = 1/2 + h1/2, h1 = h0/2  =>  h0 = 2/3, h1 = 1/3.
    P = np.zeros((5, 5))
    P[0, 0] = 1
    P[1, 2] = P[2, 1] = 1
    P[3, 0], P[3, 4] = 0.5, 0.5
    P[4, 3], P[4, 1] = 0.5, 0.5
    return sp.csr_matrix(P)


def test_two_closed_classes_absorption_by_hand():
    P = _two_classes()
    res = analyse_chain(P)
    assert groups_of(res) == [[0], [1, 2]]
    # Uniform start over 5 states: a_A = (1 + 2/3 + 1/3) / 5, a_B = (2 + 1/3 + 2/3) / 5.
    np.testing.assert_allclose(res.absorption, [2 / 5, 3 / 5], atol=1e-14)
    np.testing.assert_allclose(res.pi, [0.4, 0.3, 0.3, 0, 0], atol=1e-14)
    T, X = absorption_matrix(P, res.groups)
    assert T.tolist() == [3, 4]
    np.testing.assert_allclose(X, [[2 / 3, 1 / 3], [1 / 3, 2 / 3]], atol=1e-14)
    # A start distribution: all mass on t1.
    a = absorption_probabilities(P, res.groups, start=[0, 0, 0, 0, 1])
    np.testing.assert_allclose(a, [1 / 3, 2 / 3], atol=1e-14)


def test_open_component_is_not_persistent():
    # {0, 1} is strongly connected but leaks to 2; {3} is an unreachable absorbing state.
    P = sp.csr_matrix([[0, 1, 0, 0], [0.5, 0, 0.5, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])
    labels, groups = closed_classes(P)
    assert [g.tolist() for g in groups] == [[2], [3]]
    assert labels[0] == labels[1] != labels[2]


def test_zero_entries_are_not_edges():
    P = sp.csr_matrix((np.array([1.0, 0.0, 1.0]), (np.array([0, 0, 1]), np.array([0, 1, 1]))),
                      shape=(2, 2))
    assert [g.tolist() for g in analyse_chain(P).groups] == [[0], [1]]


@pytest.mark.parametrize("bad, msg", [
    (np.array([[0.5, 0.4], [0, 1]]), "sums to"),
    (np.array([[1.5, -0.5], [0, 1]]), "negative"),
    (np.ones((2, 3)) / 3, "square"),
])
def test_check_stochastic_rejects(bad, msg):
    with pytest.raises(ValueError, match=msg):
        check_stochastic(bad)


# ---------------------------------------------------------------------------- random chains
def random_chain(rng, n, density=0.25, absorbing=0.15):
    """A random sparse row-stochastic matrix with a mix of closed and transient parts."""
    P = np.zeros((n, n))
    for i in range(n):
        if rng.random() < absorbing:
            P[i, i] = 1.0
            continue
        k = rng.integers(1, max(2, int(density * n)) + 1)
        cols = rng.choice(n, size=k, replace=False)
        P[i, cols] = rng.random(k) + 0.05
        P[i] /= P[i].sum()
    return P


def cesaro_limit(P, start):
    """Independent check: μ (½(I + P))^(2^40) by repeated squaring (dense).

    The lazy chain has the same closed classes, stationary distributions and absorption
    probabilities as P, and is aperiodic, so its powers converge to the limiting matrix.
    Rows are renormalised after every squaring so that round-off cannot leak mass.
    """
    L = 0.5 * (np.eye(len(P)) + P)
    for _ in range(40):
        L = L @ L
        L /= L.sum(axis=1, keepdims=True)
    return start @ L


def test_matches_quantecon_and_cesaro_limit_on_random_chains():
    qe = pytest.importorskip("quantecon")
    rng = np.random.default_rng(20240611)
    for trial in range(60):
        n = int(rng.integers(2, 14))
        P = random_chain(rng, n, density=float(rng.uniform(0.1, 0.4)))
        res = analyse_chain(sp.csr_matrix(P))
        mc = qe.MarkovChain(P)
        ours = sorted(tuple(g.tolist()) for g in res.groups)
        theirs = sorted(tuple(sorted(c.tolist())) for c in mc.recurrent_classes)
        assert ours == theirs, trial
        for dist in mc.stationary_distributions:
            support = np.flatnonzero(dist > 1e-12)
            np.testing.assert_allclose(res.stationary[support], dist[support], atol=1e-10)
        mu = np.full(n, 1.0 / n)
        np.testing.assert_allclose(res.pi, cesaro_limit(P, mu), atol=1e-9)
        assert res.pi.sum() == pytest.approx(1.0)


def random_run_chain(rng, n, nruns):
    """Random chain whose states form nruns disjoint deterministic runs ending in branches."""
    perm = rng.permutation(n)
    cuts = np.sort(rng.choice(np.arange(1, n), size=nruns - 1, replace=False))
    succ = np.full(n, -1)
    branch_states = []
    for run in np.split(perm, cuts):
        succ[run[:-1]] = run[1:]
        branch_states.append(run[-1])
    B = np.zeros((n, n))
    for b in branch_states:
        k = int(rng.integers(1, 4))
        cols = rng.choice(n, size=k, replace=False)
        B[b, cols] = rng.random(k) + 0.05
        B[b] /= B[b].sum()
    full = B.copy()
    has = succ >= 0
    full[np.flatnonzero(has), succ[has]] = 1.0
    return succ, sp.csr_matrix(B), sp.csr_matrix(full)


def test_run_chain_matches_full_matrix_analysis():
    rng = np.random.default_rng(7)
    for trial in range(80):
        n = int(rng.integers(3, 40))
        nruns = int(rng.integers(1, n))
        succ, B, full = random_run_chain(rng, n, nruns)
        start = rng.random(n) if trial % 2 else None
        a = analyse_run_chain(succ, B, start=start)
        b = analyse_chain(full, start=start)
        assert groups_of(a) == groups_of(b), trial
        np.testing.assert_allclose(a.absorption, b.absorption, atol=1e-12)
        np.testing.assert_allclose(a.stationary, b.stationary, atol=1e-12)
        np.testing.assert_allclose(a.pi, b.pi, atol=1e-12)
        assert a.transient_fraction == b.transient_fraction


def test_run_chain_rejects_bad_successor_tables():
    B = sp.csr_matrix(np.array([[0, 0, 1.0], [0, 0, 0], [0, 0, 0]]))
    with pytest.raises(ValueError, match="not injective"):
        analyse_run_chain(np.array([-1, 0, 0]), B)
    with pytest.raises(ValueError, match="cycle"):
        run_ends(np.array([1, 2, 0]))


def test_run_ends_by_hand():
    assert run_ends(np.array([1, 2, -1, 4, -1, -1])).tolist() == [2, 2, 2, 4, 4, 5]


# ---------------------------------------------------------------------------- solvers
def test_iterative_solver_path_matches_direct():
    # n > 2000 takes the ILU + GMRES path: compare with a direct LU on the same system.
    rng = np.random.default_rng(3)
    n = 3000
    P = sp.random(n, n, density=4 / n, random_state=np.random.RandomState(1), format="csr")
    P = sp.diags(1 / np.maximum(np.asarray(P.sum(axis=1)).ravel(), 1e-12)) @ P
    M = (sp.identity(n) - 0.99 * P).tocsc()
    rhs = rng.random(n)
    from scipy.sparse.linalg import spsolve
    np.testing.assert_allclose(sparse_solve(M, rhs), spsolve(M, rhs), rtol=1e-9, atol=1e-12)


def test_large_cycle_stationary_is_uniform():
    # A 5000-state cycle with lazy self-loops: π is exactly uniform (iterative path).
    n = 5000
    i = np.arange(n)
    P = sp.csr_matrix((np.r_[np.full(n, 0.5), np.full(n, 0.5)],
                       (np.r_[i, i], np.r_[i, (i + 1) % n])), shape=(n, n))
    pi = stationary_distributions(P, [i])
    np.testing.assert_allclose(pi, 1 / n, rtol=1e-9)
