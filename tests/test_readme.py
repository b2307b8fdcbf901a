"""The README's "Python API" blocks run as written (so the README cannot drift)."""

from __future__ import annotations

import re
from pathlib import Path

import matplotlib
import pytest

README = Path(__file__).resolve().parent.parent / "README.md"


def python_blocks(section: str = "Python API") -> list[str]:
    """The ```python fences under the README's ``## <section>`` heading, in order."""
    text = README.read_text(encoding="utf-8")
    m = re.search(rf"^## {re.escape(section)}\n(.*?)(?=^## )", text, re.S | re.M)
    assert m, f"the README has no '## {section}' section"
    return re.findall(r"^```python\n(.*?)^```", m.group(1), re.S | re.M)


def test_the_section_has_two_blocks():
    assert len(python_blocks()) == 2


@pytest.mark.parametrize("index", [0, 1], ids=["plan-execute-plot", "coverage-mix"])
def test_readme_block_runs(index, tmp_path, monkeypatch):
    matplotlib.use("Agg")                 # non-interactive, whatever the environment says
    import matplotlib.pyplot as plt
    monkeypatch.chdir(tmp_path)           # the blocks save figures in the working folder
    code = python_blocks()[index]
    try:
        exec(compile(code, f"README.md (Python API block {index + 1})", "exec"), {})
    finally:
        plt.close("all")
    assert any(tmp_path.glob("*.png"))
