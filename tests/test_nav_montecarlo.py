"""The navigation Monte-Carlo experiment: the planner registry end to end on a tiny room,
noise-free execution, the statistics and the heading classes of hand-made plans.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from experiments import nav_montecarlo as nm
from experiments import nav_planners as npl
from planners.cells import CellSpace
from planners.navigation import Navigator
from planners.navigation.exact import ExactNavigator
from planners.plan import Plan

from .conftest import room


def _tiny_room(tmp_path):
    """A 4 x 3 cell room with a one-cell block at (1, 1), written as an env file."""
    path = tmp_path / "tiny.json"
    path.write_text(json.dumps(room(4, 3, [(1, 1, 2, 2)], name="tiny").to_dict()))
    return str(path)


def test_registry_runs_both_planners_on_a_tiny_room(tmp_path, monkeypatch):
    # a third planner plugs in with one line; this one never finds a plan
    class Nothing:
        plan, decisions, decision_s = None, 1, 0.0

        def __call__(self, robot):
            raise npl.NoPlan("none")

    monkeypatch.setitem(npl.PLANNERS, "nothing", lambda env, s, g, config, rng: Nothing())
    tiny, out = _tiny_room(tmp_path), tmp_path / "nm"
    argv = ["--quick", "--maps", tiny, "--planners", "step,exact,nothing", "--out", str(out),
            "--workers", "1", "--no-progress", "--twin-glance", "0"]
    assert nm.main(argv) == 0
    runs = pd.read_csv(out / "runs.csv")
    cfg = json.loads((out / "config.json").read_text())
    q = nm.QUICK
    assert cfg["twin_glance_deg"] == 0 and cfg["planners"] == ["step", "exact", "nothing"]
    assert cfg["argv"] == argv and cfg["command"].startswith("python -m experiments.nav_montecarlo")
    # every pair, planner and level; the noise-free level once, the others reps times
    per_pair = 1 + (len(q["sigmas"]) - 1) * q["reps"]
    assert len(runs) == q["pairs"] * 3 * per_pair == cfg["sweep"]["n_trials"]
    assert set(runs["noise"]) == {f"gauss:{s:g}" for s in q["sigmas"]}
    # the plans are the planners' own answers (cross-check with fresh planners)
    cells = CellSpace(npl.world(tiny))
    step, exact = Navigator(cells, nm.ANGLES), ExactNavigator(cells, nm.ANGLES)
    for _, r in runs[runs["noise"] == "gauss:0"].iterrows():
        if r["planner"] == "step":
            assert r["plan"] == str(step.plan(int(r["start"]), int(r["goal"])).plan)
        elif r["planner"] == "exact":
            route = exact.plan(int(r["start"]), int(r["goal"]))
            assert r["plan"] == route.plan.exact_text()
            # exact plans replay to their goal in the front-half twin they are planned for
            assert r["success"], (r["plan"], r["reason"])
        else:
            assert not r["success"] and r["reason"] == "no plan" and not r["has_plan"]
    assert (runs["decisions"] == 1).all() and (runs["decision_ms"] >= 0).all()
    # the pooled summary counts what runs.csv holds
    s = pd.read_csv(out / "summary_noise.csv")
    pooled = s[(s["env"] == "all") & (s["noise"] == "gauss:2")].set_index("planner")
    for planner in ("step", "exact", "nothing"):
        mine = runs[(runs["planner"] == planner) & (runs["noise"] == "gauss:2")]
        assert pooled.loc[planner, "trials"] == len(mine)
        assert pooled.loc[planner, "successes"] == mine["success"].sum()
    assert pooled.loc["nothing", "success_rate"] == 0.0
    for name in ("noise", "length", "headings"):
        t = pd.read_csv(out / f"summary_{name}.csv")
        assert (t["ci_low"] <= t["success_rate"] + 1e-12).all()
        assert (t["success_rate"] <= t["ci_high"] + 1e-12).all()
    for png in ("success", "success_by_map", "success_by_length"):
        assert (out / f"{png}.png").stat().st_size > 10_000
    # the figures are drawn from runs.csv alone
    (out / "success.png").unlink()
    (out / "runs.jsonl").unlink()
    assert nm.main(["--plot-only", "--out", str(out)]) == 0
    assert (out / "success.png").exists()


def test_rerun_resumes_and_a_different_budget_is_refused(tmp_path, capsys):
    out = tmp_path / "nm"
    base = ["--quick", "--out", str(out), "--workers", "1", "--no-progress", "--maps",
            _tiny_room(tmp_path), "--planners", "step", "--pairs", "2"]
    assert nm.main(base) == 0
    first = pd.read_csv(out / "runs.csv")
    assert nm.main(base) == 0
    assert "0 trials (" in capsys.readouterr().out     # nothing left to run
    cols = [c for c in first.columns if c not in ("wall_s", "decision_s", "decision_ms")]
    pd.testing.assert_frame_equal(first[cols], pd.read_csv(out / "runs.csv")[cols])
    assert nm.main(base[:-1] + ["3"]) == 2
    err = capsys.readouterr().err
    assert "different sweep" in err and "\n" == err[-1] and err.count("\n") == 1
    assert nm.main(base[:-1] + ["3", "--restart"]) == 0
    assert nm.main(base + ["--planners", "nope"]) == 2
    assert "unknown planner nope" in capsys.readouterr().err


def _trial(start, goal, noise="gauss:0", planner="step", seed=1):
    params = {"env": "lab", "map_seed": 0, "start": start, "goal": goal, "planner": planner,
              "backend": "kinematic", "noise": noise, "glance": nm.TWIN_GLANCE_DEG}
    return nm.nav_trial(params, np.random.default_rng(seed))


def test_zero_noise_twin_succeeds_on_axis_aligned_plans_in_lab():
    # lab's walls lie on grid lines, so a robot on a cell centre heading along an axis bumps
    # exactly on a cell centre (distance r from the wall) and travels n·h for n zeros: the
    # noise-free continuous run must retrace the discrete plan on every such pair
    cells = npl.cells_of(npl.world("lab"))
    ap = Navigator(cells, nm.ANGLES).all_pairs()
    rng = np.random.default_rng(0)
    W = ap.weights.copy()
    np.fill_diagonal(W, -1)
    ii, jj = np.nonzero(W > 0)
    checked = 0
    for s in rng.permutation(len(ii)):
        route = ap.route(int(ii[s]), int(jj[s]))
        if nm.heading_class(cells.pose(route.start)[2], route.plan) != "axis":
            continue
        res = _trial(route.start, route.goal)
        assert res["plan"] == str(route.plan) and res["headings"] == "axis"
        assert res["success"], (route, res["reason"])
        assert res["deviations"] == 0 and res["position_error_m"] < 1e-6
        checked += 1
        if checked == 12:
            break
    assert checked == 12


def test_zero_noise_twin_succeeds_on_a_plan_ending_along_a_diagonal():
    # a discrete step along a diagonal moves to the diagonal neighbour's centre, √2·h away,
    # so the trailing "00" must drive 2·√2·h (it drove 2·h once and stopped 0.282 m short)
    res = _trial(24, 183)
    assert res["plan"] == "0 135° 00"                     # east 1 cell, bump, 2 steps NW
    assert res["success"], res["reason"]
    assert res["position_error_m"] < 1e-6 and res["deviations"] == 0


def test_wilson_interval_hand_computed():
    z = 1.959963984540054                          # the 97.5 % normal quantile
    # k = 8 of n = 10: centre (p + z²/2n)/(1 + z²/n), half-width z·sqrt(p(1-p)/n + z²/4n²)/(..)
    lo, hi = nm.wilson(8, 10)
    assert float(lo) == pytest.approx(0.49016, abs=1e-5)
    assert float(hi) == pytest.approx(0.94332, abs=1e-5)
    # k = 0: the lower end is 0 and the upper end z²/(n + z²)
    lo, hi = nm.wilson(0, 5)
    assert float(lo) == pytest.approx(0.0, abs=1e-12)
    assert float(hi) == pytest.approx(z * z / (5 + z * z), rel=1e-9)
    # vectorised, n = 0 gives NaN
    lo, hi = nm.wilson(np.array([3, 0]), np.array([3, 0]))
    assert hi[0] == pytest.approx(1.0) and math.isnan(lo[1]) and math.isnan(hi[1])


def test_headings_follow_every_turn_of_a_hand_made_plan():
    # the distinct angles (Plan.angles) are (90,) here; the robot turns twice (Plan.turns)
    plan = Plan.parse("0 90° 90° 0")
    assert plan.angles == (90,) and plan.turns == (90, 90)
    assert nm.plan_headings(0.0, plan) == [0.0, 90.0, 180.0]
    # an exact plan: north, 135° twice -> 225° -> 0°
    e = Plan.exact([135, 135], [0.5, 0.0], 0.3, h=0.34)
    assert nm.plan_headings(90.0, e) == [90.0, 225.0, 0.0]
    assert nm.heading_class(90.0, e) == "diagonal"
    assert nm.heading_class(0.0, Plan.parse("00 90° 0 270° 0")) == "axis"
    assert nm.heading_class(0.0, Plan.parse("45° 45° 00")) == "diagonal"      # 45° between
    assert nm.heading_class(45.0, Plan.parse("0")) == "diagonal"
    bins = nm.length_bin([0, 5, 6, 10, 11, 40, 41, 300]).tolist()
    assert bins == ["0-5", "0-5", "6-10", "6-10", "11-20", "21-40", "41+", "41+"]


def test_time_per_decision_is_total_time_over_total_decisions():
    runs = pd.DataFrame({"planner": ["a", "a", "a", "b"], "env": ["m"] * 4,
                         "backend": ["kinematic"] * 3 + ["pybullet"],
                         "decisions": [1, 3, 4, 1], "decision_s": [0.010, 0.030, 0.002, 9.0]})
    runs["decision_ms"] = 1e3 * runs["decision_s"] / runs["decisions"]
    d = nm.summarise_decisions(runs).set_index("planner")
    assert list(d.index) == ["a"]                      # the twin only
    assert d.loc["a", "mean_ms"] == pytest.approx(1e3 * 0.042 / 8)
    assert d.loc["a", "median_ms"] == pytest.approx(10.0)      # of 10, 10, 0.5
    assert d.loc["a", "max_ms"] == pytest.approx(10.0) and d.loc["a", "trials"] == 3


def test_trial_is_a_pure_function_of_params_and_seed():
    a = _trial(8, 0, noise="gauss:5", seed=4)
    b = _trial(8, 0, noise="gauss:5", seed=4)
    for r in (a, b):
        for key in ("wall_s", "decision_s", "decision_ms"):
            r.pop(key)
    assert a == b
    exact = _trial(8, 0, planner="exact", seed=4)
    assert exact["success"] and exact["deviations"] == 0 and exact["has_plan"]


def test_maps_are_seeded_and_of_the_declared_kinds():
    a, b = npl.world("rect1", 0), npl.world("rect1", 0)
    assert a is b and npl.world("rect1", 1).to_dict() != a.to_dict()
    d = a.to_dict()
    # rectilinear: every vertex on the 0.34 m grid
    for ring in [d["boundary"], *d["obstacles"]]:
        assert np.allclose(np.asarray(ring) / 0.34, np.round(np.asarray(ring) / 0.34))
    for n in (1, 2, 3):
        d = npl.world(f"poly{n}", 0).to_dict()
        assert len(d["boundary"]) in (5, 6) and len(d["obstacles"]) == 1
    assert len(npl.world("pentagon").to_dict()["boundary"]) == 5


def test_sigmas_option_sets_the_noise_levels_and_refuses_bad_ones(tmp_path, capsys):
    out = tmp_path / "nm"
    base = ["--quick", "--out", str(out), "--workers", "1", "--no-progress", "--maps",
            _tiny_room(tmp_path), "--planners", "step", "--pairs", "2", "--reps", "3"]
    assert nm.main(base + ["--sigmas", "0,4"]) == 0
    runs = pd.read_csv(out / "runs.csv")
    # 2 pairs: the noise-free level once, σ = 4° three times
    assert sorted(runs["noise"].value_counts().items()) == [("gauss:0", 2), ("gauss:4", 6)]
    assert json.loads((out / "config.json").read_text())["gauss_sigmas_deg"] == [0.0, 4.0]
    assert nm.main(base + ["--sigmas", "0,-1", "--restart"]) == 2
    err = capsys.readouterr().err
    assert "--sigmas must be non-negative" in err and err.count("\n") == 1
    with pytest.raises(SystemExit):
        nm.main(base + ["--sigmas", "zero"])
