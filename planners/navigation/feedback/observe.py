"""What a bump-and-clock robot reads, as the feedback filter predicts it (docs/model.md §15):
each pose's flight to its bump under the motion layer's exact casts and the contact rule
(:func:`flights`, :func:`landings`), and the bumper-side reading's probabilities with the
declared error rate (:func:`side_probs`).
"""

from __future__ import annotations

import numpy as np
from scipy.special import ndtr

from envs import UserError
from envs.contact import contact_flights
from envs.motion import APPROACH_MIN, BUMP_RANGE, CONTACT_GAP, ContactParams, drive_distance, unit

from ._kernels import flights_kernel, side_probs_kernel
from .config import FeedbackConfig

__all__ = ["SIDES", "flights", "flights_reference", "landings", "side_of", "side_probs",
           "side_probs_reference"]

SIDES = ("both", "left", "right")
"""Bumper readings: both switches, the left one only, the right one only."""


# ============================================================================ flights
def side_of(left: bool, right: bool) -> int:
    """Index into :data:`SIDES` of a bumper reading (both, left only, right only)."""
    if left and right:
        return 0
    if left:
        return 1
    if right:
        return 2
    raise UserError("a bump needs at least one closed bumper switch.")


def flights(caster, pos, heading_deg, bearings: bool = True):
    """Exact flights of poses: (drive [m], unit headings, contact bearings [deg] or None).

    The bearings (n, F) are those of every wall feature (side or corner) the disk touches at
    its contact (within ``BUMP_RANGE`` of the first), relative to the heading, + to the
    left; NaN for the features it does not touch (two walls at once in a corner). Compiled
    (:func:`._kernels.flights_kernel`); :func:`flights_reference` is the numpy original.
    """
    pos = np.asarray(pos, dtype=float).reshape(-1, 2)
    u = unit(heading_deg)
    D, beta = flights_kernel(np.ascontiguousarray(pos[:, 0]), np.ascontiguousarray(pos[:, 1]),
                             np.ascontiguousarray(u[:, 0]), np.ascontiguousarray(u[:, 1]),
                             caster.kernel_sides, caster.kernel_corners, float(caster.r),
                             float(caster.r2), float(caster.graze), APPROACH_MIN, BUMP_RANGE,
                             CONTACT_GAP,
                             bool(bearings))
    return D, u, (beta if bearings else None)


def flights_reference(caster, pos, heading_deg, bearings: bool = True):
    """:func:`flights` in numpy (the reference the kernel is checked against)."""
    pos = np.asarray(pos, dtype=float).reshape(-1, 2)
    u = unit(heading_deg)
    if not bearings:
        t = caster.cast(pos, u)
        t = np.where(np.isfinite(t), t, 1e6)
        return np.where(t <= BUMP_RANGE, 0.0, drive_distance(t)), u, None
    fd = caster.feature_distances(pos, u)
    t = fd.min(axis=1)
    t = np.where(np.isfinite(t), t, 1e6)
    D = np.where(t <= BUMP_RANGE, 0.0, drive_distance(t))
    c = pos + t[:, None] * u
    rel = c[:, None, :] - caster.A[None]                               # (n, ns, 2)
    lam = np.clip((rel * caster.e[None]).sum(2), 0.0, caster.L[None])
    touch = np.concatenate([caster.A[None] + lam[..., None] * caster.e[None],
                            np.broadcast_to(caster.vertices[None],
                                            (len(c), len(caster.vertices), 2))], axis=1)
    w = touch - c[:, None, :]
    beta = np.degrees(np.arctan2(u[:, None, 0] * w[..., 1] - u[:, None, 1] * w[..., 0],
                                 u[:, None, 0] * w[..., 0] + u[:, None, 1] * w[..., 1]))
    near = (fd <= t[:, None] + BUMP_RANGE) & (np.abs(beta) < 90.0)
    return D, u, np.where(near, beta, np.nan)


def landings(caster, pos, heading_deg, contact: ContactParams | None, bearings: bool = True):
    """Flights of poses to their bump under a contact rule (docs/model.md §15, §9).

    Returns (clock [m], end (n, 2) [m], bearings (n, F) [deg] or None, slid (n,) bool or
    None, straight [m], heading at the bump (n,) [deg]): ``straight`` is :func:`flights`'
    drive to the first contact and ``clock`` the clock length to the bump, where the robot
    ends (``end``). With a contact rule, a flight whose first contact lies outside the
    bumper arc ±(90° − β) slides on (:func:`envs.contact.contact_flights`, ``slid``), and
    its bearings are those at the bump; bearings outside the arc are NaN (they press no
    switch); a rule that turns the body into the wall (``turn_in``) changes its heading by
    the bump. ``contact`` None: the front-half bumper, bitwise :func:`flights` (clock =
    straight, slid None, the heading kept).
    """
    pos = np.asarray(pos, dtype=float).reshape(-1, 2)
    D, u, beta = flights(caster, pos, heading_deg, bearings)
    head = np.broadcast_to(np.asarray(heading_deg, dtype=float).reshape(-1), (len(pos),))
    if contact is None:
        return D, pos + D[:, None] * u, beta, None, D, head
    # resampled copies share a pose: slide each distinct (x, y, heading) once
    _, first, inv = np.unique(np.column_stack([pos, head]), axis=0, return_index=True,
                              return_inverse=True)
    inv = inv.reshape(-1)
    fl = contact_flights(caster, pos[first], u[first], D[first], contact, legs=False)
    clock, end, slid = fl.clock[inv], fl.end[inv], fl.slid[inv]
    turned = slid & np.any(fl.u_end[inv] != fl.u[inv], axis=1)
    if turned.any():
        head = head.copy()
        v = fl.u_end[inv][turned]
        head[turned] = np.degrees(np.arctan2(v[:, 1], v[:, 0])) % 360.0
    if beta is not None:
        arc = 90.0 - contact.beta_deg
        if slid.any():
            beta = beta.copy()
            beta[slid] = flights(caster, end[slid], head[slid])[2]
        with np.errstate(invalid="ignore"):
            beta = np.where(np.abs(beta) <= arc, beta, np.nan)
    return clock, end, beta, slid, D, head


def side_probs(beta, cfg: FeedbackConfig) -> np.ndarray:
    """:func:`side_probs_reference`, compiled (:func:`._kernels.side_probs_kernel`)."""
    beta = np.ascontiguousarray(beta, dtype=float)
    return side_probs_kernel(beta.reshape(len(beta), -1), float(cfg.centre_zone_deg),
                             float(max(cfg.side_blur_deg, 1e-9)), float(cfg.side_union),
                             float(cfg.p_side))


def side_probs_reference(beta, cfg: FeedbackConfig) -> np.ndarray:
    """(n, 3) probability of each reading of :data:`SIDES` given the touched features'
    bearings (n, F) [deg] (NaN: not touched).

    A feature at bearing β closes the left switch when β >= −zone and the right one when
    β <= zone, blurred by a normal CDF of width ``side_blur_deg``. Where several features
    are touched (a corner) bodies differ: the twin closes every switch any of them selects
    (the union), a body whose switches read one wall point the switches of one of them. The
    model weighs the two conventions ``side_union`` : 1 − ``side_union`` (one touched
    feature at random for the second); then a wrong reading with probability ``p_side``,
    spread evenly over the two others: (1 − p_side)·p + p_side·(1 − p)/2.
    """
    s = max(cfg.side_blur_deg, 1e-9)
    z = cfg.centre_zone_deg
    with np.errstate(invalid="ignore"):
        fl = ndtr((beta + z) / s)                      # (n, F): NaN where not touched
        fr = ndtr((z - beta) / s)
        left = np.nan_to_num(np.nanmax(fl, axis=1, initial=0.0))
        right = np.nan_to_num(np.nanmax(fr, axis=1, initial=0.0))
        touched = np.isfinite(beta).sum(axis=1)
        one = np.stack([np.nansum(fl * fr, axis=1), np.nansum(fl * (1 - fr), axis=1),
                        np.nansum((1 - fl) * fr, axis=1)], axis=1)
    p = np.column_stack([left * right, left * (1 - right), (1 - left) * right])
    p = cfg.side_union * p + (1 - cfg.side_union) * one / np.maximum(touched, 1)[:, None]
    total = p.sum(1, keepdims=True)
    p = np.where(total > 0, p / np.maximum(total, 1e-300), 1.0 / 3)    # nothing touched
    return (1 - cfg.p_side) * p + cfg.p_side * (1 - p) / 2
