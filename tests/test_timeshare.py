"""planners.coverage.timeshare: the coverage of a policy mix executed in epochs (docs/model.md §19).

Independent evidence: dense brute force (matrix powers of the epoch map, and of an explicit
step-level expansion of a delay chain) on random small chains, the one-angle and long-epoch
limits against the models' own q, and the kinematic twin on fig1, where docs/model.md §16's
Σ α_i q_i is far off.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as la
import scipy.sparse as sp

import envs
from planners.cells import CellSpace
from planners.coverage import TurnNoise, design_mix, model_for, timeshared_coverage
from planners.coverage.timeshare import PARALLEL_MIN, DelayChain, TimeShared, timeshared
from planners.metrics import tv_distance
from planners.plan import PolicyMix


def _stochastic(rng, n, m):
    W = rng.random((n, m)) + 0.05        # positive: irreducible, aperiodic
    return W / W.sum(axis=1, keepdims=True)


def _stationary(M):
    w, v = la.eig(M.T)
    x = np.real(v[:, np.argmin(np.abs(w - 1))])
    return x / x.sum()


def _epoch_occupancy(Ps, alpha, g, E):
    """Dense: epoch map M = Σ α_i P_i^E, its stationary μ and the normalised occupancy
    Σ α_i Σ_{t=1..E} μ P_i^t g.
    """
    M = sum(a * np.linalg.matrix_power(Pm, E) for a, Pm in zip(alpha, Ps))
    mu = _stationary(M)
    occ = np.zeros(g.shape[1])
    for a, Pm in zip(alpha, Ps):
        x = mu.copy()
        for _ in range(E):
            x = x @ Pm
            occ += a * (x @ g)
    return occ / occ.sum()


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("E", [1, 3, 8])
def test_stepwise_chain_matches_dense_epoch_map(seed, E):
    rng = np.random.default_rng(seed)
    n, P, m = 7, 3, 3
    Ws = [_stochastic(rng, n, n) for _ in range(m)]
    R = np.zeros((n, P))
    R[np.arange(n), rng.integers(0, P, n)] = rng.uniform(0.5, 1.0, n)   # some steps dropped
    alpha = rng.dirichlet(np.ones(m))
    chain = DelayChain.stepwise(sp.csr_matrix(R), np.full(n, 1 / n))
    res = timeshared(chain, [sp.csr_matrix(W) for W in Ws], alpha, E, tol=1e-9)
    assert res.converged
    np.testing.assert_allclose(res.q, _epoch_occupancy(Ws, alpha, R, E), atol=2e-6)
    # counted fraction: the reward's row sums weighted by the occupancy of the states
    assert 0.5 <= res.counted_fraction <= 1.0


def _brute_delay(chain: DelayChain, Ws, alpha, E):
    """The delay chain expanded into an ordinary step chain over (flight f, steps flown j),
    j = 0 … d_f − 1: flight f at j < d_f − 1 moves to j + 1; at the last step it lands in
    dst_f, turns by W and starts flight f' (weight w_f') at j = 0. The reward of a flight
    is counted when it starts: g(f, 0) = R[src_f].
    """
    F = chain.src.size
    idx = {}
    for f in range(F):
        for j in range(chain.delay[f]):
            idx[f, j] = len(idx)
    S = len(idx)
    R = chain.reward.toarray()
    g = np.zeros((S, R.shape[1]))
    for f in range(F):
        g[idx[f, 0]] = R[chain.src[f]]
    Ps = []
    for W in Ws:
        Pm = np.zeros((S, S))
        for f in range(F):
            for j in range(chain.delay[f]):
                if j + 1 < chain.delay[f]:
                    Pm[idx[f, j], idx[f, j + 1]] = 1.0
                else:
                    land = chain.dst[f]
                    for f2 in range(F):
                        Pm[idx[f, j], idx[f2, 0]] += W[land, chain.src[f2]] * chain.weight[f2]
        Ps.append(Pm)
    # the mass at (f', 0) is v[s'] w_f', and Σ_f' w_f' R[s'] = R[s']
    return _epoch_occupancy(Ps, alpha, g, E)


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("E", [1, 4, 9])
def test_delay_chain_matches_step_level_expansion(seed, E):
    rng = np.random.default_rng(100 + seed)
    n, P, m, S = 5, 3, 2, 2
    src = np.repeat(np.arange(n), S)
    dst = rng.integers(0, n, src.size)
    delay = rng.integers(1, 4, src.size)
    w = np.full(src.size, 1.0 / S)
    R = sp.csr_matrix(rng.uniform(0, 1, (n, P)) * (rng.random((n, P)) < 0.6))
    R = R + sp.csr_matrix((np.full(n, 0.1), (np.arange(n), np.zeros(n, int))), shape=(n, P))
    chain = DelayChain(src=src, dst=dst, delay=delay, weight=w, reward=sp.csr_matrix(R),
                       start=np.full(n, 1 / n))
    Ws = [_stochastic(rng, n, n) for _ in range(m)]
    alpha = rng.dirichlet(np.ones(m))
    res = timeshared(chain, [sp.csr_matrix(W) for W in Ws], alpha, E, tol=1e-10)
    np.testing.assert_allclose(res.q, _brute_delay(chain, Ws, alpha, E), atol=5e-6)


def test_a_step_split_over_threads_gives_the_same_numbers():
    # a chain above PARALLEL_MIN states splits every step into row blocks on threads: the
    # same float32 numbers for any split, and a plain float64 recursion over all states
    # agrees (the products skip the states no flight lands in: ~e⁻² of them here)
    rng = np.random.default_rng(3)
    n, S, D, steps = PARALLEL_MIN + 5000, 2, 5, 40
    src = np.repeat(np.arange(n), S)
    dst = rng.integers(0, n, src.size)
    delay = rng.integers(1, D + 1, src.size)
    w = rng.dirichlet(np.ones(S), n).ravel()
    start = np.zeros(n)
    start[:10] = 0.1
    chain = DelayChain(src=src, dst=dst, delay=delay, weight=w,
                       reward=sp.identity(n, format="csr"), start=start)
    cols = rng.integers(0, n, (n, 4))
    W = sp.csr_matrix((rng.dirichlet(np.ones(4), n).ravel(), (np.repeat(np.arange(n), 4),
                                                               cols.ravel())), shape=(n, n))
    ts = TimeShared(chain)
    WT = ts.turn(W)
    hist = np.zeros((ts.D, n), dtype=np.float32)
    hist[0] = rng.dirichlet(np.ones(n))
    runs = [ts.advance(WT, hist, steps, threads=k) for k in (1, 2, 3)]
    assert len(ts._split(WT, 3)) == 3 and len(ts._split(ts.Hc, 3)) == 3
    assert 0.8 * n < ts.live.size < 0.9 * n
    for end, dep in runs[1:]:
        assert np.array_equal(end, runs[0][0]) and np.array_equal(dep, runs[0][1])
    # plain recursion: x_t = Σ_f w_f v_{t−d_f}[src_f] e_{dst_f}, v_t = Wᵀ x_t
    past = [hist[j].astype(float) for j in range(ts.D)]          # v_{t−1}, v_{t−2}, …
    total = np.zeros(n)
    for _ in range(steps):
        x = np.zeros(n)
        for d in range(1, ts.D + 1):
            f = delay == d
            np.add.at(x, dst[f], w[f] * past[d - 1][src[f]])
        v = W.T @ x
        past = [v, *past[:-1]]
        total += v
    np.testing.assert_allclose(runs[0][1], total, rtol=1e-4, atol=1e-9)
    np.testing.assert_allclose(runs[0][0], np.array(past), rtol=1e-4, atol=1e-9)


def test_bad_input_is_refused_in_one_sentence():
    chain = DelayChain.stepwise(sp.identity(2, format="csr"), [0.5, 0.5])
    W = sp.identity(2, format="csr")
    with pytest.raises(envs.UserError, match="epoch"):
        timeshared(chain, [W], [1.0], 0)
    with pytest.raises(envs.UserError, match="one α per angle"):
        timeshared(chain, [W, W], [1.0], 10)
    with pytest.raises(envs.UserError, match="non-negative"):
        timeshared(chain, [W, W], [1.0, -0.5], 10)
    with pytest.raises(ValueError, match="at least one step"):
        DelayChain(src=np.arange(2), dst=np.arange(2), delay=np.zeros(2, int),
                   weight=np.ones(2), reward=sp.identity(2, format="csr"), start=np.ones(2) / 2)


@pytest.mark.parametrize("model", ["step", "sampled", "event"])
def test_one_angle_is_that_angles_limit(model):
    """α = (1,): the epochs change nothing, so the recursion converges to the model's q."""
    cs = CellSpace(envs.load("lab", orientations=24))
    q = model_for(cs, model).analyse(75, TurnNoise(15, 0.8)).q
    ts = timeshared_coverage(model_for(cs, model), PolicyMix([75], [1.0], 15, 0.8), epoch=200,
                             tol=1e-6)
    assert ts.converged
    assert tv_distance(ts.q, q) < 1e-4


def test_a_bodys_own_turns_reach_the_time_shared_prediction():
    """``noise=`` with a body's turn offset (§11b): one angle's time-shared q is that angle's
    limit under the same noise, not under the mix's plain ε and r (validate's mix
    prediction for a MuJoCo body takes its declared turns this way).
    """
    cs = CellSpace(envs.load("lab", orientations=72))
    model = model_for(cs, "event")
    body = TurnNoise(5, 0.8).with_body("gauss:0.5,offset=-3")
    mix = PolicyMix([75], [1.0], 5, 0.8)
    q_body = model.analyse(75, body).q
    ts = timeshared_coverage(model, mix, epoch=200, tol=1e-6, noise=body)
    plain = timeshared_coverage(model, mix, epoch=200, tol=1e-6)
    assert tv_distance(ts.q, q_body) < 1e-4
    assert tv_distance(plain.q, q_body) > 0.01     # the offset matters here
    # a Gaussian mix's own σ: the event model's continuous-heading flights (§11a)
    gauss = PolicyMix([75], [1.0], 0, 1, 3.0)
    ts = timeshared_coverage(model, gauss, epoch=200, tol=1e-6)
    assert tv_distance(ts.q, model.analyse(75, gauss.noise).q) < 1e-4


@pytest.mark.parametrize("model", ["step", "event"])
def test_long_epochs_tend_to_the_sum_rule(model):
    """E ≫ mixing time: docs/model.md §16's Σ α_i q_i; E = 1 differs from it."""
    cs = CellSpace(envs.load("lab", orientations=24))
    res = design_mix(model_for(cs, model), (30, 75, 315), TurnNoise(15, 0.8))
    alpha = [0.3, 0.3, 0.4]
    q_sum = np.column_stack([a.q for a in res.per_angle]) @ alpha
    mix = PolicyMix((30, 75, 315), alpha, 15, 0.8)
    long = timeshared_coverage(model_for(cs, model), mix, epoch=20000)
    short = timeshared_coverage(model_for(cs, model), mix, epoch=1)
    assert tv_distance(long.q, q_sum) < 0.005
    assert tv_distance(short.q, q_sum) > 2 * tv_distance(long.q, q_sum)


def test_fig1_mix_matches_the_twin_where_the_sum_rule_fails():
    """fig1, Table I setting at K = 72, the event model's α (≈ 0.76 at 75°, 0.24 at 315°)
    run in 1000-step epochs. At 315° the robot leaks into a pocket at about 1e-4 per step, so
    Σ α_i q_i (which puts the whole 315° share in the pocket) is ≈ 0.17 from the twin; the
    time-shared prediction is within 0.05. Statistical bound: two twin seeds of 200 robots
    × 5000 steps after a 20 000-step burn-in differ by the noise floor (0.016 for seeds 1
    and 2, which many robots sharing few epochs make large), and we require the pooled
    time-shared TV below 0.02 + 1.5 floors.
    """
    from bouncesim.robots.kinematic import KinematicBatch
    from bouncesim.robots.noise import noise_for_mix

    cs = CellSpace(envs.load("fig1", orientations=72))
    angles = (30.0, 75.0, 315.0)
    res = design_mix(model_for(cs, "event"), angles, TurnNoise(5, 0.8))
    ts = timeshared_coverage(model_for(cs, "event"), res.mix, epoch=1000)
    mix = res.mix
    hist = [KinematicBatch(cs.env, 200, np.random.default_rng(seed), cells=cs).run(
        mix, 5000, epoch=1000, noise=noise_for_mix(mix, cs.delta_deg), burn_in=20000)
        for seed in (1, 2)]
    floor = tv_distance(hist[0].counts, hist[1].counts)
    pooled = hist[0].counts + hist[1].counts
    assert floor < 0.05
    assert tv_distance(ts.q, pooled) <= 0.02 + 1.5 * floor
    assert tv_distance(res.mixed_q(), pooled) > 0.12
    # the dropped share of steps is predicted too (steps counted in no free cell)
    dropped = sum(h.dropped for h in hist) / sum(h.dropped + h.counts.sum() for h in hist)
    assert abs((1 - ts.counted_fraction) - dropped) < 0.01
