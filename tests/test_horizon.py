"""Coverage over a horizon and the time to the limit (docs/model.md §20).

Independent evidence: dense matrix powers of the step model's chain (and a dense epoch
recursion for mixes), hand-counted first steps, the kinematic twin's Monte-Carlo histograms
(within their seed-to-seed noise floor) and the limit of §11 / §17.
"""

from __future__ import annotations

import csv
import json
import os

import numpy as np
import pytest

import envs
from bouncesim.robots.kinematic import KinematicBatch
from bouncesim.robots.noise import GaussianNoise, SteppedNoise
from envs import UserError
from experiments.coverage_horizon import two_room
from planners.cells import CellSpace
from planners.coverage import (
    Horizon,
    TurnNoise,
    design_mix,
    model_for,
    steps_to_limit,
    steps_to_limit_each,
)
from planners.coverage.horizon import KEPT_RUNS
from planners.coverage.step import transition_matrix
from planners.metrics import tv_distance

from .conftest import random_room

NOISE8 = TurnNoise(45, 0.8)


def _dense_horizon(cs, Ws, alpha, epoch, T, p0):
    """(1/T) Σ_{t<T} p_t per cell for a mix run in epochs: dense, branch per epoch."""
    Ws = [W.toarray() for W in Ws]
    p, counts = p0.copy(), np.zeros(cs.N)
    t = 0
    while t < T:
        L = min(epoch, T - t)
        ends = []
        for W, a in zip(Ws, alpha):
            x = p.copy()
            for _ in range(L):
                counts += a * x
                x = x @ W
            ends.append(a * x)
        p, t = sum(ends), t + L
    q = counts.reshape(cs.K, cs.P).sum(axis=0)
    return q / q.sum()


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_step_model_is_the_chain_averaged_over_the_first_T_steps(seed):
    rng = np.random.default_rng(seed)
    cs = CellSpace(random_room(rng, K=8))
    hz = Horizon(model_for(cs, "step"))
    angle = float(rng.choice([90, 135, 225]))
    W = transition_matrix(cs, angle, NOISE8)
    z = int(rng.integers(cs.N))
    for T in (1, 2, 7, 60):
        for start, p0 in ((None, np.full(cs.N, 1 / cs.N)), (z, np.eye(cs.N)[z])):
            got = hz.coverage([angle], T, noise=NOISE8, start=start).q
            want = _dense_horizon(cs, [W], [1.0], T, T, p0)
            np.testing.assert_allclose(got, want, atol=2e-6)


def test_mix_in_epochs_matches_a_dense_epoch_recursion():
    cs = CellSpace(envs.load("lab"))
    hz = Horizon(model_for(cs, "step"))
    angles, alpha = (90.0, 135.0), np.array([0.3, 0.7])
    Ws = [transition_matrix(cs, a, NOISE8) for a in angles]
    p0 = np.full(cs.N, 1 / cs.N)
    for epoch, T in ((1, 9), (3, 10), (7, 50)):
        got = hz.coverage(angles, T, noise=NOISE8, alpha=alpha, epoch=epoch).q
        np.testing.assert_allclose(got, _dense_horizon(cs, Ws, alpha, epoch, T, p0),
                                   atol=2e-6)


def test_first_step_is_counted_where_the_robot_starts():
    # from a cell centre the first step is forward (counted in the start cell) or a bump at
    # a wall of that cell (counted there too): q_1 is the start cell, for every model
    cs = CellSpace(envs.load("lab", orientations=16))
    for name in ("step", "event"):
        hz = Horizon(model_for(cs, name))
        for z in (0, 5, cs.N - 1):
            q = hz.coverage([90], 1, noise=TurnNoise(22.5, 0.8), start=z).q
            assert q[z % cs.P] == pytest.approx(1.0, abs=1e-6)


def test_corridor_event_horizon_by_hand():
    # docs/model.md §17's corridor (K = 4, φ = 90°) from the east-facing centre of the west
    # cell: steps 0, 1 forward (cells 0, 1), bump step 2 in cell 2, then north: a 0.06 m
    # flight, one bump step in cell 2 (step 3), west: two forward steps (cells 2, 1) and the
    # bump in cell 0 (steps 4-6). First 5 steps: cells 0, 1, 2, 2, 2.
    env = envs.Environment.from_dict({
        "boundary": [[0, 0], [1.1, 0], [1.1, 0.4], [0, 0.4]], "robot_radius": 0.17,
        "discretization": {"cell_size": 0.34, "orientations": 4}})
    cs = CellSpace(env)
    hz = Horizon(model_for(cs, "event", {"bin_length": 0.01}))
    z = 0 * cs.P + 0
    np.testing.assert_allclose(hz.coverage([90], 5, start=z).q, [0.2, 0.2, 0.6], atol=1e-6)
    np.testing.assert_allclose(hz.coverage([90], 7, start=z).q, [2 / 7, 2 / 7, 3 / 7],
                               atol=1e-6)


def test_long_horizon_reproduces_the_limit():
    cs = CellSpace(envs.load("lab", orientations=16))
    noise = TurnNoise(22.5, 0.8)
    for name in ("step", "event"):
        model = model_for(cs, name)
        lim = model.analyse(135, noise).q
        hz = Horizon(model)
        tv = {T: tv_distance(c, lim) for T, c, _ in hz.run([135], [500, 5000], noise=noise)}
        assert tv[5000] < 0.01 and tv[5000] < tv[500]


def _twin(env, cs, angle, T, robots, noise, seed):
    batch = KinematicBatch(env, robots, np.random.default_rng(seed), cells=cs)
    twin_noise = GaussianNoise(noise.sigma_deg) if noise.gaussian else SteppedNoise(
        noise.eps_deg, noise.r, cs.delta_deg)
    return batch.run(angle, T, noise=twin_noise).counts


def _check_twin(env, angle, noise, horizons):
    cs = CellSpace(env)
    hz = Horizon(model_for(cs, "event"))
    for T, robots in horizons:
        q = hz.coverage([angle], T, noise=noise).q
        h0, h1 = (_twin(env, cs, angle, T, robots, noise, s) for s in (1, 2))
        floor = tv_distance(h0, h1)
        tv = tv_distance(q, h0 + h1)
        # the goal (TV 0.05) plus the pooled sample's own noise (≈ floor/√2)
        assert tv < 0.05 + floor, (env.name, T, tv, floor)


@pytest.mark.parametrize("seed", [3])
def test_event_horizon_matches_the_twin_on_random_rooms(seed):
    rng = np.random.default_rng(seed)
    env = random_room(rng, K=36)
    _check_twin(env, 130.0, TurnNoise(10, 0.8), [(100, 600), (2000, 60)])


def test_event_horizon_with_gaussian_noise_matches_the_twin():
    # docs/model.md §11a: with gauss:σ the event model's flights leave at sub-bin headings and
    # the horizon must count those flights, not the grid headings' (on this room the grid
    # flights under Gaussian turns are off by TV 0.15 at T = 1000, the twin's floor 0.04)
    env = random_room(np.random.default_rng(4), K=72)
    _check_twin(env, 130.0, TurnNoise.gauss(5), [(100, 1000), (1000, 200)])


@pytest.mark.slow
def test_event_horizon_matches_the_twin_on_two_rooms_with_a_robot_wide_door():
    _check_twin(two_room(0.34, 72), 30.0, TurnNoise(5, 0.8), [(100, 600), (2000, 80)])


@pytest.mark.slow
@pytest.mark.skipif(os.environ.get("BOUNCESIM_LONG_TESTS") != "1",
                    reason="minutes of CPU (10 ms per step at K = 72); BOUNCESIM_LONG_TESTS=1")
def test_event_horizon_matches_the_twin_at_20000_steps():
    _check_twin(two_room(0.34, 72), 75.0, TurnNoise(5, 0.8), [(20_000, 12)])


def test_steps_to_limit_shrinks_as_the_door_widens():
    noise = TurnNoise(22.5, 0.8)
    got = []
    for door in (0.34, 0.68, 1.02):
        model = model_for(CellSpace(two_room(door, 16)), "step")
        lim = model.analyse(135, noise).q
        res = steps_to_limit(Horizon(model), [135], lim, noise=noise, cap=200_000)
        assert res["steps"] is not None and res["tv"] <= 0.05
        got.append(res["steps"])
    assert got[0] > got[1] > got[2]


def test_one_pass_for_the_angles_and_their_mix_gives_each_policy_its_own_answer():
    # steps_to_limit_each reads the mix (each run keeps one angle) off the angles' runs and
    # drops runs once they are done: every policy gets what its own pass gives, to the bit
    # (here two angles reach their limits at different T, one and the mix reach the cap)
    noise = TurnNoise(22.5, 0.8)
    model = model_for(CellSpace(two_room(0.34, 16)), "step")
    angles, alpha = (157.5, 112.5, 67.5), np.array([0.2, 0.3, 0.5])
    lims = [model.analyse(a, noise).q for a in angles]
    mix_lim = np.column_stack(lims) @ alpha
    hz = Horizon(model)
    each, mix = steps_to_limit_each(hz, angles, lims, noise=noise, alpha=alpha,
                                    mix_limit=mix_lim, cap=5000)
    refs = [steps_to_limit(Horizon(model), [a], lim, noise=noise, cap=5000)
            for a, lim in zip(angles, lims)]
    refs.append(steps_to_limit(Horizon(model), angles, mix_lim, noise=noise, alpha=alpha,
                               cap=5000))
    key = ("steps", "tv", "last")
    assert [[r[k] for k in key] for r in [*each, mix]] == [[r[k] for k in key] for r in refs]
    assert len({r["steps"] for r in refs}) == 3 and refs[-1]["steps"] is None


def test_kept_runs_answer_as_a_fresh_run_whatever_was_asked_before():
    # a Horizon keeps each angle's run at its last grid point and resumes it (the α fit at T,
    # then steps_to_limit): every answer equals a fresh Horizon's, to the bit, in any order
    # of questions (on the grid, off it, behind the kept point, a mix of kept runs)
    noise = TurnNoise(22.5, 0.8)
    model = model_for(CellSpace(random_room(np.random.default_rng(5), K=16)), "event")
    kept = Horizon(model)
    asks = [([45.0], 150), ([45.0], 2000), ([45.0], 130), ([45.0], 1000), ([112.5], 700),
            ([45.0, 112.5], 900)]
    for angles, T in asks:
        alpha = None if len(angles) == 1 else [0.3, 0.7]
        got = kept.coverage(angles, T, noise=noise, alpha=alpha).q
        ref = Horizon(model).coverage(angles, T, noise=noise, alpha=alpha).q
        assert np.array_equal(got, ref), (angles, T)
    # past KEPT_RUNS (angle, start) runs the oldest is forgotten, and asked again is fresh
    for z in range(KEPT_RUNS + 1):
        kept.coverage([45.0], 300, noise=noise, start=z)
    assert len(kept._runs) == KEPT_RUNS
    assert np.array_equal(kept.coverage([45.0], 2000, noise=noise).q,
                          Horizon(model).coverage([45.0], 2000, noise=noise).q)
    lim = model.analyse(45, noise).q
    assert (steps_to_limit(kept, [45.0], lim, noise=noise, cap=5000)
            | {"seconds": 0}) == (steps_to_limit(Horizon(model), [45.0], lim, noise=noise,
                                                 cap=5000) | {"seconds": 0})


def test_steps_to_limit_reports_the_cap_honestly():
    noise = TurnNoise(22.5, 0.8)
    model = model_for(CellSpace(two_room(0.34, 16)), "step")
    lim = model.analyse(135, noise).q
    res = steps_to_limit(Horizon(model), [135], lim, noise=noise, cap=1000)
    assert res["steps"] is None and res["tv"] > 0.05 and res["last"] <= 1000


def test_alpha_for_a_horizon():
    cs = CellSpace(envs.load("lab"))
    model = model_for(cs, "step")
    angles = (90, 135)
    lin = design_mix(model, angles, NOISE8, horizon=200)
    # each run keeps one angle: the fit is linear in the angles' q_T columns
    np.testing.assert_allclose(lin.mixed, lin.columns @ lin.alpha, atol=1e-12)
    assert lin.horizon == 200 and lin.convergence is None
    ep = design_mix(model, angles, NOISE8, horizon=200, epoch=20)
    hz = Horizon(model)
    executed = hz.coverage(angles, 200, noise=NOISE8, alpha=ep.alpha, epoch=20).q
    np.testing.assert_allclose(ep.mixed, executed, atol=1e-9)
    conv = ep.convergence
    assert ep.method == "slsqp-horizon"
    assert conv["objective"] <= conv["linear_objective"] + 1e-12
    assert conv["projected_gradient_norm"] < 1e-3


def test_horizon_runs_beside_the_analyses_give_what_one_by_one_gives(monkeypatch):
    # design_mix with a horizon runs the angles' horizon runs on the analyses' threads (one
    # row block each): the same limits, q_T columns and α as analysing and running the
    # angles one after the other on a fresh Horizon, for the event model (start states and
    # delays) and the step model
    import planners.coverage.api as api
    from planners.coverage.horizon import fit_horizon_mix

    monkeypatch.setattr(api, "default_threads", lambda: 2)
    cs = CellSpace(envs.load("lab", orientations=16))
    angles, noise = (45, 112.5, 315), TurnNoise(22.5, 0.8)
    for name in ("event", "step"):
        model = model_for(cs, name)
        got = design_mix(model, angles, noise, horizon=300)
        per = tuple(model.analyse(a, noise) for a in angles)
        ref = fit_horizon_mix(Horizon(model), angles, noise, got.target, 300, None, per)
        for g, r in zip(got.per_angle, per):
            assert np.array_equal(g.q, r.q), (name, g.angle)
        assert np.array_equal(got.columns, ref.columns), name
        assert np.array_equal(got.alpha, ref.alpha), name


def test_two_sealed_rooms_share_the_steps_as_the_start_does():
    # two rooms with no door: a robot never changes room, so at every T the left room's
    # share of the steps is its share of the start configurations, P_left / P (by hand); the
    # limit q says the same, for every model
    env = envs.Environment.from_dict({
        "boundary": [[0, 0], [2.72, 0], [2.72, 1.02], [0, 1.02]],
        "obstacles": [[[1.02, 0], [1.36, 0], [1.36, 1.02], [1.02, 1.02]]],
        "robot_radius": 0.17, "discretization": {"cell_size": 0.34, "orientations": 8}})
    cs = CellSpace(env)
    left = cs.centres[:, 0] < 1.02
    share = left.sum() / cs.P
    for name in ("step", "event"):
        model = model_for(cs, name)
        for _, counts, _ in Horizon(model).run([135], [1, 10, 300], noise=NOISE8):
            assert counts[left].sum() / counts.sum() == pytest.approx(share, abs=1e-5)
        # the limit q is the per-step limit (docs/model.md §17, §20): the rooms' flights
        # differ in length, so weighting classes by their flights would miss the share
        lim = model.analyse(135, NOISE8).q
        assert lim[left].sum() == pytest.approx(share, abs=1e-6)


def test_cli_horizon_writes_q_T_and_steps_to_limit(tmp_path, capsys):
    from bouncesim.cli import main
    out = tmp_path / "o"
    rc = main(["coverage", "lab", "--angles", "90,135", "--eps", "45", "--r", "0.8",
               "--horizon", "50", "--start", "8", "--limit-cap", "5000", "--out", str(out),
               "--no-plots", "--json"])
    assert rc == 0
    summary = json.loads(capsys.readouterr().out)
    hz = summary["horizon"]
    assert hz["T"] == 50 and hz["start"] == 8 and len(hz["per_angle"]) == 2
    cs = CellSpace(envs.load("lab"))
    want = Horizon(model_for(cs, "step")).coverage([90], 50, noise=NOISE8, start=8).q
    rows = [r for r in csv.DictReader(open(out / "coverage.csv")) if r["angle"] == "90"]
    np.testing.assert_allclose([float(r["q"]) for r in rows], want, atol=1e-12)
    for r in hz["per_angle"]:
        assert r["steps"] is None or r["tv"] <= 0.05


def test_cli_horizon_with_epochs_reports_each_angle_as_its_own_pass(capsys):
    # with --epoch the mix gets its own pass; the angles still share one, and each angle's
    # steps_to_limit is what steps_to_limit gives it alone
    from bouncesim.cli import main
    rc = main(["coverage", "lab", "--angles", "90,135", "--eps", "45", "--r", "0.8",
               "--horizon", "50", "--epoch", "10", "--limit-cap", "2000", "--json"])
    assert rc == 0
    hz = json.loads(capsys.readouterr().out)["horizon"]
    model = model_for(CellSpace(envs.load("lab")), "step")
    for r in hz["per_angle"]:
        lim = model.analyse(r["angle"], NOISE8).q
        ref = steps_to_limit(Horizon(model), [r["angle"]], lim, noise=NOISE8, cap=2000)
        assert (r["steps"], r["tv"], r["last"]) == (ref["steps"], ref["tv"], ref["last"])
    assert hz["epoch"] == 10 and (hz["mix"]["steps"] is None or hz["mix"]["tv"] <= 0.05)


def test_a_settled_run_counts_the_rest_at_its_limit():
    # with the limit given, a run stops stepping once two segments in a row spent their
    # steps alike (TV 1e-6) and near the limit (1e-4); the rest counts at the limit: the
    # same q_T as stepping all the way (to 1e-4), and horizons far beyond what can be
    # stepped are the limit's
    from planners.coverage.horizon import SETTLED_LIMIT, STEP_CAP
    model = model_for(CellSpace(envs.load("lab")), "step")
    lim = model.analyse(135, NOISE8).q
    T = 300_000
    stepped = Horizon(model).coverage([135], T, noise=NOISE8).q
    hz = Horizon(model)
    settled = hz.coverage([135], T, noise=NOISE8, limits=[lim]).q
    run = next(iter(hz._runs.values()))
    assert run.t < T // 10                          # it stopped stepping early
    assert tv_distance(settled, stepped) <= SETTLED_LIMIT
    far = hz.coverage([135], 10 ** 12, noise=NOISE8, limits=[lim]).q
    assert tv_distance(far, lim) <= 1e-7 and 10 ** 12 > STEP_CAP
    # no limit: a horizon beyond the steps the recursion runs is one sentence
    with pytest.raises(UserError, match="more than the"):
        Horizon(model).coverage([135], 10 ** 12, noise=NOISE8)


def test_a_horizon_the_run_cannot_settle_for_is_refused_early(monkeypatch):
    # two rooms joined by a door one cell wide at 135°: the run's slow mode (relaxation about
    # 7300 steps) settles near the limit after about 6·10^4 steps, so a horizon of
    # 1e12 is computed; with the recursion capped at 2·10^4 steps it is refused early, from
    # the slow mode, after a few thousand steps rather than at the cap
    import planners.coverage.horizon as horizon
    noise = TurnNoise(22.5, 0.8)
    model = model_for(CellSpace(two_room(0.34, 16)), "step")
    lim = model.analyse(135, noise).q
    hz = Horizon(model)
    assert tv_distance(hz.coverage([135], 10 ** 12, noise=noise, limits=[lim]).q, lim) <= 1e-7
    assert 20_000 < next(iter(hz._runs.values())).t < horizon.STEP_CAP
    monkeypatch.setattr(horizon, "STEP_CAP", 20_000)
    hz = Horizon(model)
    with pytest.raises(UserError, match="settles at its limit only after about"):
        hz.coverage([135], 10 ** 12, noise=noise, limits=[lim])
    assert next(iter(hz._runs.values())).t < 10_000


def test_cli_horizon_far_beyond_the_recursion_is_the_limit(capsys):
    from bouncesim.cli import main
    rc = main(["coverage", "lab", "--angles", "90,135", "--eps", "45", "--r", "0.8",
               "--horizon", str(10 ** 12), "--json"])
    assert rc == 0
    hz = json.loads(capsys.readouterr().out)["horizon"]
    assert all(r["tv_to_limit"] <= 1e-6 for r in [*hz["per_angle"], hz["mix"]])
