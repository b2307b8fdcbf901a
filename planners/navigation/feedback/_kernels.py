"""Compiled kernels of the feedback filter (numba): the flights of many poses with the
bearings of what they touch, and the bumper-side probabilities of those bearings
(docs/model.md §15). They compute what :func:`planners.navigation.feedback.observe.flights`
and :func:`~planners.navigation.feedback.observe.side_probs` computed with numpy, the same
formulas in one pass per pose instead of (poses × walls) temporaries: a global belief of
6000 particles is updated in a few ms instead of 30.

The numpy versions are kept as the reference (``flights_reference``,
``side_probs_reference``); ``tests/test_kernels.py`` checks the two on random poses.
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = ["flights_kernel", "side_probs_kernel"]


@numba.njit(cache=True)
def flights_kernel(px, py, ux, uy, S, V, r, r2, graze, approach_min, bump_range, gap,
                   want_bearings):
    """Per pose (``px``, ``py``, ``ux``, ``uy``), against the sides ``S`` (ns, 5: Ax, Ay, ex,
    ey, L; the normal is (−ey, ex)) and corners ``V`` (nv, 2) of
    :attr:`envs.motion.WallCaster.kernel_sides` and ``kernel_corners``: the drive D to the
    first contact [m] (``drive_distance`` of the contact distance, 0 within ``bump_range``,
    1e6 when nothing is ahead) and, with ``want_bearings``, the bearing [deg] of every
    feature (sides, then corners) it touches at the contact (within ``bump_range`` of the
    first, |bearing| < 90°), NaN elsewhere: :meth:`envs.motion.WallCaster.feature_distances`'
    formulas.
    """
    n, ns, nv = px.size, S.shape[0], V.shape[0]
    D = np.empty(n)
    beta = np.full((n if want_bearings else 0, ns + nv), np.nan)
    fd = np.empty(ns + nv)
    for i in range(n):
        x, y, u, v = px[i], py[i], ux[i], uy[i]
        t = np.inf
        for j in range(ns):
            ex, ey = S[j, 2], S[j, 3]
            nx, ny = -ey, ex
            rx = x - S[j, 0]
            ry = y - S[j, 1]
            s0 = rx * nx + ry * ny
            un = u * nx + v * ny
            a = -un if s0 >= 0 else un
            fd[j] = np.inf
            if a > approach_min:
                tj = max((abs(s0) - r) / a, 0.0)
                lam = rx * ex + ry * ey + tj * (u * ex + v * ey)
                if lam >= 0.0 and lam <= S[j, 4]:
                    fd[j] = tj
                    t = min(t, tj)
        for k in range(nv):
            vx = x - V[k, 0]
            vy = y - V[k, 1]
            b = vx * u + vy * v
            disc = r2 - (vx * vx + vy * vy - b * b)
            fd[ns + k] = np.inf
            if b < 0.0 and disc > graze:
                tk = max(-b - math.sqrt(disc), 0.0)
                fd[ns + k] = tk
                t = min(t, tk)
        if not np.isfinite(t):
            t = 1e6
        D[i] = 0.0 if t <= bump_range else max(t - gap, 0.0)
        if want_bearings:
            cx, cy = x + t * u, y + t * v
            for j in range(ns + nv):
                if fd[j] <= t + bump_range:
                    if j < ns:
                        Ax, Ay, ex, ey = S[j, 0], S[j, 1], S[j, 2], S[j, 3]
                        lam = min(max((cx - Ax) * ex + (cy - Ay) * ey, 0.0), S[j, 4])
                        wx = Ax + lam * ex - cx
                        wy = Ay + lam * ey - cy
                    else:
                        wx = V[j - ns, 0] - cx
                        wy = V[j - ns, 1] - cy
                    bj = math.degrees(math.atan2(u * wy - v * wx, u * wx + v * wy))
                    if abs(bj) < 90.0:
                        beta[i, j] = bj
    return D, beta


@numba.njit(cache=True)
def _ndtr(x):
    return 0.5 * math.erfc(-x / math.sqrt(2.0))


@numba.njit(cache=True)
def side_probs_kernel(beta, zone, blur, union, p_side):
    """(n, 3) probabilities of the readings both / left / right given the touched features'
    bearings (n, F) [deg] (NaN: not touched): the formulas of ``side_probs_reference``.
    """
    n, F = beta.shape
    out = np.empty((n, 3))
    for i in range(n):
        left = right = 0.0
        o0 = o1 = o2 = 0.0
        touched = 0
        for j in range(F):
            b = beta[i, j]
            if b == b:                                   # not NaN
                fl = _ndtr((b + zone) / blur)
                fr = _ndtr((zone - b) / blur)
                left = max(left, fl)
                right = max(right, fr)
                o0 += fl * fr
                o1 += fl * (1 - fr)
                o2 += (1 - fl) * fr
                touched += 1
        m = max(touched, 1)
        p0 = union * left * right + (1 - union) * o0 / m
        p1 = union * left * (1 - right) + (1 - union) * o1 / m
        p2 = union * (1 - left) * right + (1 - union) * o2 / m
        total = p0 + p1 + p2
        if total > 0:
            p0, p1, p2 = p0 / max(total, 1e-300), p1 / max(total, 1e-300), p2 / max(total,
                                                                                    1e-300)
        else:
            p0 = p1 = p2 = 1.0 / 3
        out[i, 0] = (1 - p_side) * p0 + p_side * (1 - p0) / 2
        out[i, 1] = (1 - p_side) * p1 + p_side * (1 - p1) / 2
        out[i, 2] = (1 - p_side) * p2 + p_side * (1 - p2) / 2
    return out
