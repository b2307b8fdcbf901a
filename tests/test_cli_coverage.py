"""``bouncesim coverage``: outputs, their consistency, and one-sentence errors (exit 2)."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from bouncesim.cli import main


def read_csv(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def test_writes_csv_json_and_heatmaps(tmp_path, capsys):
    out = tmp_path / "cov"
    rc = main(["coverage", "lab", "--angles", "90,135", "--eps", "45", "--r", "0.8",
               "--out", str(out)])
    assert rc == 0
    printed = capsys.readouterr().out
    assert "alpha" in printed and "135°" in printed and "TV" in printed
    for f in ("coverage.csv", "alpha.json", "heatmap_angle_90.png", "heatmap_angle_135.png",
              "heatmap_mix_vs_target.png"):
        assert (out / f).stat().st_size > 0, f
    summary = json.loads((out / "alpha.json").read_text())
    assert summary["angles"] == [90, 135]
    assert summary["K"] == 8 and summary["P"] == 48 and summary["N"] == 384
    assert summary["env"] == "lab" and summary["eps"] == 45 and summary["r"] == 0.8
    alpha = np.array(summary["alpha"])
    assert alpha.min() >= 0 and alpha.sum() == pytest.approx(1.0)
    for pa in summary["per_angle"]:
        assert pa["persistent_groups"] == len(pa["group_sizes"]) >= 1
        assert 0 <= pa["transient_fraction"] < 1
    rows = read_csv(out / "coverage.csv")
    assert list(rows[0]) == ["angle", "p", "i", "j", "x", "y", "q"]
    by = {}
    for r in rows:
        by.setdefault(r["angle"], np.zeros(48))[int(r["p"])] = float(r["q"])
    assert set(by) == {"90", "135", "mix", "target"}
    for q in by.values():
        assert q.sum() == pytest.approx(1.0)
    # the mix row is A alpha, and the JSON's residual and TV are computed from it
    mixed = alpha[0] * by["90"] + alpha[1] * by["135"]
    np.testing.assert_allclose(by["mix"], mixed, atol=1e-12)
    diff = by["mix"] - by["target"]
    assert summary["residual"] == pytest.approx(np.linalg.norm(diff), rel=1e-9)
    assert summary["tv"] == pytest.approx(0.5 * np.abs(diff).sum(), rel=1e-9)


def test_json_output_and_custom_target(tmp_path, capsys):
    target = tmp_path / "t.csv"
    target.write_text("p,weight\n0,1\n47,1\n")
    rc = main(["coverage", "lab", "--angles", "45,90", "--target", str(target), "--json"])
    assert rc == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["target"] == str(target)
    assert len(summary["alpha"]) == 2


def test_configuration_space(tmp_path, capsys):
    target = tmp_path / "z.csv"
    target.write_text("z,weight\n" + "\n".join(f"{z},1" for z in range(0, 384, 7)))
    out = tmp_path / "o"
    rc = main(["coverage", "lab", "--angles", "90,135", "--target", str(target),
               "--target-space", "configurations", "--out", str(out), "--no-plots"])
    assert rc == 0
    summary = json.loads((out / "alpha.json").read_text())
    assert summary["target_space"] == "configurations"
    rows = read_csv(out / "coverage_configurations.csv")
    assert list(rows[0]) == ["angle", "z", "p", "k", "pi"]
    assert len(rows) == 4 * 384
    assert not list(out.glob("*.png"))


@pytest.mark.parametrize("argv, match", [
    (["--angles", "30"], "bouncing angle 30° is not allowed with 8 orientations"),
    (["--angles", "90", "--eps", "10"], "error range eps 10° is not allowed"),
    (["--angles", "90", "--r", "1.5"], "reliability r must lie in [0, 1]"),
    (["--angles", "90,abc"], "--angles takes numbers"),
    (["--angles", "90", "--target", "{missing}"], "no target file"),
    (["--angles", "90", "--target", "{neg}"], "negative weight"),
    (["--angles", "90", "--target", "{zero}"], "sum to zero"),
    (["--angles", "90", "--target", "{short}"], "must have 6 rows x 9 columns"),
    (["--angles", "90", "--target", "{neg}", "--target-space", "configurations"],
     "needs columns z and weight"),
    (["--angles", "90", "--epoch", "0"], "--epoch must be at least one step"),
    (["--angles", "90", "--epoch", "10", "--target-space", "configurations"],
     "--epoch predicts coverage over position cells only"),
])
def test_user_errors_exit_2_with_one_sentence(tmp_path, capsys, argv, match):
    files = {"missing": tmp_path / "missing.csv", "neg": tmp_path / "neg.csv",
             "zero": tmp_path / "zero.csv", "short": tmp_path / "short.txt"}
    files["neg"].write_text("p,weight\n0,1\n1,-2\n")
    files["zero"].write_text("p,weight\n0,0\n1,0\n")
    files["short"].write_text("1 1 1\n1 1 1\n")
    argv = [a.format(**files) for a in argv]
    rc = main(["coverage", "lab", *argv])
    assert rc == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("bouncesim: error: ") and match in err
    assert "\n" not in err and "Traceback" not in err


def test_epoch_reports_the_mix_as_executed(tmp_path, capsys):
    """--epoch: the time-shared prediction next to A alpha, consistent across the outputs.
    The target ½(q_90 + q_135) makes alpha = (½, ½); switching the angle every step (1-step
    epochs) is then the chain ½(W_90 + W_135), whose coverage differs from A alpha.
    """
    first = tmp_path / "first"
    assert main(["coverage", "lab", "--angles", "90,135", "--eps", "45", "--r", "0.8",
                 "--out", str(first), "--no-plots"]) == 0
    q = {}
    for r in read_csv(first / "coverage.csv"):
        q.setdefault(r["angle"], []).append(float(r["q"]))
    target = tmp_path / "target.csv"
    target.write_text("p,weight\n" + "".join(
        f"{p},{0.5 * (a + b)!r}\n" for p, (a, b) in enumerate(zip(q["90"], q["135"]))))
    out = tmp_path / "cov"
    capsys.readouterr()
    rc = main(["coverage", "lab", "--angles", "90,135", "--eps", "45", "--r", "0.8",
               "--target", str(target), "--epoch", "1", "--out", str(out)])
    assert rc == 0
    assert "executed in 1-step epochs: TV to target" in capsys.readouterr().out
    assert (out / "heatmap_mix_epochs_vs_target.png").stat().st_size > 0
    summary = json.loads((out / "alpha.json").read_text())
    np.testing.assert_allclose(summary["alpha"], [0.5, 0.5], atol=1e-6)
    ts = summary["timeshared"]
    assert ts["epoch"] == 1 and ts["converged"]
    series = {}
    for r in read_csv(out / "coverage.csv"):
        series.setdefault(r["angle"], []).append(float(r["q"]))
    executed, mixed, tgt = (np.array(series[k]) for k in ("mix_epochs", "mix", "target"))
    assert executed.sum() == pytest.approx(1.0)
    assert ts["tv"] == pytest.approx(0.5 * np.abs(executed - tgt).sum(), abs=1e-12)
    assert ts["tv_to_A_alpha"] == pytest.approx(0.5 * np.abs(executed - mixed).sum(),
                                                abs=1e-12)
    assert ts["tv_to_A_alpha"] > 0.01


def test_help_documents_target_formats(capsys):
    with pytest.raises(SystemExit):
        main(["coverage", "--help"])
    text = capsys.readouterr().out
    assert "top row first" in text and "p and weight" in text and "z and weight" in text


def test_table1_experiment_quick(tmp_path, capsys):
    from experiments import coverage_table1
    out = tmp_path / "t1"
    assert coverage_table1.main(["--quick", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "paper" in printed and "residual" in printed
    table = read_csv(out / "table1.csv")
    assert [r["angle"] for r in table] == ["30", "75", "315"]
    assert [float(r["alpha_paper"]) for r in table] == list(coverage_table1.PAPER_ALPHA)
    for col in ("alpha", "alpha_configurations"):
        assert sum(float(r[col]) for r in table) == pytest.approx(1.0)
    config = json.loads((out / "config.json").read_text())
    assert config["params"]["K"] == 72 and config["params"]["N"] == 72 * 183
    for f in ("coverage.csv", "groups.csv", "fig10_limiting.png", "fig11_mix_vs_target.png",
              "fig9_groups_315.png"):
        assert (out / f).stat().st_size > 0, f


def test_contact_rule_reaches_the_event_model(tmp_path, capsys):
    """--contact pybullet gives the event model's coverage with the fitted rule (the same
    numbers as the Python API with that rule, and different from no rule); the rule is
    refused for the other models, and the header names the noise as given.
    """
    import envs
    from envs.motion import PYBULLET_CONTACT
    from planners.cells import CellSpace
    from planners.coverage import TurnNoise, model_for
    # K = 72, ε = 5°: headings 5° off a wall occur, below the rule's β = 9.6°
    args = ["coverage", "lab", "--orientations", "72", "--angles", "30", "--model", "event"]
    got = {}
    for contact in ("off", "pybullet"):
        out = tmp_path / contact
        assert main(args + ["--eps", "5", "--r", "0.8", "--contact", contact, "--no-plots",
                            "--out", str(out)]) == 0
        rows = read_csv(out / "coverage.csv")
        got[contact] = np.array([float(r["q"]) for r in rows if r["angle"] == "30"])
    summary = json.loads((tmp_path / "pybullet" / "alpha.json").read_text())
    assert summary["model_settings"]["contact"] == {"beta_deg": PYBULLET_CONTACT.beta_deg,
                                                    "slide_friction":
                                                    PYBULLET_CONTACT.slide_friction,
                                                    "turn_in": []}
    cs = CellSpace(envs.load("lab", orientations=72))
    want = model_for(cs, "event", {"contact": PYBULLET_CONTACT}).analyse(
        30, TurnNoise(5, 0.8)).q
    np.testing.assert_allclose(got["pybullet"], want, atol=1e-12)
    assert 0.5 * np.abs(got["pybullet"] - got["off"]).sum() > 0.05     # measured: 0.17
    capsys.readouterr()
    assert main(["coverage", "lab", "--angles", "90", "--contact", "pybullet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1] == ("bouncesim: error: the contact rule is part of the event model only, "
                       "not the step model.")
    assert main(["coverage", "lab", "--angles", "90", "--noise", "gauss:45"]) == 0
    assert "noise=gauss:45 " in capsys.readouterr().out


def test_epoch_takes_gaussian_noise(tmp_path, capsys):
    """--noise gauss:σ with --epoch: long epochs reach the sum rule A α (§16); a time-shared
    prediction that dropped σ turned exactly (0.25 from the one-angle limit at 75°).
    """
    out = tmp_path / "g"
    assert main(["coverage", "lab", "--orientations", "72", "--noise", "gauss:3", "--angles",
                 "30,75", "--model", "event", "--epoch", "20000", "--no-plots", "--json",
                 "--out", str(out)]) == 0
    ts = json.loads(capsys.readouterr().out)["timeshared"]
    assert ts["converged"] and ts["tv_to_A_alpha"] < 0.005
