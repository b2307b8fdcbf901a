"""experiments.coverage_validation: the --quick run CI does, and the numbers it reports."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from experiments import coverage_validation as cv


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    pytest.importorskip("pybullet")
    out = tmp_path_factory.mktemp("cv")
    assert cv.main(["--quick", "--out", str(out), "--workers", "1", "--no-progress"]) == 0
    return out


def test_quick_run_writes_tables_and_figures(quick_run):
    for name in ("runs.csv", "histograms.csv", "predictions.csv", "alpha.csv", "tv.csv",
                 "config.json", "heatmaps_lab_step.png", "heatmaps_fig1_step.png",
                 "tv_twin.png", "tv_pybullet.png"):
        assert (quick_run / name).stat().st_size > 0, name
    cfg = json.loads((quick_run / "config.json").read_text())
    assert cfg["seed"] == 0 and cfg["orientations"] == 72 and cfg["git_revision"] is not None
    tv = pd.read_csv(quick_run / "tv.csv", dtype={"policy": str})
    # every env x (3 angles + mix) against the twin, one PyBullet row (lab, 75°)
    assert len(tv[tv.backend == "twin"]) == 8
    assert len(tv[tv.backend == "pybullet"]) == 1
    assert (tv[tv.backend == "twin"].steps >= 2 * 100_000).all()


def test_tv_table_agrees_with_raw_histograms(quick_run):
    """Recompute one TV from histograms.csv and predictions.csv by hand."""
    preds = pd.read_csv(quick_run / "predictions.csv", dtype={"policy": str})
    hist = pd.read_csv(quick_run / "histograms.csv", dtype={"policy": str})
    tv = pd.read_csv(quick_run / "tv.csv", dtype={"policy": str})
    q = preds[(preds.env == "lab") & (preds.policy == "30")].sort_values("p").q.to_numpy()
    h = hist[(hist.env == "lab") & (hist.policy == "30") & (hist.backend == "twin")]
    h0 = h[h.replicate == 0].sort_values("p")["count"].to_numpy(float)
    h1 = h[h.replicate == 1].sort_values("p")["count"].to_numpy(float)
    row = tv[(tv.env == "lab") & (tv.policy == "30") & (tv.backend == "twin")].iloc[0]
    assert row.tv == pytest.approx(0.5 * np.abs(q - h0 / h0.sum()).sum(), abs=1e-4)
    assert row.noise_floor == pytest.approx(0.5 * np.abs(h0 / h0.sum() - h1 / h1.sum()).sum(),
                                            abs=1e-4)
    assert q.sum() == pytest.approx(1.0)


def test_step_model_misses_continuous_motion(quick_run):
    """The finding this experiment exists to report (docs/model.md §16's cell-centre steps against
    continuous motion): the step model is further from the twin than sampling noise explains,
    by a wide margin, for every angle and the mix.
    """
    tv = pd.read_csv(quick_run / "tv.csv", dtype={"policy": str})
    twin = tv[(tv.backend == "twin") & (tv.model == "step")]
    angles = twin[~twin.policy.str.startswith("mix")]
    assert (angles.tv_pooled > 3 * angles.noise_floor).all()
    # the mix's floor is larger (few 1000-step epochs per robot in --quick)
    assert (twin.tv_pooled > 0.15).all()


def test_policy_labels_round_trip():
    label = cv.policy_label((30.0, 75.0, 315.0), (0.0, 0.25, 0.75))
    assert label == "mix:75=0.250000,315=0.750000"
    mix = cv.parse_policy(label)
    assert mix.angles == (75.0, 315.0) and mix.alpha == (0.25, 0.75)
    assert (mix.eps, mix.r) == (cv.EPS, cv.R)
    assert cv.policy_label((30.0, 75.0), (1.0, 0.0)) == "30"


def test_envs_accepts_an_env_file_path(tmp_path):
    """--envs takes an env file path as well as a catalogue name: the lab copied to a file
    gives the lab's predictions and a heatmap named after the file.
    """
    import shutil

    import envs
    room = tmp_path / "rooms" / "mylab.json"
    room.parent.mkdir()
    shutil.copy(envs.CATALOG_DIR / "lab.json", room)
    assert cv.env_label(str(room)) == "mylab" and cv.env_label("lab") == "lab"
    out = tmp_path / "out"
    assert cv.main(["--quick", "--envs", f"lab,{room}", "--twin-steps", "4000",
                    "--pybullet-steps", "0", "--twin-burn-in", "10", "--out", str(out),
                    "--workers", "1", "--no-progress"]) == 0
    preds = pd.read_csv(out / "predictions.csv", dtype={"policy": str})
    a = preds[preds.env == "lab"].sort_values(["policy", "p"]).q.to_numpy()
    b = preds[preds.env == str(room)].sort_values(["policy", "p"]).q.to_numpy()
    assert len(a) == len(b) > 0 and abs(a - b).max() <= 1e-12
    assert (out / "heatmaps_mylab_step.png").exists()


@pytest.mark.physics
def test_a_mujoco_run_counts_its_steps(tmp_path):
    # --physics mujoco: the short runs on the second engine, one trial by hand through the
    # sweep's trial function (60 steps at 75° in lab, every step counted or dropped), and
    # the CLI refuses an engine it does not know in one line
    pytest.importorskip("mujoco")
    row = cv.simulate({"env": "lab", "orientations": 72, "policy": "75", "backend": "mujoco",
                       "steps": 60, "robots": 1, "epoch": 1000, "speed": 0.3},
                      np.random.default_rng(2))
    counts = np.array(row["counts"].split(), dtype=int)
    assert row["counted"] == counts.sum() and row["counted"] + row["dropped"] == 60
    assert row["bumps"] > 0
    with pytest.raises(SystemExit):
        cv.main(["--physics", "gazebo", "--out", str(tmp_path)])
