"""Gaussian turn noise (docs/model.md §11a), the event model's large-class solvers (§17) and
passages exactly one robot wide (§10), each against independent evidence.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import scipy.sparse as sp

import envs
from envs import Environment, UserError
from envs.generated import office
from planners.cells import CellSpace
from planners.coverage import TurnNoise, model_for
from planners.coverage.event import EventSettings
from planners.coverage.markov import closed_classes, stationary_distributions
from planners.coverage.stationary import _aggregated_stationary
from planners.metrics import tv_distance


def _phi(x: float) -> float:
    return 0.5 * (1.0 + math.erf(x / math.sqrt(2.0)))


def test_discretised_gaussian_by_hand():
    # σ = Δ = 1°: p_j = Φ(j + ½) − Φ(j − ½); the tails beyond ±5.5σ hold 3.8e-8 < 1e-6
    # and beyond ±4.5σ 6.8e-6 > 1e-6, so M = 5
    d, p = TurnNoise.gauss(1.0).support(360)
    assert d.tolist() == list(range(-5, 6))
    hand = np.array([_phi(j + 0.5) - _phi(j - 0.5) for j in range(-5, 6)])
    assert np.allclose(p, hand / hand.sum(), atol=1e-12)
    assert abs(p[5] - (2 * _phi(0.5) - 1)) < 1e-7         # 0.3829
    # a 90° bump at K = 360: steps 85 … 95 with the same probabilities
    steps, probs = TurnNoise.gauss(1.0).turns(360, 90)
    assert steps.tolist() == list(range(85, 96)) and np.allclose(probs, p)


def test_wide_gaussian_wraps_the_circle():
    # σ = 400° at K = 4: nearly uniform over the 4 headings once wrapped
    steps, probs = TurnNoise.gauss(400.0).turns(4, 90)
    per = np.bincount(steps, weights=probs, minlength=4)
    assert abs(per.sum() - 1) < 1e-12 and np.allclose(per, 0.25, atol=0.01)


def test_gauss_sampling_and_spec():
    rng = np.random.default_rng(3)
    x = TurnNoise.gauss(3.0).sample(rng, 90.0, 40000, delta_deg=1.0)
    assert abs(x.mean() - 90.0) < 4 * 3.0 / math.sqrt(x.size)
    assert abs(x.std() - 3.0) < 0.05                           # ~5 standard errors
    assert TurnNoise.from_spec("gauss:3") == TurnNoise.gauss(3)
    assert TurnNoise.from_spec("model:eps=5,r=0.8") == TurnNoise(5, 0.8)
    assert TurnNoise.gauss(0).exact and not TurnNoise.gauss(2).exact
    for bad in ("gauss:x", "gauss:-1", "uniform:3"):
        with pytest.raises(UserError):
            TurnNoise.from_spec(bad)
    with pytest.raises(UserError):
        TurnNoise(5, 0.8, sigma_deg=2)


def test_aggregation_solver_matches_direct_solve():
    # two random 'rooms' of 1500 states joined by 3 rare edges (probability 1e-4): a slowly
    # mixing class; aggregates of 10 states never straddle the rooms
    rng = np.random.default_rng(0)
    n, half = 3000, 1500
    rows = np.repeat(np.arange(n), 6)
    room = rows // half
    cols = rng.integers(0, half, rows.size) + room * half
    T = sp.csr_matrix((rng.random(rows.size), (rows, cols)), shape=(n, n)).tolil()
    for i, j in ((3, 2000), (40, 1700), (2500, 7)):
        T[i, j] = 1e-4 * T[i].sum()
    T = sp.csr_matrix(T)
    T = sp.csr_matrix(sp.diags(1.0 / np.asarray(T.sum(axis=1)).ravel()) @ T)
    direct = stationary_distributions(T, [np.arange(n)])
    pi, cycles = _aggregated_stationary(T, np.arange(n) // 10)
    assert np.abs(pi - direct).sum() < 1e-5
    assert np.abs(pi @ T - pi).sum() < 1e-7


def _wedge_room(K: int) -> Environment:
    """A 1.36 m × 1.02 m room with a triangle on its floor (a wall at 60.5°): not
    rectilinear; every gap is wider than the robot.
    """
    return Environment.from_dict({
        "name": "wedge", "boundary": [[0, 0], [1.36, 0], [1.36, 1.02], [0, 1.02]],
        "obstacles": [[[0.51, 0.0], [0.85, 0.0], [0.85, 0.6]]], "robot_radius": 0.17,
        "discretization": {"cell_size": 0.34, "orientations": K}})


@pytest.mark.slow
def test_gauss_event_model_matches_twin():
    from bouncesim.robots.kinematic import KinematicBatch
    from bouncesim.robots.noise import GaussianNoise
    cs = CellSpace(_wedge_room(180))                           # Δ = 2°: σ = 3° spans bins
    model = model_for(cs, "event", EventSettings(bin_length=0.03))
    q = model.analyse(76, TurnNoise.gauss(3.0)).q

    def twin(seed):
        return KinematicBatch(cs.env, 200, np.random.default_rng(seed), cells=cs).run(
            76.0, 1000, noise=GaussianNoise(3.0), burn_in=50).counts
    h0, h1 = twin(0), twin(1)
    floor = tv_distance(h0, h1)
    assert floor < 0.02                                        # the budget resolves 0.05
    assert tv_distance(q, h0) < 0.05
    # the grid noise of the same variance is a different prediction on this map (§11a)
    qg = model.analyse(76, TurnNoise(6, 0.8)).q
    assert tv_distance(qg, q) > tv_distance(q, h0)


@pytest.mark.slow
def test_knife_edge_door_same_rule_in_twin_and_event_model():
    # the office's door (x = 2.04–2.38 m) is exactly 2r wide; its axis y = 1.19 m is also the
    # contact line of the east pillar's top (docs/model.md §10)
    from bouncesim.robots.kinematic import KinematicBatch
    cs = CellSpace(office(door=0.34, orientations=72))
    # twin: from the pillar top, exactly on the axis heading west, the robot drives through
    # the door; 0.1 mm off the axis, or 0.25° off the heading, it meets a jamb and stays east
    batch = KinematicBatch(cs.env, 3, np.random.default_rng(0), cells=cs)
    batch.pos = np.array([[3.23, 1.19 + 1e-9], [3.23, 1.1901], [3.23, 1.19 + 1e-9]])
    batch.heading = np.array([180.0, 180.0, 180.25])
    batch.run(90.0, 6)
    assert batch.pos[0, 0] < 2.04 and np.all(batch.pos[1:, 0] > 2.04)
    # event model, grid headings: the flights that cross the door start in bins of the
    # pillar top (bin centres within a bin length, 0.03 m, of the axis: a corner bin's
    # centre lies on its rounded corner) heading exactly west (k = 36 at K = 72)
    model = model_for(cs, "event")
    bd = model.boundary
    src, dst, _, _ = model.flights
    cross = bd.part_of_bin[src // cs.K] != bd.part_of_bin[dst // cs.K]
    assert model.knife_edge_flights == cross.sum() > 0
    y = bd.points(src[cross] // cs.K, np.full(cross.sum(), 0.5))[:, 1]
    assert np.all(np.abs(y - 1.19) < 0.03) and np.all(src[cross] % cs.K == 36)
    # Gaussian noise: no flight heading is exactly on the axis, the door is closed
    model._flight_set(True)
    assert model.knife_edge_flights == 0
    # the step model (§4's tolerant free test) passes the door: east from the cell west of it
    at = np.abs(cs.centres[:, 1] - 1.19) < 1e-9
    i_door = int(np.flatnonzero(at & (np.abs(cs.centres[:, 0] - 2.21) < 1e-9))[0])
    i_w = int(np.flatnonzero(at & (np.abs(cs.centres[:, 0] - 1.87) < 1e-9))[0])
    assert cs.forward[0 * cs.P + i_w] == i_door


def test_cli_coverage_accepts_gauss_noise(capsys):
    from bouncesim.cli import main
    rc = main(["coverage", "lab", "--orientations", "72", "--angles", "90,135",
               "--noise", "gauss:5", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert rc == 0 and out["noise"] == "gauss:5"
    assert abs(sum(out["alpha"]) - 1) < 1e-9
    assert main(["coverage", "lab", "--angles", "90", "--noise", "gauss:5", "--eps", "45",
                 "--r", "0.8"]) == 2


def test_aggregation_survives_states_of_vanishing_mass():
    # lab at K = 72, 315°, ε = 5°, r = 0.8: a 9008-state class where some contact bins carry
    # a vanishing share of π. Their masses underflowed to 0 over the cycles, the coarse chain
    # lost edges and its solve was singular ("the event model counts no step in a free cell").
    # The aggregation solver must agree with the direct solve.
    cs = CellSpace(envs.load("lab", orientations=72))
    model = model_for(cs, "event")
    T, mu = model.chain(315, TurnNoise(5, 0.8))
    groups = closed_classes(T)[1]
    g = max(groups, key=len)
    assert len(g) > 2000
    Tg = T[g][:, g]
    x, cycles = _aggregated_stationary(Tg, (np.arange(model.n_states) // cs.K)[g])
    ref = stationary_distributions(Tg, [np.arange(len(g))])     # direct sparse solve
    assert np.isfinite(x).all() and cycles < 20000
    assert np.abs(x - ref).sum() < 1e-5



def _rooms_chain(rng, n: int, rooms: int) -> sp.csr_matrix:
    """A random stochastic chain on ``rooms`` equal rooms of states, 6 edges per state, the
    rooms joined by three edges of probability 1e-4 (one room: it mixes at once).
    """
    size = n // rooms
    rows = np.repeat(np.arange(n), 6)
    cols = rng.integers(0, size, rows.size) + (rows // size) * size
    T = sp.csr_matrix((rng.random(rows.size), (rows, cols)), shape=(n, n)).tolil()
    if rooms == 2:
        for i, j in ((3, size + 500), (40, size + 200), (n - 50, 7)):
            T[i, j] = 1e-4 * T[i].sum()
    T = sp.csr_matrix(T)
    return sp.csr_matrix(sp.diags(1.0 / np.asarray(T.sum(axis=1)).ravel()) @ T)


@pytest.mark.parametrize("rooms", [1, 2])
def test_large_classes_power_then_aggregation(rooms, monkeypatch):
    # a class above the direct-solve size (20 000 states; lowered to 2 000 here so that the
    # reference direct solve stays quick) gets the power iteration first; one
    # aggregation cycle confirms a fast-mixing class's answer, while two rooms joined by rare
    # edges (where the power iteration stops early, its change below tolerance long before
    # the mass between the rooms has settled) need more cycles; both agree with the direct
    # sparse solve (docs/model.md §17)
    from planners.coverage import stationary

    cycles = []
    real = stationary._aggregated_stationary

    def counted(*a, **k):
        x, c = real(*a, **k)
        cycles.append(c)
        return x, c

    monkeypatch.setattr(stationary, "_aggregated_stationary", counted)
    monkeypatch.setattr(stationary, "_DIRECT_MAX", 2000)
    n = 3000
    T = _rooms_chain(np.random.default_rng(1), n, rooms)
    res = stationary.analyse_contact_chain(T, np.full(n, 1.0 / n), np.arange(n) // 10,
                                      method="aggregation")
    direct = stationary_distributions(T, [np.arange(n)])
    assert (cycles == [1]) == (rooms == 1), cycles
    assert np.abs(res.stationary - direct).sum() < 1e-5


@pytest.mark.parametrize("kind", ["one room", "two rooms", "periodic"])
def test_krylov_then_aggregation_matches_direct_solve(kind, monkeypatch):
    # the default large-class solve (BiCGSTAB, then the aggregation's check; docs/model.md
    # §17) against the direct sparse solve: on a fast-mixing class and a pure cycle of
    # period 3000 (π uniform; the power iteration needs its damping there, the linear solve
    # does not) BiCGSTAB's answer is the fixed point (one aggregation cycle); on two rooms
    # joined by rare edges its residual is below 1e-7 while the mass between the rooms is
    # still off (the residual cannot see it), and the aggregation cycles move it
    from planners.coverage import stationary

    monkeypatch.setattr(stationary, "_DIRECT_MAX", 2000)
    used = {"power": 0, "cycles": []}
    real_agg = stationary._aggregated_stationary

    def power(*a, **k):
        used["power"] += 1
        return None, 0

    def agg(*a, **k):
        x, c = real_agg(*a, **k)
        used["cycles"].append(c)
        return x, c

    monkeypatch.setattr(stationary, "_power_stationary", power)
    monkeypatch.setattr(stationary, "_aggregated_stationary", agg)
    n = 3000
    if kind == "periodic":
        T = sp.csr_matrix((np.ones(n), (np.arange(n), (np.arange(n) + 1) % n)), shape=(n, n))
        direct = np.full(n, 1.0 / n)
    else:
        T = _rooms_chain(np.random.default_rng(1), n, 1 if kind == "one room" else 2)
        direct = stationary_distributions(T, [np.arange(n)])
    krylov, _ = stationary._krylov_stationary(T)
    assert krylov is not None and np.abs(T.T @ krylov - krylov).sum() < 1e-7
    res = stationary.analyse_contact_chain(T, np.full(n, 1.0 / n), np.arange(n) // 10)
    assert used["power"] == 0
    assert (used["cycles"] == [1]) == (kind != "two rooms"), used
    assert np.abs(res.stationary - direct).sum() < 1e-5
    if kind != "two rooms":
        assert np.abs(krylov - direct).sum() < 1e-6
    else:
        assert np.abs(krylov - direct).sum() > 1e-3          # what the check is for


def test_krylov_failure_falls_back_to_the_aggregation(monkeypatch):
    # a BiCGSTAB that stops unconverged (one iteration) hands the class to the power
    # iteration and aggregation path, which still gets π
    from planners.coverage import stationary

    monkeypatch.setattr(stationary, "_DIRECT_MAX", 2000)
    monkeypatch.setattr(stationary, "_KRYLOV_MAX", 1)
    n = 3000
    T = _rooms_chain(np.random.default_rng(2), n, 2)
    x, products = stationary._krylov_stationary(T)
    assert x is None and products <= 4
    res = stationary.analyse_contact_chain(T, np.full(n, 1.0 / n), np.arange(n) // 10)
    direct = stationary_distributions(T, [np.arange(n)])
    assert np.abs(res.stationary - direct).sum() < 1e-5


def test_a_bodys_own_turn_errors_on_the_grid_by_hand_and_by_sampling():
    """docs/model.md §11b: a body that adds N(μ, σ²) to every turn. By hand (no scatter of
    its own, Δ = 1°, μ = −1°, σ = 1°): offset −1 holds Φ(½) − Φ(−½) = 0.3829 and 0 holds
    Φ(1.5) − Φ(½) = 0.2417. On top of ε = 5°, r = 0.8 (the convolution): the support against
    the sampled turns of the same noise and of the simulated body (body_noise), binned to the
    grid, within 5 standard errors of 200 000 draws each.
    """
    from bouncesim.robots.noise import BodyErrors, body_noise
    d, p = TurnNoise().with_body("gauss:1,offset=-1").support(360)
    assert p[d == -1][0] == pytest.approx(0.382925, abs=1e-6)
    assert p[d == 0][0] == pytest.approx(0.241730, abs=1e-6)
    noise = TurnNoise(5, 0.8).with_body("gauss:0.6,offset=-1.26")
    assert noise.gaussian and not noise.exact and str(noise).endswith(
        "+ body gauss:0.6,offset=-1.26")
    d, p = noise.support(360)
    assert p.sum() == pytest.approx(1.0, abs=1e-12)
    body = body_noise(noise, 1.0)
    assert isinstance(body, BodyErrors)
    n = 200_000
    for draws in (noise.sample(np.random.default_rng(1), 0.0, n, delta_deg=1.0),
                  body.sample_many(np.random.default_rng(2), 0.0, n)):
        j = np.floor(draws + 0.5).astype(int)
        freq = np.array([(j == v).mean() for v in d])
        assert np.all(np.abs(freq - p) <= 5 * np.sqrt(p * (1 - p) / n) + 1e-4)
    with pytest.raises(UserError, match="gauss:S,offset=O"):
        TurnNoise().with_body("model:eps=5,r=0.8")
