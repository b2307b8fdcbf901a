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
        for num in plt.get_fignums():
            assert_panels_apart(plt.figure(num))
    finally:
        plt.close("all")
    assert any(tmp_path.glob("*.png"))


def assert_panels_apart(fig) -> None:
    """No two panels of ``fig`` overlap: their tight bounding boxes (ticks, labels, titles
    and the colour bars inset beside them included) are disjoint.
    """
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    children = {id(c) for ax in fig.axes for c in ax.child_axes}
    panels = [ax for ax in fig.axes if id(ax) not in children and ax.get_visible()]
    boxes = [ax.get_tightbbox(renderer) for ax in panels]
    for i in range(len(boxes)):
        for j in range(i + 1, len(boxes)):
            assert not boxes[i].overlaps(boxes[j]), \
                f"panels {i} and {j} of the README figure overlap"


# --- the README stays a five-minute read, and its links (and the docs index's) resolve -----

INDEX = README.parent / "docs" / "index.md"
MAX_README_LINES = 300


def test_readme_is_short():
    lines = README.read_text(encoding="utf-8").splitlines()
    assert len(lines) <= MAX_README_LINES, (
        f"README.md has {len(lines)} lines (at most {MAX_README_LINES}): move details into docs/")


def relative_links(path: Path) -> list[str]:
    """The relative targets of ``[text](target)`` and ``![alt](target)`` outside code fences,
    without their ``#anchor``; web links (http, https, mailto) and anchor-only links are left
    out.
    """
    text = path.read_text(encoding="utf-8")
    text = re.sub(r"^```.*?^```", "", text, flags=re.S | re.M)      # fenced code blocks
    text = re.sub(r"`[^`\n]*`", "", text)                           # inline code
    targets = []
    for target in re.findall(r"\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)", text):
        if re.match(r"^(https?:|mailto:|#)", target):
            continue
        targets.append(target.split("#", 1)[0])
    return targets


@pytest.mark.parametrize("page", [README, INDEX, README.parent / "results" / "README.md"],
                         ids=["README.md", "docs/index.md", "results/README.md"])
def test_relative_links_resolve(page):
    assert page.exists(), f"{page} is missing"
    targets = relative_links(page)
    assert targets, f"{page.name} has no relative links (is the link parser broken?)"
    missing = sorted({t for t in targets if not (page.parent / t).exists()})
    assert not missing, f"{page.name} links to files that do not exist: {missing}"


def test_link_parser(tmp_path):
    sample = tmp_path / "sample.md"
    sample.write_text('[a](docs/x.md#sec) ![b](fig.png "title") [c](https://e.org) [d](#top)\n'
                      "`[e](code.md)`\n```\n[f](fenced.md)\n```\n", encoding="utf-8")
    assert relative_links(sample) == ["docs/x.md", "fig.png"]
