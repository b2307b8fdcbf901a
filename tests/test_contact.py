"""The contact rule of docs/model.md §9 (``envs.contact``), shared by the twin and the event
model.

Independent evidence: slides computed by hand from the geometry (a 5° incidence into a
straight wall, then the corner), the corner wrap's clock against numerical quadrature of its
ODE, the twin's histogram against the event model within the simulation's own noise, and the
rule at β = 0 reducing bitwise to the front-half bumper (the paper's model).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad

from bouncesim.robots.kinematic import KinematicBatch, KinematicRobot
from envs.contact import advance, leg_length
from envs.motion import PYBULLET_CONTACT, STEP_TOL, ContactParams, casters, flight_steps
from planners.cells import CellSpace
from planners.coverage import TurnNoise
from planners.coverage.event import EventModel, EventSettings
from planners.metrics import tv_distance
from planners.plan import PolicyMix

from .conftest import room

R = 0.17
RULE = ContactParams(beta_deg=9.6, slide_friction=0.006)


def _deg(a: float) -> tuple[float, float]:
    return math.cos(math.radians(a)), math.sin(math.radians(a))


def _hand_slide(x0: float, y0: float, alpha: float, x_end: float, rule: ContactParams):
    """A robot at (x0, y0) heading −alpha° towards the wall y = R (C-space): the straight
    drive to the wall, the slide to x_end, and the clock length of both.
    """
    a = math.radians(alpha)
    straight = (y0 - R) / math.sin(a)
    x_hit = x0 + straight * math.cos(a)
    slide = x_end - x_hit
    f = math.cos(a) - rule.slide_friction * math.sin(a)
    return straight, slide, straight + slide / f


def test_slide_at_5_degrees_into_a_wall_then_the_corner_by_hand():
    env = room(9, 4)                                  # 3.06 m x 1.36 m, no obstacle
    caster = casters(env)[0]
    x0, y0 = 0.5, 0.3
    straight, slide, clock = _hand_slide(x0, y0, 5.0, 3.06 - R, RULE)
    assert slide == pytest.approx(0.9041, abs=1e-4)   # x_hit = 0.5 + 0.13 / tan 5°
    ux, uy = _deg(-5.0)
    x, y, used, bumped, legs, _ = advance(caster, x0, y0, ux, uy, RULE)
    # slides along the south wall into the south-east corner, where the east wall is met at
    # 85° incidence (bearing 5°): a bump
    assert bumped and (x, y) == pytest.approx((3.06 - R, R), abs=1e-8)
    assert used == pytest.approx(clock, abs=1e-8)
    assert legs[1][0] == "line" and legs[1][3:5] == (1.0, 0.0)    # due east, along the wall
    assert leg_length(legs[1]) == pytest.approx(slide, abs=1e-8)
    # the front-half bumper (no rule) stops at the first contact; 20° incidence bumps too
    x, y, used, bumped, _, _ = advance(caster, x0, y0, ux, uy, None)
    assert bumped and used == pytest.approx(straight, abs=1e-8) and y == pytest.approx(R)
    x, y, used, bumped, _, _ = advance(caster, x0, y0, *_deg(-20.0), RULE)
    assert bumped and used == pytest.approx(0.13 / math.sin(math.radians(20)), abs=1e-8)
    # the clock runs out mid-slide: the robot stops on the wall, not bumped
    x, y, used, bumped, _, _ = advance(caster, x0, y0, ux, uy, RULE, budget=straight + 0.5)
    assert not bumped and used == straight + 0.5
    f = math.cos(math.radians(5)) - 0.006 * math.sin(math.radians(5))
    assert x == pytest.approx(x0 + straight * math.cos(math.radians(5)) + 0.5 * f, abs=1e-8)


def test_twin_robot_and_batch_follow_the_hand_slide():
    """The one robot's elapsed time is clock / v; the batch counts floor((ℓ + tol)/h) forward
    steps then the bump step at the corner (docs/model.md §8 with §9's clock).
    """
    env = room(9, 4, K=72)
    x0, y0 = 0.5, 0.3
    _, _, clock = _hand_slide(x0, y0, 5.0, 3.06 - R, RULE)
    bot = KinematicRobot(env, contact=RULE)
    bot.place(x0, y0, 355.0)
    ev = bot.drive_until_bump(0.2, 60.0)
    assert ev.bumped and ev.elapsed == pytest.approx(clock / 0.2, rel=1e-9)
    assert bot.true_pose()[:2] == pytest.approx((3.06 - R, R), abs=1e-8)
    batch = KinematicBatch(env, 1, 0, contact=RULE, starts=[0])
    batch.pos[:] = (x0, y0)
    batch.heading = np.array([355.0])
    n = int(flight_steps(clock, env.cell_size))
    bumps = [bool(batch.step(90.0)[1][0]) for _ in range(n + 1)]
    assert bumps == [False] * n + [True]
    assert batch.pos[0] == pytest.approx((3.06 - R, R), abs=1e-8)
    assert clock - n * env.cell_size < env.cell_size - STEP_TOL


def test_corner_wrap_clock_matches_quadrature():
    """Wrapping round a convex corner at incidence γ0 with friction μ: clock
    r ∫₀^γ0 dγ / (cos γ − μ sin γ), ending abeam the corner (then straight on).
    """
    env = room(6, 4, obstacles=[(3, 1, 4, 3)])       # block [1.02, 1.36] x [0.34, 1.02]
    caster = casters(env)[0]
    rule = ContactParams(beta_deg=15.0, slide_friction=0.05)
    d = R - 0.001                                     # passes 1 mm inside the corner's reach
    y0 = 0.34 - d
    x, y, used, bumped, legs, _ = advance(caster, 0.3, y0, 1.0, 0.0, rule)
    g0 = math.acos(d / R)                             # incidence on the corner circle, 6.2°
    assert 0 < math.degrees(g0) < 15
    wrap = R * quad(lambda g: 1.0 / (math.cos(g) - 0.05 * math.sin(g)), 0.0, g0)[0]
    x_touch = 1.02 - math.sqrt(R * R - d * d)
    assert [leg[0] for leg in legs][:3] == ["line", "arc", "line"]
    assert bumped and (x, y) == pytest.approx((2.04 - R, 0.34 - R), abs=1e-8)
    assert used == pytest.approx((x_touch - 0.3) + wrap + (2.04 - R - 1.02), rel=1e-9)


@pytest.mark.parametrize("heading", [268.5, 269.0, 271.5])
@pytest.mark.parametrize("tick", [0.0075, 0.004, 0.013])
def test_a_drive_in_ticks_slides_past_a_face_end_like_one_drive(heading, tick):
    """Sliding down a block's face at 1-1.5° into it: a drive cut into ticks (as the Create 2
    emulator drives) must pass the face's end as one drive does. A tick that stops within
    BUMP_RANGE's reach of the end touches the face and its end vertex, one surface (it once
    counted them as a pocket, a bump no switch reads, and the robot stayed there).
    """
    env = room(8, 6, obstacles=[(3, 2, 4, 3)])       # block [1.02, 1.36] x [0.68, 1.02]
    caster = casters(env)[0]
    rule = ContactParams(beta_deg=10.0)
    side = 1.36 + R if heading < 270 else 1.02 - R    # touching the face, heading into it
    ux, uy = _deg(heading)
    # the face ends at y = 0.68; start so that a tick stops just above the end, within reach
    # of the end vertex (the stuck case: 6.7e-5 m above it)
    y0 = 0.68 + 6.7e-5 - 20 * tick * uy
    x1, y1, used, bumped, _, _ = advance(caster, side, y0, ux, uy, rule)
    assert bumped and y1 == pytest.approx(R, abs=1e-8)  # one drive: down to the south wall
    for off in (2e-5, 6.7e-5, 3e-4):                  # from just above the end: on, no bump
        _, y, u, b, _, _ = advance(caster, side, 0.68 + off, ux, uy, rule, tick)
        assert not b and u == tick and y < 0.68
    x, y, t = side, y0, 0.0
    for _ in range(2000):
        x, y, u, b, _, _ = advance(caster, x, y, ux, uy, rule, tick)
        t += u
        if b:
            break
    assert b and (x, y) == pytest.approx((x1, y1), abs=1e-6)
    assert t == pytest.approx(used, abs=1e-6)


def test_rule_with_beta_zero_is_the_front_half_bumper_bitwise():
    """β = 0: every front contact closes the bumper, so the shared rule must reproduce the
    paper's model exactly, in the event model and in the twin batch.
    """
    env = room(5, 4, obstacles=[(2, 1, 3, 2)], K=24)
    cs = CellSpace(env)
    noise = TurnNoise(15.0, 0.8)
    off = EventModel(cs, EventSettings()).analyse(75.0, noise).q
    zero = EventModel(cs, EventSettings(contact=ContactParams(0.0, 0.0))).analyse(75.0, noise).q
    assert np.array_equal(off, zero)
    runs = [KinematicBatch(env, 20, 3, cells=cs, contact=c).run(75.0, 300)
            for c in (None, ContactParams(0.0, 0.0))]
    assert np.array_equal(runs[0].counts, runs[1].counts) and runs[0].bumps == runs[1].bumps


def _twin_against(env, cs, rule, q):
    """Two independent halves of the twin under ``rule`` (100 robots × 600 steps each, 100
    of burn-in; 75°, ε = 5°, r = 0.8): (their TV, the floor; TV(q, pooled); bumps per step).
    """
    mix = PolicyMix((75.0,), (1.0,), 5.0, 0.8)               # the same ε, r in the twin
    halves = [KinematicBatch(env, 100, seed, cells=cs, contact=rule).run(
        mix, 600, burn_in=100) for seed in (1, 2)]
    counts = [h.counts.astype(float) for h in halves]
    bumps = sum(h.bumps for h in halves) / sum(h.total for h in halves)
    return tv_distance(counts[0], counts[1]), tv_distance(q, counts[0] + counts[1]), bumps


def test_twin_and_event_model_agree_with_the_contact_rule():
    """A small room with an interior block (straight slides and corner wraps), K = 72, 75°,
    ε = 5°, r = 0.8: TV(event q, twin q̂) at most 1.5 × the floor (two independent halves)
    plus 0.01, as tests/test_validate.py bounds it without the rule, at 1 cm contact bins
    (measured: TV 0.011 on, 0.008 off at 6·10⁵ steps; 0.021 and 0.019 at the default 3 cm);
    bumps per step within 0.02; and the rule lowers the bump rate by more than that.
    """
    env = room(5, 4, obstacles=[(2, 1, 3, 2)], K=72)
    cs = CellSpace(env)
    noise = TurnNoise(5.0, 0.8)
    ac = EventModel(cs, EventSettings(0.01, contact=PYBULLET_CONTACT)).analyse(75.0, noise)
    off = EventModel(cs, EventSettings()).analyse(75.0, noise)
    floor, tv, bumps = _twin_against(env, cs, PYBULLET_CONTACT, ac.q)
    assert 0 < floor < 0.1
    assert tv <= 1.5 * floor + 0.01, (tv, floor)
    assert abs(bumps - 1.0 / ac.steps_per_flight) <= 0.02
    assert 1.0 / off.steps_per_flight - 1.0 / ac.steps_per_flight > 0.03


def test_twin_and_event_model_agree_with_a_turn_in_rule():
    """MuJoCo's rule (slides that turn into the wall, then bump at 10.44°) in the same room,
    K = 360, 75°, ε = 5°, r = 0.8: TV(event q, twin q̂) at most 2 × the floor + 0.02
    (measured 0.030, floor 0.012: the twin's headings leave the 1° grid at every turn-in,
    which the model splits between the two nearest grid headings), bumps per step within
    0.01 (0.583 / 0.585); the rule moves the model by TV 0.18 from PyBullet's (bumps 0.539),
    far outside the bound.
    """
    from envs.motion import MUJOCO_CONTACT
    env = room(5, 4, obstacles=[(2, 1, 3, 2)], K=360)
    cs = CellSpace(env)
    noise = TurnNoise(5.0, 0.8)
    ac = EventModel(cs, EventSettings(contact=MUJOCO_CONTACT)).analyse(75.0, noise)
    pb = EventModel(cs, EventSettings(contact=PYBULLET_CONTACT)).analyse(75.0, noise)
    floor, tv, bumps = _twin_against(env, cs, MUJOCO_CONTACT, ac.q)
    assert 0 < floor < 0.05
    assert tv <= 2 * floor + 0.02, (tv, floor)
    assert abs(bumps - 1.0 / ac.steps_per_flight) <= 0.01
    assert tv_distance(ac.q, pb.q) > 0.1


def test_validate_contact_option(capsys):
    """--contact pybullet is an event-model option: the step model refuses it in one line."""
    from bouncesim.cli import main
    argv = ["validate", "lab", "--angles", "90", "--steps", "400", "--workers", "1",
            "--no-progress", "--model", "step", "--contact", "pybullet"]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "event model" in err[0]


# ---------------------------------------------------------------------------- turn-in slides
TURN = ContactParams(beta_deg=10.0, slide_friction=0.0, turn_in=((2.0, 2.0), (6.0, 0.5)))
"""L(α): 2 m from 2°, 0.5 m from 6°, 0 at β = 10° (linear between)."""


def test_a_turning_in_slide_bumps_at_beta_after_its_table_length_by_hand():
    """4° into the south wall of a 6 m room: L(4°) = 1.25 m of slide (halfway between the
    table's 2 m and 0.5 m), then the bump with the heading at β = 10° into the wall; the
    slide keeps its distance to the wall and costs 1.25 / cos β of clock (μ = 0: the speed
    factor of β throughout).
    """
    env = room(18, 4)                                 # 6.12 m x 1.36 m
    caster = casters(env)[0]
    x0, y0 = 0.5, 0.3
    ux, uy = _deg(-4.0)
    straight, _, _ = _hand_slide(x0, y0, 4.0, 0.0, TURN)
    x, y, used, bumped, legs, (vx, vy) = advance(caster, x0, y0, ux, uy, TURN)
    x_hit = x0 + straight * math.cos(math.radians(4.0))
    assert bumped and (x, y) == pytest.approx((x_hit + 1.25, R), abs=1e-8)
    assert math.degrees(math.atan2(vy, vx)) == pytest.approx(-10.0, abs=1e-9)
    assert used == pytest.approx(straight + 1.25 / math.cos(math.radians(10.0)), rel=1e-9)
    assert [leg[0] for leg in legs] == ["line", "line"]
    # below the table (1°) the heading is kept and the body slides to the east wall
    x, y, _, bumped, _, v = advance(caster, x0, y0, *_deg(-1.0), TURN)
    assert bumped and x == pytest.approx(6.12 - R, abs=1e-6) and v == _deg(-1.0)


def test_a_turning_in_slide_cut_short_goes_on_from_the_incidence_it_reached():
    """L depends on the incidence alone: a drive cut into clock ticks, each going on from
    the heading the last one ended with, ends where one drive ends, with its heading; and
    a wall that ends first (0.30 m of a block's face) hands the body on round its end at
    the incidence L⁻¹(L(α) − 0.30 m).
    """
    env = room(18, 4)
    caster = casters(env)[0]
    x0, y0 = 0.5, 0.3
    x1, y1, used, _, _, v1 = advance(caster, x0, y0, *_deg(-3.0), TURN)
    x, y, ux, uy, t = x0, y0, *_deg(-3.0), 0.0
    for _ in range(5000):
        x, y, u, b, _, (ux, uy) = advance(caster, x, y, ux, uy, TURN, 0.01)
        t += u
        if b:
            break
    assert b and (x, y) == pytest.approx((x1, y1), abs=1e-6)
    assert (ux, uy) == pytest.approx(v1, abs=1e-9) and t == pytest.approx(used, abs=1e-6)
    # along a face shorter than the slide: 0.30 m of the top face from 3°, L 1.625 ->
    # 1.325 m, so it wraps round the face's end at L⁻¹(1.325) = 3.8° (by hand from the table)
    env = room(18, 6, obstacles=[(4, 2, 5, 3)])      # block [1.36, 1.70] x [0.68, 1.02]
    caster = casters(env)[0]
    a0, top = 3.0, 1.02 + R
    x0 = 1.40 - 0.02 / math.tan(math.radians(a0))
    _, _, _, _, legs, _ = advance(caster, x0, top + 0.02, *_deg(-a0), TURN)
    assert [leg[0] for leg in legs[:3]] == ["line", "line", "arc"]
    assert legs[1][5] == pytest.approx(0.30, abs=1e-6)          # the face's slide
    assert math.degrees(legs[2][6]) == pytest.approx(3.8, abs=1e-6)


def test_the_twin_turns_in_with_the_rule():
    """The one-robot twin and the batch take the rule's end heading: 5° into a wall, they
    bump with the heading at β, at the table's slide from the contact.
    """
    env = room(18, 4)
    robot = KinematicRobot(env, contact=TURN)
    robot.place(0.5, 0.3, -5.0)
    ev = robot.drive_until_bump(0.3, 60.0)
    x, y, th = robot.true_pose()
    assert ev.bumped and th == pytest.approx(350.0, abs=1e-9)
    straight, _, _ = _hand_slide(0.5, 0.3, 5.0, 0.0, TURN)
    assert x == pytest.approx(0.5 + straight * math.cos(math.radians(5.0))
                              + TURN.slide_left(5.0), abs=1e-6)
