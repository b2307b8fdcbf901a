"""The contact rule: which contacts close the bumper, and how the body slides (docs/model.md §9).

Part of the motion layer (:mod:`envs.motion` holds the casts, constants and the calibrated
:class:`~envs.motion.ContactParams`); written once and used by the kinematic twin (one robot
and the batch) and by the event coverage model, so that their flights are the same paths.

- A front contact at bearing b from the heading (|b| < 90°) meets the wall at incidence
  α = 90° − |b|. With ``contact`` = None every front contact closes the bumper (the paper's
  front-half bumper, docs/model.md §8). With a :class:`~envs.motion.ContactParams` only
  contacts with α ≥ β do (the bumper arc ±(90° − β)).
- A contact outside the arc is a **slide**: the body moves along the wall with its velocity
  projected on the wall's tangent, reduced by friction: speed factor f = cos α − μ sin α.
  The heading is kept, except under a rule with a turn-in table (``ContactParams.turn_in``):
  along a straight wall the incidence then grows as the table says and the body bumps when
  it reaches β, after L(α) of slide, at the speed factor of β throughout (a constant rate,
  so a slide cut into clock ticks ends where one drive ends). Along a straight wall the
  path is a straight leg; around a convex wall corner the body wraps on the corner's circle
  of radius r (its heading kept) until the corner is abeam (bearing 90°), then drives
  straight on. A slide ends in a bump when a contact inside the
  arc appears (a concave corner), and it continues on the next wall when the new contact is
  again outside the arc.
- Time is counted as clock length ℓ = v · time [m]: a straight metre costs 1 m of clock, a
  sliding metre 1/f. A step is h of clock (docs/model.md §8: it drives h by the clock).
- Decision: two distinct contacts outside the arc at once (a pocket), or a slide blocked at
  once, count as a bump, so every flight ends in a bump (the twin stalled there before).

>>> import envs
>>> from envs.motion import ContactParams, casters
>>> caster = casters(envs.load("lab"))[0]
>>> # 5° into lab's south wall (C-space y = 0.17): slides east along the bottom row
>>> x, y, used, bumped, legs, _ = advance(caster, 0.51, 0.18, math.cos(math.radians(-5)),
...                                       math.sin(math.radians(-5)), ContactParams(10.0, 0.0))
>>> bumped, round(x, 4), round(y, 4), len(legs)
(True, 2.89, 0.17, 3)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ._contact_kernel import advance_kernel
from .motion import (
    APPROACH_MIN,
    BUMP_RANGE,
    CENTRE_ZONE_DEG,
    CONTACT_GAP,
    GRAZE_TOL,
    ContactParams,
    WallCaster,
    drive_distance,
)

__all__ = ["REST_FLIGHT", "at_speed", "advance", "advance_many", "slide_on", "front_contacts",
           "closes_bumper", "switches", "leg_point", "leg_length", "ContactFlights",
           "contact_flights", "glancing"]

REST_FLIGHT = 1e-3
"""[m] A bump after a flight shorter than this (since the last turn) is a bump from rest: the
turn before left the robot facing its wall. A body may turn differently after one
(docs/model.md §11b); the event model's flights and the twin use this one threshold."""

_MAX_EVENTS = 1000       # contacts handled within one drive (collinear wall pieces add events)
_SAME_CONTACT = 1e-5     # [m] contacts closer than this are one (a side's end and its vertex)
_CHUNK = 4096            # rays per vectorised feature cast


def at_speed(table: dict, speed: float | None, tol: float = 0.01):
    """The entry of ``table`` (keyed by drive speed [m/s]) measured at ``speed``, within
    ``tol``; None when ``speed`` is None or nothing was measured there. A body's contact
    rule and turn errors are declared per speed this way (docs/model.md §9, §15).

    >>> at_speed({0.3: "a", 0.2: "b"}, 0.205), at_speed({0.3: "a"}, 0.25)
    ('b', None)
    """
    if speed is None:
        return None
    for v, entry in table.items():
        if abs(float(speed) - v) <= tol:
            return entry
    return None


def front_contacts(caster: WallCaster, x: float, y: float, ux: float, uy: float
                   ) -> list[tuple[float, float, float, tuple | None]]:
    """Front contacts within BUMP_RANGE ahead: (bearing b [deg], x, y, side or None)."""
    out = []
    for px, py, side in caster.cast_one(x, y, ux, uy, BUMP_RANGE):
        wx, wy = px - x, py - y
        b = math.degrees(math.atan2(ux * wy - uy * wx, ux * wx + uy * wy))
        if abs(b) < 90.0:       # behind the centre line: not the bumper
            out.append((b, px, py, side))
    return out


def closes_bumper(bearing_deg: float, contact: ContactParams | None) -> bool:
    """Whether a front contact at ``bearing_deg`` [deg] closes the bumper."""
    arc = 90.0 if contact is None else 90.0 - contact.beta_deg
    return abs(bearing_deg) <= arc


def switches(bearings_deg) -> tuple[bool, bool]:
    """(left, right) bumper switches closed by front contacts at these bearings [deg] from the
    heading (+ to the left): a bearing within ±``CENTRE_ZONE_DEG`` closes both, one further left
    the left switch, one further right the right switch (docs/model.md §8).

    >>> switches([0.0]), switches([30.0]), switches([-30.0]), switches([30.0, -30.0]), switches([])
    ((True, True), (True, False), (False, True), (True, True), (False, False))
    """
    left = right = False
    for beta in bearings_deg:
        left |= beta >= -CENTRE_ZONE_DEG
        right |= beta <= CENTRE_ZONE_DEG
    return bool(left), bool(right)


def _group(contacts) -> list[list]:
    """Front contacts grouped into distinct contacts: a contact within ``_SAME_CONTACT`` of a
    group's first, or a vertex that ends a side of the group (the robot near a side's end
    touches the side and, within BUMP_RANGE, its end vertex: one surface, not a pocket,
    however close to the end a drive stopped), joins that group.
    """
    groups: list[list] = []
    for c in sorted(contacts, key=lambda c: c[3] is None):     # a side before its vertex
        for g in groups:
            if math.hypot(c[1] - g[0][1], c[2] - g[0][2]) < _SAME_CONTACT or (
                    c[3] is None and any(_ends_side(c[1], c[2], m[3]) for m in g)):
                g.append(c)
                break
        else:
            groups.append([c])
    return groups


def _ends_side(px: float, py: float, side) -> bool:
    """Whether the point (px, py) is an end of ``side`` (Ax, Ay, ex, ey, L)."""
    if side is None:
        return False
    Ax, Ay, ex, ey, L = side
    return (math.hypot(px - Ax, py - Ay) < _SAME_CONTACT
            or math.hypot(px - Ax - L * ex, py - Ay - L * ey) < _SAME_CONTACT)


def _clear(caster: WallCaster, x: float, y: float) -> bool:
    """Whether a disk at (x, y) stays off every wall (by more than r − GRAZE_TOL)."""
    p = np.array([x, y])
    lam = np.clip(((p - caster.A) * caster.e).sum(1), 0.0, caster.L)
    foot = caster.A + lam[:, None] * caster.e
    return bool(np.hypot(*(p - foot).T).min() >= caster.r - GRAZE_TOL)


def _gd_inv(x: float) -> float:
    """The inverse Gudermannian, ∫₀ˣ dγ / cos γ = asinh(tan x)."""
    return math.asinh(math.tan(x))


def advance(caster: WallCaster, x: float, y: float, ux: float, uy: float,
            contact: ContactParams | None, budget: float = math.inf):
    """Drive forward along the heading (ux, uy) under the contact rule, for at most ``budget``
    [m] of clock length.

    Returns
    -------
    x, y : float         where the robot ends [m]
    used : float         clock length used [m] (= budget unless it bumped first)
    bumped : bool        whether a contact closed the bumper (then ``used`` is its clock)
    legs : list          the path: ("line", x0, y0, dx, dy, length, rate) with rate the clock
                         per metre, and ("arc", Vx, Vy, mx, my, sign, γ0, μ, r, clock) for a
                         wrap around the corner V from the outward normal (mx, my) at
                         incidence γ0 [rad]; see :func:`leg_point`
    u : (ux, uy)         the heading at the end (the start's, unless a slide turned in)
    """
    used = 0.0
    legs: list[tuple] = []
    mu = 0.0 if contact is None else float(contact.slide_friction)
    r = caster.r
    for _ in range(_MAX_EVENTS):
        left = budget - used
        d = drive_distance(caster.cast_one(x, y, ux, uy))
        if d >= left:                                  # the clock runs out first
            if left > 0:
                legs.append(("line", x, y, ux, uy, left, 1.0))
            return x + left * ux, y + left * uy, budget, False, legs, (ux, uy)
        if d > 0:
            legs.append(("line", x, y, ux, uy, d, 1.0))
            x, y, used = x + d * ux, y + d * uy, used + d
            left = budget - used
        cs = front_contacts(caster, x, y, ux, uy)
        if contact is None or not cs or any(closes_bumper(b, contact) for b, *_ in cs):
            return x, y, used, True, legs, (ux, uy)
        groups = _group(cs)
        if len(groups) != 1:                           # a pocket: counted as a bump
            return x, y, used, True, legs, (ux, uy)
        _, px, py, side = groups[0][0]
        if side is not None:                           # the side's own normal, exactly
            nx, ny = -side[3], side[2]
            if (x - px) * nx + (y - py) * ny < 0:
                nx, ny = -nx, -ny
        else:
            nx, ny = x - px, y - py
            nn = math.hypot(nx, ny)
            nx, ny = nx / nn, ny / nn                  # wall -> centre
        un = ux * nx + uy * ny                         # −sin α
        tx, ty = ux - un * nx, uy - un * ny            # the push along the wall
        ts = math.hypot(tx, ty)                        # cos α
        f = ts + mu * un                               # speed factor cos α − μ sin α
        if ts < 1e-12 or f <= 0:
            return x, y, used, True, legs, (ux, uy)
        tx, ty = tx / ts, ty / ts
        if side is not None:                           # slide along a straight wall
            Ax, Ay, ex, ey, L = side
            tx, ty = (ex, ey) if tx * ex + ty * ey > 0 else (-ex, -ey)
            lam = (x - Ax) * ex + (y - Ay) * ey
            along = tx * ex + ty * ey
            to_end = (L - lam if along > 0 else lam) / abs(along) + 1e-9
            block = drive_distance(caster.cast_one(x, y, tx, ty))
            turn = contact.slide_left(math.degrees(math.asin(min(max(-un, 0.0), 1.0))))
            if turn < math.inf:                        # turning in: the speed factor at β
                bt = math.radians(contact.beta_deg)
                f = math.cos(bt) - mu * math.sin(bt)
            d = min(to_end, block, left * f, turn)
            if d <= 0:                                 # blocked at once: a bump
                return x, y, used, True, legs, (ux, uy)
            legs.append(("line", x, y, tx, ty, d, 1.0 / f))
            x, y = x + d * tx, y + d * ty
            if turn < math.inf:                        # turned in: the incidence it reached
                a = math.radians(contact.incidence_after(turn - d))
                ux, uy = tx * math.cos(a) - nx * math.sin(a), ty * math.cos(a) - ny * math.sin(a)
            if d == left * f:
                return x, y, budget, False, legs, (ux, uy)
            used += d / f
            if d == turn:                              # turned in up to β: a bump
                return x, y, used, True, legs, (ux, uy)
            continue
        # wrap around the corner V = (px, py) until it is abeam; γ: incidence on the circle
        g0 = math.asin(min(max(-un, 0.0), 1.0))
        c = math.atan(mu)
        k = math.sqrt(1.0 + mu * mu)
        full = r / k * (_gd_inv(g0 + c) - _gd_inv(c))
        part = left < full
        clock = left if part else full
        g1 = math.atan(math.sinh(_gd_inv(g0 + c) - clock * k / r)) - c if part else 0.0
        sgn = 1.0 if (nx * ty - ny * tx) > 0 else -1.0  # the normal turns toward the push
        a = sgn * (g0 - max(g1, 0.0))
        mx, my = math.cos(a) * nx - math.sin(a) * ny, math.sin(a) * nx + math.cos(a) * ny
        qx, qy = px + r * mx, py + r * my
        if not _clear(caster, qx, qy):                 # another wall in the way: a bump
            return x, y, used, True, legs, (ux, uy)
        legs.append(("arc", px, py, nx, ny, sgn, g0, mu, r, clock))
        x, y = qx, qy
        if part:
            return x, y, budget, False, legs, (ux, uy)
        used += full
    return x, y, used, True, legs, (ux, uy)


def slide_on(caster: WallCaster, contact: ContactParams | None, lx: float, ly: float,
             ux: float, uy: float) -> tuple[float, float, float]:
    """(x, y, extra clock [m]) of one straight flight's end under ``contact``: where its
    contact at (lx, ly) lies outside the bumper arc the robot slides on (:func:`advance`) to
    its bump; else (lx, ly, 0). :func:`contact_flights` for one flight in plain Python (3x
    faster; the same end and clock to 5e-9 m: advance may first close a ~1e-9 m gap), for
    the planners that follow one flight at a time (§13's exact planner, §15's searches).
    """
    if contact is None or any(closes_bumper(b, contact)
                              for b, *_ in front_contacts(caster, lx, ly, ux, uy)):
        return lx, ly, 0.0
    sx, sy, extra, _, _, _ = advance(caster, lx, ly, ux, uy, contact)
    return (sx, sy, extra) if extra > 0 else (lx, ly, 0.0)


def leg_length(leg: tuple) -> float:
    """Geometric length [m] of a leg of :func:`advance`."""
    if leg[0] == "line":
        return leg[5]
    _, _, _, _, _, _, g0, mu, r, clock = leg
    c, k = math.atan(mu), math.sqrt(1.0 + mu * mu)
    g1 = math.atan(math.sinh(_gd_inv(g0 + c) - clock * k / r)) - c
    return r * (g0 - max(g1, 0.0))


def leg_clock(leg: tuple) -> float:
    """Clock length [m] of a leg."""
    return leg[5] * leg[6] if leg[0] == "line" else leg[9]


def leg_point(leg: tuple, s: float) -> tuple[float, float]:
    """The point [m] reached ``s`` [m] of clock into a leg (0 <= s <= its clock)."""
    if leg[0] == "line":
        _, x0, y0, dx, dy, _, rate = leg
        d = s / rate if rate != 1.0 else s
        return x0 + d * dx, y0 + d * dy
    _, vx, vy, nx, ny, sgn, g0, mu, r, _ = leg
    c, k = math.atan(mu), math.sqrt(1.0 + mu * mu)
    g1 = math.atan(math.sinh(_gd_inv(g0 + c) - s * k / r)) - c
    a = sgn * (g0 - max(g1, 0.0))
    return (vx + r * (math.cos(a) * nx - math.sin(a) * ny),
            vy + r * (math.sin(a) * nx + math.cos(a) * ny))


def glancing(caster: WallCaster, pos, u, contact: ContactParams) -> np.ndarray:
    """(n,) bool: robots at ``pos`` (n, 2) heading ``u`` (n, 2) whose first contact ahead may
    lie outside the bumper arc (the feature they hit first is met at incidence below β, or it
    is more than BUMP_RANGE away). A conservative filter: :func:`advance` decides.
    """
    pos = np.asarray(pos, dtype=float).reshape(-1, 2)
    u = np.asarray(u, dtype=float).reshape(-1, 2)
    out = np.zeros(len(pos), dtype=bool)
    ns = len(caster.L)
    sin_b = math.sin(math.radians(contact.beta_deg)) + 1e-6
    for s in range(0, len(pos), _CHUNK):
        p, v = pos[s:s + _CHUNK], u[s:s + _CHUNK]
        fd = caster.feature_distances(p, v)
        j = np.argmin(fd, axis=1)
        t = fd[np.arange(len(p)), j]
        side = j < ns
        js = np.where(side, j, 0)
        lam = np.clip(((p - caster.A[js]) * caster.e[js]).sum(1), 0.0, caster.L[js])
        foot = caster.A[js] + lam[:, None] * caster.e[js]
        cp = np.where(side[:, None], foot, caster.vertices[np.where(side, 0, j - ns)])
        w = cp - p
        cosb = (w * v).sum(1) / np.maximum(np.hypot(w[:, 0], w[:, 1]), 1e-300)
        out[s:s + len(p)] = (cosb < sin_b) | ~(t <= BUMP_RANGE)
    return out


@dataclass(frozen=True, eq=False)
class ContactFlights:
    """Flights from starts along headings until their bump, under a contact rule.

    Attributes
    ----------
    start, u : (n, 2)     flight starts [m] and headings
    straight : (n,)       the first straight drive [m]
    clock : (n,)          clock length to the bump [m] (= straight unless it slid)
    end : (n, 2)          the bump position [m]
    u_end : (n, 2)        the heading at the bump (= u unless a slide turned in,
                          ``ContactParams.turn_in``)
    legs : dict           flight index -> legs of :func:`advance` (only flights that slid;
                          empty when made without legs)
    slid : (n,) bool      the flights that slid
    """

    start: np.ndarray
    u: np.ndarray
    straight: np.ndarray
    clock: np.ndarray
    end: np.ndarray
    u_end: np.ndarray
    legs: dict
    slid: np.ndarray

    def points(self, idx, s) -> np.ndarray:
        """(m, 2) points [m] of flights ``idx`` after ``s`` [m] of clock (each <= its clock)."""
        idx = np.asarray(idx, dtype=np.int64)
        s = np.asarray(s, dtype=float)
        if not self.legs and self.slid[idx].any():
            raise ValueError("these flights slid and were made without their legs "
                             "(contact_flights(legs=False)): no point along them is known.")
        out = self.start[idx] + s[:, None] * self.u[idx]
        for m in np.flatnonzero(np.isin(idx, np.fromiter(self.legs, np.int64,
                                                          len(self.legs)))):
            rest = float(s[m])
            for leg in self.legs[int(idx[m])]:
                c = leg_clock(leg)
                if rest <= c:
                    break
                rest -= c
            out[m] = leg_point(leg, min(rest, c))
        return out


def contact_flights(caster: WallCaster, start, u, straight, contact: ContactParams | None,
                    legs: bool = True) -> ContactFlights:
    """Continue straight flights (``straight`` [m] from ``start`` along ``u``, each ending at
    a contact) under the contact rule: those whose contact lies outside the bumper arc slide
    on (:func:`advance`) until their bump. With ``contact`` None every flight ends where it
    is (end = start + straight·u, bitwise). Without ``legs`` the slides are followed by the
    compiled :func:`envs._contact_kernel.advance_kernel` (the same ends and clocks, no legs:
    :meth:`ContactFlights.points` then knows only straight flights).
    """
    start = np.asarray(start, dtype=float).reshape(-1, 2)
    u = np.asarray(u, dtype=float).reshape(-1, 2)
    straight = np.asarray(straight, dtype=float)
    end = start + straight[:, None] * u
    clock = straight.copy()
    slide = np.zeros(len(start), bool) if contact is None else glancing(caster, end, u, contact)
    u_end = u.copy()
    if not legs:
        idx = np.flatnonzero(slide)
        slid = np.zeros(len(start), dtype=bool)
        if idx.size:
            x, y, used, _, vx, vy = advance_many(caster, end[idx], u[idx], contact)
            moved = used > 0
            k = idx[moved]
            slid[k] = True
            clock[k] += used[moved]
            end[k, 0], end[k, 1] = x[moved], y[moved]
            u_end[k, 0], u_end[k, 1] = vx[moved], vy[moved]
        return ContactFlights(start=start, u=u, straight=straight, clock=clock, end=end,
                              u_end=u_end, legs={}, slid=slid)
    return _with_legs(caster, start, u, straight, contact, end, clock, slide, u_end)


def advance_many(caster: WallCaster, pos, u, contact: ContactParams):
    """:func:`advance` (no clock budget, with a contact rule) of every flight from ``pos``
    (n, 2) along ``u`` (n, 2), compiled: (x, y, used, bumped, ux, uy) arrays (the end's
    heading last), no legs.
    """
    ta, tl = contact.turn_table
    pos = np.asarray(pos, dtype=float).reshape(-1, 2)
    u = np.asarray(u, dtype=float).reshape(-1, 2)
    return advance_kernel(caster.kernel_sides, caster.kernel_corners, float(caster.r),
                          float(caster.r2), float(caster.graze),
                          APPROACH_MIN, BUMP_RANGE, CONTACT_GAP, GRAZE_TOL, _SAME_CONTACT,
                          _MAX_EVENTS, 90.0 - float(contact.beta_deg),
                          float(contact.slide_friction), ta, tl, math.inf,
                          np.ascontiguousarray(pos[:, 0]), np.ascontiguousarray(pos[:, 1]),
                          np.ascontiguousarray(u[:, 0]), np.ascontiguousarray(u[:, 1]))


def _with_legs(caster, start, u, straight, contact, end, clock, slide, u_end
               ) -> ContactFlights:
    """:func:`contact_flights` with the legs of every slide (plain Python :func:`advance`)."""
    legs = {}
    for i in np.flatnonzero(slide):
        x, y, used, _, lg, v = advance(caster, float(end[i, 0]), float(end[i, 1]),
                                       float(u[i, 0]), float(u[i, 1]), contact)
        if used > 0:
            first = ("line", float(start[i, 0]), float(start[i, 1]), float(u[i, 0]),
                     float(u[i, 1]), float(straight[i]), 1.0)
            legs[int(i)] = [first, *lg]
            clock[i] += used
            end[i] = (x, y)
            u_end[i] = v
    slid = np.zeros(len(start), dtype=bool)
    slid[np.fromiter(legs, np.int64, len(legs))] = True
    return ContactFlights(start=start, u=u, straight=straight, clock=clock, end=end,
                          u_end=u_end, legs=legs, slid=slid)
