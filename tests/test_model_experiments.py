"""The coverage-model choice everywhere: the CLI flag and the --quick runs of the model
experiments (alpha_delivery, model_convergence, coverage_validation with every model).
"""

from __future__ import annotations

import json

import pandas as pd
import pytest

from bouncesim.cli import main as cli


def test_cli_coverage_model_flag(tmp_path, capsys):
    out = tmp_path / "cov"
    assert cli(["coverage", "lab", "--orientations", "72", "--angles", "30,75,315", "--eps",
                "5", "--r", "0.8", "--model", "event", "--model-option", "bin_length=0.05",
                "--out", str(out), "--no-plots"]) == 0
    summary = json.loads((out / "alpha.json").read_text())
    assert summary["model"] == "event"
    assert summary["model_settings"]["bin_length"] == 0.05
    assert abs(sum(summary["alpha"]) - 1) < 1e-9
    cov = pd.read_csv(out / "coverage.csv", dtype={"angle": str})
    assert cov[cov.angle == "30"].q.sum() == pytest.approx(1.0)


@pytest.mark.parametrize("argv, words", [
    (["--model", "event", "--model-option", "bins=3"], "KEY=VALUE"),
    (["--model", "event", "--model-option", "samples=two"], "needs a int"),
    (["--model", "sampled", "--target-space", "configurations"], "position cells only"),
])
def test_cli_coverage_model_errors(argv, words, capsys):
    assert cli(["coverage", "lab", "--orientations", "72", "--angles", "30", *argv]) == 2
    err = capsys.readouterr().err
    assert words in err and "Traceback" not in err


def test_model_convergence_quick(tmp_path):
    from experiments import model_convergence as mc
    assert mc.main(["--quick", "--out", str(tmp_path), "--workers", "1",
                    "--no-progress"]) == 0
    d = pd.read_csv(tmp_path / "convergence.csv")
    assert (tmp_path / "convergence.png").stat().st_size > 0
    step = d[d.model == "step"].tv_max.min()
    event = d[(d.model == "event")].sort_values("value").iloc[0]    # finest bins
    # 2·10^5 twin steps per angle: the noise floor is about 0.03 (stated in the row)
    assert event.tv_max < 0.05 + event.noise_floor
    assert step > 3 * event.tv_max


def test_alpha_delivery_quick(tmp_path):
    from experiments import alpha_delivery as ad
    assert ad.main(["--quick", "--models", "step,event", "--pybullet-steps", "0",
                    "--out", str(tmp_path), "--workers", "1", "--no-progress"]) == 0
    d = pd.read_csv(tmp_path / "delivery.csv")
    assert set(d.label) == {"step", "event", "oracle"}
    twin = d[d.backend == "twin"].set_index("label")
    # the event model's promise is kept far better than the step model's
    assert twin.loc["event", "prediction_error"] < twin.loc["step", "prediction_error"] / 2
    assert (tmp_path / "alpha_delivery.png").stat().st_size > 0
    al = pd.read_csv(tmp_path / "alpha.csv")
    for _, g in al.groupby("label"):
        assert g.alpha.sum() == pytest.approx(1.0)
