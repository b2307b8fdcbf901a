"""Shared fixtures: small hand-made environments whose answers can be worked out on paper."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

from envs import Environment


def traced_peak(fn) -> int:
    """Peak bytes traced by tracemalloc while fn runs, above what was allocated before."""
    tracemalloc.start()
    try:
        tracemalloc.reset_peak()
        before = tracemalloc.get_traced_memory()[0]
        fn()
        return tracemalloc.get_traced_memory()[1] - before
    finally:
        tracemalloc.stop()


def room(cols: int, rows: int, obstacles=(), K: int = 8, h: float = 0.34,
         name: str = "room") -> Environment:
    """A cols x rows cell rectangle (cell h = 2 r) with grid-aligned obstacles given as
    (i0, j0, i1, j1) cell ranges (inclusive-exclusive).
    """
    W, H = cols * h, rows * h
    obs = [[[i0 * h, j0 * h], [i1 * h, j0 * h], [i1 * h, j1 * h], [i0 * h, j1 * h]]
           for (i0, j0, i1, j1) in obstacles]
    return Environment.from_dict({
        "name": name, "boundary": [[0, 0], [W, 0], [W, H], [0, H]], "obstacles": obs,
        "robot_radius": h / 2, "discretization": {"cell_size": h, "orientations": K}})


def random_room(rng: np.random.Generator, K: int = 8) -> Environment:
    """A small random rectilinear room with a few random (possibly wall-touching) blocks."""
    cols, rows = int(rng.integers(3, 7)), int(rng.integers(2, 6))
    obs = []
    for _ in range(int(rng.integers(0, 3))):
        i0, j0 = int(rng.integers(0, cols)), int(rng.integers(0, rows))
        obs.append((i0, j0, min(cols, i0 + int(rng.integers(1, 3))),
                    min(rows, j0 + int(rng.integers(1, 3)))))
    try:
        return room(cols, rows, obs, K=K, name="random")
    except ValueError:
        return room(cols, rows, (), K=K, name="random")


@pytest.fixture
def corridor():
    """A 3 x 1 cell corridor at K = 4: P = 3, N = 12."""
    return room(3, 1, K=4, name="corridor")


# ----------------------------------------------------------------------------- fuzz failures
# `make fuzz` sets BOUNCESIM_FUZZ_FAILURES to a file: every failing fuzz test appends its
# falsifying example (Hypothesis prints it into the report) with the traceback.
def pytest_runtest_makereport(item, call):
    import os
    from pathlib import Path

    path = os.environ.get("BOUNCESIM_FUZZ_FAILURES")
    if not path or call.when != "call" or call.excinfo is None:
        return
    if "test_fuzz" not in item.nodeid:
        return
    text = str(item.repr_failure(call.excinfo))
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    with open(out, "a") as fh:
        fh.write(f"{'=' * 100}\n{item.nodeid}\n{'-' * 100}\n{text}\n\n")


@pytest.fixture
def figures(monkeypatch):
    """The figures the commands and experiments save through ``save_figure`` (matplotlib
    objects stay readable after closing), in order.
    """
    import bouncesim.coverage_plots as coverage_plots
    import bouncesim.plots as plots
    saved = []
    original = plots.save_figure

    def keep(fig, path, dpi=120):
        saved.append(fig)
        return original(fig, path, dpi=dpi)
    monkeypatch.setattr(plots, "save_figure", keep)
    monkeypatch.setattr(coverage_plots, "save_figure", keep)
    return saved
