"""The time a policy needs to reach its limit: ``steps_to_limit`` (docs/model.md §20).

The exact answer is read off one pass of the horizon recursion (:class:`Horizon.run
<planners.coverage.horizon.Horizon>`) at the horizons of :func:`~planners.coverage.horizon.grid`:
the first grid T at which q_T from the start is within TV ``tol`` of the limit. On a map
whose rooms exchange the robot rarely that T can be millions of steps, hours of recursion.
Then the pass stops at its time budget and the rest is extrapolated from the run's slowest
mode (:func:`slow_mode`): once the faster modes have died out, the share of each step in
each cell differs from the limit by a vector u·λ^t of fixed direction, so every later
horizon's counts are known in closed form and the grid is scanned without stepping. The
answer then says so (``method`` "extrapolated", with λ as a relaxation time 1/(1 − λ)).

A chain that relaxes by 1 % per step from a deviation of 0.4 in its first cell: the
extrapolation from steps 100–400 finds the first grid T where the exact counts come within
TV 0.05.

>>> import numpy as np
>>> q, u = np.array([0.5, 0.5]), np.array([0.4, -0.4])
>>> def counts(T):                       # Σ_{t<T} (q + u·0.99^t)
...     return T * q + u * (1 - 0.99 ** T) / 0.01
>>> from planners.coverage.horizon import grid
>>> history = [(T, counts(T)) for T in grid(400)]
>>> sm = slow_mode(history, q)
>>> round(sm.relaxation)
100
>>> first_within(sm.counts_at, q, 0.05, after=400)
800
>>> next(T for T in grid(10**4) if tv_distance(counts(T), q) <= 0.05)
800
"""

from __future__ import annotations

import math
import time

import numpy as np

from envs import UserError

from ..metrics import tv_distance
from ..noise import TurnNoise
from .horizon import CAP, LIMIT_TV, Horizon, grid
from .slow_mode import SlowMode, at_end, slow_mode

__all__ = ["SlowMode", "slow_mode", "first_within", "steps_to_limit", "steps_to_limit_each",
           "ESTIMATE_CAP"]

ESTIMATE_CAP = 10 ** 12     # largest T an extrapolation looks at [steps]
_FIRST_CHECK = 400          # settle: the first check of the extrapolation [steps]
_SETTLE_RATIO = 2 ** (1 / 8) * (1 + 1e-9)   # ... two checks within one grid point settle it
_EXACT = TurnNoise()


def _settled(history, limit_q) -> SlowMode:
    """A run already within tolerance of its limit and with no mode left to fit: its later
    steps are taken at the limit (u = 0), for the extrapolation of a mix it is part of.
    """
    return at_end(history, limit_q, np.zeros(len(limit_q)), 0.5)


def first_within(counts_at, q, tol: float, *, after: int, cap: int = ESTIMATE_CAP) -> int | None:
    """The first horizon of :func:`~planners.coverage.horizon.grid` above ``after`` (up to
    ``cap``) whose counts ``counts_at(T)`` are within TV ``tol`` of ``q``, or None.
    """
    for T in grid(cap):
        if T > after and tv_distance(counts_at(T), q) <= tol:
            return T
    return None


class _Policy:
    """One policy's progress through a pass: its exact state, and with ``settle`` its
    extrapolation at the last two checks (every doubling of T from 400 steps).
    """

    def __init__(self, limit_q, tol: float, settle: bool) -> None:
        self.q, self.tol, self.settle = np.asarray(limit_q, dtype=float), tol, settle
        self.state = {"steps": None, "tv": math.nan, "last": 0}
        self.mode: SlowMode | None = None
        self.estimate: int | None = None
        self.settled = False
        self.next_check = _FIRST_CHECK

    @property
    def done(self) -> bool:
        """Exact, or settled on its extrapolation: the pass need not go on for it."""
        return self.state["steps"] is not None or self.settled

    def observe(self, T: int, counts) -> None:
        """The counts of the first T steps (no effect once done)."""
        if self.done:
            return
        self.state.update(last=T, tv=tv_distance(counts, self.q))
        if self.state["tv"] <= self.tol:
            self.state["steps"] = T

    def check(self, T: int, extrapolate) -> None:
        """At every doubling of T: ``extrapolate()`` gives (slow mode, estimate) or
        (None, None); two checks in a row within one grid point of each other settle it.
        """
        if self.done or not self.settle or T < self.next_check:
            return
        self.next_check = 2 * T
        mode, est = extrapolate()
        if est is not None and self.estimate is not None and \
                max(est, self.estimate) <= _SETTLE_RATIO * min(est, self.estimate):
            self.settled = True
        self.mode, self.estimate = mode, est

    def record(self, cap: int, t0: float, extrapolate) -> dict:
        """The policy's steps_to_limit record (see :func:`steps_to_limit`)."""
        if self.state["steps"] is not None:
            mode, est, method = None, self.state["steps"], "exact"
        else:
            mode, est = (self.mode, self.estimate) if self.settled else extrapolate()
            method = "bound" if est is None else "extrapolated"
        return {**self.state, "estimate": est, "method": method,
                "relaxation_steps": None if mode is None else mode.relaxation,
                "cap": int(cap), "tol": self.tol, "seconds": time.perf_counter() - t0}


def _extrapolation(history, limit_q, tol: float):
    """(slow mode, first grid T it reaches) of one run's history, or (None, None)."""
    sm = slow_mode(history, limit_q)
    if sm is None:
        return None, None
    return sm, first_within(sm.counts_at, sm.q, tol, after=sm.T)


def steps_to_limit(hz: Horizon, angles, limit_q, *, noise: TurnNoise = _EXACT, alpha=None,
                   epoch: int | None = None, tol: float = LIMIT_TV, cap: int = CAP,
                   max_seconds: float | None = None, settle: bool = False) -> dict:
    """The smallest T on :func:`~planners.coverage.horizon.grid` at which q_T from the uniform
    start is within TV ``tol`` of ``limit_q`` (docs/model.md §20).

    The pass ends there, at the cap, after ``max_seconds``, or with ``settle`` once the
    extrapolation from the run's slow mode (:func:`slow_mode`) gives the same grid T, to
    within one grid point, at two doublings of T in a row (checked from 400 steps on).

    Returns
    -------
    dict  ``steps`` (int, or None when the pass ended before a grid T got there), ``tv``
          (TV at that T, or at the last T run), ``last`` (last T run), ``estimate``
          (``steps`` when exact; else the first grid T the run's slow mode reaches, or
          None), ``method`` ("exact", "extrapolated" or "bound": only "more than ``last``"
          is known), ``relaxation_steps`` (1/(1 − λ) of the slow mode, or None), ``cap``,
          ``tol``, ``seconds``
    """
    t0 = time.perf_counter()
    pol = _Policy(limit_q, tol, settle)
    history: list = []

    def extrapolate():
        return _extrapolation(history, pol.q, tol)

    def stop(T, counts):
        history.append((T, np.array(counts, dtype=float)))
        pol.observe(T, counts)
        pol.check(T, extrapolate)
        return pol.done or (max_seconds is not None and time.perf_counter() - t0 > max_seconds)

    for _ in hz.run(angles, grid(cap), noise=noise, alpha=alpha, epoch=epoch, stop=stop):
        pass
    return pol.record(cap, t0, extrapolate)


def steps_to_limit_each(hz: Horizon, angles, limits, *, noise: TurnNoise = _EXACT,
                        alpha=None, mix_limit=None, tol: float = LIMIT_TV, cap: int = CAP,
                        max_seconds: float | None = None,
                        settle: bool = False) -> tuple[list[dict], dict | None]:
    """:func:`steps_to_limit` of every angle alone (against ``limits[i]``) and, with ``alpha``
    and ``mix_limit``, of the mix whose runs each keep one angle drawn with probabilities α
    (no epochs), in one pass (docs/model.md §20).

    The mix's counts are Σ α_i of the angles' counts at every T, so it costs no run of its
    own (:func:`steps_to_limit` on the mix runs every angle again); the angles' runs go in
    lockstep and each leaves the pass once it and the mix are done (exact, or with
    ``settle`` settled on their extrapolation). The pass ends there, at the cap, or after
    ``max_seconds`` per policy. Each angle's result is the one :func:`steps_to_limit`
    gives it alone (same arithmetic). The mix's extrapolation is Σ α_i of its angles' slow
    modes (an angle already at its limit with no mode left to fit counts at the limit).

    Returns
    -------
    (list of the angles' dicts, the mix's dict or None), each as :func:`steps_to_limit`'s
    """
    t0 = time.perf_counter()
    angles = tuple(float(a) for a in angles)
    if len(limits) != len(angles):
        raise UserError("steps_to_limit needs one limit per angle.")
    pols = [_Policy(q, tol, settle) for q in limits]
    histories: list[list] = [[] for _ in angles]
    w, mix = None, None
    if alpha is not None and mix_limit is not None:
        w = np.asarray(alpha, dtype=float).ravel()
        if w.size != len(angles) or (w < 0).any() or not w.sum() > 0:
            raise UserError("a mix needs one non-negative α per angle, with a positive sum.")
        w = w / w.sum()
        mix = _Policy(mix_limit, tol, settle)
    horizons = grid(cap)
    runs = {i: hz.run([a], horizons, noise=noise) for i, a in enumerate(angles)}
    budget = None if max_seconds is None else max_seconds * (len(angles) + (w is not None))

    def angle_extrapolation(i):
        return lambda: _extrapolation(histories[i], pols[i].q, tol)

    def mix_extrapolation():
        parts = []
        for i in np.flatnonzero(w > 0):
            sm = slow_mode(histories[i], pols[i].q)
            if sm is None and pols[i].state["steps"] is not None and len(histories[i]) > 1:
                sm = _settled(histories[i], pols[i].q)
            if sm is None:
                return None, None
            parts.append((w[i], sm))
        after = max(sm.T for _, sm in parts)
        est = first_within(lambda T: sum(wi * sm.counts_at(T) for wi, sm in parts), mix.q,
                           tol, after=after)
        return max((sm for _, sm in parts), key=lambda sm: sm.lam), est   # the slowest

    while runs:
        counts = {i: next(r) for i, r in runs.items()}           # (T, counts, total)
        T = next(iter(counts.values()))[0]
        for i, (_, c, _) in counts.items():
            histories[i].append((T, np.array(c, dtype=float)))
            pols[i].observe(T, c)
            pols[i].check(T, angle_extrapolation(i))
        if mix is not None:
            mix.observe(T, sum(w[i] * counts[i][1] for i in counts))
            mix.check(T, mix_extrapolation)
        for i in list(runs):
            if pols[i].done and (mix is None or mix.done or w[i] == 0):
                del runs[i]
        if T >= horizons[-1] or (budget is not None and time.perf_counter() - t0 > budget):
            break
    out = [p.record(cap, t0, angle_extrapolation(i)) for i, p in enumerate(pols)]
    return out, None if mix is None else mix.record(cap, t0, mix_extrapolation)
