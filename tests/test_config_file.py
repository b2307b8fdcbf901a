"""``bouncesim --config RUN.toml``: a command's options from a file, flags overriding it."""

from __future__ import annotations

import json

import pytest

from bouncesim.cli import main

RUN = """\
command = "coverage"
env = "lab"
angles = [90, 135]
orientations = 8
eps = 45
r = 0.8
model_option = []
no_plots = true
"""


def _untimed(obj):
    """``obj`` without its wall-clock fields (``seconds``), which differ run to run."""
    if isinstance(obj, dict):
        return {k: _untimed(v) for k, v in obj.items() if k != "seconds"}
    if isinstance(obj, list):
        return [_untimed(v) for v in obj]
    return obj


def _json_run(argv, capsys) -> dict:
    assert main(argv) == 0
    return _untimed(json.loads(capsys.readouterr().out))


def test_the_file_gives_what_the_flags_would(tmp_path, capsys):
    """The same run from the file and from flags prints the same result; a flag after the
    file overrides its value; config.json records the file and its values.
    """
    path = tmp_path / "run.toml"
    path.write_text(RUN)
    flags = ["coverage", "lab", "--angles", "90,135", "--orientations", "8", "--eps", "45",
             "--r", "0.8", "--no-plots", "--json"]
    assert _json_run(["--config", str(path), "--json"], capsys) == _json_run(flags, capsys)
    over = _json_run(["--config", str(path), "--json", "--r", "0.5"], capsys)
    assert over == _json_run(flags[:-4] + ["--r", "0.5", "--no-plots", "--json"], capsys)
    out = tmp_path / "out"
    assert main([f"--config={path}", "coverage", "fig1", "--out", str(out)]) == 0
    cfg = json.loads((out / "config.json").read_text())
    assert cfg["env"] == "fig1"                      # the positional from the command line
    assert cfg["config_file"] == {"path": str(path), "values": {
        "command": "coverage", "env": "lab", "angles": [90, 135], "orientations": 8,
        "eps": 45, "r": 0.8, "model_option": [], "no_plots": True}}
    assert cfg["argv"][:2] == [f"--config={path}", "coverage"]


@pytest.mark.parametrize("text, message", [
    ('command = "coverage"\nenv = "lab"\nangles = [90]\nfoo = 1\n',
     "coverage has no option 'foo'"),
    ('command = "coverage"\nenv = "lab"\nangles = [90]\nmodel = "nope"\n',
     "config key 'model' must be one of step"),
    ('command = "coverage"\nenv =\n', "is not valid TOML"),
    ('env = "lab"\n', "needs command = one of info"),
    ('command = "coverage"\nenv = "lab"\nangles = [90]\nno_plots = "yes"\n',
     "'no_plots' is a switch"),
    ('command = "coverage"\nenv = "lab"\nangles = [90]\norientations = "x"\n',
     "'orientations' must be an integer, got 'x'"),
    ('command = "coverage"\nenv = "lab"\nangles = [90]\nr = [[1]]\n',
     "'r' takes a single value"),
], ids=["unknown key", "bad choice", "bad toml", "no command", "switch", "type", "nested"])
def test_a_bad_file_is_one_sentence(text, message, tmp_path, capsys):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    assert main(["--config", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("bouncesim: error: ") and message in err and "\n" not in err, err


def test_a_file_for_another_command_or_none_at_all(tmp_path, capsys):
    path = tmp_path / "run.toml"
    path.write_text(RUN)
    assert main(["--config", str(path), "plan"]) == 2
    assert "is for coverage, not plan" in capsys.readouterr().err
    assert main(["--config", str(tmp_path / "missing.toml")]) == 2
    assert "is not a file" in capsys.readouterr().err
    assert main(["--config"]) == 2
    assert "needs a TOML file name" in capsys.readouterr().err
