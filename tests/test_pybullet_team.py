"""Teams of PyBullet Create 2 bodies that bump each other (PyBulletBatch(interact="bump"),
``validate --robots K --backend pybullet``; docs/model.md §24).

Independent evidence: two robots driven head-on, whose meeting point follows from the
geometry alone (each drives half of the gap between them less one body diameter), the same
world with the robots passing through each other, and the starts' cells.
"""

from __future__ import annotations

import importlib.util
import json

import numpy as np
import pytest

import envs
from bouncesim.cli import main
from bouncesim.robots.noise import NoNoise
from envs import UserError
from planners.cells import CellSpace

pytestmark = [pytest.mark.physics,
              pytest.mark.skipif(importlib.util.find_spec("pybullet") is None,
                                 reason="pybullet is not installed")]


@pytest.fixture(scope="module")
def lab8():
    env = envs.load("lab")
    return env, CellSpace(env)


def _head_on(lab8, interact):
    """Robot 0 in the bottom row's first cell facing east, robot 1 four cells east facing
    west, both bouncing by 180° without turn noise, two steps each.
    """
    from bouncesim.robots.pybullet.batch import PyBulletBatch
    env, cs = lab8
    row = [p for p in range(cs.P) if abs(cs.centres[p][1] - cs.centres[0][1]) < 1e-9]
    p, q = row[0], row[4]
    with PyBulletBatch(env, 2, np.random.default_rng(0), cells=cs, noise=NoNoise(),
                       starts=[cs.z(p, 0), cs.z(q, cs.K // 2)], interact=interact) as batch:
        run = batch.run(180.0, 2)
        return run, batch.host.body_radius, cs.centres[p][0], cs.centres[q][0]


def test_two_robots_head_on_meet_where_their_disks_touch(lab8):
    run, r_body, x0, x1 = _head_on(lab8, "bump")
    # 1.36 m apart: each drives (1.36 - 2 r_body) / 2 = 0.512 m, one forward step of h and
    # a bump step that another robot ended
    travel = (x1 - x0 - 2 * r_body) / 2
    assert run.meetings.tolist() == [1, 1] and run.bumps.tolist() == [1, 1]
    assert run.poses[0, 0] == pytest.approx(x0 + travel, abs=0.004)
    assert run.poses[1, 0] == pytest.approx(x1 - travel, abs=0.004)
    assert run.poses[1, 0] - run.poses[0, 0] == pytest.approx(2 * r_body, abs=0.003)


def test_robots_that_pass_through_each_other_never_meet(lab8):
    run, _, x0, x1 = _head_on(lab8, "off")
    # two forward steps of h each, through each other
    assert run.meetings.tolist() == [0, 0] and run.bumps.tolist() == [0, 0]
    assert run.poses[0, 0] == pytest.approx(x0 + 0.68, abs=0.01)
    assert run.poses[1, 0] == pytest.approx(x1 - 0.68, abs=0.01)


def test_a_team_starts_in_distinct_cells_and_meets(lab8):
    from bouncesim.robots.pybullet.batch import PyBulletBatch
    env, cs = lab8
    # all 48 cells taken: every robot draws again until its cell is free
    with PyBulletBatch(env, cs.P, np.random.default_rng(1), cells=cs, interact="bump") as b:
        starts = cs.cell_of_point(b.run(90.0, 0).poses[:, :2])
    assert sorted(starts.tolist()) == list(range(cs.P))
    with PyBulletBatch(env, cs.P, np.random.default_rng(1), cells=cs) as b:
        alone = cs.cell_of_point(b.run(90.0, 0).poses[:, :2])
    assert len(set(alone.tolist())) < cs.P     # independent robots share cells
    with pytest.raises(UserError, match="1 to 48 robots"):
        PyBulletBatch(env, cs.P + 1, np.random.default_rng(1), cells=cs, interact="bump")
    with pytest.raises(UserError, match="off or bump"):
        PyBulletBatch(env, 2, np.random.default_rng(1), cells=cs, interact="yes")
    # four robots in lab's 48 cells meet often; passing through, never
    for interact in ("bump", "off"):
        with PyBulletBatch(env, 4, np.random.default_rng(2), cells=cs,
                           interact=interact) as b:
            run = b.run(90.0, 150, burn_in=10)
        assert (run.meetings.sum() > 0) == (interact == "bump")
        assert run.total == 4 * 150


def test_validate_runs_pybullet_teams(capsys):
    common = ["validate", "lab", "--angles", "90", "--eps", "0", "--r", "1",
              "--steps", "400", "--workers", "1", "--json", "--robots", "4"]
    assert main(common + ["--backend", "pybullet"]) == 0
    row = json.loads(capsys.readouterr().out)
    assert row["robots"] == 4 and row["interact"] == "bump" and row["steps"] == 400
    assert row["meetings_per_1000_steps"] > 0 and row["backend"] == "pybullet"
    assert main(common + ["--backend", "mujoco"]) == 2
    assert "no --backend mujoco" in capsys.readouterr().err
