"""The cell model and step table (docs/model.md §4, §6, §7) against hand computation and a per-cell
loop.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely

import envs
from planners.cells import AngleError, CellSpace, angle_steps

from .conftest import random_room, room


def reference_forward(cs: CellSpace) -> np.ndarray:
    """docs/model.md §7 written out cell by cell with plain shapely objects."""
    env = cs.env
    E, walls, r, tol, h = env.free_space, env.free_space.boundary, env.robot_radius, env.tol, \
        env.cell_size
    out = np.full(cs.N, -1)
    for k in range(cs.K):
        th = 2 * math.pi * k / cs.K
        ux, uy = math.cos(th), math.sin(th)
        ux, uy = (0.0 if abs(ux) < 1e-12 else ux), (0.0 if abs(uy) < 1e-12 else uy)
        for p in range(cs.P):
            cx, cy = cs.centres[p]
            dx, dy = cx + h * ux, cy + h * uy
            q = cs.cell_of_point([[dx + 1e-6 * h * ux, dy + 1e-6 * h * uy]])[0]
            seg = shapely.LineString([(cx, cy), (dx, dy)])
            if q >= 0 and E.covers(shapely.Point(dx, dy)) and seg.distance(walls) >= r - tol:
                out[k * cs.P + p] = k * cs.P + q
    return out


def test_corridor_by_hand(corridor):
    cs = CellSpace(corridor)
    assert (cs.P, cs.N) == (3, 12)
    # east: 0->1->2->bump; north/south: bump; west: 2->1->0->bump
    assert cs.forward.tolist() == [1, 2, -1, -1, -1, -1, -1, 6, 7, -1, -1, -1]
    assert cs.rotate(2, 180) == 8
    assert cs.pk(7) == (1, 2)


def test_room_diagonals_by_hand():
    cs = CellSpace(room(2, 2, K=8))
    # NE from (0,0): centre (0.17,0.17) + 0.34*(0.707,0.707) = (0.41,0.41) -> cell (1,1) = p 3
    assert cs.forward[cs.z(0, 1)] == cs.z(3, 1)
    # but a 3-cell-wide room's corner cell facing NE: the segment grazes no wall -> free
    assert cs.forward[cs.z(3, 1)] == -1


def test_no_corner_cutting():
    # an obstacle at cell (1,0) of a 2x2 room: the NE step from (0,0) ends in free cell (1,1)
    # at (0.41,0.41), but the segment passes within r of the obstacle's corner (0.34, 0.34)
    cs = CellSpace(room(2, 2, [(1, 0, 2, 1)], K=8))
    assert cs.P == 3
    assert cs.forward[cs.z(0, 1)] == -1


@pytest.mark.parametrize("seed", range(8))
def test_step_table_matches_per_cell_reference(seed):
    rng = np.random.default_rng(seed)
    env = random_room(rng, K=int(rng.choice([4, 8, 12])))
    cs = CellSpace(env)
    np.testing.assert_array_equal(cs.forward, reference_forward(cs))


@pytest.mark.parametrize("name", ["lab", "fig1", "complex"])
def test_catalogue_step_tables_match_reference(name):
    cs = CellSpace(envs.load(name))
    np.testing.assert_array_equal(cs.forward, reference_forward(cs))


def test_index_order_row_major_from_bottom():
    cs = CellSpace(envs.load("lab"))
    ij = cs.cells_ij
    key = ij[:, 1] * 1000 + ij[:, 0]
    assert np.all(np.diff(key) > 0)


def test_config_of_pose():
    cs = CellSpace(envs.load("lab"))
    assert cs.config_of_pose(0.2, 0.2, 0) == 0
    assert cs.config_of_pose(0.2, 0.2, 92) == 2 * 48
    assert cs.config_of_pose(2.9, 0.9, 0) == -1  # inside the wall block


def test_angle_validation():
    assert angle_steps(315, 8) == 7
    for bad in (0, 360, 100, -45, float("nan"), "x"):
        with pytest.raises(AngleError, match="multiple of 45°|not a number"):
            angle_steps(bad, 8)
    assert angle_steps(5, 360) == 5
