"""The closed-loop value of the feedback navigator's decisions under turn noise
(docs/model.md §15, "Deciding by value").

The open-loop score of a plan (the chance that its whole turn sequence ends in the goal cell
with no correction on the way) ranks the 10–20-turn plans of a cluttered room poorly: it is
0.02–0.2 for all of them, while the robot re-decides after every bump. This module gives the
decision rule what it lacks, the value of a contact state when the robot keeps deciding:

- **States.** A contact state is a contact bin of the C-space boundary (the exact
  planner's bins, h/4 long) and the heading of the flight that ended there, on a grid of
  ``heading_step_deg`` (1°), so that the heading's offset from the Δ grid, which decides
  where a noisy robot goes, is kept.
- **Transitions (goal-free, computed once per map, angles, noise and contact rule).** A
  turn by φ ∈ Φ ends at the heading + φ + n, and the flight to the next bump (the exact ray
  cast, the contact rule's slide) lands in the next state. The ``nodes`` flights of a state
  and φ are equally likely: node q has the turn error n_q, the normal quantile at
  (q + ½)/M of N(0, σ²), and starts from its own point along the bin (stratified, in an
  order that does not pair with n_q). So a state's value is averaged over where in its bin
  the robot is, as the belief, a few cm wide, does not know it either: a value from the
  bin's centre alone promised 0.52 where every flight from the true point of `lab`'s
  corridor gave 0.06 (a development measurement of that variant).
- **Stop values (per goal).** Turning by φ and making the final drive succeeds with the
  probability (over the same nodes) that one drive length, the one that brings the noise-free
  heading's flight nearest the goal cell's centre, ends in the goal cell with the heading
  within Δ/2 of the goal heading, before the bump. The stop's turn errors are the nodes of
  a wider normal, √(σ² + e²) (the navigator passes e = σ, ``FeedbackConfig.stop_extra``
  = 1; the table's own default e = 0 is a stop from a known state): a stop from a belief,
  whose heading at a bump is known only to about the last turn's spread. The contact that
  would cut the drive short is the first one of the stop's own flight (the node's point,
  the heading with the stop's turn error), cast only where the drive could succeed; with
  ``at_bump`` (``FeedbackConfig.stop_at_bump``, default) a drive that runs into that
  flight's bump succeeds when the bump lies in the goal cell (a goal on a wall or in a
  corner; cast too from states with a flight that bumps near the cell).
- **Values.** With t flights left, V_t(s) = max over φ of max(stop(s, φ), γ · E V_{t−1}(s'))
  and V_0(s) = max over φ of stop(s, φ): the best success probability of a robot that knows
  its contact state after every bump (value iteration on the noisy contact-state chain, a
  discount γ per bump for the cost of time and the belief's imperfections).

The navigator (:meth:`FeedbackNavigator.choose` with ``decision="value"``) weighs this value
over the belief (QMDP: the belief's particles are turned by each φ with the declared noise,
flown to their bump and looked up), turns the best φ, and makes the final drive when the
belief's mass in the goal cell is at least the value of flying on.
"""

from __future__ import annotations

import math
import weakref

import numpy as np
from scipy.special import ndtri

from ...measures import heading_ok
from .observe import landings

__all__ = ["ValueTable", "Transitions", "transitions"]

_CHUNK = 40_000            # flights cast at once (memory: walls × chunk)
_CACHE: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


class Transitions:
    """The goal-free part of the value: every contact state's flights after each turn.

    Attributes
    ----------
    n_bins, n_head : int            contact bins and heading steps; a state is
                                    ``bin · n_head + heading step``
    step_deg : float                heading step [deg]
    weights : (M,)                  the nodes' probabilities (1/M each)
    offsets : (M,) [deg]            the turn error of each node: the normal quantiles at
                                    (q + ½)/M of N(0, σ²)
    fracs : (M,)                    where along its bin each node's flight starts
    nxt : (A, S, M) int32           the state each flight lands in
    points : (M, n_bins, 2)         the nodes' start points [m]
    """

    def __init__(self, nav, sigma_deg: float, step_deg: float, nodes: int) -> None:
        bd, caster, contact = nav.boundary, nav.caster, nav.contact
        self.boundary = bd
        self.n_bins = int(bd.n_bins)
        self.n_head = int(round(360.0 / step_deg))
        self.step_deg = 360.0 / self.n_head
        M = max(int(nodes), 1)
        q = np.arange(M)
        self.offsets = sigma_deg * ndtri((q + 0.5) / M)
        self.weights = np.full(M, 1.0 / M)
        # node q flies from its own point of the bin, a fraction (πq + ½)/M along it (π a
        # stride coprime to M, so that position and turn error are not paired in order)
        stride = next(k for k in range(max(M // 2, 1), 0, -1) if math.gcd(k, M) == 1)
        self.fracs = ((q * stride) % M + 0.5) / M
        self.points = np.stack([bd.points(np.arange(self.n_bins), np.full(self.n_bins, f))
                                for f in self.fracs])                     # (M, n_bins, 2)
        angles = np.asarray(nav.angles, dtype=float)
        S = self.n_bins * self.n_head
        self.nxt = np.empty((len(angles), S, M), dtype=np.int32)
        b = np.repeat(np.arange(self.n_bins), self.n_head)
        head0 = np.tile(np.arange(self.n_head) * self.step_deg, self.n_bins)
        for i, a in enumerate(angles):
            for q, off in enumerate(self.offsets):
                th = head0 + a + off
                for lo in range(0, S, _CHUNK):
                    sl = slice(lo, min(lo + _CHUNK, S))
                    _, end, _, _, _, th_end = landings(caster, self.points[q, b[sl]],
                                                       th[sl], contact, bearings=False)
                    self.nxt[i, sl, q] = self.state(end, th_end)

    def state(self, pos, heading_deg) -> np.ndarray:
        """The contact state of bump poses (pos (n, 2) [m], heading (n,) [deg])."""
        bins = np.asarray(self.boundary.bin_of(pos), dtype=np.int64)
        k = np.rint(np.asarray(heading_deg, dtype=float) / self.step_deg).astype(np.int64)
        return (bins * self.n_head + k % self.n_head).astype(np.int32)


def transitions(nav, sigma_deg: float, step_deg: float = 1.0, nodes: int = 7) -> Transitions:
    """The :class:`Transitions` of an exact navigator's map, angles and contact rule under
    turn noise σ, cached per cell space (the experiments plan many goals on one map).
    """
    key = (tuple(float(a) for a in nav.angles), round(float(sigma_deg), 9), float(step_deg),
           int(nodes), nav.contact, round(float(nav.bin_length), 12))
    per_map = _CACHE.setdefault(nav.cells, {})
    tr = per_map.get(key)
    if tr is None:
        tr = per_map[key] = Transitions(nav, sigma_deg, step_deg, nodes)
    return tr


class ValueTable:
    """V_t over contact states for one goal (module docstring).

    Parameters
    ----------
    fnav : FeedbackNavigator      its goal cell, goal heading and exact navigator
    sigma_deg : float             turn noise σ of the transitions
    horizon : int                 the largest t kept
    gamma : float                 discount per bump
    stop_extra_deg : float        [deg] heading error added in quadrature to σ in the stop
                                  values (module docstring)
    at_bump : bool                a final drive that runs into its bump in the goal cell
                                  succeeds (module docstring)
    """

    def __init__(self, fnav, sigma_deg: float, horizon: int, gamma: float,
                 step_deg: float = 1.0, nodes: int = 7, stop_extra_deg: float = 0.0,
                 at_bump: bool = False) -> None:
        self.tr = tr = transitions(fnav.nav, sigma_deg, step_deg, nodes)
        self.gamma = float(gamma)
        M = len(tr.offsets)
        self.stop_offsets = math.hypot(sigma_deg, stop_extra_deg) * \
            ndtri((np.arange(M) + 0.5) / M)
        self.at_bump = bool(at_bump)
        stop = self._stops(fnav)                                # (A, S)
        self.stop = stop
        w = tr.weights.astype(np.float32)
        V = [stop.max(axis=0)]
        for _ in range(int(horizon)):
            cont = np.float32(self.gamma) * (V[-1][tr.nxt] @ w)        # (A, S)
            V.append(np.maximum(stop, cont).max(axis=0))
        self.V = np.stack(V)                                    # (horizon + 1, S)

    def _stops(self, fnav) -> np.ndarray:
        """(A, S) the probability that turning by φ and the final drive end in the goal.

        Each node's drive is checked against the stop's own flight (its point, the heading
        with the stop's turn error), cast only where it can matter: where the drive ends in
        the goal cell with the heading in range, and (``at_bump``) where a flight of the
        state bumps near the cell.
        """
        tr, cs = self.tr, fnav.cells
        x0, y0, x1, y1 = fnav.box
        centre = np.array([(x0 + x1) / 2, (y0 + y1) / 2])
        half = (x1 - x0) / 2
        A, S, M = tr.nxt.shape
        b = np.repeat(np.arange(tr.n_bins), tr.n_head)
        head0 = np.tile(np.arange(tr.n_head) * tr.step_deg, tr.n_bins)
        out = np.zeros((A, S), dtype=np.float32)
        reach = cs.delta_deg / 2 + 4 * float(np.abs(self.stop_offsets).max()) + 1.0
        if self.at_bump:         # states with a flight that bumps within 1.5 h of the cell
            bd = tr.boundary
            near_bin = np.abs(bd.points(np.arange(tr.n_bins), np.full(tr.n_bins, 0.5))
                              - centre).max(axis=1) <= half + cs.h
            lands_near = near_bin[tr.nxt // tr.n_head].any(axis=2)          # (A, S)
        for i, a in enumerate(fnav.nav.angles):
            th = head0 + float(a)
            near = heading_ok(th, fnav.goal_heading, 2 * reach)
            idx = np.flatnonzero(near)
            if idx.size == 0:
                continue
            t = th[idx]
            rad = np.radians(t)
            u = np.column_stack([np.cos(rad), np.sin(rad)])
            ok = np.zeros(idx.size)
            for q, off in enumerate(self.stop_offsets):
                p = tr.points[q, b[idx]]
                d = np.maximum(((centre - p) * u).sum(1), 0.0)
                rq = np.radians(t + off)
                end = p + d[:, None] * np.column_stack([np.cos(rq), np.sin(rq)])
                depth = half - np.abs(end - centre).max(axis=1)
                aimed = heading_ok(t + off, fnav.goal_heading, cs.delta_deg)
                cast = aimed & ((depth >= 0) | (lands_near[i, idx] if self.at_bump else False))
                ok += tr.weights[q] * self._good(fnav, p, t + off, d, depth, cast)
            out[i, idx] = ok
        return out

    def _good(self, fnav, p, heading, d, depth, cast) -> np.ndarray:
        """(n,) bool: the final drive ``d`` [m] from ``p`` (n, 2) at ``heading`` (n,) [deg]
        ends in the goal cell (``depth`` >= 0) before its flight's first contact, or
        (``at_bump``) runs into the flight's bump (d at least its clock) and the bump lies
        in the goal cell; only where ``cast`` (heading in range; the others are False
        without a cast).
        """
        out = np.zeros(len(p), dtype=bool)
        k = np.flatnonzero(cast)
        if k.size == 0:
            return out
        clock, end, _, _, straight, _ = landings(fnav.nav.caster, p[k], heading[k],
                                                 fnav.nav.contact, bearings=False)
        good = (depth[k] >= 0) & (d[k] <= straight)
        if self.at_bump:
            x0, y0, x1, y1 = fnav.box
            inside = (end[:, 0] >= x0) & (end[:, 0] <= x1) & (end[:, 1] >= y0) & \
                (end[:, 1] <= y1)
            good |= inside & (d[k] >= clock)
        out[k] = good
        return out

    def values(self, pos, heading_deg, left: int) -> np.ndarray:
        """V_left of bump poses (pos (n, 2), heading (n,) [deg]); ``left`` is clipped to the
        horizon (and 0 below).
        """
        t = min(max(int(left), 0), len(self.V) - 1)
        return self.V[t][self.tr.state(pos, heading_deg)]
