"""The command line never surprises: map warnings that teach (envs.diagnostics), output paths
checked before any work, memory refused up front, --pairs rows named, --version, progress
lines on stderr (--quiet), and coverage columns labelled by model.

Every map is hand-built on the 0.34 m grid (tests.conftest.room) so the expected warnings
follow from the geometry on paper.
"""

from __future__ import annotations

import json
import subprocess
import sys
from importlib import metadata
from pathlib import Path

import numpy as np
import pytest

import envs
from bouncesim.cli import main
from envs import Environment
from envs.diagnostics import CHECKS, PASSAGE_SLACK, diagnose, narrow_passages, off_grid_edges
from planners import resources
from planners.cells import CellSpace
from planners.coverage import TurnNoise, model_for
from planners.plan import Plan

from .conftest import room

H = 0.34                                     # cell size = robot diameter (r = 0.17)


def two_rooms(gap_cells: int):
    """6 x 6 cells split by a one-cell wall (column 2) that leaves a gap of ``gap_cells``
    cells at the top: 1 gap cell = a passage exactly one robot wide.
    """
    return room(6, 6, [(2, 0, 3, 6 - gap_cells)], name=f"gap{gap_cells}")


def wall_gap(width: float) -> Environment:
    """A 2.04 m square with a wall at x = 0.85 to 1.19 m leaving a gap of ``width`` [m] at
    the top: the passage's middle is at x = 1.02 m.
    """
    return Environment.from_dict({
        "boundary": [[0, 0], [2.04, 0], [2.04, 2.04], [0, 2.04]],
        "obstacles": [[[0.85, 0], [1.19, 0], [1.19, 2.04 - width], [0.85, 2.04 - width]]],
        "robot_radius": 0.17, "discretization": {"cell_size": H, "orientations": 8}})


@pytest.fixture
def env_file(tmp_path):
    def write(env: Environment, name: str = "map") -> str:
        path = tmp_path / f"{name}.json"
        path.write_text(json.dumps(env.to_dict()))
        return str(path)
    return write


def run(argv, capsys):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def warnings_in(err: str) -> list[str]:
    return [ln for ln in err.splitlines() if ln.startswith("bouncesim: warning: ")]


def without_warnings(err: str) -> str:
    """The stderr text without the map warnings (lab has one: its robot-wide bottom corridor)."""
    return "".join(ln + "\n" for ln in err.splitlines() if ln not in warnings_in(err))


# ============================================================================ map diagnostics
def test_a_clean_map_has_no_warning(env_file, capsys):
    env = two_rooms(2)                       # a gap two robots wide, every wall on the grid
    assert diagnose(env) == ()
    code, out, err = run(["info", env_file(env), "--json"], capsys)
    assert code == 0 and err == ""
    assert json.loads(out)["warnings"] == []


def test_off_grid_walls_are_counted_edge_by_edge():
    # 2.00 m wide: the right wall at x = 2.00 is off the 0.34 m grid, and so are the ends
    # of the bottom and top walls there: 3 of the 4 edges (the left wall is on the grid)
    env = Environment.from_dict({"boundary": [[0, 0], [2.0, 0], [2.0, 2.04], [0, 2.04]],
                                 "robot_radius": 0.17,
                                 "discretization": {"cell_size": H, "orientations": 8}})
    assert len(off_grid_edges(env)) == 3
    (w,) = [w for w in diagnose(env) if w.code == "off-grid-walls"]
    assert "3 of 4 wall edges" in w.message and "cell centres" in w.message
    # a triangle with every vertex on a grid point: only its slanted edge is off the grid
    tri = Environment.from_dict({
        "boundary": [[0, 0], [2.04, 0], [2.04, 2.04], [0, 2.04]],
        "obstacles": [[[0.68, 0.68], [1.36, 0.68], [0.68, 1.36]]],
        "robot_radius": 0.17, "discretization": {"cell_size": H, "orientations": 8}})
    (edge,) = off_grid_edges(tri)
    assert sorted(map(tuple, np.round(edge, 9))) == [(0.68, 1.36), (1.36, 0.68)]


@pytest.mark.parametrize("cell, fires", [(0.17, True), (0.3399, True), (0.34, False),
                                         (0.51, False)])
def test_cell_size_below_the_robot_diameter(cell, fires):
    env = room(6, 6).with_discretization(cell_size=cell)
    codes = [w.code for w in diagnose(env, checks=("cell-below-diameter",))]
    assert codes == (["cell-below-diameter"] if fires else [])


@pytest.mark.parametrize("width, narrow", [(0.30, True), (0.34, True),
                                           (0.34 * (1 + PASSAGE_SLACK) - 0.002, True),
                                           (0.34 * (1 + PASSAGE_SLACK) + 0.002, False),
                                           (0.68, False)])
def test_a_passage_no_wider_than_the_robot(width, narrow):
    mids = narrow_passages(wall_gap(width))
    if not narrow:
        assert mids == ()
        return
    (x, y), = mids                           # one passage, in the gap above the wall
    assert x == pytest.approx(1.02, abs=1e-3)
    assert 2.04 - width - 0.17 <= y <= 2.04


@pytest.mark.parametrize("width, narrow", [(0.30, False), (0.34, True), (0.40, False)])
def test_a_dead_end_counts_when_the_robot_just_fits(width, narrow):
    # a notch of the given width, 1.02 m deep, below a 2.04 x 0.68 m open strip: narrower
    # than the robot it holds no free cell centre (nothing is sent there); exactly as wide,
    # the robot fits with no clearance; wider than 2r (1 + 5 %), it is an ordinary room
    x0 = 1.02 - width / 2
    env = Environment.from_dict({
        "boundary": [[0, 0], [2.04, 0], [2.04, 1.7], [0, 1.7]],
        "obstacles": [[[0, 0], [x0, 0], [x0, 1.02], [0, 1.02]],
                      [[x0 + width, 0], [2.04, 0], [2.04, 1.02], [x0 + width, 1.02]]],
        "robot_radius": 0.17, "discretization": {"cell_size": H, "orientations": 8}})
    mids = narrow_passages(env)
    assert len(mids) == int(narrow)
    if narrow:
        (x, y), = mids                       # in the notch
        assert x == pytest.approx(1.02, abs=1e-3) and 0 <= y <= 1.02 + 0.17


def test_corners_alone_are_not_narrow():
    assert narrow_passages(room(6, 6)) == ()     # four corners the disk cannot reach


def test_warnings_print_once_on_stderr_and_info_lists_them(env_file, capsys):
    path = env_file(two_rooms(1))            # a gap exactly one robot wide
    code, out, err = run(["plan", path, "--angles", "90", "--start", "0", "--goal", "1",
                          "--json"], capsys)
    assert code in (0, 3)
    (line,) = warnings_in(err)
    assert "no wider than the robot" in line
    json.loads(out.splitlines()[0])          # stdout stays machine-readable
    code, out, err = run(["info", path, "--json"], capsys)
    info = json.loads(out)
    assert [w["code"] for w in info["warnings"]] == ["narrow-passage"]
    x, y = info["warnings"][0]["where"][0]   # in the gap: column 2, top row
    assert 2 * H <= x <= 3 * H and y >= 5 * H - 0.17
    assert err == ""                         # info lists them instead of warning twice
    assert set(CHECKS) >= {w["code"] for w in info["warnings"]}


def test_a_user_error_is_one_line_even_on_a_map_with_warnings(env_file, capsys):
    path = env_file(two_rooms(1))
    code, out, err = run(["plan", path, "--angles", "100", "--start", "0", "--goal", "1"],
                         capsys)
    assert code == 2 and out == ""
    (line,) = err.splitlines()               # the warning waits for valid inputs
    assert line.startswith("bouncesim: error: ") and "100" in line


# ============================================================================ output paths
class WorkStarted(AssertionError):
    pass


@pytest.fixture
def no_work(monkeypatch):
    """Loading ENV (the first piece of work of every command) fails the test."""
    def refuse(*a, **k):
        raise WorkStarted("the command started its work before checking its output paths")
    monkeypatch.setattr(envs, "load", refuse)


WRITERS = [
    (["allpairs", "lab", "--angles", "90,135"], "--out"),
    (["coverage", "lab", "--angles", "90,135"], "--out"),
    (["run-plan", "lab", "--angles", "90,135", "--start", "8", "--goal", "0"], "--trace"),
    (["run-plan", "lab", "--angles", "90,135", "--start", "8", "--goal", "0",
      "--robot", "pybullet"], "--record"),
]


@pytest.mark.parametrize("bad", ["/proc/bouncesim/x.gif", "FILE/x.gif", "EMPTY"])
@pytest.mark.parametrize("argv, option", WRITERS, ids=lambda v: " ".join(v)
                         if isinstance(v, list) else v)
def test_unwritable_output_exits_2_before_the_work(argv, option, bad, tmp_path, capsys,
                                                   no_work):
    regular = tmp_path / "a_file"
    regular.write_text("x")
    target = {"FILE/x.gif": str(regular / "x.gif"), "EMPTY": ""}.get(bad, bad)
    code, out, err = run(argv + [f"{option}={target}"], capsys)
    assert code == 2 and out == ""
    (line,) = err.splitlines()               # one sentence, no progress line, no warning
    assert line.startswith("bouncesim: error: ") and option in line and line.endswith(".")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_file"]


def test_an_existing_file_as_output_folder(tmp_path, capsys, no_work):
    f = tmp_path / "results"
    f.write_text("x")
    code, _, err = run(["allpairs", "lab", "--angles", "90", "--out", f], capsys)
    assert code == 2 and err.strip() == f"bouncesim: error: --out {f} is a file, not a folder."


def test_a_failed_command_leaves_no_empty_output_folder(tmp_path, capsys):
    out = tmp_path / "new" / "deeper"
    code, _, err = run(["allpairs", "lab", "--angles", "7", "--out", out], capsys)
    assert code == 2 and "7" in err             # 7° is no multiple of 45° at K = 8
    assert list(tmp_path.iterdir()) == []


# ============================================================================ memory
COMMANDS = [["info", "lab"], ["emulator", "lab", "--duration", "1"],
            ["plan", "lab", "--angles", "90", "--start", "0", "--goal", "1"],
            ["allpairs", "lab", "--angles", "90", "--out", "OUT"],
            ["coverage", "lab", "--angles", "90"],
            ["run-plan", "lab", "--angles", "90", "--start", "0", "--goal", "1"]]
TINY, HUGE_K = ["--cell-size", "1e-5"], ["--orientations", "10000000"]


# info and the emulator build no step table: only the grid can be too large for them
@pytest.mark.parametrize("argv, override",
                         [(c, TINY) for c in COMMANDS] + [(c, HUGE_K) for c in COMMANDS[2:]],
                         ids=lambda v: v[0] if len(v) > 2 else v[-1])
def test_memory_is_refused_in_one_sentence_before_allocating(argv, override, tmp_path,
                                                             capsys):
    argv = [str(tmp_path / "out") if a == "OUT" else a for a in argv]
    code, out, err = run(argv + override + ["--max-memory", "1G"], capsys)
    assert code == 2 and out == ""
    line = [ln for ln in err.splitlines() if not ln.startswith("bouncesim: warning:")]
    assert len(line) == 1 and line[0].startswith("bouncesim: error: ")
    assert "--max-memory" in line[0]
    assert not (tmp_path / "out").exists()


def test_memory_warning_when_the_machine_has_less_free(monkeypatch, capsys):
    est = resources.MemoryEstimate("the step table", 3 * 2**20)
    assert resources.memory_warning(est, available=2**30) is None
    assert "3 MiB" in resources.memory_warning(est, available=2**20)
    monkeypatch.setattr(resources, "available_memory", lambda: 1024)
    code, _, err = run(["plan", "lab", "--angles", "90", "--start", "0", "--goal", "1"],
                       capsys)
    assert code in (0, 3)
    (line,) = [ln for ln in warnings_in(err) if "memory" in ln]
    assert "memory free now" in line and "1 KiB" in line


# ============================================================================ --pairs
@pytest.mark.parametrize("row, why", [("5,x", "goal 'x'"), ("5", "has no goal"),
                                      ("99999,0", "out of range")])
def test_a_bad_pairs_row_is_named_before_any_query_runs(row, why, tmp_path, capsys):
    pairs = tmp_path / "q.csv"
    pairs.write_text(f"start,goal\n8,0\n\"2.55,0.17,90\",8\n{row}\n1,2\n")
    code, out, err = run(["plan", "lab", "--angles", "90,135", "--pairs", pairs], capsys)
    assert code == 2 and out == ""               # the good rows before it were not planned
    err = without_warnings(err)
    assert err.startswith(f"bouncesim: error: {pairs}, line 4: ") and why in err


# ============================================================================ --version
def test_version(capsys):
    assert main(["--version"]) == 0             # the exit status, as for every command
    out = capsys.readouterr().out
    assert out.startswith(f"bouncesim {metadata.version('bouncesim')}")


def test_python_dash_m_runs_the_same_command_line():
    # `python -m bouncesim` is the installed script: same version line, same exit codes
    ok = subprocess.run([sys.executable, "-m", "bouncesim", "--version"], capture_output=True,
                        text=True, timeout=120)
    assert ok.returncode == 0
    assert ok.stdout.startswith(f"bouncesim {metadata.version('bouncesim')}")
    bad = subprocess.run([sys.executable, "-m", "bouncesim", "info", "no_such_map"],
                         capture_output=True, text=True, timeout=120)
    assert bad.returncode == 2 and bad.stderr.startswith("bouncesim: error: ")


# ============================================================================ progress
def test_progress_lines_per_segment_on_stderr_and_quiet(capsys):
    argv = ["run-plan", "lab", "--angles", "90,135", "--start", "8", "--goal", "0", "--json"]
    code, out, err = run(argv, capsys)
    result = json.loads(out)                 # stdout: exactly one JSON object
    assert code == 0 and result["success"]
    n = len(Plan.parse(result["plan"]).segments())
    lines = err.splitlines()
    # lab's robot-wide bottom corridor is warned about before the robot moves
    assert lines.index(warnings_in(err)[0]) < lines.index(
        f"running {n} segment(s) on the kinematic robot")
    seg = [ln for ln in lines if ln.startswith("segment ")]
    assert [ln.split(":")[0] for ln in seg] == [f"segment {i}/{n}" for i in range(1, n + 1)]
    # the long drive of the plan (8 zeros along the bottom wall: 8 cells = 2.72 m)
    assert any("drive 2.72 m" in ln for ln in seg)
    code, out2, err2 = run(argv + ["--quiet"], capsys)
    assert code == 0 and without_warnings(err2) == "" and json.loads(out2)["success"]


def test_a_noisy_miss_says_it_is_an_outcome(capsys):
    code, _, err = run(["run-plan", "lab", "--angles", "90,135", "--start", "103", "--goal",
                        "8", "--noise", "gauss:2", "--seed", "1"], capsys)
    assert code == 4                         # the README example: this seed misses
    assert "not an error" in err


# ============================================================================ coverage labels
def test_largest_group_is_counted_in_position_cells_for_every_model(capsys):
    cs = CellSpace(envs.load("lab"))
    cov = model_for(cs, "step").analyse(90, TurnNoise())
    expected = sorted(len(set((np.asarray(g) % cs.P).tolist())) for g in cov.groups)
    code, out, _ = run(["coverage", "lab", "--angles", "90", "--json"], capsys)
    pa = json.loads(out)["per_angle"][0]
    assert code == 0 and sorted(pa["group_cells"]) == expected
    code, out, _ = run(["coverage", "lab", "--angles", "90", "--model", "event",
                        "--model-option", "bin_length=0.15", "--json"], capsys)
    summary = json.loads(out)
    pa = summary["per_angle"][0]
    assert summary["states"]["kind"].startswith("contact states")
    assert summary["states"]["count"] > cs.P       # states are not cells ...
    assert 1 <= max(pa["group_cells"]) <= cs.P     # ... the cells column is


def test_output_piped_into_a_reader_that_leaves_is_quiet(tmp_path):
    # `bouncesim run-plan ... --json | head -c 20`: the reader closes the pipe before the
    # JSON is written; the command says nothing (no traceback) and its figure stays
    out = tmp_path / "figs"
    proc = subprocess.Popen([sys.executable, "-m", "bouncesim", "run-plan", "lab", "--angles",
                             "90,135", "--start", "8", "--goal", "0", "--json", "--plot",
                             str(out / "run.png")],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    proc.stdout.close()                      # the reader leaves at once
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=120) == 141
    assert "Traceback" not in err and "Broken pipe" not in err, err
    assert (out / "run.png").stat().st_size > 0


def test_an_output_path_that_is_a_folder_is_one_plain_sentence(tmp_path):
    from bouncesim.commands.common import writable_path
    from envs import UserError
    (tmp_path / "isdir.json").mkdir()
    with pytest.raises(UserError) as err:
        writable_path(tmp_path / "isdir.json")
    msg = str(err.value)
    assert msg == f"--out {tmp_path / 'isdir.json'} is a folder, not a file."
    # an OS error's reason is wrapped once, with no doubled full stop
    (tmp_path / "afile").write_text("")
    with pytest.raises(UserError) as err:
        writable_path(tmp_path / "afile" / "x.json")
    assert str(err.value).startswith("cannot write --out") and ".)." not in str(err.value)


@pytest.mark.parametrize("argv", [
    ["allpairs", "lab", "--angles", "90,135"],
    ["coverage", "lab", "--orientations", "8", "--angles", "90,135", "--no-plots"],
    ["validate", "lab", "--orientations", "72", "--angles", "90", "--eps", "5", "--r", "0.8",
     "--model", "step", "--backend", "kinematic", "--steps", "400", "--workers", "1",
     "--seed", "3"],
], ids=["allpairs", "coverage", "validate"])
def test_every_output_folder_has_its_provenance(argv, tmp_path, capsys):
    from bouncesim.runs.metadata import env_sha256
    out = tmp_path / "out"
    full = argv + ["--out", str(out)]
    assert main(full) == 0
    # one "wrote" line per file, and every file in the folder has one
    wrote = {Path(line.split(" ", 1)[1]) for line in capsys.readouterr().out.splitlines()
             if line.startswith("wrote ")}
    assert wrote == {p for p in out.rglob("*") if p.is_file()}
    cfg = json.loads((out / "config.json").read_text())
    assert cfg["argv"] == full and cfg["command"].startswith("bouncesim " + argv[0])
    assert cfg["env"] == "lab" and cfg["versions"]["numpy"] == np.__version__
    assert "git_revision" in cfg and "created" in cfg and "seed" in cfg
    # the hash is the room's, whichever way it was given: the same dict from a file
    orientations = int(argv[argv.index("--orientations") + 1]) if "--orientations" in argv \
        else None
    lab = envs.load("lab", orientations=orientations)
    path = tmp_path / "lab_copy.json"
    path.write_text(json.dumps(lab.to_dict()))
    assert cfg["env_sha256"] == env_sha256(lab) == env_sha256(envs.load(path))
    assert env_sha256(lab) != env_sha256(envs.load("lab", orientations=16))
    assert cfg["seed"] == (3 if "--seed" in argv else None)      # None: no randomness


def test_run_plan_files_carry_their_provenance_beside_them(tmp_path, capsys):
    """run-plan --trace/--plot: each file gets NAME.config.json (one per name), with the
    command line, seed and map hash; under --json the "wrote" lines go to stderr, so stdout
    stays one JSON object. The feedback planner draws its run too.
    """
    from bouncesim.runs.metadata import env_sha256
    base = ["run-plan", "lab", "--angles", "45,90,135", "--orientations", "8", "--start", "1",
            "--goal", "40", "--quiet", "--seed", "5"]
    full = base + ["--trace", str(tmp_path / "run.csv"), "--plot", str(tmp_path / "run.png"),
                   "--json"]
    assert main(full) in (0, 4)
    io = capsys.readouterr()
    json.loads(io.out)                                  # stdout: the result alone
    wrote = [line.split(" ", 1)[1] for line in io.err.splitlines() if line.startswith("wrote ")]
    assert wrote == [str(tmp_path / n) for n in ("run.csv", "run.png", "run.config.json")]
    cfg = json.loads((tmp_path / "run.config.json").read_text())
    assert cfg["argv"] == full and cfg["seed"] == 5
    assert cfg["env_sha256"] == env_sha256(envs.load("lab", orientations=8))
    feedback = base + ["--planner", "feedback", "--noise", "gauss:2",
                       "--plot", str(tmp_path / "fb.svg")]
    assert main(feedback) in (0, 4)
    assert (tmp_path / "fb.svg").stat().st_size > 0
    assert json.loads((tmp_path / "fb.config.json").read_text())["argv"] == feedback


def test_run_plan_plans_for_the_contact_rule_it_is_given(capsys):
    """run-plan --contact pybullet runs the plan that ``plan --contact pybullet`` prints (it
    differs from the front-half plan on this pair), and the twin whose bumper has the
    PyBullet arc (--glance 80) executes it to the goal; the step planner refuses the flag.
    """
    base = ["lab", "--angles", "30,75,315", "--orientations", "24", "--start", "0", "--goal",
            "69", "--planner", "exact", "--json"]
    texts = {}
    for contact in ("off", "pybullet"):
        assert main(["plan", *base, "--contact", contact]) == 0
        texts[contact] = json.loads(capsys.readouterr().out)["plan_text"]
    assert texts["off"] != texts["pybullet"]
    assert main(["run-plan", *base, "--contact", "pybullet", "--glance", "80", "--quiet"]) == 0
    run = json.loads(capsys.readouterr().out)
    assert run["plan"] == texts["pybullet"] and run["success"] is True
    assert main(["run-plan", *base[:-3], "--json", "--contact", "pybullet"]) == 2
    assert "--contact is for the planners" in capsys.readouterr().err


def test_the_shipped_queries_file_plans_one_line_per_row(capsys):
    """docs/readme_paper.md's ``plan --pairs examples/queries.csv``: one JSON line per row,
    in order, a pose given as X,Y,DEG read as its configuration, each the plan of the same
    single query.
    """
    import pandas as pd
    path = Path(__file__).resolve().parents[1] / "examples" / "queries.csv"
    rows = pd.read_csv(path, dtype=str)
    base = ["plan", "complex", "--angles", "45,90,135", "--json"]
    assert main([*base, "--pairs", str(path)]) == 0
    lines = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert len(lines) == len(rows) >= 3
    for line, (_, row) in zip(lines, rows.iterrows()):
        assert main([*base, "--start", row.start, "--goal", row.goal]) == 0
        assert json.loads(capsys.readouterr().out) == line
    from planners.cells import CellSpace
    x, y, deg = (float(v) for v in rows.start[2].split(","))
    assert lines[2]["start"] == CellSpace(envs.load("complex")).config_of_pose(x, y, deg)


def test_version_needs_none_of_the_numeric_stack():
    """``bouncesim --version`` answers before the commands are imported: importing the CLI
    and printing the version loads no numpy, scipy, shapely or matplotlib (their imports
    cost most of a second).
    """
    code = ("import sys, contextlib, io\n"
            "from bouncesim.cli import main\n"
            "buf = io.StringIO()\n"
            "with contextlib.redirect_stdout(buf):\n"
            "    assert main(['--version']) == 0\n"
            "heavy = [m for m in ('numpy', 'scipy', 'shapely', 'matplotlib') "
            "if m in sys.modules]\n"
            "print(buf.getvalue().strip(), heavy)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120, check=True).stdout
    assert out.startswith("bouncesim ") and out.rstrip().endswith("[]"), out


def test_an_output_file_in_a_new_folder_says_it_made_the_folder(tmp_path, capsys):
    out = tmp_path / "a" / "b" / "map.png"
    assert main(["show", "lab", "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert f"bouncesim: warning: created the folder {tmp_path / 'a'} for --out {out}." in err
    assert out.is_file()
    # an --out folder the command is asked to make is made without a note
    assert main(["coverage", "lab", "--angles", "90", "--orientations", "8", "--eps", "45",
                 "--no-plots", "--out", str(tmp_path / "cov")]) == 0
    assert "created the folder" not in capsys.readouterr().err


def test_run_plan_feedback_takes_the_robots_rule_and_mujocos_rule_follows_speed():
    # run-plan's --contact defaults to auto: the feedback planner then takes the executing
    # body's declared rule when it runs (at --speed), the exact planner plans without one;
    # an explicit --contact mujoco is MuJoCo's rule at the command's speed (run-plan 0.2 m/s,
    # validate 0.3 m/s), and a speed with no fitted rule says which one it used
    from bouncesim.cli import build_parser
    from bouncesim.commands.common import _PENDING, contact_name, contact_rule
    from bouncesim.commands.plan import make_planner_of
    from envs.motion import MUJOCO_CONTACT, MUJOCO_CONTACTS
    p = build_parser()
    base = ["run-plan", "lab", "--angles", "45,90,135", "--start", "8", "--goal", "0"]
    fb = p.parse_args(base + ["--planner", "feedback"])
    assert fb.contact == "auto" and make_planner_of(fb).contact == "auto"
    assert make_planner_of(p.parse_args(base + ["--planner", "exact"])).contact is None
    slow = p.parse_args(base + ["--planner", "feedback", "--contact", "mujoco"])
    assert contact_rule(slow) == MUJOCO_CONTACTS[0.2] != MUJOCO_CONTACT
    assert contact_name(contact_rule(slow)) == "mujoco"
    val = p.parse_args(["validate", "lab", "--angles", "30", "--backend", "mujoco"])
    assert contact_rule(val) == MUJOCO_CONTACT
    _PENDING.clear()
    odd = p.parse_args(base + ["--contact", "mujoco", "--speed", "0.15"])
    assert contact_rule(odd) == MUJOCO_CONTACTS[0.2]
    assert any("0.2 m/s rule is used" in line for line in _PENDING)
    _PENDING.clear()
