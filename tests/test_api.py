"""The notebook API: ``import bouncesim`` is light, exports what it says, draws traces."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import matplotlib
import pytest

import bouncesim

ROOT = Path(__file__).resolve().parent.parent


def test_import_is_light():
    code = ("import sys, bouncesim; heavy = ('matplotlib', 'pybullet', 'serial', 'scipy', "
            "'shapely', 'pandas', 'planners', 'envs'); "
            "print(sorted({m.split('.')[0] for m in sys.modules} & set(heavy)))")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                         text=True, check=True).stdout.strip()
    assert out == "[]"


def test_every_export_resolves():
    for name in bouncesim.__all__:
        assert getattr(bouncesim, name) is not None, name
    assert set(bouncesim.__all__) <= set(dir(bouncesim))
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        bouncesim.nope  # noqa: B018


def test_plots_do_not_choose_a_backend():
    # a notebook keeps its inline backend: no module-level matplotlib.use(...)
    for mod in ("bouncesim/plots.py", "bouncesim/coverage_plots.py"):
        tree = ast.parse((ROOT / mod).read_text())
        calls = [n for stmt in tree.body for n in ast.walk(stmt)
                 if not isinstance(stmt, (ast.FunctionDef, ast.ClassDef))
                 and isinstance(n, ast.Call) and getattr(n.func, "attr", "") == "use"]
        assert not calls, mod


def test_draw_trace_of_a_run(tmp_path):
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    env = bouncesim.load("lab")
    with bouncesim.make_robot("kinematic", env) as bot:
        run = bouncesim.execute("90° 90° 00000000 90° 90°", bot, start=8, goal=0)
    ax = bouncesim.draw_trace(run, env, goal=run.goal_pose)
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels[0] == "executed" and "start" in labels and "goal" in labels
    assert "bump" in labels and "turn" in labels
    frame = run.trace.to_frame()                       # a DataFrame (or its CSV) works too
    fig, ax2 = plt.subplots()
    assert bouncesim.draw_trace(frame, ax=ax2) is ax2
    assert "end" in [t.get_text() for t in ax2.get_legend().get_texts()]
    plt.close("all")


def test_draw_trace_needs_poses():
    from bouncesim.runs.trace import Trace
    tr = Trace()
    tr.add(0.0, None, "start")
    with pytest.raises(ValueError, match="no poses"):
        bouncesim.draw_trace(tr)
