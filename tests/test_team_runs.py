"""Coverage runs of teams (bouncesim.runs.team_runs) and ``validate --robots``: counting, a
hand-computed corridor where the two robots meet on every other flight, and the CLI.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

import envs
from bouncesim.cli import main
from bouncesim.robots.noise import NoNoise
from bouncesim.runs.team_runs import team_coverage
from envs import UserError
from planners.cells import CellSpace

CORRIDOR = envs.Environment.from_dict({
    "name": "corridor", "boundary": [[0, 0], [1.36, 0], [1.36, 0.34], [0, 0.34]],
    "robot_radius": 0.17, "discretization": {"cell_size": 0.34, "orientations": 4}})


def test_two_robots_in_a_corridor_meet_on_every_other_flight():
    cs = CellSpace(CORRIDOR)
    # robot 0 in cell 0 facing east, robot 1 in cell 3 facing west; they bounce by 180°
    res = team_coverage(CORRIDOR, 180.0, NoNoise(), robots=2, steps=30, burn_in=0,
                        interact="bump", rng=np.random.default_rng(0), cells=cs,
                        starts=[cs.z(0, 0), cs.z(3, 2)])
    # by hand: they meet half-way (centres 0.34 m apart at x = 0.51 and 0.85, 0.34 m each, one
    # step and a bump step), turn, reach their walls (one step and a bump step), turn, meet...
    # every flight is 2 steps, so 15 flights each; flights 1, 3, ..., 15 end at the other
    # robot: 8 meetings each
    assert res.flights == 2 * 15 and res.meetings == 2 * 8
    assert res.per_robot[0].tolist() == [15, 15, 0, 0]
    assert res.per_robot[1].tolist() == [0, 0, 15, 15]
    turn = np.pi * 0.235 / 2 / 0.1                     # 180° at wheel speeds ±0.1 m/s [s]
    assert res.seconds == pytest.approx(15 * 0.34 / 0.2 + 14 * turn, abs=1e-6)


def test_robots_that_pass_through_each_other_never_meet_and_count_every_step():
    res = team_coverage(envs.load("lab"), 75.0, NoNoise(), robots=3, steps=500, burn_in=50,
                        interact="off", rng=np.random.default_rng(2))
    assert res.meetings == 0
    assert res.per_robot.sum(axis=1).tolist() == [500, 500, 500]     # lab drops no steps
    with pytest.raises(UserError, match="1 to 48 robots"):
        team_coverage(envs.load("lab"), 75.0, NoNoise(), robots=49, steps=1,
                      rng=np.random.default_rng(0))


def test_validate_teams(capsys):
    common = ["validate", "lab", "--orientations", "8", "--angles", "90", "--eps", "0",
              "--r", "1", "--steps", "4000", "--workers", "1", "--json"]
    assert main(common + ["--robots", "2", "--interact", "off"]) == 0
    off = json.loads(capsys.readouterr().out)
    assert off["robots"] == 2 and off["interact"] == "off"
    assert off["meetings_per_1000_steps"] == 0 and off["steps"] == 4000
    assert main(common + ["--robots", "4"]) == 0
    bump = json.loads(capsys.readouterr().out)
    assert bump["interact"] == "bump" and bump["meetings_per_1000_steps"] > 0
    for extra, message in ((["--interact", "bump"], "give --robots K"),
                           (["--robots", "2", "--alpha", "1"], "one angle at a time"),
                           (["--robots", "0"], "at least 1")):
        assert main(common + extra) == 2
        assert message in capsys.readouterr().err


def test_first_visits_and_the_covered_fraction_by_hand():
    cs = CellSpace(CORRIDOR)
    res = team_coverage(CORRIDOR, 180.0, NoNoise(), robots=2, steps=6, burn_in=0,
                        interact="bump", rng=np.random.default_rng(0), cells=cs,
                        starts=[cs.z(0, 0), cs.z(3, 2)])
    # robot 0: step 0 in cell 0, step 1 (its bump step) in cell 1; robot 1 mirrored
    assert res.first_visit.tolist() == [0, 1, 1, 0]
    assert res.covered([1, 2, 10]).tolist() == [0.5, 1.0, 1.0]
    alone = team_coverage(CORRIDOR, 180.0, NoNoise(), robots=1, steps=6, burn_in=0,
                          interact="bump", rng=np.random.default_rng(0), cells=cs,
                          starts=[cs.z(0, 0)])
    assert alone.first_visit.tolist() == [0, 1, 2, 3]      # a lone robot sweeps the corridor


def test_team_cover_quick(tmp_path):
    import pandas as pd

    from experiments import team_cover
    assert team_cover.main(["--quick", "--out", str(tmp_path)]) == 0
    t = pd.read_csv(tmp_path / "team_cover.csv")
    assert t["mode"].tolist() == ["model (independent)", "twin team, off", "twin team, bump"]
    assert t.contacts_per_1000.tolist()[:2] == [0.0, 0.0] and t.contacts_per_1000[2] > 0
    # the model and the passing team meet (share a cell) often in lab's 48 cells; bumping
    # robots are disks and share cells far less
    assert (t.meet_reached[:2] > 0.9).all() and (t.colocated_per_1000[:2] > 50).all()
    assert t.colocated_per_1000[2] < t.colocated_per_1000[1]
    assert np.isnan(t.contact_first[:2]).all() and t.contact_first[2] >= 0
    c = t[[col for col in t.columns if col.startswith("C(")]].to_numpy()
    assert (np.diff(c, axis=1) >= 0).all() and (c <= 1).all()     # C(t) grows to at most 1


def test_team_cover_runs_a_map_given_on_the_command_line(tmp_path, capsys):
    import pandas as pd

    from experiments import team_cover
    assert team_cover.main(["--quick", "--case", "lab:90:32", "--out", str(tmp_path)]) == 0
    t = pd.read_csv(tmp_path / "team_cover.csv")
    assert t["map"].tolist() == ["lab"] * 3 and (t.angle == 90).all()
    assert [c for c in t.columns if c.startswith("C(")] == ["C(2)", "C(4)", "C(8)", "C(16)",
                                                             "C(32)"]
    assert team_cover.main(["--case", "lab:90", "--out", str(tmp_path)]) == 2
    assert "MAP:ANGLE:T" in capsys.readouterr().err
