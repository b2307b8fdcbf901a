"""results/canonical/: the stored headline tables agree with a fresh full run, and the
comparison that says so can fail.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pandas as pd
import pytest

from experiments import allpairs_fig7, compare, coverage_table1, nav_fig3

CANONICAL = Path(__file__).resolve().parents[1] / "results" / "canonical"


@pytest.mark.parametrize("module, argv", [
    (coverage_table1, []),
    (allpairs_fig7, []),
    (nav_fig3, ["--no-physics"]),
    pytest.param(nav_fig3, [], marks=pytest.mark.physics),
], ids=["coverage_table1", "allpairs_fig7", "nav_fig3 plans", "nav_fig3 with PyBullet"])
def test_a_full_rerun_agrees_with_the_canonical_tables(module, argv, tmp_path, capsys):
    name = module.__name__.rsplit(".", 1)[1]
    stored = CANONICAL / name
    assert (stored / "config.json").is_file() and list(stored.glob("*.csv"))
    if "--no-physics" in argv:      # the plans only: compare plans.csv alone
        only = tmp_path / "stored"
        only.mkdir()
        shutil.copy(stored / "plans.csv", only)
        stored = only
    out = tmp_path / "run"
    assert module.main([*argv, "--out", str(out), "--compare", str(stored)]) == 0, \
        capsys.readouterr().out
    assert "agrees with" in capsys.readouterr().out


def test_the_comparison_finds_a_changed_number_a_missing_table_and_new_columns(tmp_path):
    stored, new = tmp_path / "stored", tmp_path / "new"
    stored.mkdir()
    new.mkdir()
    table = pd.DataFrame({"angle": [30, 75], "alpha": [0.25, 0.75], "label": ["a", "b"],
                          "note": [None, "x"], "seconds": [1.0, 2.0]})
    table.to_csv(stored / "t.csv", index=False)
    # the same numbers within the tolerance and another timing: they agree
    table.assign(alpha=[0.25 * (1 + 1e-9), 0.75], seconds=[9.0, 9.0]).to_csv(
        new / "t.csv", index=False)
    assert compare.compare_folders(stored, new) == []
    # a number beyond the tolerance, a changed label
    table.assign(alpha=[0.25, 0.7501], label=["a", "c"]).to_csv(new / "t.csv", index=False)
    diffs = compare.compare_folders(stored, new)
    assert diffs == ["t.csv: row 1, alpha: stored 0.75, now 0.7501",
                     "t.csv: row 1, label: stored 'b', now 'c'"]
    assert compare.main([str(stored), str(new)]) == 1
    table.drop(columns="label").to_csv(new / "t.csv", index=False)
    assert "columns differ" in compare.compare_folders(stored, new)[0]
    table.to_csv(stored / "u.csv", index=False)
    assert f"u.csv: missing in {new}" in compare.compare_folders(stored, new)
    assert compare.main([str(new / "nothing"), str(new)]) == 2
