"""Corner bins of the event model (docs/model.md §5, §17): a contact in a concave corner is
binned to the corner itself, and its flights start there, as the twin's do.

Hand-computed on small rectangles of 0.34 m cells (r = 0.17 m, h = 0.34 m): a flight from a
corner along a wall of C-space length n·h is n − 2e-9 m long (CONTACT_GAP off at both ends),
within STEP_TOL of n steps, so it makes n forward steps at the cell centres along the wall and
bumps in the next corner. Before corner bins the corner's ordinary bin started its flights a
few mm along a wall, one forward step short (the limit of the 4 × 3 room at φ = 90° had no
step in four of the ten wall cells).
"""

from __future__ import annotations

import numpy as np
import pytest

from bouncesim.robots.kinematic import KinematicBatch
from envs.motion import CONTACT_GAP, GRAZE_TOL
from planners.boundary import Boundary
from planners.cells import CellSpace
from planners.coverage import EventModel, EventSettings

from .conftest import room

H = 0.34


def _flights_of(model: EventModel, state: int):
    """(landing state, steps, cells of the counted steps) of every sampled flight of a state."""
    src, dst, delay, _ = model.flights
    steps = model.flight_cells().steps
    return [(int(dst[f]), int(delay[f]), steps.cell[steps.flight == f].tolist())
            for f in np.flatnonzero(src == state)]


def test_rectangle_has_a_bin_for_each_corner():
    env = room(4, 3, K=4)                  # C-space [0.17, 1.19] x [0.17, 0.85], ring 3.4 m
    bd = Boundary(env, 0.03, corners=True)
    assert bd.n_ring_bins == 114 and bd.n_corners == 4 and bd.n_bins == 118
    assert Boundary(env, 0.03).n_bins == 114              # off by default (navigation)
    want = {(0.17, 0.17), (1.19, 0.17), (1.19, 0.85), (0.17, 0.85)}
    assert {tuple(v) for v in bd.corner_vertex.round(12).tolist()} == want
    for c, v in enumerate(bd.corner_vertex):
        b = bd.n_ring_bins + c
        inward = np.sign(np.array([0.68, 0.51]) - v)      # towards the room's middle
        np.testing.assert_allclose(bd.corner_point[c], v + CONTACT_GAP * inward, atol=1e-15)
        for frac in (0.0, 0.25, 1.0):
            assert bd.points([b], [frac]).tolist() == [bd.corner_point[c].tolist()]
        assert int(bd.bin_of(bd.corner_point[c][None])[0]) == b
    sw = bd.n_ring_bins + int(np.flatnonzero((bd.corner_vertex == 0.17).all(axis=1))[0])
    # within GRAZE_TOL of the corner: its bin; 1e-6 m along the south wall: an ordinary bin
    assert int(bd.bin_of([[0.17 + 0.5 * GRAZE_TOL, 0.17 + CONTACT_GAP]])[0]) == sw
    assert int(bd.bin_of([[0.17 + 1e-6, 0.17 + CONTACT_GAP]])[0]) < bd.n_ring_bins


@pytest.mark.parametrize("pillar", [False, True])
def test_flights_from_a_corner_start_in_it(pillar):
    # 3 x 4 cells; with a pillar on cell (1, 1), 0.34 m = 2r from the west and south walls, the
    # corner's flights along the walls pass the gaps of zero clearance (rect0's cells 7 and 9)
    env = room(3, 4, obstacles=[(1, 1, 2, 2)] if pillar else [], K=4)
    cs = CellSpace(env)
    model = EventModel(cs, EventSettings())
    bd, K = model.boundary, cs.K

    def corner(x, y):
        return bd.n_ring_bins + int(np.flatnonzero(
            np.isclose(bd.corner_vertex, [x, y]).all(axis=1))[0])

    def cells(*pts):
        return cs.cell_of_point(np.array(pts)).tolist()

    sw, se, nw = corner(0.17, 0.17), corner(0.85, 0.17), corner(0.17, 1.19)
    # from the south-west corner due east: 0.68 m, 2 forward steps and the bump in the corner
    assert _flights_of(model, sw * K + 0) == [
        (se * K + 0, 3, cells((0.17, 0.17), (0.51, 0.17), (0.85, 0.17)))] * 2
    # from the north-west corner due south: 1.02 m, 3 forward steps (through the gap)
    assert _flights_of(model, nw * K + 3) == [
        (sw * K + 3, 4, cells((0.17, 1.19), (0.17, 0.85), (0.17, 0.51), (0.17, 0.17)))] * 2
    # into either wall: a bump where it stands
    for k in (2, 3):
        assert _flights_of(model, sw * K + k) == [(sw * K + k, 1, cells((0.17, 0.17)))] * 2
    # the twin: from the centre of cell (0, 2) due south, the robot stops in the corner, and
    # the model's first flight from that configuration lands in the corner's bin
    p = cells((0.17, 0.85))[0]
    z = 3 * cs.P + p
    bot = KinematicBatch(env, 1, np.random.default_rng(0), cells=cs, starts=[z])
    bumped = [False]
    while not bumped[0]:
        _, bumped = bot.step(90.0)
    assert np.hypot(*(bot.pos[0] - [0.17, 0.17])) < 1e-8
    assert int(model.flight_cells().start_land[z]) == sw * K + 3


def test_corner_circulation_matches_hand_count_and_twin():
    # 4 x 3 cells, K = 4, φ = 90°: after its first bump every robot flies along a wall from
    # corner to corner: 3 + 1, 2 + 1, 3 + 1 and 2 + 1 steps per lap (14), two in each corner
    # cell, one in the other wall cells, none inside
    env = room(4, 3, K=4)
    cs = CellSpace(env)
    res = EventModel(cs, EventSettings()).analyse(90.0)
    hand = np.array([2, 1, 1, 2,
                     1, 0, 0, 1,
                     2, 1, 1, 2]) / 14
    np.testing.assert_allclose(res.q, hand, atol=1e-9)
    assert res.steps_per_flight == pytest.approx(3.5)
    twin = KinematicBatch(env, 50, np.random.default_rng(0), cells=cs).run(90.0, 400,
                                                                             burn_in=20)
    assert twin.tv(res.q) < 0.01          # measured 0.0011 (20 000 counted steps)
