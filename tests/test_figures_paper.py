"""Figures fit for a paper: what the eye checks, pinned by measurement.

Rounded lengths in titles (and only there), legends off the map and clear of its axis labels,
executed paths and bumps visible over the plan and the start/goal markers, a failed run's
trace drawn with its outcome (and nothing said when the trace does not tell), configuration
ids that neither overlap nor leave their cell, GIF frames without dithering and without the
ground plane showing through the floor, and a vector format wherever the CLI writes a figure.
Extents are matplotlib's window extents after the figure is drawn; pixels are read back from
the written files.
"""

from __future__ import annotations

import contextlib
import io
import re

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: E402

import bouncesim.plots as plots  # noqa: E402
import envs  # noqa: E402
from bouncesim.cli import main  # noqa: E402
from planners.cells import CellSpace  # noqa: E402
from planners.plan import Plan  # noqa: E402

LONG_DECIMALS = re.compile(r"\d\.\d{5,}")
READABLE_PT = 5.0           # [pt] smallest id font taken as readable on a printed page
CORRIDOR = {"name": "corridor", "boundary": [[0, 0], [6.12, 0], [6.12, 0.68], [0, 0.68]],
            "obstacles": [], "robot_radius": 0.17,
            "discretization": {"cell_size": 0.34, "orientations": 8}}


def _renderer(fig):
    canvas = fig.canvas if hasattr(fig.canvas, "get_renderer") else FigureCanvasAgg(fig)
    canvas.draw()
    return canvas.get_renderer()


def _quiet(argv) -> int:
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        return main(argv)


def _legend_clear_of_map_and_axis(fig) -> None:
    """Every legend of ``fig`` lies outside its axes' map and clear of its x tick labels
    and x label.
    """
    r = _renderer(fig)
    for ax in fig.axes:
        legend = ax.get_legend()
        if legend is None:
            continue
        box = legend.get_window_extent(r)
        assert not box.overlaps(ax.patch.get_window_extent(r)), ax.get_title()
        assert not box.overlaps(ax.xaxis.get_tightbbox(r)), ax.get_title()


def _pixels_near(png, rgb, tol=40) -> int:
    img = (plt.imread(png)[..., :3] * 255).astype(int)
    return int((np.abs(img - np.array(rgb)).sum(-1) < tol).sum())


# ------------------------------------------------------------------ 1. rounded titles
def test_exact_text_rounds_only_when_asked():
    plan = Plan.exact([90, 90], [0.0, 2.719999999], 0.339999999, 0.34)
    exact = plan.exact_text()
    assert "2.719999999" in exact and Plan.parse(exact) == plan       # unchanged, re-parsed
    assert plan.exact_text(decimals=2) == "90° 00000000 90° 0 | flights 0 2.72 m | final 0.34 m"
    # whole metres keep their zeros (10 m is not 1 m)
    assert "flights 10 m" in Plan.exact([90], [10.2], 0.0, 3.4).exact_text(decimals=0)
    assert Plan.exact([90], [0.004], 0.0, 0.34).exact_text(decimals=2).endswith(
        "flights 0 m | final 0 m")
    with pytest.raises(ValueError):
        plan.exact_text(decimals=-1)


def test_titles_with_exact_plans_print_no_long_decimals(figures, tmp_path):
    """Fig. 3's step-vs-exact panels and ``show``/``run-plan --plot`` of an exact plan; the
    plans.csv column keeps the exact text.
    """
    from experiments import nav_fig3
    cfg = nav_fig3.Config()
    env, cells, _, routes, table = nav_fig3.plan_routes(cfg.angles, cfg.w1, cfg.w2)
    exact = nav_fig3.exact_routes(cells, table, cfg.angles, cfg.w1, cfg.w2)
    assert any(LONG_DECIMALS.search(t or "") for t in table["exact"])   # the CSV: exact
    nav_fig3.draw_step_vs_exact(nav_fig3.step_vs_exact_rows(env, cells, routes, exact, table,
                                                            cfg.angles), tmp_path / "s.png")
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        assert main(["plan", "studio", "--angles", "90,135", "--planner", "exact", "--start",
                     "670", "--goal", "603", "--json"]) == 0
    (tmp_path / "plan.json").write_text(buf.getvalue().splitlines()[0] + "\n")
    assert _quiet(["show", "studio", "--plan", str(tmp_path / "plan.json"), "--out",
                   str(tmp_path / "show.png")]) == 0
    assert _quiet(["run-plan", "studio", "--angles", "90,135", "--planner", "exact",
                   "--start", "670", "--goal", "603", "--quiet",
                   "--plot", str(tmp_path / "run.png")]) in (0, 4)
    titles = [ax.get_title() for fig in figures for ax in fig.axes]
    assert len(titles) >= 8
    for title in titles:
        assert not LONG_DECIMALS.search(title), title


# ------------------------------------------------------------------ 2. legends
def _twin_run(env_or_cells, start, goal, angles=(90, 135)):
    from bouncesim.robots import make_robot
    from bouncesim.runs.execute import execute
    from planners.navigation import Navigator
    cs = env_or_cells
    route = Navigator(cs, list(angles)).plan(start, goal)
    with make_robot("kinematic", cs.env) as bot:
        return route, execute(route.plan, bot, start=start, goal=goal, cells=cs)


@pytest.mark.parametrize("name", ["lab", "corridor"])
def test_map_legends_clear_the_map_and_its_axis_labels(name, figures, tmp_path):
    """draw_trace, plan_vs_executed and show: on lab and on a corridor whose map is only
    0.68 m high (a legend placed at a fraction of the axes' height would cover the tick
    labels there).
    """
    cs = CellSpace(envs.load(CORRIDOR) if name == "corridor" else envs.load("lab"))
    start, goal = (8, 0) if name == "lab" else (cs.P - 1 - cs.P // 2, 0)
    route, run = _twin_run(cs, start, goal)
    ax = plots.draw_trace(run, cs.env, goal=run.goal_pose)
    _legend_clear_of_map_and_axis(ax.figure)
    fig = plots.plan_vs_executed(cs.env, cs, route.path, run.trace, goal=run.goal_pose,
                                 title="plan and run")
    plots.save_figure(fig, tmp_path / "pve.png")
    run.trace.to_csv(tmp_path / "t.csv")
    if name == "lab":
        assert _quiet(["show", "lab", "--trace", str(tmp_path / "t.csv"), "--start",
                       str(start), "--goal", str(goal), "--out", str(tmp_path / "s.png")]) == 0
    for fig in [ax.figure, *figures]:
        _legend_clear_of_map_and_axis(fig)
    plt.close("all")


# ------------------------------------------------------------------ 3. Fig. 3 paths
def test_fig3_paths_show_both_runs_their_bumps_and_one_goal_pose(figures, tmp_path):
    """Two backends that run the plan exactly (here both the twin's noise-free run): each
    path's colour is on the written picture along the plan, bumps are drawn above the
    start and goal markers, and the goal star is the goal cell's centre, as in the
    step-vs-exact figure.
    """
    from experiments import nav_fig3
    env, cells, _, routes, table = nav_fig3.plan_routes((90.0, 135.0))
    executed = {}
    for route, (_, row) in zip(routes, table.iterrows()):
        tr = nav_fig3._replay(env, cells, route)[1]
        executed[(row["plan"], "pybullet")] = executed[(row["plan"], "kinematic")] = tr
    png = tmp_path / "paths.png"
    nav_fig3.draw(env, cells, routes, table, png, executed)
    fig = figures[-1]
    _legend_clear_of_map_and_axis(fig)
    # plan 1 drives 2.72 m along the bottom row: both colours show over that length
    px_per_m = fig.axes[0].bbox.width / np.ptp(fig.axes[0].get_xlim())
    for rgb in ((0x1f, 0x4e, 0x9c), (0xff, 0x7f, 0x0e)):          # PyBullet, twin
        assert _pixels_near(png, rgb) > 2 * 0.8 * 2.72 * px_per_m * 130 / fig.dpi
    for ax, (_, row) in zip(fig.axes, table.iterrows()):
        lines = {ln.get_label(): ln for ln in ax.lines}
        star = lines["goal (cell centre)"]
        assert np.allclose(star.get_xydata()[0], cells.pose(int(row["goal_z"]))[:2])
        for backend in ("pybullet", "kinematic"):
            bumps = lines[f"bumps ({backend})"]
            assert len(bumps.get_xdata()) == row["bumps"]
            assert bumps.get_zorder() > max(star.get_zorder(),
                                            lines["start (cell centre)"].get_zorder())
            assert lines[f"executed ({backend})"].get_zorder() > \
                lines["planned (cell centres)"].get_zorder()
        # the wide line underneath is the wider one: the narrow one on top leaves it visible
        assert lines["executed (pybullet)"].get_linewidth() > \
            2 * lines["executed (kinematic)"].get_linewidth()


# ------------------------------------------------------------------ 4. failed traces
def test_a_failed_trace_is_drawn_and_an_untold_outcome_is_not_invented(figures, tmp_path):
    import pandas as pd
    trace = tmp_path / "t.csv"
    assert _quiet(["run-plan", "lab", "--angles", "45,90,135", "--orientations", "8",
                   "--start", "1", "--goal", "40", "--noise", "gauss:10", "--seed", "3",
                   "--quiet", "--trace", str(trace)]) == 4          # this seed misses
    png = tmp_path / "fail.png"
    assert _quiet(["show", "lab", "--trace", str(trace), "--out", str(png)]) == 0
    ax = figures[-1].axes[0]
    assert "failure" in ax.get_title()
    # the path is on the picture: the executed colour (85 % over white) along its 2.4 m run
    px_per_m = ax.bbox.width / np.ptp(ax.get_xlim()) * 150 / figures[-1].dpi
    assert _pixels_near(png, (255, 146, 50)) > 2.0 * px_per_m
    # bumps at the end of the run sit above the end marker
    lines = {ln.get_label(): ln for ln in ax.lines}
    assert lines["bump"].get_zorder() > lines["end"].get_zorder()
    # the same trace without its outcome row (an older file): drawn, no outcome claimed
    df = pd.read_csv(trace)
    old = tmp_path / "old.csv"
    df[df["event"] != "outcome"].to_csv(old, index=False)
    blank = tmp_path / "blank.csv"
    df.assign(detail=df["detail"].where(df["event"] != "outcome", "")).to_csv(blank,
                                                                              index=False)
    for path in (old, blank):
        assert _quiet(["show", "lab", "--trace", str(path), "--out",
                       str(tmp_path / "o.png")]) == 0
        ax = figures[-1].axes[0]
        title = ax.get_title().replace("\n", " ")
        assert "failure" not in title and "success" not in title
        (line,) = [ln for ln in ax.lines if ln.get_label() == "executed"]
        assert len(line.get_xdata()) == int(np.isfinite(pd.read_csv(path)["x"]).sum())


# ------------------------------------------------------------------ 5. configuration ids
def _ids_are_readable(fig, cells) -> None:
    """Font at least READABLE_PT, no two ids overlapping, each id inside its own cell."""
    r = _renderer(fig)
    ax = fig.axes[0]
    texts = ax.texts
    assert len(texts) == cells.N
    boxes = np.array([t.get_window_extent(r).extents for t in texts])     # x0 y0 x1 y1
    assert min(t.get_fontsize() for t in texts) >= READABLE_PT
    order = np.argsort(boxes[:, 0])
    b = boxes[order]
    for i in range(len(b)):            # sweep: boxes that start before this one ends in x
        j = i + 1 + np.searchsorted(b[i + 1:, 0], b[i, 2])
        other = b[i + 1:j]
        assert not ((other[:, 1] < b[i, 3]) & (other[:, 3] > b[i, 1])).any(), \
            texts[order[i]].get_text()
    h = cells.h
    for t, (x0, y0, x1, y1) in zip(texts, boxes):
        p = int(t.get_text()) % cells.P
        cx, cy = cells.centres[p]
        (lx, ly), (hx, hy) = ax.transData.transform([(cx - h / 2, cy - h / 2),
                                                    (cx + h / 2, cy + h / 2)])
        assert lx <= x0 and x1 <= hx and ly <= y0 and y1 <= hy, t.get_text()


@pytest.mark.parametrize("name, k", [("lab", 8), ("lab", 4), ("lab", 6), ("fig1", 8),
                                     ("studio", 8),
                                     pytest.param("complex", 8, marks=pytest.mark.slow)])
def test_configuration_ids_are_readable(name, k, figures, tmp_path):
    assert _quiet(["show", name, "--orientations", str(k), "--ids", "configurations",
                   "--out", str(tmp_path / "ids.png")]) == 0
    cells = CellSpace(envs.load(name, orientations=k))
    _ids_are_readable(figures[-1], cells)


# ------------------------------------------------------------------ 6. recordings
def test_gif_frames_are_not_dithered_and_share_one_palette(tmp_path):
    """A horizontal ramp of 300 colours (more than a GIF holds) beside a flat floor and the
    overlay's colours: every column stays one colour (dithering would scatter two or more
    down it), the floor and the overlay keep their exact colours in every frame.
    """
    from PIL import Image

    from bouncesim.robots.pybullet.video import write_video
    ramp = np.zeros((40, 300, 3), dtype=np.uint8)
    ramp[..., 0] = np.linspace(0, 255, 300).astype(np.uint8)[None, :]
    ramp[..., 1] = np.linspace(255, 0, 300).astype(np.uint8)[None, :]
    ramp[..., 2] = 90
    frames = []
    for i in range(4):
        f = np.full((100, 300, 3), (222, 222, 210), dtype=np.uint8)      # the floor
        f[:40] = ramp
        f[60:62, 10:10 + 60 * (i + 1)] = (255, 127, 14)                   # path so far
        f[80:84, 200:204] = (44, 160, 44)                                 # goal
        frames.append(f)
    path = tmp_path / "x.gif"
    write_video(path, frames, 0.1)
    gif = Image.open(path)
    assert gif.n_frames == 4
    for i in range(4):
        gif.seek(i)
        img = np.asarray(gif.convert("RGB")).astype(int)
        columns = img[:40]
        assert (columns == columns[:1]).all()                 # no dithering down a column
        assert np.abs(columns[0] - ramp[0].astype(int)).max() <= 24
        floor = img[45:58].reshape(-1, 3)
        assert {tuple(c) for c in floor} == {(222, 222, 210)}
        assert (img[60:62, 10:10 + 60 * (i + 1)] == (255, 127, 14)).all()
        assert (img[80:84, 200:204] == (44, 160, 44)).all()


@pytest.mark.slow
@pytest.mark.physics
def test_pybullet_floor_renders_one_colour(tmp_path):
    """The floor of a recorded frame, away from walls, obstacles and the robot, is one
    colour: the ground plane's checker does not show through it (coplanar faces speckle).
    """
    pytest.importorskip("pybullet")
    import shapely
    from shapely.geometry import Point

    from bouncesim.robots import make_robot
    env = envs.load("lab")
    with make_robot("pybullet", env, record=tmp_path / "r.gif") as bot:
        bot.place(0.51, 0.17, 0.0)
        bot.wait(0.2)
        frame = bot.frames[-1]
        cam = bot.recorder.camera
        pose = bot.true_pose()
    H, W, _ = frame.shape
    cols, rows = np.meshgrid(np.arange(W) + 0.5, np.arange(H) + 0.5)
    s = cam.pixels_per_metre
    x, y = cam.cx + (cols - W / 2) / s, cam.cy - (rows - H / 2) / s
    free = env.boundary.buffer(-0.12)
    for ob in env.obstacles:
        free = free.difference(ob.buffer(0.12))
    free = free.difference(Point(pose[0], pose[1]).buffer(0.35))
    inside = shapely.contains_xy(free, x, y)
    assert inside.sum() > 0.4 * H * W
    colours = np.unique(frame[inside].reshape(-1, 3), axis=0)
    assert len(colours) == 1, colours[:5]


# ------------------------------------------------------------------ 7. vector figures
def test_every_cli_figure_file_option_takes_pdf_and_svg():
    """Every output option declared with figure suffixes (show --out, run-plan --plot, ...)
    takes .pdf and .svg beside .png; every --figures option offers pdf and svg.
    """
    import argparse

    from bouncesim.cli import build_parser
    parser = build_parser()
    subs = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    figure_outputs = figures_args = 0
    for name, sub in subs.choices.items():
        for _dest, flag, _, _, suffixes in sub.get_default("_outputs") or ():
            if ".png" in suffixes:
                figure_outputs += 1
                assert {".svg", ".pdf"} <= set(suffixes), (name, flag)
        for action in sub._actions:
            if "--figures" in action.option_strings:
                figures_args += 1
                assert {"png", "svg", "pdf"} <= set(action.choices), name
    assert figure_outputs >= 2 and figures_args >= 2


def test_show_writes_a_pdf_with_configuration_ids(tmp_path):
    out = tmp_path / "ids.pdf"
    assert _quiet(["show", "lab", "--ids", "configurations", "--out", str(out)]) == 0
    assert out.read_bytes().startswith(b"%PDF")
