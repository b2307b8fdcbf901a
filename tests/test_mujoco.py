"""The MuJoCo Create 2 (bouncesim.robots.mujoco): the conformance suite, bumps against
hand-computed wall distances, turns, the world's geometry, collision filtering and the
paper's Fig. 3 plan on the lab through ``run-plan --robot mujoco``.

Independent evidence: wall distances computed by hand from the room's coordinates, the
encoder counts a 90° turn must give (508.8 counts per 0.072π m of wheel travel), and the
step model's plan (the planner) for the run-plan outcome.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import envs
from bouncesim.cli import main
from bouncesim.robots import check_robot, make_robot
from bouncesim.robots.conformance import room_env
from envs import UserError

mujoco = pytest.importorskip("mujoco")

from bouncesim.robots.mujoco import MuJoCoRobot  # noqa: E402
from bouncesim.robots.mujoco.world import world_xml  # noqa: E402

pytestmark = pytest.mark.physics


def hdiff(a: float, b: float) -> float:
    """A − b for headings [deg], wrapped to (−180, 180]."""
    return (a - b + 180.0) % 360.0 - 180.0


def test_conformance_all_checks():
    assert len(check_robot(MuJoCoRobot)) >= 12
    assert len(check_robot("mujoco")) >= 12


def test_bump_stops_at_the_hand_computed_wall_distance():
    # lab: the obstacle touching the east wall has its west face at x = 2.38 for 0.34 <= y
    # <= 1.02; from (0.51, 0.68) facing east the free travel is 2.38 - 0.17 - 0.51 = 1.70 m
    with MuJoCoRobot("lab") as bot:
        bot.place(0.51, 0.68, 0.0)
        ev = bot.drive_until_bump(0.2, 30.0)
        x, y, h = bot.true_pose()
        assert ev.bumped and ev.left and ev.right
        assert abs(0.2 * ev.elapsed - 1.70) <= 0.02
        assert abs(x - (2.38 - 0.17)) <= 5e-3 and abs(y - 0.68) <= 1e-3
        assert abs(h) <= 0.5


def test_bump_in_a_corner_sees_the_nearest_wall_side():
    # heading 60° from (1.3, 0.51) in the conformance room: the north wall y = 1.02 is met
    # ahead-left (bearing 30°), the left switch only
    with MuJoCoRobot(room_env()) as bot:
        bot.place(1.3, 0.51, 60.0)
        ev = bot.drive_until_bump(0.2, 10.0)
        _, y, _ = bot.true_pose()
        assert ev.bumped and ev.left and not ev.right
        assert abs(y - (1.02 - 0.17)) <= 5e-3


def test_turn_90_and_its_encoder_counts():
    with MuJoCoRobot(room_env()) as bot:
        bot.place(0.85, 0.51, 10.0)
        e0 = bot.encoders()
        t0 = bot.clock()
        bot.turn(90.0)
        x, y, h = bot.true_pose()
        e1 = bot.encoders()
        assert abs(hdiff(h, 100.0)) <= 1.0
        assert math.hypot(x - 0.85, y - 0.51) <= 2e-3
        # 90° at 0.1 m/s wheels: quarter of the 0.235π m turning circle per wheel
        counts = (math.pi * 0.235 / 4) / (math.pi * 0.072 / 508.8)
        assert abs((e1[1] - e0[1]) - counts) <= 0.03 * counts
        assert abs((e0[0] - e1[0]) - counts) <= 0.03 * counts
        # by the clock: φ / ω with ω = 2 · 0.1 / 0.235 rad/s, plus two settle steps
        assert abs(bot.clock() - t0 - (math.pi / 2) / (0.2 / 0.235)) <= 0.02


def test_turn_noise_is_drawn_from_the_seeded_rng():
    from bouncesim.robots.noise import parse_noise

    def final(seed):
        with MuJoCoRobot(room_env(), parse_noise("gauss:5", 45.0), seed) as bot:
            bot.place(0.85, 0.51, 0.0)
            bot.turn(90.0)
            return bot.true_pose()[2]
    assert final(1) == final(1)
    assert abs(final(1) - final(2)) > 0.01


def test_noise_without_rng_is_refused():
    from bouncesim.robots.noise import parse_noise
    with pytest.raises(UserError):
        MuJoCoRobot(room_env(), parse_noise("gauss:1", 45.0))


def test_place_into_a_wall_is_refused_and_closed_robot_raises():
    bot = MuJoCoRobot(room_env())
    with pytest.raises(UserError, match="overlap a wall"):
        bot.place(0.05, 0.51, 0.0)
    bot.close()
    bot.close()
    with pytest.raises(Exception, match="closed"):
        bot.drive(0.1)


def test_world_walls_match_the_environment():
    env = envs.load("lab")
    model = mujoco.MjModel.from_xml_string(world_xml(env, 1))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    geomid = np.zeros(1, np.int32)
    # horizontal rays at mid-wall height from free points hit the walls where shapely says
    rng = np.random.default_rng(0)
    import shapely
    hits = 0
    for _ in range(40):
        x, y, _ = env.random_pose(rng)
        a = rng.uniform(0, 2 * math.pi)
        d = np.array([math.cos(a), math.sin(a), 0.0])
        dist = mujoco.mj_ray(model, data, np.array([x, y, 0.15]), d, None, 1, -1, geomid)
        far = shapely.LineString([(x, y), (x + 10 * d[0], y + 10 * d[1])])
        cut = far.intersection(env.walls)
        want = min(shapely.distance(shapely.points(x, y), g) for g in
                   shapely.get_parts(cut)) if not cut.is_empty else math.inf
        if math.isfinite(want):
            hits += 1
            assert abs(dist - want) <= 1e-6
    assert hits == 40


def test_robots_in_one_world_ignore_each_other():
    from bouncesim.robots.mujoco.robot import Bodies, place_body, pose_of
    env = room_env()
    model = mujoco.MjModel.from_xml_string(world_xml(env, 2))
    data = mujoco.MjData(model)
    bodies = Bodies(mujoco, model, 2)
    # both at the same spot, one driving east: it passes through the other
    place_body(mujoco, model, data, bodies, 0, 0.5, 0.51, 0.0, 0.036)
    place_body(mujoco, model, data, bodies, 1, 0.5, 0.51, 180.0, 0.036)
    data.ctrl[bodies.act[0]] = (0.2 / 0.036, 0.2 / 0.036)
    mujoco.mj_step(model, data, nstep=200)
    x0, _, _ = pose_of(data, bodies.qadr[0])
    x1, _, _ = pose_of(data, bodies.qadr[1])
    assert abs(x0 - 0.5 - 0.2) <= 0.01 and abs(x1 - 0.5) <= 1e-3


def test_make_robot_and_unknown_option():
    bot = make_robot("mujoco", room_env())
    assert isinstance(bot, MuJoCoRobot)
    bot.close()
    with pytest.raises(UserError, match="takes no option 'gui'"):
        make_robot("mujoco", room_env(), gui=True)


def test_run_plan_fig3_on_mujoco(capsys):
    rc = main(["run-plan", "lab", "--angles", "90,135", "--start", "8", "--goal", "0",
               "--robot", "mujoco", "--quiet"])
    out = capsys.readouterr().out
    assert rc == 0, out
    assert "success" in out


def test_batch_robot_follows_the_single_robot():
    """Robot 0 of a batch of three (the others elsewhere in the same world, ignored) bumps
    where one MuJoCoRobot driven by the same program bumps: same start, same turns.
    """
    from bouncesim.robots.mujoco.batch import MuJoCoBatch
    from bouncesim.robots.noise import NoNoise
    from planners.cells import CellSpace
    env = envs.load("lab")
    cs = CellSpace(env)
    with MuJoCoBatch(env, 3, 0, cells=cs, noise=NoNoise(), starts=[16, 40, 200],
                     speed=0.3) as batch:
        res = batch.run(90.0, 30, record=True)
    bumps = [t[:2] for t in res.turns[0]]
    assert len(bumps) >= 3
    # the same program on one robot, by hand: drive by the clock a cell at a time
    bot = MuJoCoRobot(env)
    bot.place(*cs.pose(16))
    got = []
    for _ in range(30):
        ev = bot.drive_for(0.3, cs.h / 0.3)
        if ev.bumped and 0.3 * ev.elapsed < cs.h:
            got.append(bot.true_pose()[:2])
            bot.turn(90.0)
    bot.close()
    assert len(got) == len(bumps)
    assert np.allclose(got, bumps, atol=5e-3)


@pytest.mark.slow
def test_validate_mujoco_backend_few_steps(capsys):
    import json
    assert main(["validate", "lab", "--orientations", "72", "--eps", "5", "--r", "0.8",
                 "--angles", "75", "--backend", "mujoco", "--steps", "128", "--burn-in",
                 "2", "--json"]) == 0
    r = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert r["backend"] == "mujoco" and r["steps"] == 128
    assert 0 <= r["bumps_per_step_sim"] <= 1 and 0 < r["tv"] <= 1
    assert math.isfinite(r["floor"])


def test_contact_calibration_quick_mujoco(tmp_path):
    """The MuJoCo body bumps at once above 10.5° (the ±80° arc), slides at 0.5°–1°, and in
    between turns into the wall and bumps (β between 1° and 3°, against PyBullet's 9.6°:
    the engines disagree there, docs/readme_physics_mujoco.md).
    """
    import json

    import pandas as pd

    from experiments import contact_calibration as cc
    out = tmp_path / "cc"
    assert cc.main(["--quick", "--backend", "mujoco", "--out", str(out)]) == 0
    cfg = json.loads((out / "config.json").read_text())
    assert cfg["backend"] == "mujoco"
    assert 1.0 <= cfg["fit"]["beta_deg"] <= 3.0
    t = pd.read_csv(out / "trials.csv")
    assert (t[t.incidence_deg >= 3].bump == 1).all()
    assert (t[t.incidence_deg <= 1].bump == 0).all()
    assert (t[t.incidence_deg >= 11].slide_m <= 1e-3).all()
    turned = t[(t.incidence_deg >= 3) & (t.incidence_deg <= 9)]
    assert (turned.heading_change_deg < -1.0).all()          # into the wall


def test_the_declared_turn_in_rule_is_what_the_engine_does():
    """The MuJoCo body declares its contact rule per drive speed (docs/model.md §9, §15a):
    at 0.2 and 0.3 m/s, default settings only. Driven into a wall at 4° and 7° the engine
    slides, turns in and bumps where the declared rule says: the slide within 20 % of L(α)
    and the bump heading within 0.3° of β (fitted from other trials: 144 at 2°-90°).
    """
    from bouncesim.robots.mujoco import MuJoCoRobot
    from bouncesim.runs.feedback import body_contact
    from envs.motion import MUJOCO_CONTACT, MUJOCO_CONTACTS
    from experiments.contact_calibration import trial, wall_room
    with MuJoCoRobot(wall_room()) as bot:
        assert body_contact(bot, 0.3) == MUJOCO_CONTACT and body_contact(bot) is None
        assert bot.contact_at(0.25) is None
        for speed in (0.2, 0.3):
            rule = bot.contact_at(speed)
            assert rule is MUJOCO_CONTACTS[speed]
            for alpha in (4.0, 7.0):
                rec = trial(bot, alpha, 0.002, speed, 3.0)
                assert rec["bump"] == 1
                assert rec["slide_m"] == pytest.approx(rule.slide_left(alpha), rel=0.2)
                assert alpha - rec["heading_change_deg"] == pytest.approx(rule.beta_deg,
                                                                          abs=0.3)
    with MuJoCoRobot(wall_room(), time_step=0.004) as bot:
        assert bot.contact_at(0.2) is None


def test_slides_do_not_depend_on_their_direction_in_the_world():
    """The declared rule is one rule for every wall, so the body's slides must not depend on
    the wall's direction in the world: from 7° the slide, its turn-in and its bump agree on
    the south and west walls of a square room within 1 cm and 0.05° (docs/model.md
    Appendix B; PyBullet's do not: 6 m without a bump on the south wall, 1.6 m on the west).
    """
    from experiments.contact_calibration import make_body, trial
    recs = {}
    for wall in ("south", "west"):
        with make_body("mujoco", 80.0, 3.0, wall) as bot:
            recs[wall] = trial(bot, 7.0, 0.002, 0.3, 3.0)
    s, w = recs["south"], recs["west"]
    assert s["bump"] == w["bump"] == 1
    assert w["slide_m"] == pytest.approx(s["slide_m"], abs=0.01)
    assert w["heading_change_deg"] == pytest.approx(s["heading_change_deg"], abs=0.05)
