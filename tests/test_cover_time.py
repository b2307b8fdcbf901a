"""Coverage-time metrics (docs/model.md §20a).

Independent evidence: cover times worked out by hand on the three-cell corridor, a brute-force
chain on (configuration, visited set) written here over the step model's own transition
matrix, the union of independent robots by direct enumeration, the sampled path against the
exact one within its standard error, and the kinematic twin's Monte-Carlo covered fraction.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

import bouncesim
import envs
from bouncesim.cli import main
from bouncesim.runs.cover import twin_cover
from envs import UserError
from envs.generated import random_rectilinear_room
from experiments.coverage_horizon import two_room
from planners.cells import CellSpace
from planners.coverage import TurnNoise, model_for
from planners.coverage.cover_time import coverage_metrics, metric_times, return_times, visited_by
from planners.coverage.step import transition_matrix
from planners.plan import PolicyMix

CORRIDOR = envs.Environment.from_dict({
    "boundary": [[0, 0], [1.1, 0], [1.1, 0.4], [0, 0.4]], "robot_radius": 0.17,
    "discretization": {"cell_size": 0.34, "orientations": 4}})
RING = envs.Environment.from_dict({          # 8 cells around a pillar
    "boundary": [[0, 0], [1.2, 0], [1.2, 1.2], [0, 1.2]],
    "obstacles": [[[0.4, 0.4], [0.8, 0.4], [0.8, 0.8], [0.4, 0.8]]],
    "robot_radius": 0.15, "discretization": {"cell_size": 0.4, "orientations": 4}})
LEVELS = ("0.5", "0.8", "0.9", "1.0")


def _brute(cs, angle, noise, T, start=None, K=1):
    """Pr(visited set = V after t steps) for t = 1 … T for a team of K, by enumeration:
    one robot's chain on (configuration, visited set) as a dict over the step model's
    transition matrix, then the K-fold union over all K-tuples of sets.
    """
    M = transition_matrix(cs, angle, noise).toarray()
    p0 = np.full(cs.N, 1 / cs.N) if start is None else np.eye(cs.N)[start]
    dist = {(z, 0): p for z, p in enumerate(p0) if p > 0}
    out = []
    for _ in range(T):
        seen, nxt = {}, {}
        for (z, V), p in dist.items():
            V |= 1 << (z % cs.P)
            seen[V] = seen.get(V, 0.0) + p
            for z2 in np.flatnonzero(M[z]):
                nxt[(z2, V)] = nxt.get((z2, V), 0.0) + p * M[z, z2]
        team = {0: 1.0}
        for _ in range(K):
            team2 = {}
            for U, pu in team.items():
                for V, pv in seen.items():
                    team2[U | V] = team2.get(U | V, 0.0) + pu * pv
            team = team2
        out.append(team)
        dist = nxt
    return out


def _brute_stats(sets, P, x):
    """(mean covered fraction per t, Pr(T_X ≤ t) per t) of the brute-force distributions."""
    k = math.ceil(x * P - 1e-9)
    mean = [sum(p * bin(V).count("1") for V, p in d.items()) / P for d in sets]
    cdf = [sum(p for V, p in d.items() if bin(V).count("1") >= k) for d in sets]
    return np.array(mean), np.array(cdf)


def test_corridor_cover_times_by_hand():
    # φ = 90° without noise: from cell 0 facing east (z = 0) the robot steps through cells
    # 0, 1, 2: T_1/3 = 1, T_2/3 = 2, T_1 = 3 (docs/model.md §16's circulation)
    model = model_for(CellSpace(CORRIDOR), "step")
    m, = coverage_metrics(model, 90, horizon=10, start=0, times=[1, 2, 3, 10])
    assert m.method == "exact"
    assert m.covered_mean.tolist() == pytest.approx([1 / 3, 2 / 3, 1, 1])
    assert m.T["0.5"]["mean"] == 2 and m.T["1.0"]["mean"] == 3 and m.T["1.0"]["median"] == 3
    assert m.T["1.0"]["not_reached"] == 0
    # from cell 2 facing north (z = 3·1 + 2 = 5): bump, turn west at step 0; steps 1, 2 in
    # cells 1 and 0 (hand-traced on the step table)
    m, = coverage_metrics(model, 90, horizon=10, start=5, times=[1, 2, 3])
    assert m.covered_mean.tolist() == pytest.approx([1 / 3, 1 / 3, 2 / 3])
    assert m.T["1.0"]["mean"] == 4


@pytest.mark.parametrize("env,angle,start", [(CORRIDOR, 90, None), (CORRIDOR, 180, 0),
                                             (RING, 90, None), (RING, 180, None)])
@pytest.mark.parametrize("K", [1, 2])
def test_exact_against_brute_force(env, angle, start, K):
    cs = CellSpace(env)
    noise = TurnNoise(90, 0.7)
    T = 12
    m, = coverage_metrics(model_for(cs, "step"), angle, noise, horizon=T, start=start,
                          robots=K, times=range(1, T + 1), exact=True)
    sets = _brute(cs, angle, noise, T, start, K)
    for x in LEVELS:
        mean, cdf = _brute_stats(sets, cs.P, float(x))
        assert m.covered_mean == pytest.approx(mean, abs=1e-12)
        assert m.T[x]["not_reached"] == pytest.approx(1 - cdf[-1], abs=1e-12)
        if cdf[-1] > 0:
            pmf = np.diff(np.concatenate([[0.0], cdf]))
            assert m.T[x]["mean"] == pytest.approx(pmf @ np.arange(1, T + 1) / cdf[-1])


@pytest.mark.parametrize("name,env", [("step", RING), ("event", CORRIDOR),
                                      ("sampled", CORRIDOR)])
def test_sampled_against_exact(name, env):
    model = model_for(CellSpace(env), name)
    noise = TurnNoise(90, 0.8)
    mix = PolicyMix((90.0, 180.0), (0.6, 0.4), 90, 0.8)
    times = [1, 2, 3, 5, 8, 13, 21, 30]
    for policy in (90.0, mix):
        kw = {"robots": [1, 3], "horizon": 30, "epoch": 4, "times": times, "runs": 20_000}
        if not isinstance(policy, PolicyMix):
            kw.pop("epoch")
        ex = coverage_metrics(model, policy, noise, exact=True, **kw)
        sa = coverage_metrics(model, policy, noise, exact=False, rng=1, **kw)
        for e, s in zip(ex, sa):
            assert e.method == "exact" and s.method == "sampled" and e.robots == s.robots
            # within 4 standard errors (a 6e-5 chance per point) and 1e-3 for a zero se
            assert np.all(np.abs(e.covered_mean - s.covered_mean) <= 4 * s.covered_se + 1e-3)
            for x in LEVELS:
                assert s.T[x]["not_reached"] == pytest.approx(e.T[x]["not_reached"], abs=0.01)
                if e.T[x]["mean"] is not None and s.T[x]["mean_se"]:
                    assert abs(e.T[x]["mean"] - s.T[x]["mean"]) <= 4 * s.T[x]["mean_se"] + 1e-3


def test_a_team_of_one_is_one_robot_and_teams_are_independent_unions():
    model = model_for(CellSpace(RING), "step")
    noise = TurnNoise(90, 0.8)
    one, team1, team3 = coverage_metrics(model, 90, noise, robots=[1, 1, 3], horizon=20,
                                         times=range(1, 21), rng=0)
    assert one.robots == team1.robots == 1
    assert team1.covered_mean == pytest.approx(one.covered_mean, abs=0)
    assert team1.T == one.T
    # E C_K(t) = 1 − mean over cells of (1 − Pr(cell visited by t))^K
    sets = _brute(CellSpace(RING), 90, noise, 20)
    for t, d in enumerate(sets):
        pc = np.array([sum(p for V, p in d.items() if V >> c & 1) for c in range(8)])
        assert team3.covered_mean[t] == pytest.approx(np.mean(1 - (1 - pc) ** 3), abs=1e-12)
        # each cell's share visited (always sampled: 1000 runs) against the exact marginal,
        # within 4 binomial standard errors (at least 1e-3)
        pk = np.stack([pc, 1 - (1 - pc) ** 3])
        got = np.stack([one.cell_visited[t], team3.cell_visited[t]])
        assert np.all(np.abs(got - pk) <= 4 * np.sqrt(pk * (1 - pk) / one.runs) + 1e-3), (
            t, got, pk)
    # the sampled path: K = 1 runs the same sampler as one robot
    a, = coverage_metrics(model, 90, noise, robots=1, horizon=20, rng=5, exact=False)
    b, = coverage_metrics(model, 90, noise, robots=[1], horizon=20, rng=5, exact=False)
    assert a.covered_mean.tolist() == b.covered_mean.tolist()


def _ring_sample(seed):
    m, = coverage_metrics(model_for(CellSpace(RING), "step"), 90, TurnNoise(90, 0.8),
                          robots=3, horizon=200, rng=seed, exact=False, runs=400)
    return m.covered_mean.tolist(), m.idleness_worst


def test_sampler_threads_and_forked_processes_agree_with_a_serial_call():
    # the sampler shares its runs among the cores; calls from several Python threads at once
    # (numba's default thread pool takes one at a time) give the serial records
    from concurrent.futures import ThreadPoolExecutor
    call = _ring_sample
    serial = [call(s) for s in range(4)]
    with ThreadPoolExecutor(4) as ex:
        assert list(ex.map(call, range(4))) == serial
    # and in processes forked after this one sampled (GNU OpenMP's pool would kill them)
    import multiprocessing
    with multiprocessing.get_context("fork").Pool(2) as pool:
        assert pool.map_async(call, range(4)).get(timeout=120) == serial


def test_return_times_are_kac():
    model = model_for(CellSpace(CORRIDOR), "step")
    # φ = 90° exact: q = (3, 2, 3)/8, every step counted: return times 8/3, 4, 8/3 steps
    assert return_times(model, TurnNoise(), 90) == pytest.approx([8 / 3, 4, 8 / 3])
    ev = model_for(CellSpace(CORRIDOR), "event")
    assert return_times(ev, TurnNoise(), 90) == pytest.approx([8 / 3, 4, 8 / 3], rel=1e-6)
    m, = coverage_metrics(model, 90, horizon=50, start=0, rng=0)
    assert m.to_json()["return_time_mean"] == pytest.approx([8 / 3, 4, 8 / 3])
    # worst idleness: from z = 0 the cycle visits cells 0, 1, 2, 2, 2, 1, 0, 0 (§16), so
    # the longest stretch without a visit is 5 steps (cell 0 in steps 1–5, cell 2 in 5–9)
    assert m.idleness_worst == 5.0
    # a cell no closed class visits has an infinite return time (null in metrics.json)
    assert return_times(model, TurnNoise(), 90, limit=(np.array([0.5, 0.5, 0.0]), 1.0)
                        ).tolist() == [2.0, 2.0, math.inf]


def test_metric_times_and_json_record():
    assert metric_times(100) == [100]
    assert metric_times(20_000)[:3] == [100, 119, 141] and metric_times(20_000)[-1] == 20_000
    model = model_for(CellSpace(RING), "step")
    m, = coverage_metrics(model, 90, TurnNoise(90, 0.8), horizon=150, rng=0)
    rec = json.loads(json.dumps(m.to_json()))
    assert rec["angle"] == 90 and rec["robots"] == 1 and rec["t"] == [100, 119, 141, 150]
    for key in ("covered_mean", "covered_p10", "covered_p90", "covered_se"):
        assert len(rec[key]) == 4
    assert set(rec["T"]) == set(LEVELS)
    assert set(rec["T"]["0.9"]) >= {"mean", "median", "not_reached"}
    assert len(rec["return_time_mean"]) == 8 and rec["method"] == "exact"
    assert bouncesim.coverage_metrics is coverage_metrics


def test_bad_input_is_one_sentence():
    model = model_for(CellSpace(RING), "step")
    with pytest.raises(UserError, match="at least one robot"):
        coverage_metrics(model, 90, robots=0)
    with pytest.raises(UserError, match="horizon"):
        coverage_metrics(model, 90, horizon=0)
    with pytest.raises(UserError, match="at most 20 cells"):
        coverage_metrics(model_for(CellSpace(envs.load("lab")), "step"), 90, exact=True)
    with pytest.raises(UserError, match="steps of C"):
        coverage_metrics(model, 90, horizon=10, times=[20])


def _twin_check(env, angle, noise, robots, T, times, runs):
    cs = CellSpace(env)
    m, = coverage_metrics(model_for(cs, "event"), angle, noise, robots=robots, horizon=T,
                          times=times, runs=2000, rng=0, exact=False)
    sim = twin_cover(env, angle, noise, robots=robots, runs=runs, horizon=T, times=times,
                     rng=1, cells=cs)
    # per cell: the shares visited average to the covered fraction, in model and twin alike
    assert m.cell_visited.mean(axis=1) == pytest.approx(m.covered_mean, abs=1e-12)
    assert visited_by(sim.first, times).mean(axis=1) == pytest.approx(sim.covered_mean,
                                                                       abs=1e-12)
    se = np.hypot(m.covered_se, sim.covered_se)
    # the goal (0.03) where the simulation is precise; 3 combined standard errors beyond it
    assert np.all(np.abs(m.covered_mean - sim.covered_mean) <= 0.03 + 3 * se), (
        env.name, angle, robots, m.covered_mean, sim.covered_mean, se)


@pytest.mark.parametrize("seed", [0, 1])
def test_model_against_twin_on_random_rooms(seed):
    env = random_rectilinear_room(np.random.default_rng(seed), orientations=72)
    noise = TurnNoise(5, 0.8)
    for robots in (1, 4):
        _twin_check(env, 30.0 if seed else 75.0, noise, robots, 2000, [100, 500, 2000], 150)


def test_model_against_twin_on_two_rooms():
    env = two_room(0.5, 72)
    for robots in (1, 4):
        _twin_check(env, 30.0, TurnNoise(5, 0.8), robots, 3000, [100, 1000, 3000], 150)


def test_cli_writes_metrics(tmp_path, capsys):
    out = tmp_path / "out"
    rc = main(["coverage", "lab", "--orientations", "8", "--angles", "90,135", "--eps", "45",
               "--r", "0.9", "--metrics", "--robots", "2", "--horizon", "300",
               "--metrics-runs", "50", "--simulate", "4", "--out", str(out)])
    assert rc == 0
    data = json.loads((out / "metrics.json").read_text())
    recs = data["records"]
    assert [(r["angle"], r["robots"]) for r in recs] == [(90, 1), (90, 2), (135, 1), (135, 2),
                                                        ("mix", 1), ("mix", 2)]
    assert all(r["t"][-1] == 300 and r["method"] == "sampled" for r in recs)
    assert all(len(r["twin_covered_mean"]) == len(r["t"]) for r in recs)
    assert (out / "cover_time.png").stat().st_size > 0
    assert "coverage-time metrics over 300 steps" in capsys.readouterr().out


def test_cli_metrics_default_horizon_and_start(tmp_path):
    out = tmp_path / "out"
    assert main(["coverage", "lab", "--orientations", "8", "--angles", "90", "--metrics",
                 "--start", "0", "--metrics-runs", "20", "--no-plots", "--out", str(out)]) == 0
    data = json.loads((out / "metrics.json").read_text())
    assert data["horizon"] == 20_000 and data["start"] == 0
    assert [r["robots"] for r in data["records"]] == [1]
    assert not (out / "cover_time.png").exists()


def test_cli_designs_for_a_time_objective(tmp_path, capsys):
    # --objective cover90: alpha is the simplex-grid candidate with the least mean time to
    # cover 90 % (the API's own design, the same seed), and alpha.json's tv is that mix's
    out = tmp_path / "out"
    argv = ["coverage", "lab", "--orientations", "8", "--angles", "90,135", "--eps", "45",
            "--r", "0.9", "--horizon", "400", "--epoch", "100", "--robots", "2", "--json"]
    assert main([*argv, "--objective", "cover90", "--no-plots", "--out", str(out)]) == 0
    got = json.loads(capsys.readouterr().out)
    from planners.coverage import design_mix
    from planners.metrics import tv_distance
    cs = CellSpace(envs.load("lab", orientations=8))
    model = model_for(cs, "step")
    d = design_mix(model, (90, 135), TurnNoise(45, 0.9), objective="cover90", horizon=400,
                   epoch=100, robots=2, rng=0)
    assert got["alpha"] == pytest.approx(d.alpha.tolist())
    assert got["objective"]["value_steps"] == pytest.approx(d.value)
    assert got["objective"]["robots"] == 2 and got["objective"]["name"] == "cover90"
    per = design_mix(model, (90, 135), TurnNoise(45, 0.9), horizon=400, epoch=100)
    q = per.columns @ d.alpha
    assert got["tv"] == pytest.approx(tv_distance(q, per.target))
    assert got["objective"]["tv_design_alpha"] == pytest.approx(per.alpha.tolist())


@pytest.mark.parametrize("argv,msg", [(["--objective", "idleness", "--start", "0"],
                                       "drop --start"),
                                      (["--robots", "3"], "--robots needs --metrics"),
                                      (["--seed", "3"], "--seed needs --metrics"),
                                      (["--metrics", "--robots", "0"], "at least 1"),
                                      (["--metrics", "--metrics-runs", "1"], "at least 2")])
def test_cli_refuses_bad_metrics_flags(argv, msg, capsys):
    assert main(["coverage", "lab", "--orientations", "8", "--angles", "90", *argv]) != 0
    assert msg in capsys.readouterr().err


def test_experiment_quick(tmp_path):
    from experiments import cover_time
    assert cover_time.main(["--quick", "--out", str(tmp_path)]) == 0
    rows = tmp_path.joinpath("cover_time.csv").read_text().splitlines()
    assert rows[0].startswith("map,P,angle,robots,t,model") and len(rows) == 1 + 3 * 2 * 3
    assert (tmp_path / "cover_time.png").stat().st_size > 0
    cells = pd.read_csv(tmp_path / "cover_cells.csv")
    assert len(cells) == 3 * 2 * 3 * cells.cell.nunique()
    assert cells[["model", "twin"]].stack().between(0, 1).all()
    # a cell's share visited by t can only grow with t
    for _, g in cells.groupby(["angle", "robots", "cell"]):
        assert np.all(np.diff(g.sort_values("t")[["model", "twin"]].to_numpy(), axis=0) >= 0)
    cfg = json.loads((tmp_path / "config.json").read_text())
    assert cfg["quick"] is True and cfg["orientations"] == 72


def test_the_twins_T90_mean_and_its_standard_error_by_hand():
    # four teams, three of which reach 90 % at steps 10, 20 and 30: mean 20, sd 10, standard
    # error 10 / √3; one team reaching gives no error; none, no mean
    import math

    import numpy as np

    from bouncesim.runs.cover import TwinCover
    reach = np.array([[1, 5, 10, 40], [1, 5, 20, -1], [1, 5, -1, -1], [1, 5, 30, -1]])
    tc = TwinCover(t=np.array([1]), covered=np.zeros((4, 1)), reach=reach, seconds=0.0)
    assert tc.T_mean(0.9) == (20.0, 0.25)
    assert tc.T_mean_se(0.9) == pytest.approx(10 / math.sqrt(3))
    assert tc.T_mean_se(1.0) is None and tc.T_mean(1.0) == (40.0, 0.75)
