"""The contact rule's slides, compiled (numba): :func:`envs.contact.advance` for many flights
at once, without the legs (docs/model.md §9).

The feedback navigator flies hundreds of particles per decision; under a contact rule those
that meet a wall at a glancing incidence slide on, and :func:`~envs.contact.advance` follows
each in plain Python (a few hundred µs apiece). :func:`advance_kernel` follows the same
steps with the same floating-point operations in the same order (the scalar cast of
:func:`envs.motion.cast_scalar`, the front contacts, their grouping, the slide along a side
and the wrap around a corner), so its ends and clocks are those of ``advance``;
``tests/test_kernels.py`` checks the two on random flights. ``advance`` stays the reference
and the path of everything that needs the legs (a point along a slide).
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = ["advance_kernel"]


@numba.njit(cache=True)
def _side_t(S, i, r, approach_min, x, y, ux, uy):
    """The contact distance [m] of the disk at (x, y) moving along (ux, uy) with side ``i``
    (:func:`envs.motion.cast_scalar`'s side formula), −1 when it does not meet the side.
    """
    Ax, Ay, ex, ey, L = S[i, 0], S[i, 1], S[i, 2], S[i, 3], S[i, 4]
    rx = x - Ax
    ry = y - Ay
    s0 = ry * ex - rx * ey
    un = uy * ex - ux * ey
    a = -un if s0 >= 0 else un
    if not a > approach_min:
        return -1.0
    t = (abs(s0) - r) / a
    if t < 0.0:
        t = 0.0
    lam = rx * ex + ry * ey + t * (ux * ex + uy * ey)
    return t if 0.0 <= lam <= L else -1.0


@numba.njit(cache=True)
def _corner_t(V, j, r2, graze, x, y, ux, uy):
    """The contact distance [m] with corner ``j`` (``cast_scalar``'s corner formula), −1 when
    the disk does not meet it.
    """
    vx = x - V[j, 0]
    vy = y - V[j, 1]
    b = vx * ux + vy * uy
    if not b < 0.0:
        return -1.0
    disc = r2 - (vx * vx + vy * vy - b * b)
    if not disc > graze:
        return -1.0
    t = -b - math.sqrt(disc)
    return t if t > 0.0 else 0.0


@numba.njit(cache=True)
def _cast(S, V, r, r2, graze, approach_min, x, y, ux, uy):
    """:func:`envs.motion.cast_scalar` without ``within``: the contact distance [m]."""
    best = math.inf
    for i in range(S.shape[0]):
        t = _side_t(S, i, r, approach_min, x, y, ux, uy)
        if t >= 0.0 and t < best:
            best = t
    for j in range(V.shape[0]):
        t = _corner_t(V, j, r2, graze, x, y, ux, uy)
        if t >= 0.0 and t < best:
            best = t
    return best


@numba.njit(cache=True)
def _bearing(x, y, ux, uy, px, py):
    """[deg] the bearing of the point (px, py) from the heading (ux, uy) at (x, y)."""
    wx, wy = px - x, py - y
    return math.degrees(math.atan2(ux * wy - uy * wx, ux * wx + uy * wy))


@numba.njit(cache=True)
def _front(S, V, r, r2, graze, approach_min, within, x, y, ux, uy, hx, hy, hb, hs):
    """:func:`envs.contact.front_contacts`: the wall points touched within ``within`` [m]
    ahead with |bearing| < 90°, sides first, then corners (``cast_scalar``'s order), into
    hx, hy, hb (bearing [deg]) and hs (the side's index, −1 for a corner). Returns their
    count (at most len(S) + len(V), the arrays' length).
    """
    n = 0
    for i in range(S.shape[0]):
        t = _side_t(S, i, r, approach_min, x, y, ux, uy)
        if t < 0.0 or t > within:
            continue
        Ax, Ay, ex, ey, L = S[i, 0], S[i, 1], S[i, 2], S[i, 3], S[i, 4]
        cx, cy = x + t * ux - Ax, y + t * uy - Ay
        k = min(max(cx * ex + cy * ey, 0.0), L)
        px, py = Ax + k * ex, Ay + k * ey
        b = _bearing(x, y, ux, uy, px, py)
        if abs(b) < 90.0:
            hx[n], hy[n], hb[n], hs[n] = px, py, b, i
            n += 1
    for j in range(V.shape[0]):
        t = _corner_t(V, j, r2, graze, x, y, ux, uy)
        if t < 0.0 or t > within:
            continue
        b = _bearing(x, y, ux, uy, V[j, 0], V[j, 1])
        if abs(b) < 90.0:
            hx[n], hy[n], hb[n], hs[n] = V[j, 0], V[j, 1], b, -1
            n += 1
    return n


@numba.njit(cache=True)
def _ends_side(S, px, py, i, same):
    """Whether (px, py) is an end of side ``i`` (:func:`envs.contact._ends_side`)."""
    if i < 0:
        return False
    Ax, Ay, ex, ey, L = S[i, 0], S[i, 1], S[i, 2], S[i, 3], S[i, 4]
    return (math.hypot(px - Ax, py - Ay) < same
            or math.hypot(px - Ax - L * ex, py - Ay - L * ey) < same)


@numba.njit(cache=True)
def _groups(S, n, hx, hy, hs, same, gid, first):
    """:func:`envs.contact._group` of the first ``n`` contacts (sides come first already):
    the group of each (gid) and each group's first contact (first). Returns the count.
    """
    ng = 0
    for c in range(n):
        joined = -1
        for g in range(ng):
            f = first[g]
            if math.hypot(hx[c] - hx[f], hy[c] - hy[f]) < same:
                joined = g
            elif hs[c] < 0:
                for m in range(c):
                    if gid[m] == g and _ends_side(S, hx[c], hy[c], hs[m], same):
                        joined = g
                        break
            if joined >= 0:
                break
        if joined < 0:
            first[ng] = c
            joined = ng
            ng += 1
        gid[c] = joined
    return ng


@numba.njit(cache=True)
def _clear(S, x, y, limit):
    """Whether a disk at (x, y) stays off every wall: its distance to each side >= limit."""
    best = math.inf
    for i in range(S.shape[0]):
        Ax, Ay, ex, ey, L = S[i, 0], S[i, 1], S[i, 2], S[i, 3], S[i, 4]
        lam = min(max((x - Ax) * ex + (y - Ay) * ey, 0.0), L)
        d = math.hypot(x - (Ax + lam * ex), y - (Ay + lam * ey))
        if d < best:
            best = d
    return best >= limit


@numba.njit(cache=True)
def _gd_inv(x):
    return math.asinh(math.tan(x))


@numba.njit(cache=True)
def _advance_one(S, V, r, r2, graze, approach_min, bump_range, gap, graze_tol, same,
                 max_events, arc, mu, ta, tl, budget, x, y, ux, uy, hx, hy, hb, hs, gid,
                 first):
    """One flight of :func:`envs.contact.advance` (with a contact rule): (x, y, used,
    bumped, ux, uy).
    """
    used = 0.0
    for _ in range(max_events):
        left = budget - used
        d = max(_cast(S, V, r, r2, graze, approach_min, x, y, ux, uy) - gap, 0.0)
        if d >= left:
            return x + left * ux, y + left * uy, budget, False, ux, uy
        if d > 0:
            x, y, used = x + d * ux, y + d * uy, used + d
            left = budget - used
        n = _front(S, V, r, r2, graze, approach_min, bump_range, x, y, ux, uy, hx, hy, hb, hs)
        if n == 0:
            return x, y, used, True, ux, uy
        for c in range(n):
            if abs(hb[c]) <= arc:
                return x, y, used, True, ux, uy
        if _groups(S, n, hx, hy, hs, same, gid, first) != 1:
            return x, y, used, True, ux, uy
        px, py, si = hx[0], hy[0], hs[0]
        if si >= 0:
            nx, ny = -S[si, 3], S[si, 2]
            if (x - px) * nx + (y - py) * ny < 0:
                nx, ny = -nx, -ny
        else:
            nx, ny = x - px, y - py
            nn = math.hypot(nx, ny)
            nx, ny = nx / nn, ny / nn
        un = ux * nx + uy * ny
        tx, ty = ux - un * nx, uy - un * ny
        ts = math.hypot(tx, ty)
        f = ts + mu * un
        if ts < 1e-12 or f <= 0:
            return x, y, used, True, ux, uy
        tx, ty = tx / ts, ty / ts
        if si >= 0:
            Ax, Ay, ex, ey, L = S[si, 0], S[si, 1], S[si, 2], S[si, 3], S[si, 4]
            if tx * ex + ty * ey > 0:
                tx, ty = ex, ey
            else:
                tx, ty = -ex, -ey
            lam = (x - Ax) * ex + (y - Ay) * ey
            along = tx * ex + ty * ey
            to_end = (L - lam if along > 0 else lam) / abs(along) + 1e-9
            block = max(_cast(S, V, r, r2, graze, approach_min, x, y, tx, ty) - gap, 0.0)
            turn = _slide_left(ta, tl, math.degrees(math.asin(min(max(-un, 0.0), 1.0))))
            if turn < math.inf:
                bt = math.radians(ta[ta.shape[0] - 1])
                f = math.cos(bt) - mu * math.sin(bt)
            d = min(to_end, block, left * f, turn)
            if d <= 0:
                return x, y, used, True, ux, uy
            x, y = x + d * tx, y + d * ty
            if turn < math.inf:
                a = math.radians(np.interp(turn - d, tl[::-1], ta[::-1]))
                ux, uy = tx * math.cos(a) - nx * math.sin(a), ty * math.cos(a) - ny * math.sin(a)
            if d == left * f:
                return x, y, budget, False, ux, uy
            used += d / f
            if d == turn:
                return x, y, used, True, ux, uy
            continue
        g0 = math.asin(min(max(-un, 0.0), 1.0))
        c = math.atan(mu)
        k = math.sqrt(1.0 + mu * mu)
        full = r / k * (_gd_inv(g0 + c) - _gd_inv(c))
        part = left < full
        clock = left if part else full
        g1 = math.atan(math.sinh(_gd_inv(g0 + c) - clock * k / r)) - c if part else 0.0
        sgn = 1.0 if (nx * ty - ny * tx) > 0 else -1.0
        a = sgn * (g0 - max(g1, 0.0))
        mx, my = math.cos(a) * nx - math.sin(a) * ny, math.sin(a) * nx + math.cos(a) * ny
        qx, qy = px + r * mx, py + r * my
        if not _clear(S, qx, qy, r - graze_tol):
            return x, y, used, True, ux, uy
        x, y = qx, qy
        if part:
            return x, y, budget, False, ux, uy
        used += full
    return x, y, used, True, ux, uy


@numba.njit(cache=True)
def _slide_left(ta, tl, incidence):
    """``ContactParams.slide_left`` from its ``turn_table`` (ta, tl)."""
    if ta.shape[0] == 0 or incidence < ta[0]:
        return math.inf
    return np.interp(incidence, ta, tl)


@numba.njit(cache=True)
def advance_kernel(S, V, r, r2, graze, approach_min, bump_range, gap, graze_tol, same,
                   max_events, arc, mu, ta, tl, budget, xs, ys, uxs, uys):
    """:func:`envs.contact.advance` (with a contact rule) of every flight (xs, ys, uxs,
    uys): (x, y, used, bumped, ux, uy) arrays. ``S`` (ns, 5): the sides (Ax, Ay, ex, ey,
    L); ``V`` (nv, 2): the corners; ``arc`` [deg]: the bumper arc 90° − β; ``mu``: the slide
    friction; ``ta``, ``tl``: the rule's ``turn_table`` (empty: slides keep their heading).
    """
    m = xs.shape[0]
    ox, oy, used = np.empty(m), np.empty(m), np.empty(m)
    vx, vy = np.empty(m), np.empty(m)
    bumped = np.empty(m, dtype=np.bool_)
    cap = S.shape[0] + V.shape[0]
    hx, hy, hb = np.empty(cap), np.empty(cap), np.empty(cap)
    hs, gid, first = (np.empty(cap, dtype=np.int64), np.empty(cap, dtype=np.int64),
                      np.empty(cap, dtype=np.int64))
    for i in range(m):
        ox[i], oy[i], used[i], bumped[i], vx[i], vy[i] = _advance_one(
            S, V, r, r2, graze, approach_min, bump_range, gap, graze_tol, same, max_events,
            arc, mu, ta, tl, budget, xs[i], ys[i], uxs[i], uys[i], hx, hy, hb, hs, gid,
            first)
    return ox, oy, used, bumped, vx, vy
