"""The navigation Monte-Carlo experiment: quick run end to end, noise-free execution, statistics."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from experiments import nav_montecarlo as nm
from planners.navigation import Navigator
from planners.plan import Plan


def test_quick_run_writes_the_tables_and_the_figure(tmp_path):
    out = tmp_path / "nm"
    argv = ["--quick", "--out", str(out), "--workers", "1", "--no-progress", "--seed", "3"]
    assert nm.main(argv) == 0
    runs = pd.read_csv(out / "runs.csv")
    cfg = json.loads((out / "config.json").read_text())
    assert cfg["twin_glance_deg"] == 80.0 and cfg["seed"] == 3 and cfg["quick"] is True
    assert len(runs) == cfg["sweep"]["n_trials"] and runs["trial"].is_unique
    q = nm.QUICK
    n_levels = len(q["sigmas"]) + len(q["model_r"])
    twin = runs[runs["backend"] == "kinematic"]
    # 12 pairs per environment, every level, the exact level once and the others 3 times
    assert twin.groupby("env")["pair"].nunique().to_dict() == {"lab": 12, "complex": 12}
    assert len(twin) == 2 * 12 * (1 + (n_levels - 1) * q["reps"])
    assert set(runs["noise"]) == {"gauss:0", "gauss:2", "gauss:10", "model:eps=45,r=0.9"}
    for col in ("success", "deviations", "early", "late", "position_error_m",
                "heading_error_deg", "wall_s", "length", "angles_used", "headings"):
        assert col in runs.columns
    assert (runs["deviations"] == runs["early"] + runs["late"]).all()
    assert (runs["wall_s"] > 0).all()
    # every plan string is the shortest plan of its pair (cross-check with a second planner)
    nav = Navigator(nm._world("lab")[1], nm.ANGLES)
    for _, r in runs[runs["env"] == "lab"].drop_duplicates("pair").iterrows():
        assert str(nav.plan(int(r["start"]), int(r["goal"])).plan) == r["plan"]
    for name in ("noise", "length", "angles", "headings"):
        s = pd.read_csv(out / f"summary_{name}.csv")
        assert (s["ci_low"] <= s["success_rate"] + 1e-12).all()
        assert (s["success_rate"] <= s["ci_high"] + 1e-12).all()
        assert s["trials"].sum() == len(runs)
    s = pd.read_csv(out / "summary_noise.csv")
    lab0 = s[(s["env"] == "lab") & (s["backend"] == "kinematic") & (s["noise"] == "gauss:0")]
    want = twin[(twin["env"] == "lab") & (twin["noise"] == "gauss:0")]["success"].mean()
    assert lab0["success_rate"].item() == pytest.approx(want)
    assert (out / "success.png").stat().st_size > 10_000
    assert (out / "success_by_length.png").stat().st_size > 10_000
    # the figure is drawn from runs.csv alone
    (out / "success.png").unlink()
    (out / "runs.jsonl").unlink()
    assert nm.main(["--plot-only", "--out", str(out)]) == 0
    assert (out / "success.png").exists()


def test_rerun_resumes_and_a_different_budget_is_refused(tmp_path, capsys):
    out = tmp_path / "nm"
    base = ["--quick", "--out", str(out), "--workers", "1", "--no-progress", "--physics-pairs",
            "0", "--envs", "lab", "--pairs", "3"]
    assert nm.main(base) == 0
    first = pd.read_csv(out / "runs.csv")
    assert nm.main(base) == 0
    assert "0 trials (" in capsys.readouterr().out     # nothing left to run
    pd.testing.assert_frame_equal(first.drop(columns="wall_s"),
                                  pd.read_csv(out / "runs.csv").drop(columns="wall_s"))
    assert nm.main(base[:-1] + ["4"]) == 2
    err = capsys.readouterr().err
    assert "different sweep" in err and "\n" == err[-1] and err.count("\n") == 1
    assert nm.main(base[:-1] + ["4", "--restart"]) == 0


def _lab_routes():
    env, cells = nm._world("lab")
    ap = Navigator(cells, nm.ANGLES).all_pairs()
    return cells, ap


def test_zero_noise_twin_succeeds_on_axis_aligned_plans_in_lab():
    # lab's walls lie on grid lines, so a robot on a cell centre heading along an axis bumps
    # exactly on a cell centre (distance r from the wall) and travels n·h for n zeros: the
    # noise-free continuous run must retrace the discrete plan on every such pair
    cells, ap = _lab_routes()
    rng = np.random.default_rng(0)
    W = ap.weights.copy()
    np.fill_diagonal(W, -1)
    ii, jj = np.nonzero(W > 0)
    checked = 0
    for s in rng.permutation(len(ii)):
        route = ap.route(int(ii[s]), int(jj[s]))
        if nm.heading_class(cells.pose(route.start)[2], route.plan) != "axis":
            continue
        params = {"env": "lab", "start": route.start, "goal": route.goal,
                  "plan": str(route.plan), "backend": "kinematic", "noise": "gauss:0"}
        res = nm.nav_trial(params, np.random.default_rng(1))
        assert res["success"], (params, res["reason"])
        assert res["deviations"] == 0 and res["position_error_m"] < 1e-6
        checked += 1
        if checked == 12:
            break
    assert checked == 12


def test_zero_noise_twin_succeeds_on_a_plan_ending_along_a_diagonal():
    # a discrete step along a diagonal moves to the diagonal neighbour's centre, √2·h away,
    # so the trailing "00" must drive 2·√2·h (it drove 2·h once and stopped 0.282 m short)
    cells, ap = _lab_routes()
    route = ap.route(24, 183)
    assert str(route.plan) == "0 135° 00"                  # east 1 cell, bump, 2 steps NW
    res = nm.nav_trial({"env": "lab", "start": 24, "goal": 183, "plan": str(route.plan),
                        "backend": "kinematic", "noise": "gauss:0"}, np.random.default_rng(0))
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


def test_heading_class_and_length_bins():
    assert nm.heading_class(0.0, Plan.parse("00 90° 0 270° 0")) == "axis"
    assert nm.heading_class(90.0, Plan.parse("0 135° 135° 0")) == "diagonal"   # 225°, 360°
    assert nm.heading_class(45.0, Plan.parse("0")) == "diagonal"
    bins = nm.length_bin([1, 5, 6, 10, 11, 40, 41, 300]).tolist()
    assert bins == ["1-5", "1-5", "6-10", "6-10", "11-20", "21-40", "41+", "41+"]


def test_trial_is_a_pure_function_of_params_and_seed():
    params = {"env": "lab", "start": 8, "goal": 0, "plan": "90° 90° 00000000 90° 90°",
              "backend": "kinematic", "noise": "gauss:5"}
    a = nm.nav_trial(params, np.random.default_rng(4))
    b = nm.nav_trial(params, np.random.default_rng(4))
    a.pop("wall_s"), b.pop("wall_s")
    assert a == b
    exact = nm.nav_trial({**params, "noise": "gauss:0"}, np.random.default_rng(4))
    assert exact["success"] and exact["deviations"] == 0
