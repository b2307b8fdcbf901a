"""``bouncesim validate``: predicted against simulated coverage per angle.

Independent evidence: the kinematic twin's histogram against the event model within a bound
derived from the simulation's own noise floor (TV between two independent halves), the
bump rates of model and twin, and the JSON schema. Bad inputs exit 2 with one line.
"""

from __future__ import annotations

import importlib.util
import json
import math
import shlex

import numpy as np
import pandas as pd
import pytest

from bouncesim.cli import main

KEYS = {"angle", "tv", "floor", "steps", "dropped", "bumps_per_step_model",
        "bumps_per_step_sim", "model", "backend", "env"}
LAB = ["validate", "lab", "--orientations", "72", "--eps", "5", "--r", "0.8", "--workers", "1",
       "--no-progress"]


def _rows(capsys) -> list[dict]:
    return [json.loads(line) for line in capsys.readouterr().out.splitlines() if line.strip()]


def test_kinematic_matches_the_event_model_within_the_noise(capsys):
    """Lab at 75° and 315° and the 50/50 mix: TV(event q, twin) at most 1.5 × the floor plus
    0.01 (the event model's binning error on lab is about 0.01, docs/model_continuous.md);
    the floor compares two halves, each with √2 times the pooled histogram's noise, so a
    right model sits near floor/2. Bumps per step agree within 0.02.
    """
    assert main(LAB + ["--angles", "75,315", "--alpha", "1,1", "--model", "event",
                       "--steps", "100000", "--json"]) == 0
    rows = _rows(capsys)
    assert [r["angle"] for r in rows] == [75.0, 315.0, "mix"]
    for r in rows:
        assert set(r) >= KEYS
        assert r["steps"] >= 100000 and r["backend"] == "kinematic" and r["env"] == "lab"
        assert 0 < r["floor"] < 0.1
        assert r["tv"] <= 1.5 * r["floor"] + 0.01, r
        assert abs(r["bumps_per_step_model"] - r["bumps_per_step_sim"]) <= 0.02, r
    assert rows[2]["alpha"] == [0.5, 0.5]


def test_step_model_bump_rate_and_table(capsys):
    """The step model's bump rate is π over its bump configurations: at K = 72 in lab it is
    a number in (0, 1); the table prints one line per angle.
    """
    assert main(LAB + ["--angles", "75", "--model", "step", "--steps", "4000"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[1].split()[:4] == ["angle", "tv", "tv_runs", "floor"]
    assert len(out) == 3 and out[2].split()[0] == "75"
    bm, bs = (float(v) for v in out[2].split()[-2:])
    assert 0 < bm < 1 and 0 < bs < 1


@pytest.mark.parametrize("argv", [
    ["--angles", "77"],                                   # not a multiple of 5°
    ["--angles", "75", "--steps", "1"],
    ["--angles", "75,315", "--alpha", "1"],               # one weight for two angles
    ["--angles", "75", "--alpha", "x"],
    ["--angles", "75", "--epoch", "0"],
    ["--angles", "75", "--speed", "2"],
])
def test_bad_inputs_exit_2_with_one_line(argv, capsys):
    assert main(LAB + argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("bouncesim: error:")


def test_unknown_env_exits_2(capsys):
    assert main(["validate", "no_such_room", "--angles", "90"]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1


@pytest.mark.slow
@pytest.mark.physics
@pytest.mark.skipif(importlib.util.find_spec("pybullet") is None, reason="needs pybullet")
def test_pybullet_backend_few_steps(capsys):
    """Two batches of 16 PyBullet robots, 4 counted steps each: the JSON row counts them all,
    and the rates and distances are proper numbers.
    """
    assert main(LAB + ["--angles", "75", "--backend", "pybullet", "--steps", "128",
                       "--burn-in", "2", "--json"]) == 0
    (r,) = _rows(capsys)
    assert r["backend"] == "pybullet" and r["steps"] == 128
    assert 0 <= r["bumps_per_step_sim"] <= 1 and 0 < r["tv"] <= 1
    assert math.isfinite(r["floor"])


def test_floors_halves_are_whole_trials_and_splits_average():
    """Hand-made trials over two cells, t0 = t1 = (1, 0) and t2 = t3 = (0, 1), halves 0 1 0 1:
    the floor compares t0 + t2 = (1, 1) with t1 + t3 = (1, 1), TV 0; of the three equally
    likely balanced splits only {t0, t1} | {t2, t3} differs (TV 1), so floor_splits → 1/3
    (2 000 splits: standard error 0.011).
    """
    from bouncesim.commands.validate import floors
    counts = np.array([[1, 0], [1, 0], [0, 1], [0, 1]])
    floor, mean = floors(counts, np.array([0, 1, 0, 1]), np.random.default_rng(0), 2000)
    assert floor == 0.0
    assert abs(mean - 1 / 3) < 0.04


def test_more_trials_stopping_rule():
    """Floor ∝ 1/√steps: 0.04 at 40 000 steps needs 4x the steps for 0.02, +10 % = 136 000
    more, 14 trials of 10 000; met targets and the cap add none; the cap limits the rest.
    """
    from bouncesim.commands.validate import more_trials
    assert more_trials(0.04, 40_000, 10_000, 0.02, 1_000_000) == 14
    assert more_trials(0.021, 40_000, 10_000, 0.02, 1_000_000) == 2     # at least one pair
    assert more_trials(0.02, 40_000, 10_000, 0.02, 1_000_000) == 0
    assert more_trials(0.5, 1_000_000, 10_000, 0.02, 1_000_000) == 0
    assert more_trials(0.5, 960_000, 10_000, 0.02, 1_000_000) == 4


def test_out_folder_is_resumed_by_a_second_run(capsys, tmp_path):
    """The same command twice with ``--out``: the second run finds every trial done (it
    resumes instead of refusing the folder) and reports the same numbers.
    """
    argv = LAB + ["--angles", "75", "--model", "step", "--steps", "4000", "--out",
                  str(tmp_path), "--json"]
    assert main(argv) == 0
    (first,) = _rows(capsys)
    assert main(argv) == 0
    (second,) = _rows(capsys)
    drop = ("predict_s",)
    assert {k: v for k, v in first.items() if k not in drop} == \
        {k: v for k, v in second.items() if k not in drop}
    sessions = json.loads((tmp_path / "config.json").read_text())["sessions"]
    assert [s["trials_resumed"] for s in sessions] == [0, first["trials"]]
    assert [s["command"] for s in sessions] == [shlex.join(["bouncesim", *argv])] * 2
    # the table is in the folder too, as the second run printed it
    assert json.loads((tmp_path / "validation.json").read_text()) == [second]
    assert pd.read_csv(tmp_path / "validation.csv").tv.tolist() == [second["tv"]]


def test_a_folder_of_another_sweep_is_refused_before_the_prediction(capsys, tmp_path,
                                                                     monkeypatch):
    """A second run with another seed into the same --out: one sentence, exit 2, and no
    model is built (the refusal comes before the prediction's work); with --alpha design the
    check follows the design, which needs the model.
    """
    import bouncesim.commands.validate as validate
    argv = LAB + ["--angles", "75", "--model", "step", "--steps", "4000", "--out",
                  str(tmp_path), "--json"]
    assert main(argv) == 0
    capsys.readouterr()
    built = []
    real = validate.model_for
    monkeypatch.setattr(validate, "model_for", lambda *a, **k: built.append(1) or real(*a, **k))
    assert main(argv + ["--seed", "5"]) == 2
    err = capsys.readouterr().err
    assert "holds a different sweep" in err and err.count("\n") == 1 and built == []
    assert main(LAB + ["--angles", "75,135", "--alpha", "design", "--model", "step", "--steps",
                       "4000", "--out", str(tmp_path), "--json"]) == 2
    assert "holds a different sweep" in capsys.readouterr().err and built == [1]


def test_floor_target_adds_independent_trials(capsys, tmp_path):
    """Twin on lab, 75°, first round 20 000 steps (2 trials of 200 robots x 50 steps), target
    floor 0.03: trials are added in rounds until floor and floor_splits are both ≤ 0.03; every
    round is a sweep of its own root seed (new robots), and the halves alternate over the
    policy's trials across rounds, so each half is a set of whole, independent trials.
    """
    import pandas as pd
    assert main(LAB + ["--angles", "75", "--model", "event", "--steps", "20000", "--floor",
                       "0.03", "--out", str(tmp_path), "--json"]) == 0
    (r,) = _rows(capsys)
    assert r["floor"] <= 0.03 and r["floor_splits"] <= 0.03
    assert r["steps"] > 20000 and r["steps"] == 10_000 * r["trials"]
    folders = [tmp_path] + sorted(tmp_path.glob("round*"))
    assert len(folders) >= 2
    seeds = [json.loads((f / "config.json").read_text())["sweep"]["root_seed"] for f in folders]
    assert len(set(seeds)) == len(seeds)
    halves = pd.concat([pd.read_csv(f / "runs.csv") for f in folders]).half.tolist()
    assert halves == [j % 2 for j in range(r["trials"])]
    assert r["tv"] <= 1.5 * r["floor"] + 0.01, r


def test_short_runs_are_compared_with_the_models_prediction_of_them(capsys):
    """Runs of 100 steps from the uniform start, no burn-in, on lab: far from the limit
    (TV several floors), and the model's prediction of exactly those runs (the horizon
    coverage of steps 0 … 99, ``tv_runs``) within the sampling floor; validate says the
    runs are too short for the limit. With the default burn-in and long runs the two
    predictions agree (``runs_to_limit`` well below the floor).
    """
    short = LAB + ["--angles", "30", "--model", "event", "--steps", "40000", "--burn-in", "0",
                   "--json"]
    assert main(short) == 0
    io = capsys.readouterr()
    (row,) = [json.loads(line) for line in io.out.splitlines() if line.strip()]
    assert row["tv"] > 2.5 * row["floor"] and row["runs_to_limit"] > 2 * row["floor"]
    assert row["tv_runs"] < 1.2 * row["floor"]
    assert "are too short for the limit" in io.err
    full = LAB + ["--angles", "30", "--model", "event", "--steps", "200000", "--json"]
    assert main(full) == 0
    io = capsys.readouterr()
    (row,) = [json.loads(line) for line in io.out.splitlines() if line.strip()]
    assert row["runs_to_limit"] < 0.5 * row["floor"] and "too short" not in io.err
    assert abs(row["tv_runs"] - row["tv"]) <= row["runs_to_limit"] + 1e-12   # triangle


def test_validate_takes_the_mujoco_bodys_contact_rule_and_turn_errors():
    """--contact auto and --body-turns auto follow --backend: MuJoCo's turn-in rule and its
    declared turn errors (docs/model.md §9, §11b); the twin declares neither.
    """
    import argparse

    from bouncesim.commands.common import contact_rule
    from bouncesim.commands.validate import body_turn_errors
    from bouncesim.robots.mujoco.robot import DECLARED_REST_TURNS, DECLARED_TURNS, DECLARED_TURNS_AT
    from envs.motion import MUJOCO_CONTACT, PYBULLET_CONTACT
    rule = {b: contact_rule(argparse.Namespace(contact="auto", backend=b, model="event"))
            for b in ("kinematic", "pybullet", "mujoco")}
    assert rule == {"kinematic": None, "pybullet": PYBULLET_CONTACT, "mujoco": MUJOCO_CONTACT}
    assert body_turn_errors("mujoco")[0] == DECLARED_TURNS == body_turn_errors("mujoco", 0.3)[0]
    assert body_turn_errors("mujoco", 0.2)[0] == DECLARED_TURNS_AT[0.2]
    assert body_turn_errors("mujoco", 0.25)[0] is None       # not measured at that speed
    assert body_turn_errors("mujoco")[1] == DECLARED_REST_TURNS
    assert body_turn_errors("kinematic") == body_turn_errors("pybullet") == (None, None)


def test_an_explicit_body_turns_spec_turns_the_twin_as_it_tells_the_model(capsys):
    """--body-turns gauss:S,offset=O on the kinematic backend: the model adds the errors and
    the twin turns with them. The model's coverage with a 5° offset and without it lie more
    than 0.1 apart in TV; each agrees with its own twin within 1.5 floors + 0.01, so the
    twin must have turned with the offset it was given.
    """
    import envs
    from planners.cells import CellSpace
    from planners.coverage import TurnNoise, model_for
    from planners.metrics import tv_distance
    model = model_for(CellSpace(envs.load("lab", orientations=72)), "event")
    base = TurnNoise(5, 0.8)
    spec = "gauss:0.5,offset=5"
    apart = tv_distance(model.analyse(75.0, base).q, model.analyse(75.0, base.with_body(spec)).q)
    assert apart > 0.1
    args = LAB + ["--angles", "75", "--model", "event", "--steps", "100000", "--json"]
    assert main(args + ["--body-turns", spec]) == 0
    (told,) = _rows(capsys)
    assert main(args + ["--body-turns", "off"]) == 0
    (plain,) = _rows(capsys)
    assert told["body_turns"] == spec and plain["body_turns"] is None
    for r in (told, plain):
        assert r["floor"] < apart / 4 and r["tv"] <= 1.5 * r["floor"] + 0.01, r
    assert main(LAB + ["--angles", "75", "--robots", "2", "--body-turns", spec,
                       "--steps", "100"]) == 2
    assert "single robots" in capsys.readouterr().err
