"""Feedback navigation under the contact rule (docs/model.md §15 "Contact rule", §9).

Evidence: a glancing flight's slide and bump computed by hand in a 2 m × 2 m room; the pose
planner with the rule against the exact planner with the rule (§13, a second search); the
rule with β = 0 (which §9 reduces to the front-half bumper) against the rule off, to the
bit; the filter's support against the true pose of a twin that slides.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from bouncesim.robots.kinematic import KinematicRobot
from bouncesim.robots.noise import GaussianNoise
from bouncesim.runs.execute import navigate_feedback
from bouncesim.runs.feedback import body_contact
from envs import Environment
from envs.motion import PYBULLET_CONTACT, ContactParams
from planners.cells import CellSpace
from planners.navigation.exact import ExactNavigator
from planners.navigation.feedback import FeedbackConfig, FeedbackNavigator, ParticleFilter

from .test_feedback import ANGLES, RECT  # the 2 m square room and the plan angles

# 8 × 6 cells of 0.34 m; the north wall falls 0.24 m over 2.72 m (5.04° off the x axis),
# so flights at 0° and 180° under it meet it below β = 9.6° and slide
SLOPE = Environment.from_dict({
    "name": "sloped-room", "boundary": [[0, 0], [2.72, 0], [2.72, 2.04], [0, 1.8]],
    "obstacles": [[[1.2, 0.6], [1.55, 0.6], [1.55, 0.95], [1.2, 0.95]]],
    "robot_radius": 0.17, "discretization": {"cell_size": 0.34, "orientations": 8}})


def _glancing_flight():
    """The hand-computed flight from (0.5, 0.2) at −5° in RECT under PYBULLET_CONTACT:
    (straight to the south wall [m], clock to the bump [m], bump position).
    """
    a = math.radians(5.0)
    straight = (0.2 - 0.17) / math.sin(a)                # to the C-space wall y = 0.17
    x_contact = 0.5 + straight * math.cos(a)
    f = math.cos(a) - PYBULLET_CONTACT.slide_friction * math.sin(a)   # §9's speed factor
    slide = (2 - 0.17) - x_contact                         # along y = 0.17 to x = 1.83
    return straight, straight + slide / f, (2 - 0.17, 0.17)


# ---------------------------------------------------------------- the filter, by hand
def test_filter_with_the_contact_rule_predicts_a_slides_end():
    # incidence 5° < β = 9.6°: the robot slides east along the south wall at speed factor
    # cos 5° − μ sin 5° to the east wall, met at bearing +5° (both switches; the south wall
    # at −85° lies outside the ±80.4° arc). A particle at 30° (1.536 m, right switch) is
    # the alternative the reading must rule out.
    straight, clock, end = _glancing_flight()
    assert 1.3 < clock < 1.4 and straight < 0.35
    poses = [[0.5, 0.2, -5.0], [0.5, 1.0, 30.0]]
    cfg = FeedbackConfig(particles=2, contact=PYBULLET_CONTACT)
    pf = ParticleFilter(RECT, cfg, np.random.default_rng(0), poses=poses)
    up = pf.flight(clock, left=True, right=True)
    assert up.reinit == 0 and up.consistent == 1
    # the 30° particle cannot explain the reading but as a phantom bump: a sliver of weight
    # (no single reading zeroes a belief, docs/model.md §15)
    assert pf.weights[0] > 0.999 and 0 < pf.weights[1] < 1e-3
    assert np.allclose(pf.pos[0], end, atol=1e-6)
    assert (pf.heading[0] + 180) % 360 - 180 == pytest.approx(-5.0)


def test_filter_without_the_rule_cannot_explain_the_slide():
    # the front-half bumper stops the −5° particle at the south wall after 0.344 m with the
    # wall at −85° (right switch only): the reading fits no particle
    _, clock, _ = _glancing_flight()
    pf = ParticleFilter(RECT, FeedbackConfig(particles=2), np.random.default_rng(0),
                        poses=[[0.5, 0.2, -5.0], [0.5, 1.0, 30.0]])
    assert pf.flight(clock, left=True, right=True).consistent == 0


# ---------------------------------------------------------------- planning with the rule
def _routes(cells, contact, rng, n):
    exact = ExactNavigator(cells, ANGLES, contact=contact)
    plain = ExactNavigator(cells, ANGLES)
    found = differ = 0
    while found < n:
        s, g = (int(v) for v in rng.integers(0, cells.N, 2))
        route = exact.plan(s, g) if s != g else None
        if route is not None:
            found += 1
            other = plain.plan(s, g)
            differ += other is None or abs(other.cost - route.cost) > 1e-6
            yield s, g, route
    assert differ >= 1                   # the rule changed some plan: not a vacuous check


def test_plan_from_a_configuration_with_the_rule_is_the_exact_planners_plan():
    cells = CellSpace(SLOPE)
    for s, g, route in _routes(cells, PYBULLET_CONTACT, np.random.default_rng(3), 15):
        cfg = FeedbackConfig(guided=False, contact=PYBULLET_CONTACT)
        cand = FeedbackNavigator(cells, ANGLES, g, cfg).plan_from(*cells.pose(s))
        assert cand is not None
        assert cand.cost == pytest.approx(route.cost, abs=1e-6)
        ref = FeedbackNavigator(cells, ANGLES, g, FeedbackConfig(
            reference=True, contact=PYBULLET_CONTACT)).plan_from(*cells.pose(s))
        assert ref == cand                        # the fast search is the plain one


@pytest.mark.parametrize("sigma", [0.0, 3.0])
def test_fast_search_with_the_rule_gives_the_plain_searchs_plans(sigma):
    # the fast search calls the contact rule only where its first contact may lie outside
    # the arc; the plain one on every flight: the same plans to the bit from random poses
    from .test_feedback import fast_equals_plain_search
    fast_equals_plain_search(
        SLOPE, FeedbackConfig(turn_sigma_deg=sigma, guided=False, contact=PYBULLET_CONTACT), 22)


# ---------------------------------------------------------------- runs
@pytest.mark.parametrize("sigma", [0.0, 2.0])
def test_rule_with_beta_zero_is_the_rule_off_bitwise(sigma):
    # §9: with β = 0 every front contact closes the bumper, the front-half bumper; the
    # contact code paths of the filter, the search and the scores must then change nothing
    cells = CellSpace(SLOPE)
    out = []
    for contact in (None, ContactParams(0.0, 0.0)):
        noise = GaussianNoise(sigma) if sigma else None
        run = navigate_feedback(KinematicRobot(SLOPE, noise, 1), SLOPE, 3, 40, noise,
                                np.random.default_rng(2), cells=cells, contact=contact)
        out.append((run.plan.exact_text(), run.final_pose, run.p_success, run.reason,
                    [u.consistent for u in run.updates]))
    assert out[0] == out[1]


def test_body_contact_is_the_bodys_rule():
    assert body_contact(KinematicRobot(RECT)) is None
    assert body_contact(KinematicRobot(RECT, glance_deg=80)) == ContactParams(10.0, 0.0)
    assert body_contact(KinematicRobot(RECT, contact=PYBULLET_CONTACT)) == PYBULLET_CONTACT


def test_filter_holds_the_true_pose_of_a_sliding_twin():
    # the twin with PyBullet's rule, noise-free, on pairs the rule's exact plans reach:
    # after every flight some particle lies within 1 cm and 1° of the twin's pose, no
    # reading needs a re-initialisation, and the run reaches the goal; some flights slid
    from envs.motion import casters
    from planners.navigation.feedback.filter import landings
    caster = casters(SLOPE)[0]
    cells = CellSpace(SLOPE)
    rng = np.random.default_rng(7)
    slid = 0
    for i, (s, g, _) in enumerate(_routes(cells, PYBULLET_CONTACT, rng, 5)):
        bot = KinematicRobot(SLOPE, contact=PYBULLET_CONTACT)
        near, before = [], [cells.pose(s)]

        def check(event, belief, bot=bot, near=near, before=before):
            x, y, th = bot.true_pose()
            if event == "turn":
                before.append((x, y, th))
                return
            dpos = np.hypot(belief.pos[:, 0] - x, belief.pos[:, 1] - y)
            dth = np.abs((belief.heading - th + 180) % 360 - 180)
            near.append(bool(((dpos <= 0.01) & (dth <= 1.0) & (belief.weights > 0)).any()))

        run = navigate_feedback(bot, SLOPE, s, g, None, np.random.default_rng(i),
                                cells=cells, on_belief=check)
        assert run.success, run.reason
        assert run.reinits == 0 and near and all(near)
        px, py, ph = (np.array(v) for v in zip(*before))
        slid += int(landings(caster, np.column_stack([px, py]), ph, PYBULLET_CONTACT)[3].sum())
    assert slid >= 1


def test_the_filter_follows_a_body_that_turns_in():
    """MuJoCo's contact rule turns a sliding body into the wall (docs/model.md §9). The
    flights the filter casts (compiled) end where the twin's drive (plain Python) ends and
    with its heading, for glancing starts; and a feedback run on that twin, told the rule by
    the body (contact "auto", so it decides by value: the plan search does not follow a
    turn-in), keeps a particle within 1 cm and 1° of the twin after every flight.
    """
    from envs.motion import MUJOCO_CONTACT, casters
    from planners.navigation.feedback.filter import landings
    caster = casters(SLOPE)[0]
    rng = np.random.default_rng(3)
    turned = 0
    for i in range(40):                 # half of them 2°-9° into the south wall
        bot = KinematicRobot(SLOPE, contact=MUJOCO_CONTACT)
        x, y, th = SLOPE.random_pose(rng)
        if i % 2:
            x, y, th = rng.uniform(0.3, 1.0), 0.3, -rng.uniform(2.0, 9.0)
        bot.place(x, y, th)
        bot.drive_until_bump(0.2, 600.0)
        bx, by, bth = bot.true_pose()
        _, end, _, slid, _, head = landings(caster, np.array([[x, y]]), np.array([th]),
                                             MUJOCO_CONTACT)
        assert end[0] == pytest.approx((bx, by), abs=1e-6)
        assert abs((head[0] - bth + 180) % 360 - 180) <= 1e-6
        turned += int(slid[0] and abs((bth - th + 180) % 360 - 180) > 0.1)
    assert turned >= 15
    cells = CellSpace(SLOPE)
    bot = KinematicRobot(SLOPE, contact=MUJOCO_CONTACT)
    near = []

    def check(event, belief):
        if event == "turn":
            return
        x, y, th = bot.true_pose()
        dpos = np.hypot(belief.pos[:, 0] - x, belief.pos[:, 1] - y)
        dth = np.abs((belief.heading - th + 180) % 360 - 180)
        near.append(bool(((dpos <= 0.01) & (dth <= 1.0) & (belief.weights > 0)).any()))

    run = navigate_feedback(bot, SLOPE, 5, cells.N - 20, None, np.random.default_rng(1),
                            cells=cells, on_belief=check)
    assert near and all(near), near
    assert run.reinits == 0
