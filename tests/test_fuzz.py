"""Fuzzing every public entry point: it returns a result or raises the one-sentence
:class:`envs.UserError` (the CLI: exit status 0, 3 or 4, or 2 with one error line on stderr,
after any warnings and progress lines), never another exception and never a hang.

Profiles (``BOUNCESIM_FUZZ_PROFILE``): ``ci`` (default; 200 examples per entry point,
derandomized, no example database) and ``fuzz`` (10^4 random examples per entry point;
``make fuzz``; ``BOUNCESIM_FUZZ_EXAMPLES`` changes the count). Hypothesis's wall-clock
``deadline`` is off (a busy machine would make it flaky); instead the inputs are small and
a generous SIGALRM guard fails an example that runs longer than ``BOUNCESIM_FUZZ_TIMEOUT``
seconds (default 30) as a hang.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import re
import tempfile
from pathlib import Path
from unittest import mock

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

import envs
from bouncesim.cli import main
from bouncesim.robots.kinematic import KinematicRobot
from bouncesim.robots.noise import parse_noise
from bouncesim.runs.execute import execute
from envs import Environment, UserError
from planners.cells import CellSpace
from planners.coverage import (
    TurnNoise,
    default_settings,
    design_mix,
    model_for,
    timeshared_coverage,
)
from planners.navigation import Navigator
from planners.plan import Plan, PolicyMix

from . import strategies as S
from .alarm import alarm

_COMMON = dict(deadline=None, print_blob=True,
               suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                      HealthCheck.filter_too_much])
settings.register_profile("bouncesim-ci", max_examples=200, derandomize=True, database=None,
                          **_COMMON)
settings.register_profile("bouncesim-fuzz",
                          max_examples=int(os.environ.get("BOUNCESIM_FUZZ_EXAMPLES", 10_000)),
                          **_COMMON)
PROFILE = "bouncesim-" + os.environ.get("BOUNCESIM_FUZZ_PROFILE", "ci")
FUZZ = settings(settings.get_profile(PROFILE))
TIMEOUT = float(os.environ.get("BOUNCESIM_FUZZ_TIMEOUT", "30"))
LIMIT = "64M"          # --max-memory / max_memory in the fuzz: big inputs are refused at once


# what commands print on stderr besides "bouncesim: warning/error: ..." lines
PROGRESS = re.compile(r"(running \d+ segment\(s\) on the \w+ robot"
                      r"|segment \d+/\d+: drive .*|note: .*"
                      r"|wrote \S.*)$")             # under --json, "wrote" lines go to stderr


class Hang(AssertionError):
    """An example ran longer than the time guard."""


@contextlib.contextmanager
def time_guard(seconds: float = TIMEOUT):
    """A hang of an example fails it: more than ``seconds`` of CPU (30 s by default), which
    a busy machine does not inflate, or ten times that of wall time (a blocked hang).
    """
    with alarm(10 * seconds, Hang, "the example"), alarm(seconds, Hang, "the example", "cpu"):
        yield


def assert_sentence(msg: str) -> None:
    """A user error's message: one non-empty line that ends a sentence."""
    msg = str(msg)
    assert msg.strip(), "empty error message"
    assert "\n" not in msg.strip(), f"multi-line error message: {msg!r}"
    assert msg.rstrip().endswith((".", ".)", "?")), f"not a sentence: {msg!r}"


def api(fn, *args, **kw):
    """fn(*args, **kw) under the time guard; a UserError is returned (after checking its
    message), anything else propagates and fails the example.
    """
    with time_guard():
        try:
            out = fn(*args, **kw)
        except UserError as exc:
            assert_sentence(str(exc))
            event(f"{getattr(fn, '__name__', 'call')}: user error")
            return exc
    event(f"{getattr(fn, '__name__', 'call')}: result")
    return out


def cli(argv: list[str]) -> tuple[int, str, str]:
    """Run ``bouncesim argv`` in-process: (exit status, stdout, stderr), checked."""
    out, err = io.StringIO(), io.StringIO()
    with time_guard(), contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(argv)
            parser_exit = False
        except SystemExit as exc:                 # argparse: bad option syntax, exit 2
            code, parser_exit = exc.code, True
    o, e = out.getvalue(), err.getvalue()
    event(f"exit {code}" + (" (argparse)" if parser_exit else ""))
    assert "Traceback" not in e, e
    assert code in (0, 2, 3, 4), (code, e)
    lines = [ln for ln in e.splitlines() if ln.strip()]
    for ln in [] if parser_exit else lines:     # warnings and progress: one line each
        if ln.startswith("bouncesim: warning: "):
            assert_sentence(ln)
        elif not ln.startswith("bouncesim: "):
            assert PROGRESS.match(ln), f"not a progress line: {ln!r}"
    if code == 2 and not parser_exit:
        errors = [ln for ln in lines if ln.startswith("bouncesim: ")
                  and not ln.startswith("bouncesim: warning: ")]
        assert len(errors) == 1 and errors[0] == lines[-1], e
        assert errors[0].startswith("bouncesim: error: "), e
        assert_sentence(errors[0])
    if parser_exit:
        assert code == 2 and "error:" in e, e
    return code, o, e


def build_env(data) -> Environment | None:
    res = api(Environment.from_dict, data)
    return None if isinstance(res, UserError) else res


@contextlib.contextmanager
def env_file(data):
    """A temporary folder holding the env file, also the working folder (so that a stray
    relative output lands there).
    """
    with tempfile.TemporaryDirectory() as d, contextlib.chdir(d):
        path = Path(d) / "env.json"
        path.write_text(json.dumps(data) if not isinstance(data, str) else data)
        yield d, str(path)


def env_argv(path: str, draw) -> list[str]:
    """ENV plus its options: the fuzz's --max-memory, and in about one example in four an
    override (sometimes a bad one) of --cell-size, --orientations or --max-memory.
    """
    kind = draw(st.sampled_from([None] * 9 + ["max-memory", "cell-size", "orientations"]))
    argv = [path, "--max-memory=" + (LIMIT if kind != "max-memory" else
                                     draw(st.sampled_from(["1K", "x", "0", "2G", "1e400"])))]
    if kind == "cell-size":
        argv += ["--cell-size=" + draw(st.sampled_from(["0.2", "0.34", "0.05", "0", "-1",
                                                        "nan", "1e-9", "x", "1e9"]))]
    if kind == "orientations":
        argv += ["--orientations=" + draw(st.sampled_from(["4", "5", "7", "12", "3", "0",
                                                           "100000", "1000000000", "x"]))]
    return argv


def K_of(data):
    disc = data.get("discretization")
    return disc.get("orientations") if isinstance(disc, dict) else None


# ============================================================================ Python API
@FUZZ
@given(data=S.env_dicts())
def test_environment_from_dict(data):
    env = build_env(data)
    if env is not None:
        again = Environment.from_dict(env.to_dict())          # the file form round-trips
        assert again.grid_shape == env.grid_shape


@FUZZ
@given(text=S.env_texts(), suffix=st.sampled_from([".json", ".yaml", ".txt", ""]))
def test_envs_load(text, suffix):
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / f"env{suffix}"
        path.write_text(text)
        api(envs.load, path)


@FUZZ
@given(data=S.env_dicts(), poses=st.lists(st.tuples(S.small_floats, S.small_floats,
                                                     st.floats(-720, 720)), max_size=3),
       angle=st.one_of(st.integers(0, 400), S.weird_numbers))
def test_cellspace(data, poses, angle):
    env = build_env(data)
    if env is None:
        return
    cs = CellSpace(env, max_memory=LIMIT)
    fwd = api(lambda: cs.forward)
    if isinstance(fwd, UserError):
        return
    assert fwd.shape == (cs.N,) and ((fwd == -1) | ((fwd >= 0) & (fwd < cs.N))).all()
    for x, y, deg in poses:
        z = cs.config_of_pose(x, y, deg)
        assert -1 <= z < cs.N
    api(cs.rotate, 0, angle)


@FUZZ
@given(data=S.env_dicts(max_K=16), draw=st.data(),
       w=st.tuples(st.sampled_from([1.0] * 6 + [2.0, 0.0, -1.0, float("nan")]),
                   st.sampled_from([100.0] * 6 + [1.0, 0.5, float("inf")])),
       start=st.one_of(st.integers(-2, 200), st.integers(0, 50), st.floats(),
                       st.text(max_size=3)),
       goal=st.one_of(st.integers(-2, 200), st.integers(0, 50), st.floats(),
                      st.text(max_size=3)))
def test_navigator_plan(data, draw, w, start, goal):
    angles = draw.draw(S.angle_lists_for(K_of(data)))
    env = build_env(data)
    if env is None:
        return
    nav = api(Navigator, CellSpace(env, max_memory=LIMIT), angles, *w, max_memory=LIMIT)
    if isinstance(nav, UserError):
        return
    route = api(nav.plan, start, goal)
    if route is not None and not isinstance(route, UserError):
        assert route.path[0] == int(start) and route.path[-1] == int(goal)
        assert len(route.plan) == len(route.path) - 1


@FUZZ
@given(data=S.env_dicts(max_K=12), draw=st.data(),
       r=S.reliabilities, model=st.sampled_from(["step", "step", "sampled", "event", "x"]),
       space=st.sampled_from(["positions", "positions", "configurations"]),
       target=st.one_of(st.none(), st.lists(st.floats(-1, 5), max_size=6)),
       epoch=st.one_of(st.none(), st.integers(-1, 30)))
def test_coverage(data, draw, r, model, space, target, epoch):
    angles = draw.draw(S.angle_lists_for(K_of(data)))
    eps = draw.draw(S.eps_for(K_of(data)))
    env = build_env(data)
    if env is None:
        return
    cs = CellSpace(env, max_memory=LIMIT)
    if isinstance(api(lambda: cs.forward), UserError):
        return
    settings_ = None
    if model == "event":      # coarse contact bins keep the event model small
        settings_ = default_settings("event").__class__(bin_length=0.15, samples=1)
    if target is not None:
        target = (target * (cs.P // max(len(target), 1) + 1))[:cs.P] if target else []
    noise = api(TurnNoise, eps, r)
    if isinstance(noise, UserError):
        return
    chain = api(model_for, cs, model, settings_)
    if isinstance(chain, UserError):
        return
    res = api(design_mix, chain, angles, noise, target=target, space=space)
    if isinstance(res, UserError):
        return
    q = res.mixed_q()
    assert np.all(np.isfinite(q)) and abs(q.sum() - 1) < 1e-6
    if angles:
        api(chain.analyse, angles[0], noise)
    if epoch is not None:
        api(timeshared_coverage, chain, res.mix, epoch=epoch, max_epochs=50)


@FUZZ
@given(data=S.env_dicts(good_only=True), plan=S.plan_texts(), start=S.tokens(),
       goal=S.tokens(), noise=S.noise_specs, speed=st.sampled_from([0.2, 0.5, 0.0, -1.0,
                                                                      float("nan"), 1e9]),
       back_off=st.sampled_from([0.0, 0.01, -0.1, float("inf")]), seed=st.integers(0, 9))
def test_execute_plan_kinematic(data, plan, start, goal, noise, speed, back_off, seed):
    env = build_env(data)
    if env is None:
        return
    cs = CellSpace(env, max_memory=LIMIT)
    if isinstance(api(lambda: cs.forward), UserError):
        return
    model = api(parse_noise, noise, cs.delta_deg)
    if isinstance(model, UserError):
        model = None
    robot = api(KinematicRobot, env, model, np.random.default_rng(seed))
    if isinstance(robot, UserError):
        return

    def as_config(tok):
        parts = tok.split(",")
        if len(parts) == 3:
            try:
                return tuple(float(p) for p in parts)
            except ValueError:
                return tok
        try:
            return int(tok)
        except ValueError:
            return tok
    with robot:
        run = api(execute, plan, robot, start=as_config(start), goal=as_config(goal), cells=cs,
                  speed=speed, back_off=back_off)
    if not isinstance(run, UserError):
        assert isinstance(run.success, bool)


@FUZZ
@given(text=S.plan_texts(), mix=st.tuples(S.angle_lists(max_size=3),
                                           st.lists(st.floats(-0.5, 1.5), max_size=3),
                                           S.epsilons, S.reliabilities))
def test_plan_parsing(text, mix):
    plan = api(Plan.parse, text)
    if isinstance(plan, Plan):
        assert Plan.parse(str(plan)) == plan            # printing and parsing round-trip
        assert Plan.parse(plan.plain()) == plan
        assert plan.steps + plan.bumps == len(plan)
    api(PolicyMix, *mix)


# ============================================================================ command line
@FUZZ
@given(data=S.env_dicts(), draw=st.data(), as_json=st.booleans())
def test_cli_info(data, draw, as_json):
    with env_file(data) as (_, path):
        code, out, _ = cli(["info"] + env_argv(path, draw.draw) + (["--json"] if as_json
                                                                    else []))
    if code == 0 and as_json:
        info = json.loads(out)
        assert info["N"] == info["K"] * info["P"]


@FUZZ
@given(data=S.env_dicts(max_K=16), draw=st.data(), start=S.tokens(), goal=S.tokens(),
       pairs=st.one_of(st.none(), st.none(), S.pairs_csv()), as_json=st.booleans())
def test_cli_plan(data, draw, start, goal, pairs, as_json):
    angles = draw.draw(S.angles_for(K_of(data)))
    with env_file(data) as (d, path):
        argv = ["plan"] + env_argv(path, draw.draw) + ["--angles=" + angles]
        if pairs is None or draw.draw(st.integers(0, 9)) == 0:
            argv += ["--start=" + start, "--goal=" + goal]
        if pairs is not None:
            f = Path(d) / "pairs.csv"
            (f.write_bytes if isinstance(pairs, bytes) else f.write_text)(pairs)
            argv += ["--pairs", draw.draw(st.sampled_from([str(f)] * 5 + [d, "/nonexistent"]))]
        code, out, _ = cli(argv + (["--json"] if as_json else []))
    if code in (0, 3) and as_json:
        for line in out.splitlines():
            q = json.loads(line)
            assert q["plan"] is None or q["path"][0] == q["start"]


@FUZZ
@given(data=S.env_dicts(max_K=8), draw=st.data(),
       out=st.sampled_from(["new"] * 6 + ["existing-file", "/proc/fuzz", ""]),
       plots=st.sampled_from([False] * 19 + [True]))
def test_cli_allpairs(data, draw, out, plots):
    angles = draw.draw(S.angles_for(K_of(data)))
    # drawing the chart takes most of an example's time: one example in 20 draws it
    skip_chart = (contextlib.nullcontext() if plots else
                  mock.patch("bouncesim.plots.angle_use_bars", lambda *a, **k: None))
    with env_file(data) as (d, path), skip_chart:
        target = {"new": str(Path(d) / "out"), "existing-file": path}.get(out, out)
        code, _, _ = cli(["allpairs"] + env_argv(path, draw.draw) +
                         ["--angles=" + angles, "--out=" + target])
        if code == 0:
            summary = json.loads((Path(target) / "summary.json").read_text())
            assert sum(summary["histogram"]) <= summary["pairs"]


@FUZZ
@given(data=S.env_dicts(max_K=12), draw=st.data(),
       r=S.reliabilities, model=st.sampled_from(["step", "step", "sampled", "event"]),
       out=st.sampled_from([None, None, "new", "new", "/proc/fuzz", ""]),
       extra=st.lists(st.sampled_from([["--json"], ["--target-space", "configurations"],
                                       ["--epoch", "20"], ["--epoch", "0"],
                                       ["--model-option", "bin_length=0.15"],
                                       ["--model-option", "samples=x"],
                                       ["--model-option", "grid=2"],
                                       ["--target", "missing.csv"]]), max_size=3),
       no_plots=st.sampled_from([True] * 19 + [False]))
def test_cli_coverage(data, draw, r, model, out, extra, no_plots):
    angles = draw.draw(S.angles_for(K_of(data)))
    eps = draw.draw(S.eps_for(K_of(data)))
    with env_file(data) as (d, path):
        argv = (["coverage"] + env_argv(path, draw.draw) +
                ["--angles=" + angles, f"--eps={eps!r}", f"--r={r!r}", "--model", model])
        if model == "event" and not any("bin_length" in e for x in extra for e in x):
            argv += ["--model-option", "bin_length=0.15", "--model-option", "samples=1"]
        if out is not None:
            argv += ["--out=" + (str(Path(d) / "out") if out == "new" else out)]
        if no_plots:                        # plotting is slow: one example in 20 plots
            argv += ["--no-plots"]
        for x in extra:
            argv += x
        cli(argv)


@FUZZ
@given(data=S.env_dicts(max_K=16), draw=st.data(), start=S.tokens(),
       goal=S.tokens(), noise=S.noise_specs, seed=st.integers(-1, 5),
       extra=st.lists(st.sampled_from([["--json"], ["--trace", "TRACE"],
                                       ["--trace", "/proc/fuzz.csv"], ["--trace="],
                                       ["--glance", "80"],
                                       ["--glance", "nan"], ["--speed", "0"],
                                       ["--back-off", "0.01"], ["--record", "x.gif"],
                                       ["--port", "tcp"], ["--time-scale", "2"]]),
                      max_size=3))
def test_cli_run_plan_kinematic(data, draw, start, goal, noise, seed, extra):
    angles = draw.draw(S.angles_for(K_of(data)))
    with env_file(data) as (d, path):
        argv = (["run-plan"] + env_argv(path, draw.draw) +
                ["--angles=" + angles, "--start=" + start, "--goal=" + goal,
                 "--noise=" + noise, f"--seed={seed}", "--robot", "kinematic"])
        for x in extra:
            argv += [a.replace("TRACE", str(Path(d) / "t" / "trace.csv")) for a in x]
        cli(argv)


# ============================================================================ known finds
def test_tiny_reliability_is_a_user_error():
    env = Environment.from_dict({"boundary": [[0, 0], [1, 0], [1, 1], [0, 1]],
                                 "robot_radius": 0.125,
                                 "discretization": {"cell_size": 0.25, "orientations": 4}})
    # found by make fuzz: 0 < r below ~1e-16 joined persistent groups by turns of no
    # numerical weight, the stationary solve was singular and q NaN
    for r in (1e-20, 1 - 1e-12):
        with pytest.raises(UserError) as err:
            TurnNoise(90.0, r)
        assert_sentence(str(err.value))
    assert np.isfinite(design_mix(model_for(CellSpace(env)), [90.0],
                                  TurnNoise(90.0, 1e-6)).mixed_q()).all()
