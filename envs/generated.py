"""Generated maps that are not in the catalogue, shared by the benchmarks, experiments and
tests: the slowly mixing two-room office, random rectilinear rooms with blocks
(:func:`random_rectilinear_room`), the pentagon room with a hexagonal pillar
(:data:`PENTAGON`), random regular-polygon rooms with a hole (:func:`random_polygon_room`),
an L-shaped room with an octagonal pillar off the grid (:func:`l_room_octagon`) and random
rooms with slanted walls and pillars (:func:`slanted_room`): held-out maps nobody tuned for.

:func:`office` is the map of the issue that found the event model's performance cliff: a
4.08 m × 2.72 m office (12 × 8 cells of 0.34 m) split by a partition with one door, and a
pillar in each room. With the default door width 2r = 0.34 m (exactly one robot wide) the
door is a knife edge (docs/model.md §19): only a flight along the door's axis passes it.

>>> env = office(orientations=8)
>>> env.name, env.grid_shape, round(env.robot_radius, 2)
('office', (8, 12), 0.17)
"""

from __future__ import annotations

import numpy as np
import shapely

from . import load
from .environment import Environment

__all__ = ["MAPS", "PENTAGON", "l_room_octagon", "load_map", "office", "random_polygon_room",
           "random_rectilinear_room", "slanted_room"]

H = 0.34                     # [m] cell size = robot diameter
R = 0.17                     # [m] robot radius


def office(door: float = 2 * R, orientations: int = 360) -> Environment:
    """The two-room office: 4.08 m × 2.72 m, a partition one cell thick at x = 2.04–2.38 m
    with a door of width ``door`` [m] centred at y = 1.19 m, and two 0.34 m square pillars
    (x = 0.68–1.02 m, y = 1.70–2.04 m and x = 3.06–3.40 m, y = 0.68–1.02 m).

    Parameters
    ----------
    door : float          door width [m] (default 2r = 0.34 m: one robot wide)
    orientations : int    K (default 360)
    """
    W, Hh = 12 * H, 8 * H
    y0, y1 = 3.5 * H - door / 2, 3.5 * H + door / 2
    x0, x1 = 6 * H, 7 * H
    obstacles = [
        [[x0, 0.0], [x1, 0.0], [x1, y0], [x0, y0]],              # partition, south part
        [[x0, y1], [x1, y1], [x1, Hh], [x0, Hh]],                # partition, north part
        [[2 * H, 5 * H], [3 * H, 5 * H], [3 * H, 6 * H], [2 * H, 6 * H]],    # west pillar
        [[9 * H, 2 * H], [10 * H, 2 * H], [10 * H, 3 * H], [9 * H, 3 * H]],  # east pillar
    ]
    return Environment.from_dict({
        "name": "office",
        "description": "two rooms joined by one door (envs.generated.office)",
        "boundary": [[0, 0], [W, 0], [W, Hh], [0, Hh]], "obstacles": obstacles,
        "robot_radius": R,
        "discretization": {"cell_size": H, "orientations": int(orientations)}})


def random_rectilinear_room(rng: np.random.Generator, orientations: int = 360,
                            name: str = "rect") -> Environment:
    """A random rectilinear room: 6-9 × 5-7 cells of h = 0.34 m (r = 0.17 m) with one or two
    blocks of 1-2 × 1-2 cells on the grid, clear of the walls (overlapping blocks merged).

    Parameters
    ----------
    rng : numpy.random.Generator
    orientations : int    K (default 360)
    name : str

    >>> env = random_rectilinear_room(np.random.default_rng(0), orientations=8)
    >>> rows, cols = env.grid_shape
    >>> cols in range(6, 10), rows in range(5, 8), len(env.obstacles) in (1, 2)
    (True, True, True)
    """
    W = H * int(rng.integers(6, 10))
    Hh = H * int(rng.integers(5, 8))
    obs = []
    for _ in range(int(rng.integers(1, 3))):
        w, h = H * int(rng.integers(1, 3)), H * int(rng.integers(1, 3))
        x = H * int(rng.integers(1, round(W / H) - 2))
        y = H * int(rng.integers(1, round(Hh / H) - 2))
        obs.append([[x, y], [x + w, y], [x + w, y + h], [x, y + h]])
    u = shapely.union_all([shapely.Polygon(o) for o in obs])
    obs = [list(p.exterior.coords)[:-1] for p in shapely.get_parts(u)]
    return Environment.from_dict({
        "name": name, "boundary": [[0, 0], [W, 0], [W, Hh], [0, Hh]],
        "obstacles": [list(o) for o in obs], "robot_radius": R,
        "discretization": {"cell_size": H, "orientations": int(orientations)}})


PENTAGON = {
    "name": "pentagon", "description": "a pentagon room with a hexagonal pillar",
    "boundary": [[2.0, 0.0], [3.902, 1.382], [3.176, 3.618], [0.824, 3.618], [0.098, 1.382]],
    "obstacles": [[[2.4, 1.7], [2.2, 2.046], [1.8, 2.046], [1.6, 1.7], [1.8, 1.354],
                   [2.2, 1.354]]],
    "robot_radius": 0.17, "discretization": {"cell_size": 0.34, "orientations": 8}}
"""A pentagon room with a hexagonal pillar (walls off the cell grid), K = 8."""


def _regular(centre, radius: float, n: int, rotation: float) -> list:
    """The n vertices of a regular polygon [m, rounded to 1 µm]: circumradius ``radius`` about
    ``centre``, the first at angle ``rotation`` [rad].
    """
    t = rotation + 2 * np.pi * np.arange(n) / n
    return (np.asarray(centre) + radius * np.column_stack([np.cos(t), np.sin(t)])
            ).round(6).tolist()


def random_polygon_room(rng: np.random.Generator, name: str = "random",
                        sides: tuple = (5, 9)) -> Environment:
    """A regular n-gon room (n in range(*sides), default 5..8, radius 1.3-1.8 m, random
    rotation) with a regular m-gon hole (m = 3..6, radius 0.25-0.4 m) near its centre;
    r = 0.17 m, h = 0.34 m, K = 8.
    """
    n, R = int(rng.integers(*sides)), float(rng.uniform(1.3, 1.8))
    outer = _regular((R, R), R, n, rng.uniform(0, 2 * np.pi))
    m = int(rng.integers(3, 7))
    turn = rng.uniform(0, 2 * np.pi)
    c = R + rng.uniform(-0.2, 0.2, size=2)
    hole = _regular(c, rng.uniform(0.25, 0.4), m, turn)
    return Environment.from_dict({
        "name": name, "boundary": outer, "obstacles": [hole],
        "robot_radius": 0.17, "discretization": {"cell_size": 0.34, "orientations": 8}})


def l_room_octagon(orientations: int = 8) -> Environment:
    """An L-shaped room with an octagonal pillar off the grid: 4.08 m × 2.72 m (12 × 8 cells
    of 0.34 m) less its north-east 1.70 m × 1.19 m, and a regular octagon of circumradius
    0.30 m centred at (1.23, 1.07) m, turned by 10° so that none of its faces is axis-aligned.

    >>> env = l_room_octagon()
    >>> env.grid_shape, len(env.obstacles[0].exterior.coords) - 1
    ((8, 12), 8)
    >>> round(env.free_space.area, 3)
    8.82
    """
    W, Hh = 12 * H, 8 * H
    boundary = [[0, 0], [W, 0], [W, Hh - 3.5 * H], [W - 5 * H, Hh - 3.5 * H],
                [W - 5 * H, Hh], [0, Hh]]
    return Environment.from_dict({
        "name": "lroom", "description": "an L-shaped room with an octagonal pillar "
        "(envs.generated.l_room_octagon)", "boundary": boundary,
        "obstacles": [_regular((1.23, 1.07), 0.30, 8, np.radians(10.0))],
        "robot_radius": R, "discretization": {"cell_size": H, "orientations": int(orientations)}})


def slanted_room(rng: np.random.Generator, orientations: int = 8,
                 name: str = "slanted") -> Environment:
    """A random room with slanted walls: a convex quadrilateral to hexagon (a rectangle of
    3.0-4.4 m × 2.2-3.2 m whose corners move inwards by up to 0.6 m, some cut off), and one or
    two pillars (regular 3- to 8-gons of circumradius 0.18-0.35 m, turned at random) that keep
    2.2 r clear of the walls and of each other, so every part of the room stays joined.

    >>> env = slanted_room(np.random.default_rng(1))
    >>> 1 <= len(env.obstacles) <= 2, env.free_space.geom_type
    (True, 'Polygon')
    """
    W, Hh = float(rng.uniform(3.0, 4.4)), float(rng.uniform(2.2, 3.2))
    corners = np.array([[0, 0], [W, 0], [W, Hh], [0, Hh]], float)
    inward = np.array([[1, 1], [-1, 1], [-1, -1], [1, -1]], float)
    ring = []
    for c, d in zip(corners, inward, strict=True):
        if rng.random() < 0.4:        # cut the corner off: two vertices
            a, b = rng.uniform(0.3, 0.7, size=2)
            ring += [c + d * [0, a], c + d * [b, 0]] if d[0] * d[1] > 0 else \
                [c + d * [b, 0], c + d * [0, a]]
        else:                         # move it inwards along one axis: a slanted wall
            ring.append(c + d * rng.uniform(0, 0.6, size=2) * (rng.random(2) < 0.5))
    boundary = shapely.Polygon(np.round(ring, 6))
    if not boundary.is_valid or not boundary.exterior.is_ccw:
        boundary = shapely.Polygon(np.round(ring, 6)[::-1])
    pillars: list = []
    want = int(rng.integers(1, 3))
    room = boundary.buffer(-2.2 * R)
    for _ in range(200):
        if len(pillars) == want:
            break
        rad = float(rng.uniform(0.18, 0.35))
        c = rng.uniform([0.5, 0.5], [W - 0.5, Hh - 0.5])
        p = shapely.Polygon(_regular(c, rad, int(rng.integers(3, 9)), rng.uniform(0, 2 * np.pi)))
        if room.contains(p) and all(p.distance(q) > 2.2 * R for q in pillars):
            pillars.append(p)
    if not pillars:
        raise RuntimeError("slanted_room: no pillar fits (should not happen for these sizes)")
    return Environment.from_dict({
        "name": name, "description": "a room with slanted walls and pillars "
        "(envs.generated.slanted_room)",
        "boundary": np.asarray(boundary.exterior.coords)[:-1].tolist(),
        "obstacles": [np.asarray(p.exterior.coords)[:-1].tolist() for p in pillars],
        "robot_radius": R, "discretization": {"cell_size": H, "orientations": int(orientations)}})


def big_two_room(orientations: int = 360) -> Environment:
    """Two rooms of 10 × 11 cells (h = 0.34 m) joined by a 0.51 m door, a pillar in each:
    198 free position cells.
    """
    h = 0.34
    W, H = 20 * h, 11 * h
    x0, x1 = 9.5 * h, 10.5 * h
    d0, d1 = 5.5 * h - 0.255, 5.5 * h + 0.255
    return Environment.from_dict({
        "name": "big_two_room", "boundary": [[0, 0], [W, 0], [W, H], [0, H]],
        "obstacles": [[[x0, 0], [x1, 0], [x1, d0], [x0, d0]],
                      [[x0, d1], [x1, d1], [x1, H], [x0, H]],
                      [[3 * h, 7 * h], [4 * h, 7 * h], [4 * h, 8 * h], [3 * h, 8 * h]],
                      [[15 * h, 3 * h], [16 * h, 3 * h], [16 * h, 4 * h], [15 * h, 4 * h]]],
        "robot_radius": 0.17,
        "discretization": {"cell_size": h, "orientations": int(orientations)}})


MAPS = {"office": lambda K: office(2 * R, K),
        "office-pinhole": lambda K: office(2 * R + 1e-7, K),
        "office-wide": lambda K: office(0.40, K)}
"""The benchmark maps by name: the office with a door one robot wide (a knife edge, the
rooms are separate), 0.1 µm wider (joined by the flights along the door's axis only: a
slowly mixing chain) and 0.40 m wide."""


def load_map(name: str, orientations: int) -> Environment:
    """A benchmark map (:data:`MAPS`) or a catalogue map, at K = ``orientations``."""
    if name in MAPS:
        return MAPS[name](orientations)
    return load(name, orientations=orientations)
