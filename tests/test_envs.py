"""Environment loading and validation (docs/model.md §2, §4) and the catalogue counts."""

from __future__ import annotations

import json

import numpy as np
import pytest

import envs
from envs import Environment, InvalidEnvironment
from planners.cells import CellSpace

from .conftest import room

GOOD = {"boundary": [[0, 0], [1.02, 0], [1.02, 1.02], [0, 1.02]], "robot_radius": 0.17,
        "discretization": {"cell_size": 0.34, "orientations": 8}}


@pytest.mark.parametrize("name,P", [("lab", 48), ("fig1", 54), ("complex", 183)])
def test_catalogue_counts(name, P):
    cs = CellSpace(envs.load(name))
    assert (cs.P, cs.N, cs.K) == (P, 8 * P, 8)


def test_complex_at_360_orientations():
    assert CellSpace(envs.load("complex", orientations=360)).N == 65880


def test_lab_paper_ids():
    cs = CellSpace(envs.load("lab"))
    # paper id = z + 1: id 1 bottom-left facing east, id 9 bottom-right facing east
    assert cs.pose(0) == pytest.approx((0.17, 0.17, 0.0))
    assert cs.pose(8) == pytest.approx((3.06 - 0.17, 0.17, 0.0))
    assert (cs.cells_ij[:, 1] == 0).sum() == 9
    # id 104 faces north at the bottom-left corner of the obstacle touching the wall
    x, y, deg = cs.pose(103)
    assert deg == 90.0
    env = cs.env
    touching = [o for o in env.obstacles if o.touches(env.boundary.exterior)
                or o.intersection(env.boundary.exterior).length > 0]
    interior = [o for o in env.obstacles if o not in touching]
    assert len(touching) == 1 and len(interior) == 1
    ox0, oy0 = touching[0].bounds[:2]
    # the cell's top-left corner is the obstacle's bottom-left corner
    assert (x - 0.17, y + 0.17) == pytest.approx((ox0, oy0))
    assert not cs.env.points_free([[x, y + 0.34]])[0]  # facing north it bumps at once
    assert cs.forward[103] == -1


def test_tolerance_on_grid_aligned_walls():
    # with h = 2r, centres next to a wall are exactly r away: they must be free
    cs = CellSpace(room(3, 2))
    assert cs.P == 6


def test_yaml_and_json_load(tmp_path):
    p = tmp_path / "e.json"
    p.write_text(json.dumps(GOOD))
    y = tmp_path / "e.yaml"
    y.write_text("boundary: [[0, 0], [1.02, 0], [1.02, 1.02], [0, 1.02]]\nrobot_radius: 0.17\n"
                 "discretization: {cell_size: 0.34, orientations: 8}\n")
    a, b = envs.load(p), envs.load(y)
    assert CellSpace(a).P == CellSpace(b).P == 9
    assert a.name == "e"


def test_overrides():
    env = envs.load("lab", cell_size=0.17, orientations=16)
    assert (env.cell_size, env.orientations) == (0.17, 16)


def _bad(**changes):
    d = json.loads(json.dumps(GOOD))
    for k, v in changes.items():
        if k in ("cell_size", "orientations"):
            d["discretization"][k] = v
        else:
            d[k] = v
    return d


@pytest.mark.parametrize("data,needle", [
    (_bad(boundary=[[0, 0], [1, 1], [1, 0], [0, 1]]), "self-intersecting"),
    (_bad(obstacles=[[[2, 2], [3, 2], [3, 3]]]), "outside the boundary"),
    (_bad(boundary=[[0, 0], [1, 0]]), "fewer than 3"),
    (_bad(obstacles=[[[0.1, 0.1], [0.2, 0.1]]]), "fewer than 3"),
    (_bad(robot_radius=0), "robot_radius must be a positive"),
    (_bad(robot_radius=-1), "robot_radius must be a positive"),
    (_bad(cell_size=0), "cell_size must be a positive"),
    (_bad(orientations=3), "at least 4"),
    (_bad(orientations=4.5), "whole number"),
    (_bad(robot_radius=0.6), "no cell centre is free"),
    (_bad(extra=1), "unknown top-level key"),
    (_bad(obstacles=[[[0, 0], [1.02, 0], [1.02, 1.02], [0, 1.02]]]), "cover the whole"),
])
def test_invalid_inputs(data, needle):
    with pytest.raises(InvalidEnvironment, match=needle) as info:
        Environment.from_dict(data)
    msg = str(info.value)
    assert msg.endswith(".") and "\n" not in msg


def test_unknown_name_and_missing_file(tmp_path):
    with pytest.raises(InvalidEnvironment, match="neither a catalogue"):
        envs.load("nowhere")
    with pytest.raises(InvalidEnvironment, match="no environment file"):
        envs.load(tmp_path / "missing.json")
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(InvalidEnvironment, match="not valid JSON"):
        envs.load(bad)


def test_obstacle_touching_boundary_is_allowed():
    d = _bad(obstacles=[[[0, 0], [0.34, 0], [0.34, 0.34], [0, 0.34]]])
    assert CellSpace(Environment.from_dict(d)).P == 8


def test_points_free_against_a_brute_force_disk_test():
    """Free = the whole disk lies in E: checked against sampled disk points with shapely."""
    import shapely
    env = envs.load("fig1")
    rng = np.random.default_rng(1)
    x0, y0, x1, y1 = env.bounds
    pts = rng.uniform([x0, y0], [x1, y1], size=(300, 2))
    fast = env.points_free(pts)
    for (x, y), f in zip(pts, fast):
        disk = shapely.Point(x, y).buffer(env.robot_radius * (1 - 1e-6), quad_segs=64)
        assert env.free_space.covers(disk) == f or abs(
            env.walls.distance(shapely.Point(x, y)) - env.robot_radius) < 1e-3


def test_round_trip_to_dict():
    env = envs.load("complex")
    again = Environment.from_dict(env.to_dict())
    assert CellSpace(again).P == 183


def test_load_takes_an_env_as_a_dict():
    data = {"name": "box", "boundary": [[0, 0], [1.02, 0], [1.02, 0.68], [0, 0.68]],
            "robot_radius": 0.17, "discretization": {"cell_size": 0.34, "orientations": 8}}
    env = envs.load(data, orientations=4)
    assert env.name == "box" and env.grid_shape == (2, 3) and env.orientations == 4
    with pytest.raises(envs.UserError):
        envs.load({"boundary": "nope"})
