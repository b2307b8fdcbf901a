"""The experiments run end to end at their ``--quick`` budget and write what they say."""

from __future__ import annotations

import dataclasses
import json

import pandas as pd
import pytest

from experiments import (
    allpairs_fig7,
    alpha_delivery,
    coverage_table1,
    coverage_validation,
    model_convergence,
    nav_fig3,
    nav_montecarlo,
)


def _config(out):
    cfg = json.loads((out / "config.json").read_text())
    assert cfg["quick"] is True and "versions" in cfg and "git_revision" in cfg
    # the command line that ran it, whether the folder was written by a sweep or directly
    assert cfg["command"].startswith("python -m experiments.") and "--quick" in cfg["argv"]
    return cfg


@pytest.mark.parametrize("physics", [False, pytest.param(True, marks=pytest.mark.physics)],
                         ids=["plans", "plans+runs"])
def test_nav_fig3_quick(tmp_path, physics):
    argv = ["--quick", "--out", str(tmp_path)] + ([] if physics else ["--no-physics"])
    assert nav_fig3.main(argv) == 0
    plans = pd.read_csv(tmp_path / "plans.csv")
    assert list(plans["ours"]) == ["90° 90° 00000000 90° 90°", "135° 135° 0"]
    assert (tmp_path / "fig3_paths.png").stat().st_size > 0
    # lab's walls lie on the grid: the exact planner returns the same strings, with flights
    assert [e.split(" | ")[0] for e in plans["exact"]] == list(plans["ours"])
    assert plans["exact_cost"].to_numpy() == pytest.approx(plans["cost"].to_numpy(), abs=1e-6)
    assert (tmp_path / "fig3_step_vs_exact.png").stat().st_size > 0
    cfg = _config(tmp_path)
    assert cfg["angles"] == [90.0, 135.0] and cfg["physics"] is physics
    if physics:
        runs = pd.read_csv(tmp_path / "runs.csv")
        assert len(runs) > 0 and runs["success"].dtype == bool
        assert cfg["noisy_runs_per_level"] == 3


def test_allpairs_fig7_quick(tmp_path):
    assert allpairs_fig7.main(["--quick", "--out", str(tmp_path)]) == 0
    table = pd.read_csv(tmp_path / "angles_used.csv")
    assert set(table["env"]) == {"lab"} and table["plans"].sum() > 0
    assert len(pd.read_csv(tmp_path / "claims.csv")) == 3
    assert (tmp_path / "angles_used_lab.png").stat().st_size > 0
    assert _config(tmp_path)["envs"] == ["lab"]


def test_configs_are_frozen():
    for mod in (nav_fig3, allpairs_fig7):
        cfg = mod.Config()
        with pytest.raises(dataclasses.FrozenInstanceError):
            cfg.seed = 1


@pytest.mark.parametrize("mod", [alpha_delivery, coverage_table1, coverage_validation,
                                 model_convergence, nav_montecarlo],
                         ids=lambda m: m.__name__.rsplit(".", 1)[-1])
def test_config_is_frozen_and_help_exits_0(mod, capsys):
    cfg = mod.Config()
    with pytest.raises(dataclasses.FrozenInstanceError):
        cfg.seed = 1
    hash(cfg)                                   # tuples, not lists: the Config is hashable
    with pytest.raises(SystemExit) as stop:
        mod.main(["--help"])
    assert stop.value.code == 0 and "--quick" in capsys.readouterr().out


def test_bad_angles_exit_2(tmp_path, capsys):
    assert nav_fig3.main(["--angles", "7", "--no-physics", "--out", str(tmp_path)]) == 2
    assert "nav_fig3: error:" in capsys.readouterr().err


def test_nav_robustness_quick(tmp_path):
    from experiments import nav_robustness
    argv = ["--quick", "--pairs", "2", "--workers", "1", "--no-progress", "--out", str(tmp_path)]
    assert nav_robustness.main(argv) == 0
    runs = pd.read_csv(tmp_path / "runs.csv")
    # feedback runs every condition; exact and reliable only the noise ones
    fb = runs[runs["planner"] == "feedback"]
    assert set(fb["condition"]) == {"sigma0", "sigma2", "side5", "unknown"}
    assert set(runs[runs["planner"] != "feedback"]["condition"]) == {"sigma0", "sigma2"}
    assert set(runs["env"]) == {"lab", "lroom"} and runs["success"].dtype == bool
    assert (fb[fb["condition"] == "unknown"]["bumps_to_localize"] >= 0).all()
    summary = pd.read_csv(tmp_path / "summary.csv")
    assert ((summary["ci_low"] <= summary["success_rate"])
            & (summary["success_rate"] <= summary["ci_high"])).all()
    assert (tmp_path / "success_vs_sigma.png").stat().st_size > 0
    assert _config(tmp_path)["pairs_per_map"] == 2
    # every run is counted once in its outcome class, and the reached ones are the successes
    ends = pd.read_csv(tmp_path / "outcomes.csv")
    pooled = ends[ends["env"] == "all"].set_index(["planner", "body", "condition"])
    classes = [c for c in ends.columns if c not in ("planner", "body", "condition", "env")]
    per = runs.groupby(["planner", "body", "condition"])
    assert (pooled[classes].sum(axis=1) == per.size()).all()
    assert (pooled["reached"] == per["success"].sum()).all()


def test_nav_robustness_bump_budget(tmp_path, capsys):
    # --max-bumps caps every feedback run (the pairs are `lab`'s first two, which need more
    # than 3 bumps at σ = 2°) and is recorded per run and in config.json
    from experiments import nav_robustness
    argv = ["--maps", "lab", "--bodies", "twin", "--conditions", "sigma2", "--planners",
            "feedback", "--pairs", "2", "--max-bumps", "3", "--workers", "1", "--no-progress",
            "--out", str(tmp_path)]
    assert nav_robustness.main(argv) == 0
    runs = pd.read_csv(tmp_path / "runs.csv")
    assert len(runs) == 2 and (runs["max_bumps"] == 3).all() and (runs["bumps"] <= 3).all()
    assert runs["reason"].str.contains("gave up after 3 bumps").any()
    assert json.loads((tmp_path / "config.json").read_text())["max_bumps"] == 3
    assert nav_robustness.main(["--max-bumps", "0", "--out", str(tmp_path / "x")]) == 2
    assert "--max-bumps must be at least 1" in capsys.readouterr().err


def test_nav_robustness_bad_feedback_setting_exits_2(tmp_path, capsys):
    from experiments import nav_robustness
    assert nav_robustness.main(["--quick", "--feedback", "particels=10",
                                "--out", str(tmp_path)]) == 2
    assert "particels" in capsys.readouterr().err
    assert nav_robustness.main(["--quick", "--feedback", "votes=two",
                                "--out", str(tmp_path)]) == 2
    assert "--feedback votes needs a int" in capsys.readouterr().err
    cfg = nav_robustness.feedback_config("votes=3,guided=true,final_min=0.7")
    assert (cfg.votes, cfg.guided, cfg.final_min) == (3, True, 0.7)
