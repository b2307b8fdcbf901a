"""experiments.validate_compare: two validate folders' pooled histograms, by hand."""

from __future__ import annotations

import pytest

from experiments.validate_compare import compare, main


def _runs(folder, rows, sub=""):
    d = folder / sub if sub else folder
    d.mkdir(parents=True, exist_ok=True)
    (d / "runs.csv").write_text("trial,policy,half,counts\n" + "".join(
        f"{i},{pol},{i % 2},{counts}\n" for i, (pol, counts) in enumerate(rows)))


def test_pooled_histograms_compared_by_hand(tmp_path, capsys):
    a, b = tmp_path / "a", tmp_path / "b"
    _runs(a, [("90", "1 3"), ("90", "3 1")])
    _runs(a, [("90", "2 0"), ("90", "0 2")], "round1")  # another round of policy 90
    _runs(b, [("90", "2 2"), ("90", "4 0")])
    # a pools 90 to [6, 6] (uniform); b to [6, 2]: TV = ½(|½ − ¾| + |½ − ¼|) = ¼
    t = compare(a, b).set_index("policy")
    assert list(t.index) == ["90"] and t.loc["90", "tv"] == pytest.approx(0.25)
    # a against b's own halves: [2, 2] against [4, 0] is ½ apart in every split
    assert t.loc["90", "floor_b"] == pytest.approx(0.5)
    u = compare(b).set_index("policy")
    assert u.loc["90", "tv"] == pytest.approx(0.25)      # [¾, ¼] against uniform
    assert main([str(a), str(b)]) == 0 and "0.250" in capsys.readouterr().out
    _runs(tmp_path / "c", [("90", "1 1 1"), ("90", "1 1 1")])
    assert main([str(a), str(tmp_path / "c")]) == 2
    assert "compare runs of one map" in capsys.readouterr().err
    assert main([str(tmp_path / "none")]) == 2
