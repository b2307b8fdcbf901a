"""``bouncesim show`` and ``run-plan --plot``: files written, and what is drawn is what the
input files say (ids per cell, start/goal in the legend, the trace's and the heatmap's data);
bad inputs are one sentence with exit status 2. Also the figure fixes in plots.py and
coverage_plots.py (legend entries, titles inside their panel, a uniform target's scale).
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import xml.etree.ElementTree as ET

import matplotlib

matplotlib.use("Agg")

import matplotlib.image as mpimg  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

import bouncesim.plots as plots  # noqa: E402
import envs  # noqa: E402
from bouncesim.cli import main  # noqa: E402
from planners.cells import CellSpace  # noqa: E402

LAB = CellSpace(envs.load("lab"))


def _rows(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    """plan.json, plan.txt, run.csv and a coverage folder, written by the other commands."""
    d = tmp_path_factory.mktemp("show_inputs")
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        assert main(["plan", "lab", "--angles", "45,90,135", "--start", "339", "--goal", "25",
                     "--json"]) == 0
        assert main(["run-plan", "lab", "--angles", "45,90,135", "--start", "339", "--goal",
                     "25", "--noise", "gauss:2", "--seed", "2",
                     "--trace", str(d / "run.csv")]) in (0, 4)
        assert main(["coverage", "lab", "--angles", "90,135", "--eps", "45", "--r", "0.8",
                     "--no-plots", "--out", str(d / "cov")]) == 0
        assert main(["coverage", "complex", "--angles", "90,135", "--eps", "45", "--r",
                     "0.8", "--no-plots", "--out", str(d / "cov_complex")]) == 0
    plan_json = buf.getvalue().splitlines()[0]
    (d / "plan.json").write_text(plan_json + "\n")
    (d / "plan.txt").write_text(json.loads(plan_json)["plan_text"] + "\n")
    (d / "noplan.json").write_text(json.dumps({"start": 0, "goal": 1, "plan": None}) + "\n")
    (d / "bad.csv").write_text("a,b\n1,2\n")
    return d


def _show(args, tmp_path, name="fig.png"):
    out = tmp_path / name
    assert main(["show", *args, "--out", str(out)]) == 0
    return out


def _check_file(out):
    if out.suffix == ".png":
        img = mpimg.imread(out)
        assert img.ndim == 3 and img.shape[0] > 300 and img.shape[1] > 600
    else:
        root = ET.parse(out).getroot()
        assert root.tag.endswith("svg")
        assert len(list(root.iter())) > 100        # paths, text: not an empty page


COMBOS = {
    "map": ["lab"],
    "ids": ["lab", "--ids"],
    "start_goal": ["lab", "--start", "8", "--goal", "0,0.17,0"],
    "plan_json": ["lab", "--plan", "{d}/plan.json"],
    "plan_text": ["lab", "--plan", "{d}/plan.txt", "--start", "339"],
    "plan_trace": ["lab", "--ids", "--plan", "{d}/plan.json", "--trace", "{d}/run.csv"],
    "trace": ["lab", "--trace", "{d}/run.csv"],
    "coverage": ["lab", "--coverage", "{d}/cov", "--series", "135"],
    "everything": ["lab", "--ids", "--coverage", "{d}/cov", "--plan", "{d}/plan.json",
                   "--trace", "{d}/run.csv"],
    "complex": ["complex", "--start", "0", "--goal", "4.6,4.6,90"],
    "complex_coverage": ["complex", "--coverage", "{d}/cov_complex"],
}


@pytest.mark.parametrize("name", list(COMBOS))
def test_each_combination_writes_png_and_svg(name, inputs, tmp_path):
    args = [a.format(d=inputs) for a in COMBOS[name]]
    for suffix in (".png", ".svg"):
        _check_file(_show(args, tmp_path, "fig" + suffix))
    plt.close("all")


def test_position_ids_one_per_cell_in_its_corner(tmp_path, figures):
    _show(["lab", "--ids"], tmp_path)
    ax = figures[0].axes[0]
    ids = {int(t.get_text()): t.get_position() for t in ax.texts}
    assert sorted(ids) == list(range(LAB.P))                 # one text per cell, P = 48
    # lab: 9 columns of 0.34 m from the origin; cell 0 is bottom left, cell 8 bottom right;
    # an id sits in the top-left quarter of its cell
    assert 0 < ids[0][0] < 0.17 and 0.17 < ids[0][1] < 0.34
    assert 8 * 0.34 < ids[8][0] < 8.5 * 0.34 and 0.17 < ids[8][1] < 0.34
    for p, xy in ids.items():
        assert LAB.cell_of_point(np.array([xy]))[0] == p


def test_configuration_ids_sit_in_their_cell_towards_their_heading(tmp_path, figures):
    _show(["lab", "--ids", "configurations"], tmp_path)
    texts = figures[0].axes[0].texts
    assert len(texts) == LAB.N == 8 * 48
    for t in texts:
        z = int(t.get_text())
        p, k = z % LAB.P, z // LAB.P
        x, y = t.get_position()
        assert LAB.cell_of_point(np.array([[x, y]]))[0] == p
        cx, cy = LAB.centres[p]
        bearing = np.degrees(np.arctan2(y - cy, x - cx)) % 360
        assert bearing == pytest.approx(45.0 * k, abs=1e-6) or abs(bearing - 360) < 1e-6


def test_legend_holds_start_and_goal_at_their_poses(tmp_path, figures):
    # "2.55,0.17,90" is configuration 103 (plan's docstring); z = 8 is cell (8, 0) heading 0°
    _show(["lab", "--start", "2.55,0.17,90", "--goal", "8"], tmp_path)
    ax = figures[0].axes[0]
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels == ["start (z = 103)", "goal (z = 8)"]
    lines = {ln.get_label(): ln for ln in ax.lines}
    assert np.r_[lines["start (z = 103)"].get_data()].ravel() == pytest.approx([2.55, 0.17])
    assert np.r_[lines["goal (z = 8)"].get_data()].ravel() == pytest.approx([2.89, 0.17])


def test_planned_path_is_the_planners_path(inputs, tmp_path, figures):
    plan = json.loads((inputs / "plan.json").read_text())
    expected = np.array([LAB.pose(z)[:2] for z in plan["path"]])   # the planner's own path
    _show(["lab", "--plan", str(inputs / "plan.json")], tmp_path)
    _show(["lab", "--plan", str(inputs / "plan.txt"), "--start", "339"], tmp_path)
    for fig in figures:
        ax = fig.axes[0]
        line = next(ln for ln in ax.lines if ln.get_label() == "planned (cell centres)")
        assert np.column_stack(line.get_data()) == pytest.approx(expected)
    labels = [t.get_text() for t in figures[0].axes[0].get_legend().get_texts()]
    assert "start (z = 339)" in labels and "goal (z = 25)" in labels
    labels = [t.get_text() for t in figures[1].axes[0].get_legend().get_texts()]
    assert "plan end (z = 25)" in labels


def test_trace_coordinates_are_the_csvs(inputs, tmp_path, figures):
    _show(["lab", "--trace", str(inputs / "run.csv")], tmp_path)
    rows = _rows(inputs / "run.csv")
    ax = figures[0].axes[0]
    line = next(ln for ln in ax.lines if ln.get_label().startswith("executed"))
    assert list(line.get_xdata()) == pytest.approx([float(r["x"]) for r in rows])
    assert list(line.get_ydata()) == pytest.approx([float(r["y"]) for r in rows])
    bumps = next(ln for ln in ax.lines if ln.get_label() == "bump")
    assert len(bumps.get_xdata()) == sum(r["event"] == "bump" for r in rows)
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert "start" in labels and "end" in labels        # from the trace: no --start/--goal


@pytest.mark.parametrize("series", ["mix", "90", "target"])
def test_heatmap_is_coverage_csv_q(inputs, tmp_path, figures, series):
    _show(["lab", "--coverage", str(inputs / "cov"), "--series", series], tmp_path)
    img = figures[0].axes[0].images[0]
    grid = np.ma.filled(img.get_array().astype(float), np.nan)
    expected = np.full((6, 9), np.nan)            # lab: 6 rows x 9 columns of cells
    for r in _rows(inputs / "cov" / "coverage.csv"):
        if r["angle"] == series:
            expected[int(r["j"]), int(r["i"])] = float(r["q"])
    np.testing.assert_array_equal(grid, expected)
    assert img.colorbar is not None and "probability" in img.colorbar.ax.get_ylabel()


BAD = {
    "suffix": (["lab"], "x.jpg", "--out must end in .png, .svg or .pdf"),
    "folder": (["lab"], "dir.png", "is a folder"),
    "no_plan_file": (["lab", "--plan", "{d}/nope.json"], "f.png", "no plan file"),
    "no_plan": (["lab", "--plan", "{d}/noplan.json"], "f.png", "holds no plan"),
    "text_needs_start": (["lab", "--plan", "{d}/plan.txt"], "f.png", "needs --start"),
    "json_and_start": (["lab", "--plan", "{d}/plan.json", "--start", "3"], "f.png",
                       "drop --start"),
    "plan_misfits": (["lab", "--plan", "{d}/plan.txt", "--start", "0"], "f.png",
                     "does not fit the map"),
    "plan_other_map": (["complex", "--plan", "{d}/plan.json"], "f.png", "does not fit"),
    "bad_trace": (["lab", "--trace", "{d}/bad.csv"], "f.png", "needs the columns"),
    "no_coverage": (["lab", "--coverage", "{d}"], "f.png", "no coverage.csv"),
    "other_map": (["lab", "--coverage", "{d}/cov_complex"], "f.png", "another map"),
    "no_series": (["lab", "--coverage", "{d}/cov", "--series", "45"], "f.png",
                  "no series '45'"),
    "series_alone": (["lab", "--series", "90"], "f.png", "--series needs --coverage"),
    "start_range": (["lab", "--start", "999"], "f.png", "out of range"),
    "start_wall": (["lab", "--start", "1.5,1.2,0"], "f.png", "not in a free cell"),
}


@pytest.mark.parametrize("name", list(BAD))
def test_bad_input_is_one_sentence_exit_2(name, inputs, tmp_path, capsys, monkeypatch):
    args, out, message = BAD[name]
    monkeypatch.chdir(tmp_path)
    (tmp_path / "dir.png").mkdir()
    rc = main(["show", *[a.format(d=inputs) for a in args], "--out", out])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2
    assert len(err) == 1 and err[0].startswith("bouncesim: error:") and message in err[0]
    assert not (tmp_path / "f.png").exists()


def test_run_plan_plot_draws_plan_and_run(tmp_path, capsys, figures):
    out, trace = tmp_path / "run.svg", tmp_path / "run.csv"
    rc = main(["run-plan", "lab", "--angles", "90,135", "--start", "8", "--goal", "0",
               "--trace", str(trace), "--plot", str(out)])
    assert rc == 0
    _check_file(out)
    ax = figures[0].axes[0]
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    for name in ("planned (cell centres)", "executed", "start", "goal"):
        assert name in labels
    rows = _rows(trace)
    line = next(ln for ln in ax.lines if ln.get_label().startswith("executed"))
    assert list(line.get_xdata()) == pytest.approx([float(r["x"]) for r in rows])
    planned = next(ln for ln in ax.lines if ln.get_label() == "planned (cell centres)")
    # 8 -> 0 on lab: along the bottom row from x = 2.89 to x = 0.17 (README's example)
    assert planned.get_xdata()[0] == pytest.approx(2.89)
    assert planned.get_xdata()[-1] == pytest.approx(0.17)
    assert set(np.round(planned.get_ydata(), 6)) == {0.17}


def test_exact_plans_are_drawn_through_their_poses(tmp_path, capsys, figures):
    # an exact plan's JSON holds the bump poses; show and run-plan --plot draw those, not the
    # step model's cell centres (on studio the step model's replay does not even fit the map)
    query = ["studio", "--angles", "45,90,135", "--start", "180", "--goal", "448",
             "--planner", "exact"]
    assert main(["plan", *query, "--json"]) == 0
    plan = json.loads(capsys.readouterr().out.splitlines()[0])
    poses = np.array(plan["poses"])
    (tmp_path / "plan.json").write_text(json.dumps(plan) + "\n")
    _show(["studio", "--plan", str(tmp_path / "plan.json")], tmp_path)
    assert main(["run-plan", *query, "--plot", str(tmp_path / "run.png"), "--quiet"]) == 0
    for fig in figures:
        line = next(ln for ln in fig.axes[0].lines if ln.get_label() == "planned (exact poses)")
        assert np.column_stack(line.get_data()) == pytest.approx(poses[:, :2])
    # the first pose is the start configuration's cell centre, the bumps lie on the walls
    studio = CellSpace(envs.load("studio"))
    assert poses[0] == pytest.approx(studio.pose(180))
    walls = studio.env.free_space.boundary
    from shapely.geometry import Point
    for x, y, _ in poses[1:-1]:
        assert walls.distance(Point(x, y)) == pytest.approx(studio.env.robot_radius, abs=0.01)
    moved = dict(plan, poses=(poses + [5.0, 0, 0]).tolist())
    (tmp_path / "moved.json").write_text(json.dumps(moved) + "\n")
    assert main(["show", "studio", "--plan", str(tmp_path / "moved.json"),
                 "--out", str(tmp_path / "x.png")]) == 2
    assert "another map" in capsys.readouterr().err


def test_reliable_and_feedback_plans_are_drawn_through_their_poses(tmp_path, capsys, figures):
    # every plan that runs by its exact flights is drawn through its poses: the reliable
    # planner's plan of a pair (it used to be replayed on the step model and refused: "does
    # not fit the map") and the feedback planner's plan from the start
    for planner, extra in (("reliable", ["--noise", "gauss:2", "--particles", "50"]),
                           ("feedback", [])):
        query = ["studio", "--angles", "45,90,135", "--start", "180", "--goal", "448",
                 "--planner", planner, *extra, "--json"]
        assert main(["plan", *query]) == 0
        plan = json.loads(capsys.readouterr().out.splitlines()[0])
        assert plan["planner"] == planner and plan["exact_flights"] is True
        (tmp_path / f"{planner}.json").write_text(json.dumps(plan) + "\n")
        figures.clear()
        _show(["studio", "--plan", str(tmp_path / f"{planner}.json")], tmp_path)
        capsys.readouterr()
        line = next(ln for ln in figures[0].axes[0].lines
                    if ln.get_label() == "planned (exact poses)")
        assert np.column_stack(line.get_data()) == pytest.approx(np.array(plan["poses"])[:, :2])


def test_run_plan_plot_refuses_a_bad_name_before_running(tmp_path, capsys):
    rc = main(["run-plan", "lab", "--angles", "90,135", "--start", "8", "--goal", "0",
               "--plot", str(tmp_path / "run.gif")])
    captured = capsys.readouterr()
    assert rc == 2 and "--plot must end in .png, .svg or .pdf" in captured.err
    assert captured.out == ""                                  # nothing was run


def test_long_titles_stay_inside_their_panel(tmp_path):
    from bouncesim.coverage_plots import heatmap
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.6))
    q = np.full(LAB.P, 1 / LAB.P)
    for ax in axes:
        heatmap(ax, LAB, q, title="mix α, 1000-step epochs: predicted (event model, "
                "3 404 256 steps)")
    plots.save_figure(fig, tmp_path / "t.png")
    renderer = fig._get_renderer()          # the layout and extents of the saved drawing
    for ax in axes:
        box, title = ax.get_window_extent(renderer), ax.title.get_window_extent(renderer)
        assert box.x0 - 1 <= title.x0 and title.x1 <= box.x1 + 1
        assert title.y1 <= fig.bbox.y1                              # not clipped at the top


def test_uniform_target_gets_its_own_scale(tmp_path, figures):
    from bouncesim.coverage_plots import save_mix_vs_target
    rng = np.random.default_rng(0)
    mixed = rng.random(LAB.P)
    mixed /= mixed.sum()
    b = np.full(LAB.P, 1 / LAB.P)
    save_mix_vs_target(tmp_path / "m.png", LAB, mixed, b)
    mix_im, target_im = figures[0].axes[0].images[0], figures[0].axes[1].images[0]
    assert mix_im.get_clim() == pytest.approx((0, mixed.max()))
    assert target_im.get_clim() == pytest.approx((0, 2 / LAB.P))   # b in mid-scale
    assert "1/P = 0.0208" in figures[0].axes[1].get_title()       # 1/48
    marks = [ln for ln in mix_im.colorbar.ax.lines]
    assert marks and marks[0].get_ydata()[0] == pytest.approx(1 / LAB.P)
    # a target that varies shares the mix's scale
    save_mix_vs_target(tmp_path / "v.png", LAB, mixed, mixed[::-1])
    assert figures[1].axes[1].images[0].get_clim() == figures[1].axes[0].images[0].get_clim()


def test_route_legend_has_start_and_goal():
    fig, ax = plt.subplots()
    plots.draw_route(ax, LAB, [8, 104, 200, 199], label="planned")
    ax.legend()
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["planned", "start", "goal"]
    plt.close(fig)


# ----------------------------------------------------------------------------- recordings
def test_recording_captions_follow_the_plan_segments():
    from bouncesim.robots.pybullet.video import Recorder
    from bouncesim.runs.trace import Trace
    from planners.plan import Plan
    tr = Trace()                     # a run of "135° 135° 0": bump, turn, bump, turn, 1 step
    tr.add(0.0, (2.55, 0.17, 90.0), "start")
    tr.add(0.0, (2.55, 0.17, 90.0), "bump", "left+right")
    tr.add(1.8, (2.55, 0.17, 225.0), "turn", "135")
    tr.add(1.8, (2.55, 0.17, 225.0), "bump", "left")
    tr.add(3.6, (2.55, 0.17, 0.0), "turn", "135")
    tr.add(5.3, (2.89, 0.17, 0.0), "stop", "plan finished")
    rec = Recorder("x.gif", 0.1, 640, LAB.env.bounds, 0.3)
    rec.times = [10.5, 12.0, 14.2, 15.3]                  # robot clock; the run began at 10
    rec.annotate_plan(Plan.parse("135° 135° 0"), tr, goal=(2.89, 0.17, 0.0), t0=10.0)
    assert [rec.caption(i) for i in range(4)] == [
        "t = 0.5 s   segment 1/3: 135°", "t = 2.0 s   segment 2/3: 135°",
        "t = 4.2 s   segment 3/3: 0", "t = 5.3 s   segment 3/3: 0"]
    # the camera maps the room's corners to the frame, 0.15 m in from each side
    cam = rec.camera
    x0, y0, x1, y1 = LAB.env.bounds
    (c0, c1), (r0, r1) = cam.to_pixels([x0, x1], [y0, y1])
    s = cam.pixels_per_metre
    assert c0 == pytest.approx(cam.width - c1) and r1 == pytest.approx(cam.height - r0)
    assert (c1 - c0) / s == pytest.approx(x1 - x0) and (r0 - r1) / s == pytest.approx(y1 - y0)


@pytest.mark.slow
@pytest.mark.physics
def test_run_plan_record_gif_has_size_and_a_live_overlay(tmp_path, capsys):
    pytest.importorskip("pybullet")
    import imageio.v3 as iio
    out = tmp_path / "run.gif"
    rc = main(["run-plan", "lab", "--angles", "90,135", "--start", "103", "--goal", "8",
               "--robot", "pybullet", "--record", str(out)])
    assert rc == 0
    frames = iio.imread(out, index=None)
    n, H, W, _ = frames.shape
    assert W == 640 and H > 640 * 2.34 / 3.36           # the room's aspect plus a caption
    assert n > 30                                        # a ~7 s run at 10 frames per second
    map_h = int(round(640 * 2.34 / 3.36)) // 2 * 2
    strip = frames[:, map_h:].astype(int)
    # the caption (clock, segment) changes while the run goes on
    changed = [np.abs(strip[i] - strip[0]).max() > 0 for i in (n // 3, 2 * n // 3, n - 1)]
    assert all(changed)
    assert (frames[:, map_h:] < 60).all(axis=-1).any()   # dark caption text on white

    def orange(img):
        r, g, b = (img[..., c].astype(int) for c in range(3))
        return ((r > 200) & (abs(g - 127) < 40) & (b < 80)).sum()
    # the path so far: no orange line in the first frame, some in the last
    assert orange(frames[n - 1, :map_h]) > orange(frames[0, :map_h]) + 20



# ---------------------------------------------------------------- figures fit for a paper
def _overlaps(fig, a, b) -> bool:
    """Whether two artists' drawn boxes overlap (matplotlib's tight bounding boxes; a saved
    and closed figure is drawn again on a canvas of its own).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    canvas = fig.canvas if hasattr(fig.canvas, "get_renderer") else FigureCanvasAgg(fig)
    canvas.draw()
    r = canvas.get_renderer()
    return a.get_window_extent(r).overlaps(b.get_window_extent(r))


def test_fig3_panels_keep_legends_off_the_map_round_titles_and_share_the_goal(figures,
                                                                              tmp_path):
    """The step-vs-exact figure: every legend lies outside its map, no title prints a
    length to more than two decimals (the exact text itself keeps 1e-9 m), and the goal
    star of a query sits on the same point in its step and exact panels.
    """
    import re

    from experiments import nav_fig3
    cfg = nav_fig3.Config()
    env, cells, _, routes, table = nav_fig3.plan_routes(cfg.angles, cfg.w1, cfg.w2)
    exact = nav_fig3.exact_routes(cells, table, cfg.angles, cfg.w1, cfg.w2)
    rows = nav_fig3.step_vs_exact_rows(env, cells, routes, exact, table, cfg.angles)
    nav_fig3.draw_step_vs_exact(rows, tmp_path / "f.png")
    fig = figures[-1]
    axes = fig.axes
    assert len(axes) == 2 * len(rows)
    for ax in axes:
        legend = ax.get_legend()
        assert legend is not None and not _overlaps(fig, legend, ax.patch)
        assert not re.search(r"\d\.\d{5,}", ax.get_title()), ax.get_title()
    assert "2.719999999" in table["exact"].iloc[0]           # the CSV keeps the exact text

    def star(ax):
        (line,) = [ln for ln in ax.lines if ln.get_label() == "goal (cell centre)"]
        return np.array(line.get_xydata())[0]
    for left, right in zip(axes[::2], axes[1::2]):
        assert np.allclose(star(left), star(right))


def test_a_trace_legend_sits_below_the_map(figures, tmp_path):
    from bouncesim.robots import make_robot
    from bouncesim.runs.execute import execute
    from planners.navigation import Navigator
    cs = CellSpace(envs.load("lab"))
    route = Navigator(cs, [90, 135]).plan(8, 0)
    with make_robot("kinematic", cs.env) as bot:
        run = execute(route.plan, bot, start=8, goal=0, cells=cs)
    ax = plots.draw_trace(run, cs.env, goal=run.goal_pose)
    assert not _overlaps(ax.figure, ax.get_legend(), ax.patch)
    plt.close(ax.figure)


def test_show_trace_of_a_failed_run_draws_it_and_says_failure(figures, tmp_path, capsys):
    """A run that misses its goal: run-plan's trace ends with its outcome, and show draws
    the path and says "failure: ..." in the title and "executed (failure)" in the legend.
    """
    trace = tmp_path / "t.csv"
    argv = ["run-plan", "lab", "--angles", "45,90,135", "--orientations", "8", "--start",
            "1", "--goal", "40", "--noise", "gauss:10", "--seed", "3", "--quiet",
            "--trace", str(trace)]
    assert main(argv) == 4                                   # this seed misses the goal
    _show(["lab", "--trace", str(trace)], tmp_path)
    ax = figures[-1].axes[0]
    assert "failure: ended" in ax.get_title().replace("\n", " ")
    labels = [ln.get_label() for ln in ax.lines]
    (path,) = [ln for ln in ax.lines if ln.get_label() == "executed (failure)"]
    assert len(path.get_xdata()) >= 2 and "executed (failure)" in labels
    # a run that reaches its goal says so
    ok = tmp_path / "ok.csv"
    assert main(["run-plan", "lab", "--angles", "90,135", "--start", "8", "--goal", "0",
                 "--quiet", "--trace", str(ok)]) == 0
    _show(["lab", "--trace", str(ok)], tmp_path, "ok.png")
    assert "success: reached the goal" in figures[-1].axes[0].get_title().replace("\n", " ")


def test_configuration_ids_beyond_k8_fall_back_to_position_ids(figures, tmp_path, capsys):
    _show(["lab", "--orientations", "16", "--ids", "configurations"], tmp_path)
    assert "readable up to K = 8" in capsys.readouterr().err
    ax = figures[-1].axes[0]
    ids = {t.get_text() for t in ax.texts}
    assert ids == {str(p) for p in range(48)}                # P = 48 position ids
    assert "z = k·48 + p" in ax.get_title().replace("\n", " ")
    _show(["lab", "--ids", "configurations"], tmp_path, "k8.png")
    assert len(figures[-1].axes[0].texts) == 8 * 48


@pytest.mark.parametrize("argv, name", [
    (["allpairs", "lab", "--angles", "90,135", "--figures", "pdf", "--out", "{d}"],
     "angles_used.pdf"),
    (["coverage", "lab", "--angles", "90,135", "--orientations", "8", "--eps", "45",
      "--figures", "svg", "--out", "{d}"], "heatmap_mix_vs_target.svg"),
    (["run-plan", "lab", "--angles", "90,135", "--start", "8", "--goal", "0", "--quiet",
      "--plot", "{d}/run.pdf"], "run.pdf"),
    (["show", "lab", "--out", "{d}/map.pdf"], "map.pdf"),
], ids=["allpairs", "coverage", "run-plan", "show"])
def test_every_figure_can_be_vector_graphics(argv, name, tmp_path, capsys):
    assert main([a.format(d=tmp_path) for a in argv]) == 0
    head = (tmp_path / name).read_bytes()[:200]
    assert head.startswith(b"%PDF") if name.endswith(".pdf") else b"<svg" in head or \
        b"<?xml" in head
