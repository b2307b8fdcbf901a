"""docs/model.md as a reference: its worked examples run, its contents and notation are there.

- Every ``>>>`` example of the contract runs as written (one doctest over the whole file, so
  later examples may use names defined by earlier ones), and there are enough of them.
- The contents table at the top links every ``## `` and ``### `` heading of the file.
- The notation table exists and gives every symbol one row.
- The figures the contract embeds exist (``python -m experiments.model_figures`` draws the
  ``model_*`` ones).
"""

from __future__ import annotations

import doctest
import re
from pathlib import Path

import pytest

DOCS = Path(__file__).resolve().parent.parent / "docs"
MODEL = DOCS / "model.md"
MIN_EXAMPLES = 5


def _text() -> str:
    return MODEL.read_text(encoding="utf-8")


def _section(text: str, heading: str) -> str:
    """The body of the ``## heading`` section (up to the next ``## ``)."""
    m = re.search(rf"^## {re.escape(heading)}\n(.*?)(?=^## )", text, re.S | re.M)
    assert m, f"docs/model.md has no '## {heading}' section"
    return m.group(1)


def _slug(title: str) -> str:
    """GitHub's anchor of a heading: lower case, punctuation dropped, spaces to hyphens."""
    return re.sub(r"[^\w\- ]", "", title.strip().lower()).replace(" ", "-")


def test_every_example_runs():
    result = doctest.testfile(str(MODEL), module_relative=False, verbose=False,
                              optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE,
                              raise_on_error=False, report=True)
    assert result.failed == 0, f"{result.failed} of {result.attempted} examples failed"
    assert result.attempted >= MIN_EXAMPLES


def test_examples_are_many_and_spread():
    """At least the worked examples the contract promises: indices, a plan, a flight, the
    corridor's coverage in two models.
    """
    examples = doctest.DocTestParser().get_examples(_text())
    assert len(examples) >= MIN_EXAMPLES
    sources = "".join(ex.source for ex in examples)
    for needle in ("config_of_pose", "Navigator(", "drive_distance", "model_for(",
                   "EventModel(", "Boundary("):
        assert needle in sources, f"no worked example uses {needle}"


def test_contents_lists_every_heading():
    text = _text()
    contents = _section(text, "Contents")
    links = dict(re.findall(r"\[([^\]]+)\]\(#([^)]+)\)", contents))
    headings = [h for h in re.findall(r"^#{2,3} (.+)$", text, re.M) if h != "Contents"]
    assert headings
    anchors = set(links.values())
    for h in headings:
        assert _slug(h) in anchors, f"the contents table does not link '{h}'"
    assert len(anchors) == len(headings), "the contents table links a heading that is gone"


def test_notation_table_one_meaning_per_symbol():
    rows = [re.split(r"(?<!\\)\|", line)[1:-1]
            for line in _section(_text(), "Notation").splitlines() if line.startswith("|")]
    symbols = [r[0].strip() for r in rows[2:]]             # below the header and its rule
    assert all(len(r) == 3 and r[1].strip() for r in rows), "a notation row is malformed"
    assert len(symbols) >= 40
    assert len(symbols) == len(set(symbols)), "a symbol has two rows in the notation table"
    for must in ("r_b", "r", "β", "Φ", "T", "P", "D", "α", "ρ", "m", "M", "ν", "ψ", "η"):
        assert must in symbols, f"the notation table lacks {must}"


@pytest.mark.parametrize("heading", ["Conformance", "Implementation-defined choices",
                                     "Constants"])
def test_reference_tables_exist(heading):
    assert _section(_text(), heading).count("\n|") >= 5


def test_embedded_figures_exist():
    figures = re.findall(r"!\[[^\]]*\]\((figures/[^)]+)\)", _text())
    assert {"figures/model_grid.png", "figures/model_steps.png",
            "figures/model_cspace.png"} <= set(figures)
    for f in figures:
        assert (DOCS / f).is_file(), f"docs/{f} is missing"
    assert "python -m experiments.model_figures" in _text()
