"""docs/tutorial.ipynb runs from top to bottom (a small simulation budget) and its cells say
what the tutorial's text claims.
"""

import importlib.util
import re
from pathlib import Path

import pytest

NOTEBOOK = Path(__file__).resolve().parents[1] / "docs" / "tutorial.ipynb"

pytestmark = [
    pytest.mark.slow, pytest.mark.physics,
    pytest.mark.skipif(any(importlib.util.find_spec(m) is None
                           for m in ("nbclient", "ipykernel", "pybullet", "skimage")),
                       reason="needs the dev, sim and maps extras"),
]


def _text(cell) -> str:
    return "".join(o.get("text", "") for o in cell.get("outputs", ())
                   if o.get("output_type") == "stream")


def test_tutorial_runs_and_shows_what_it_says(tmp_path, monkeypatch):
    import nbformat
    from nbclient import NotebookClient

    monkeypatch.setenv("BOUNCESIM_TUTORIAL_QUICK", "1")
    monkeypatch.setenv("MPLBACKEND", "module://matplotlib_inline.backend_inline")
    nb = nbformat.read(NOTEBOOK, as_version=4)
    # a per-cell bound generous enough for a busy machine: the whole notebook takes ~1 min
    NotebookClient(nb, timeout=1200, kernel_name="python3",
                   resources={"metadata": {"path": str(tmp_path)}}).execute()
    code = [c for c in nb.cells if c.cell_type == "code"]
    out = "\n".join(_text(c) for c in code)
    images = sum("image/png" in o.get("data", {}) for c in code for o in c.get("outputs", ()))
    assert images >= 6                                   # every figure the text promises
    assert "success False" in out and "exact: success True" in out   # step misses, exact arrives
    assert "PyBullet: success True" in out
    assert "off the 0.34 m cell grid" in out             # the map's warning
    # the twin delivers the design's prediction within the noise of 20 000 steps over 103 cells
    m = re.search(r"predicted vs simulated ([0-9.]+)", out)
    assert m and float(m.group(1)) < 0.1
