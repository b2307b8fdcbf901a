"""Hypothesis strategies for the fuzz tests: environments (good, odd and broken), angles,
noise, start/goal tokens, plans and pairs files.

Sizes are kept small on purpose (rooms of at most about 1.6 m at cells of at least
0.16 m, K mostly up to 16): every example must finish in well under a second, so that a
slow example is a bug (a hang) and not a big input. Huge values still appear (K up to 10^9,
coordinates up to 1e300) where the code must refuse them before doing any work.
"""

from __future__ import annotations

import json
import math

from hypothesis import strategies as st
from shapely.geometry import Polygon

__all__ = ["angle_lists", "angle_lists_for", "angle_texts", "angles_for", "env_dicts",
           "env_texts", "eps_for", "epsilons", "noise_specs", "orientations", "pairs_csv",
           "plan_texts", "polygons", "reliabilities", "small_floats", "tokens",
           "valid_angle_text", "weird_numbers"]

# ----------------------------------------------------------------------------- numbers
def mostly(good, bad, odds: int = 6):
    """``good`` in ``odds`` examples out of ``odds + 1``, else ``bad`` (a proportional
    choice: ``st.one_of`` does not weight its branches evenly).
    """
    return st.sampled_from([True] * odds + [False]).flatmap(lambda ok: good if ok else bad)


weird_numbers = st.sampled_from([math.nan, math.inf, -math.inf, 1e300, -1e300, 1e-300, 0.0,
                                 -0.0, 5e-324, 1e15])
small_floats = st.floats(-3.0, 3.0, allow_nan=False, allow_infinity=False)


def _num_text(x: float) -> str:
    return repr(x) if isinstance(x, float) else str(x)


# ----------------------------------------------------------------------------- polygons
@st.composite
def _star(draw, convex: bool):
    """A convex (all radii equal) or star-shaped polygon around a centre in the room."""
    n = draw(st.integers(3, 9))
    cx, cy = draw(st.floats(0.8, 1.6)), draw(st.floats(0.8, 1.6))
    angles = sorted(draw(st.lists(st.floats(0, 2 * math.pi, exclude_max=True), min_size=n,
                                  max_size=n, unique=True)))
    base = draw(st.floats(0.5, 0.8))
    radii = [base] * n if convex else [draw(st.floats(0.35, 0.8)) for _ in range(n)]
    return [[round(cx + r * math.cos(a), 6), round(cy + r * math.sin(a), 6)]
            for a, r in zip(angles, radii)]


@st.composite
def _rectangle(draw, x0=0.0, y0=0.0, wmin=0.3, wmax=1.6):
    w, h = draw(st.floats(wmin, wmax)), draw(st.floats(wmin, wmax))
    return [[x0, y0], [x0 + w, y0], [x0 + w, y0 + h], [x0, y0 + h]]


@st.composite
def _self_intersecting(draw):
    """A bow tie (two edges cross), possibly scaled."""
    s = draw(st.floats(0.3, 2.0))
    return [[0, 0], [s, s], [s, 0], [0, s]]


@st.composite
def _degenerate(draw):
    """Fewer than 3 distinct points, all collinear (zero area), or a repeated ring."""
    kind = draw(st.sampled_from(["point", "two", "collinear", "closed-two"]))
    p = [draw(small_floats), draw(small_floats)]
    q = [draw(small_floats), draw(small_floats)]
    if kind == "point":
        return [p] * draw(st.integers(0, 4))
    if kind == "two":
        return [p, q, p]
    if kind == "collinear":
        t = draw(st.lists(st.floats(0, 1), min_size=3, max_size=6))
        return [[p[0] + s * (q[0] - p[0]), p[1] + s * (q[1] - p[1])] for s in t]
    return [p, q, q, p]


@st.composite
def _with_weird_coordinate(draw, base):
    poly = [list(v) for v in draw(base)]
    if poly:
        i = draw(st.integers(0, len(poly) - 1))
        poly[i][draw(st.integers(0, 1))] = draw(weird_numbers)
    return poly


_malformed = st.one_of(st.none(), st.integers(), st.text(max_size=5),
                       st.lists(st.integers(), max_size=3),
                       st.lists(st.lists(small_floats, min_size=3, max_size=3), min_size=3,
                                max_size=4),
                       st.lists(st.lists(st.text(max_size=2), min_size=2, max_size=2),
                                min_size=3, max_size=4))


def polygons(good_only: bool = False):
    """Polygons: convex, star-shaped, rectangles; unless ``good_only`` also
    self-intersecting, degenerate, collinear, NaN/huge coordinates and malformed values.
    """
    good = st.one_of(_rectangle(), _star(True), _star(False))
    if good_only:
        return good
    return st.one_of(good, good, good, _self_intersecting(), _degenerate(),
                     _with_weird_coordinate(good), _malformed)


# ----------------------------------------------------------------------------- obstacles
@st.composite
def _obstacle_for(draw, boundary, good: bool = False):
    """An obstacle inside, crossing, outside or touching the boundary's bounding box
    (``good``: inside or touching only).
    """
    xs = [v[0] for v in boundary]
    ys = [v[1] for v in boundary]
    x0, x1, y0, y1 = min(xs), max(xs), min(ys), max(ys)
    w, h = x1 - x0, y1 - y0
    kind = draw(st.sampled_from(["inside", "inside", "touching"] if good else
                                ["inside", "crossing", "outside", "touching", "any"]))
    if kind == "any":
        return draw(polygons())
    fw, fh = draw(st.floats(0.1, 0.4)), draw(st.floats(0.1, 0.4))
    bw, bh = fw * w, fh * h
    poly = Polygon(boundary).buffer(0)
    if good and not poly.is_empty and poly.area < 0.999 * w * h:
        # not a rectangle: a small box around a point inside the polygon
        c = poly.representative_point()
        s = 0.1 * min(fw, fh) * min(w, h)
        return [[c.x - s, c.y - s], [c.x + s, c.y - s], [c.x + s, c.y + s], [c.x - s, c.y + s]]
    if kind == "inside":
        ox = x0 + draw(st.floats(0.1, 0.9 - fw)) * w if fw < 0.8 else x0 + 0.1 * w
        oy = y0 + draw(st.floats(0.1, 0.9 - fh)) * h if fh < 0.8 else y0 + 0.1 * h
    elif kind == "crossing":
        ox, oy = x1 - bw / 2, y0 + h / 2
    elif kind == "outside":
        ox, oy = x1 + 1.0, y1 + 1.0
    else:                                           # touching the bottom edge of the box
        ox, oy = x0 + draw(st.floats(0.0, max(0.0, 1 - fw))) * w, y0
    return [[ox, oy], [ox + bw, oy], [ox + bw, oy + bh], [ox, oy + bh]]


orientations = st.one_of(st.integers(4, 16), st.integers(4, 16), st.integers(-2, 3),
                         st.sampled_from([10**5, 10**6, 10**9]))

# What env_dicts breaks on purpose (None: nothing, the environment is valid but for bad
# luck, e.g. no free cell): about one example in four is broken in one way.
_FAULTS = [None] * 21 + ["boundary", "obstacle", "obstacle", "radius", "cell", "K", "key"]


def _is_ring(poly) -> bool:
    return isinstance(poly, list) and len(poly) >= 3 and all(
        isinstance(v, list) and len(v) == 2 and all(
            isinstance(c, float | int) and math.isfinite(c) for c in v) for v in poly)


@st.composite
def env_dicts(draw, good_only: bool = False, max_K: int | None = None):
    """An env-file dict (MODEL §2): mostly (3 in 4) valid and small (rooms of 0.8-1.6 m, robot
    radius 0.1-0.2 m, cells from 0.4 r to 2.5 r but at least 0.16 m, K 4-16 with odd
    values), otherwise broken in one way: a bad boundary (self-intersecting, degenerate,
    collinear, NaN or huge coordinates, malformed), an obstacle crossing, outside or
    touching the boundary, a bad radius, cell size or K (tiny or huge), or a bad key.
    """
    fault = None if good_only else draw(st.sampled_from(_FAULTS))
    boundary = draw(st.one_of(_rectangle(wmin=0.8), _star(True), _star(False)))
    obstacles = draw(st.lists(_obstacle_for(boundary, good=True), max_size=2))
    radius = draw(st.floats(0.1, 0.2))      # the twin's ray-cast grid grows as (room / r)^2
    # around 2r, or below r (cells smaller than the robot), never finer than 0.16 m
    cell = max(0.16, draw(st.one_of(st.floats(1.5 * radius, 2.5 * radius),
                                    st.floats(0.4 * radius, radius))))
    K = draw(st.integers(4, 16 if max_K is None else max(4, max_K)))
    if fault == "boundary":
        boundary = draw(polygons())
        if not _is_ring(boundary):
            obstacles = []
    elif fault == "obstacle":
        obstacles.append(draw(_obstacle_for(boundary)))
    elif fault == "radius":
        radius = draw(st.sampled_from([0, -0.1, math.nan, math.inf, "0.17", True, None, 5.0,
                                       1e-12]))
    elif fault == "cell":
        cell = draw(st.sampled_from([0, -1, math.nan, "x", 1e-9, 1e9, None]))
    elif fault == "K":
        K = draw(st.one_of(st.integers(-2, 3), st.sampled_from([10**5, 10**6, 10**9, 8.5,
                                                                "8", None, 8.0])))
    data = {"name": "fuzz", "boundary": boundary, "obstacles": obstacles,
            "robot_radius": radius, "discretization": {"cell_size": cell, "orientations": K}}
    if fault == "key":
        key = draw(st.sampled_from(["bogus", "discretization", "obstacles", "meta", "name"]))
        data[key] = draw(st.one_of(st.integers(), st.text(max_size=3), st.just({"x": 1}),
                                   st.none()))
    return data


def valid_angle_text(K: int):
    """Bouncing angles allowed at K orientations (multiples of 360/K in (0, 360))."""
    return st.lists(st.integers(1, max(1, K - 1)), min_size=1, max_size=3, unique=True).map(
        lambda ks: ",".join(f"{360 * k / K:g}" for k in ks))


def angle_lists_for(K):
    """Mostly valid angle lists for K, else any angles."""
    if isinstance(K, int) and 4 <= K <= 10**4:
        valid = st.lists(st.integers(1, max(1, K - 1)), min_size=1, max_size=3,
                         unique=True).map(lambda ks: [360 * k / K for k in ks])
        return mostly(valid, angle_lists())
    return angle_lists()


def eps_for(K):
    """An error range ε: mostly 0 or a multiple of 360/K, else anything."""
    if isinstance(K, int) and 4 <= K <= 10**4:
        return mostly(st.one_of(st.just(0.0), st.integers(0, K // 2).map(
            lambda k: 360 * k / K)), epsilons, odds=4)
    return epsilons


def angles_for(K):
    """Mostly valid angles for K (when K is a usable int), else any angle text."""
    if isinstance(K, int) and 4 <= K <= 10**4:
        return mostly(valid_angle_text(K), angle_texts)
    return angle_texts


@st.composite
def env_texts(draw):
    """The text of an env file: JSON of an env dict, or broken JSON, or other bytes."""
    kind = draw(st.integers(0, 9))
    if kind <= 6:
        return json.dumps(draw(env_dicts()), allow_nan=True)
    if kind == 7:
        return json.dumps(draw(env_dicts()))[: draw(st.integers(0, 40))]
    if kind == 8:
        return draw(st.text(max_size=30))
    return "[]"


# ----------------------------------------------------------------------------- angles etc.
_angle = st.one_of(st.sampled_from([15, 30, 45, 60, 72, 90, 120, 135, 180, 225, 270, 315]),
                   st.integers(-30, 400), st.floats(-400, 400), weird_numbers)


def angle_lists(min_size: int = 0, max_size: int = 4):
    return st.lists(_angle, min_size=min_size, max_size=max_size)


def angle_text(angles) -> str:
    return ",".join(_num_text(a) for a in angles)


angle_texts = st.one_of(angle_lists().map(angle_text), st.text(max_size=8),
                        st.sampled_from(["45,,90", "90°,135°", "1e400", " ", "45;90"]))
epsilons = st.one_of(st.sampled_from([0, 0, 15, 45, 90, 180, 360]), st.floats(-10, 400),
                     weird_numbers)
reliabilities = mostly(st.floats(0, 1), st.one_of(st.sampled_from([-0.1, 1.5]),
                                                 weird_numbers))
noise_specs = mostly(st.sampled_from(["none", "none", "none", "gauss:1", "gauss:0",
                                     "model:eps=45,r=0.8"]),
                     st.one_of(st.sampled_from(["gauss:-1", "gauss:x", "model:eps=5,r=2",
                                                "model:", "bogus", "", "gauss:nan"]),
                               st.text(max_size=10)), odds=4)


@st.composite
def tokens(draw, N: int | None = None):
    """A start/goal token: an index (often in range), a pose X,Y,DEG or garbage."""
    hi = N if N else 50
    kind = draw(st.sampled_from(["index"] * 6 + ["pose"] * 3 + ["odd", "text"]))
    if kind == "index":
        return str(draw(st.integers(-2, hi + 2)))
    if kind == "pose":
        x, y = draw(st.floats(-0.5, 3.0)), draw(st.floats(-0.5, 3.0))
        deg = draw(st.one_of(st.floats(-720, 720), st.integers(0, 359)))
        return f"{x:.3f},{y:.3f},{deg}"
    if kind == "odd":
        return draw(st.sampled_from(["nan,1,0", "1,2", "1,2,3,4", "inf,0,0", "1e400", "",
                                     "x", "0.5,0.5,nan", "99999999999999999999", "-0"]))
    return draw(st.text(max_size=8))


@st.composite
def plan_texts(draw):
    """Observation strings: zeros runs and angles in the paper's or the plain form, and junk."""
    kind = draw(st.integers(0, 5))
    if kind <= 3:
        parts = draw(st.lists(st.one_of(st.integers(1, 6).map(lambda n: "0" * n),
                                        _angle.map(lambda a: f"{_num_text(a)}°"),
                                        _angle.map(_num_text)), max_size=10))
        return draw(st.sampled_from([" ", ",", ", "])).join(parts)
    if kind == 4:
        return draw(st.sampled_from(["(empty plan)", "", "0°", "00 90deg", "-90", "360",
                                     "0x10", "1_0", "٣"]))
    return draw(st.text(max_size=12))


@st.composite
def pairs_csv(draw, N: int | None = None):
    """Content of a --pairs file (text or raw bytes)."""
    kind = draw(st.integers(0, 7))
    if kind <= 4:
        header = draw(st.sampled_from(["start,goal", "goal,start", "start,goal,extra",
                                       "start", "a,b", ""]))
        rows = draw(st.lists(st.tuples(tokens(N), tokens(N)), max_size=4))
        lines = [header] + [f'"{s}","{g}"' if "," in s + g else f"{s},{g}"
                            for s, g in rows]
        return "\n".join(lines) + "\n"
    if kind == 5:
        return draw(st.binary(max_size=30))
    if kind == 6:
        return "start,goal\n\"unterminated,0\n"
    return draw(st.text(max_size=30))
