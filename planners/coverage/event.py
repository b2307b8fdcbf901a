"""The event (bump-to-bump) coverage model: exact flights between contacts.

The paper's step model (:mod:`planners.coverage.step`) snaps the robot to a cell centre after
every step, so at fine headings a robot 20° off an axis never drifts across rows. The event
model keeps the continuous geometry where it matters: the robot's state is observed only at
its contacts with the walls, and the flight from one contact to the next is an exact straight
line cast against the walls (the same caster, contact conventions and step rule as the
kinematic twin: :mod:`envs.motion`). Only the contact *point* is binned (by arc length along
the C-space boundary); the heading stays exact on the Δ = 360°/K grid (starts are
cell-centre headings θ_k and every turn φ + δ is a multiple of Δ).

The definition is docs/model.md §10; its measured accuracy ``docs/model_continuous.md``.
:class:`EventSettings` (bin length, samples per bin); :class:`Boundary` (the C-space rings
cut into bins, point → (ring, arc length)); :class:`EventModel` (flights, step rewards and
start built once; :meth:`EventModel.analyse`: one angle's chain, limit and coverage q).

Examples
--------
A corridor of three cells (1.10 m × 0.40 m, C-space [0.17, 0.93] × [0.17, 0.23] m) at K = 4
with φ = 90°: the robot circulates east → north → west → south. A 0.76 m flight is two
forward steps and a bump step, a 0.06 m flight a bump step only; per cycle the end cells get
3 steps each and the middle cell 2:

>>> from envs import Environment
>>> from planners.cells import CellSpace
>>> env = Environment.from_dict({"boundary": [[0, 0], [1.1, 0], [1.1, 0.4], [0, 0.4]],
...                              "robot_radius": 0.17,
...                              "discretization": {"cell_size": 0.34, "orientations": 4}})
>>> res = EventModel(CellSpace(env), EventSettings(bin_length=0.01)).analyse(90)
>>> res.q.round(4).tolist(), res.steps_per_flight
([0.375, 0.25, 0.375], 2.0)
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
import scipy.sparse as sp
import shapely
from shapely.geometry.polygon import orient

from envs import UserError
from envs.contact import contact_flights
from envs.motion import CONTACT_GAP, ContactParams, casters, drive_distance, flight_steps, unit

from ..cells import CellSpace
from ..timeshare import DelayChain
from .base import AngleCoverage, cached_build
from .event_flights import FlightCells, StepTable, step_table
from .noise import TurnNoise
from .stationary import analyse_contact_chain

__all__ = ["EventSettings", "Boundary", "EventModel", "flight_steps", "analyse_contact_chain"]

_EXACT = TurnNoise()

_CHUNK = 8192            # rays per vectorised cast (memory: chunk x walls floats)
_SNAP = 2e-3             # [m] a landing point must lie this close to the C-space ring
_NUDGE = CONTACT_GAP    # [m] flight starts sit this far off the ring, on the free side
_INTO_TOL = 0.03         # u · inward normal below −this: a flight of length 0 (> sin 1.41°,
#                          the angle between a rounded corner's chords and the true circle)


@dataclass(frozen=True)
class EventSettings:
    """Settings of the event model (defaults: the recommended 0.03 m bins, 2 samples).

    Attributes
    ----------
    bin_length : float
        Target length [m] of a contact bin along the C-space boundary; each ring is cut
        into ceil(length / bin_length) equal bins (so bins are at most this long).
    samples : int
        Flight start points per bin, spread evenly across it at arc-length fractions
        (j + ½)/samples; 1 means the bin centre only.
    heading_samples : int
        Gaussian noise only (docs/model.md §18): flight headings per heading bin, spread
        evenly inside it at θ_k + ((l + ½)/n_θ − ½)Δ, each crossed with the ``samples``
        start points. Grid noise keeps the exact heading θ_k.
    contact : envs.motion.ContactParams, optional
        The contact rule of docs/model.md §23 (default None: every contact bumps, §10).
    """

    bin_length: float = 0.03
    samples: int = 2
    heading_samples: int = 2
    contact: ContactParams | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.bin_length) and self.bin_length > 0):
            raise UserError(f"the contact bin length must be positive, got {self.bin_length}.")
        if int(self.samples) != self.samples or self.samples < 1:
            raise UserError(f"samples per bin must be a positive integer, got {self.samples}.")
        if int(self.heading_samples) != self.heading_samples or self.heading_samples < 1:
            raise UserError(f"heading samples per bin must be a positive integer, got "
                            f"{self.heading_samples}.")


# ============================================================================ boundary
class Boundary:
    """The C-space boundary (``env.cspace`` rings) cut into contact bins by arc length.

    Parameters
    ----------
    env : Environment
    bin_length : float   target bin length [m]

    Attributes
    ----------
    n_bins : int
    ring_of_bin : (n_bins,) int        ring of every bin
    ring_length, ring_bin_length : (R,) [m]
    ring_first_bin, ring_bins : (R,) int

    Notes
    -----
    ``env.cspace`` is E eroded by the radius with rounded corners approximated by 32
    segments per quarter circle, so the rings deviate from the exact contact set by at most
    r (1 − cos(π/128)) ≈ 5e-5 m at r = 0.17 m; they are used only to *name* contact points
    (binning) and to place flight start points. Projection: every point goes to its nearest
    ring segment among the candidates of a fine grid cell (candidates = segments within
    ``fine``·√½ + 2 mm of the cell centre).
    """

    def __init__(self, env, bin_length: float) -> None:
        rings = []
        part = []
        for poly in shapely.get_parts(env.cspace):
            if poly.is_empty:
                continue
            poly = orient(poly, sign=1.0)        # free side on the left of every ring
            rings.append(np.asarray(poly.exterior.coords))
            rings.extend(np.asarray(i.coords) for i in poly.interiors)
            part.extend([len(set(part))] * (1 + len(poly.interiors)))
        if not rings:
            raise UserError(f"{env.name} has no free C-space for the robot.")
        A, B, rid, s0 = [], [], [], []
        lengths = []
        for r_i, c in enumerate(rings):
            d = np.hypot(*(c[1:] - c[:-1]).T)
            keep = d > 0
            a, b, d = c[:-1][keep], c[1:][keep], d[keep]
            A.append(a)
            B.append(b)
            rid.append(np.full(len(a), r_i))
            s0.append(np.concatenate([[0.0], np.cumsum(d)[:-1]]))
            lengths.append(float(d.sum()))
        self.A = np.concatenate(A)
        self.B = np.concatenate(B)
        self.seg_ring = np.concatenate(rid)
        self.seg_s0 = np.concatenate(s0)
        self.seg_len = np.hypot(*(self.B - self.A).T)
        e = (self.B - self.A) / self.seg_len[:, None]
        self.seg_inward = np.column_stack([-e[:, 1], e[:, 0]])
        self.ring_length = np.array(lengths)
        self.ring_bins = np.maximum(1, np.ceil(self.ring_length / bin_length - 1e-9)
                                    ).astype(np.int64)
        self.ring_bin_length = self.ring_length / self.ring_bins
        self.ring_first_bin = np.concatenate([[0], np.cumsum(self.ring_bins)[:-1]])
        self.n_bins = int(self.ring_bins.sum())
        self.ring_of_bin = np.repeat(np.arange(len(rings)), self.ring_bins)
        self.part_of_bin = np.asarray(part)[self.ring_of_bin]   # connected part of C-space
        self._ring_seg_first = np.concatenate(
            [[0], np.cumsum(np.bincount(self.seg_ring, minlength=len(rings)))[:-1]])
        self._build_grid(max(min(0.05, env.cell_size / 4), 1e-3))

    def _build_grid(self, g: float) -> None:
        lo = np.minimum(self.A, self.B).min(axis=0) - g
        hi = np.maximum(self.A, self.B).max(axis=0) + g
        self.g, self.x0, self.y0 = g, float(lo[0]), float(lo[1])
        self.nx = int(math.ceil((hi[0] - lo[0]) / g))
        self.ny = int(math.ceil((hi[1] - lo[1]) / g))
        jj, ii = np.mgrid[0:self.ny, 0:self.nx]
        cen = np.column_stack([self.x0 + (ii.ravel() + 0.5) * g,
                               self.y0 + (jj.ravel() + 0.5) * g])
        reach = g * math.sqrt(0.5) + _SNAP
        # every segment within reach of a cell's centre (shapely's tree), by cell then segment
        tree = shapely.STRtree(shapely.linestrings(np.stack([self.A, self.B], axis=1)))
        rows, cols = tree.query(shapely.points(cen), predicate="dwithin", distance=reach)
        order = np.lexsort((cols, rows))
        rows, cols = rows[order], cols[order]
        counts = np.bincount(rows, minlength=len(cen))
        k = max(1, int(counts.max()))
        table = np.full((len(cen), k), -1, dtype=np.int64)
        slot = np.arange(rows.size) - np.concatenate([[0], np.cumsum(counts)])[rows]
        table[rows, slot] = cols
        self._cand = table

    def locate(self, pts) -> tuple[np.ndarray, np.ndarray]:
        """(ring, arc length [m]) of the nearest ring point of each point (n, 2)."""
        pts = np.asarray(pts, dtype=float).reshape(-1, 2)
        i = np.clip(((pts[:, 0] - self.x0) / self.g).astype(np.int64), 0, self.nx - 1)
        j = np.clip(((pts[:, 1] - self.y0) / self.g).astype(np.int64), 0, self.ny - 1)
        cand = self._cand[j * self.nx + i]                       # (n, k)
        valid = cand >= 0
        c = np.where(valid, cand, 0)
        d = _point_seg_dist(pts[:, None, :], self.A[c], self.B[c])
        d = np.where(valid, d, np.inf)
        best = np.argmin(d, axis=1)
        seg = c[np.arange(len(pts)), best]
        far = d[np.arange(len(pts)), best] > _SNAP
        if far.any():                                            # off the grid's reach
            dd = _point_seg_dist(pts[far][:, None, :], self.A[None], self.B[None])
            seg[far] = np.argmin(dd, axis=1)
        a, b = self.A[seg], self.B[seg]
        e = b - a
        lam = np.clip(((pts - a) * e).sum(1) / (self.seg_len[seg] ** 2), 0.0, 1.0)
        return self.seg_ring[seg], self.seg_s0[seg] + lam * self.seg_len[seg]

    def bin_of(self, pts) -> np.ndarray:
        """Contact bin of each point (n, 2)."""
        ring, s = self.locate(pts)
        local = np.minimum((s / self.ring_bin_length[ring]).astype(np.int64),
                           self.ring_bins[ring] - 1)
        return self.ring_first_bin[ring] + local

    def points(self, bins, frac, return_segment: bool = False):
        """Ring points (n, 2) at fraction ``frac`` ∈ [0, 1] along each bin, moved 1e-9 m
        into the free side (where the twin's robot stops: ``CONTACT_GAP`` short of the
        contact), so that a contact on a cell border is counted in the free cell. With
        ``return_segment`` also the ring segment of each point.
        """
        bins = np.asarray(bins, dtype=np.int64)
        ring = self.ring_of_bin[bins]
        s = (bins - self.ring_first_bin[ring] + np.asarray(frac, dtype=float)) \
            * self.ring_bin_length[ring]
        # segment of each arc length within its ring
        out = np.empty((bins.size, 2))
        seg = np.empty(bins.size, dtype=np.int64)
        for r_i in np.unique(ring):
            m = ring == r_i
            first = self._ring_seg_first[r_i]
            s0 = self.seg_s0[self.seg_ring == r_i]
            k = np.clip(np.searchsorted(s0, s[m], side="right") - 1, 0, s0.size - 1) + first
            lam = np.clip((s[m] - self.seg_s0[k]) / self.seg_len[k], 0.0, 1.0)
            out[m] = self.A[k] + lam[:, None] * (self.B[k] - self.A[k]) \
                + _NUDGE * self.seg_inward[k]
            seg[m] = k
        return (out, seg) if return_segment else out


def _point_seg_dist(p, a, b) -> np.ndarray:
    """Distance between points p and segments ab (broadcast over leading axes)."""
    e = b - a
    ee = (e * e).sum(-1)
    t = np.clip(((p - a) * e).sum(-1) / np.where(ee > 0, ee, 1.0), 0.0, 1.0)
    d = p - (a + t[..., None] * e)
    return np.hypot(d[..., 0], d[..., 1])


# ============================================================================ flights
# flight_steps (the step rule along a flight) lives in envs.motion, re-exported here.
def _cast(caster, pos, u) -> np.ndarray:
    """Free flight length [m] (:func:`envs.motion.drive_distance` of the cast), chunked."""
    out = np.empty(len(pos))
    for s in range(0, len(pos), _CHUNK):
        out[s:s + _CHUNK] = caster.cast(pos[s:s + _CHUNK], u[s:s + _CHUNK])
    if not np.all(np.isfinite(out)):
        raise UserError("a flight never meets a wall: the environment is not closed.")
    return drive_distance(out)


@dataclass(frozen=True, eq=False)
class _Flights:
    """One set of sampled flights of an :class:`EventModel` (see its attributes)."""

    flight: sp.csr_matrix
    flights: tuple
    reward: sp.csr_matrix
    length: np.ndarray
    mean_flight: float
    steps: StepTable        # the flights' counted steps, one by one


@dataclass(eq=False)
class EventModel:
    """The angle-independent part of the event model of one environment.

    Parameters
    ----------
    cs : CellSpace
    settings : EventSettings, optional

    Attributes
    ----------
    boundary : Boundary
    n_states : int                n_bins · K contact states (bin, heading after the turn)
    flight : csr (n_states, n_states)
        Flight matrix: state (b, k) → pre-turn state (b', k) where b' is the landing bin,
        averaged over the bin's sample points.
    reward : csr (n_states, P)
        Expected counted steps per flight in every position cell (renewal reward).
    length : (n_states,)          expected steps per flight (dropped ones included)
    start_pre : (n_states,)       distribution of the first landing (pre-turn states) from
                                  the uniform cell-centre start over the N configurations
    flights : tuple of (F,) arrays
        Every sampled flight: (start state, landing pre-turn state, steps including the bump
        step, weight 1/samples); ``flight``, ``reward`` and ``length`` are its sums.
    build_seconds : float
    knife_edge_flights : int      sampled flights (last set built) that pass a knife edge (§19)
    stationary_method : str
        "krylov" (default), "aggregation" or "power": how classes above 20000 states are
        solved (:func:`analyse_contact_chain`).
    """

    name: ClassVar[str] = "event"
    Settings: ClassVar[type] = EventSettings
    spaces: ClassVar[tuple] = ("positions",)
    summary: ClassVar[str] = ("bump-to-bump model: exact flights between binned contact "
                              "points (the one that matches continuous motion)")

    cs: CellSpace
    settings: EventSettings = field(default_factory=EventSettings)
    stationary_method: str = "krylov"

    def __post_init__(self) -> None:
        t0 = time.perf_counter()
        cs, st = self.cs, self.settings
        env = cs.env
        K = cs.K
        self.boundary = bd = Boundary(env, st.bin_length)
        nb = bd.n_bins
        self.n_states = n = nb * K
        caster = casters(env)[0]
        uk = unit(np.arange(K) * cs.delta_deg)
        self._flight_sets: dict = {}
        self._use(self._flight_set(False))
        # first flights from the cell centres (uniform over the N configurations)
        p0 = np.tile(np.arange(cs.P), K)
        k0 = np.repeat(np.arange(K), cs.P)
        c0 = cs.centres[p0]
        d0 = _cast(caster, c0, uk[k0])
        paths0 = contact_flights(caster, c0, uk[k0], d0, st.contact)
        lb0 = bd.bin_of(paths0.end)
        self.start_pre = np.bincount(lb0 * K + k0, minlength=n) / float(p0.size)
        self._start = (paths0, lb0 * K + k0)       # for flight_cells
        self.build_seconds = time.perf_counter() - t0

    def _use(self, fs: "_Flights") -> None:
        self.flight, self.flights, self.reward = fs.flight, fs.flights, fs.reward
        self.length, self.mean_flight = fs.length, fs.mean_flight

    def _flight_set(self, continuous: bool) -> "_Flights":
        """The sampled flights: from the exact grid headings θ_k (grid noise, docs/model.md
        §10), or with ``continuous`` from ``heading_samples`` headings spread evenly inside
        each heading bin, θ_k + ((l + ½)/n_θ − ½)Δ (Gaussian noise, §18). Cached.
        """
        if continuous in self._flight_sets:
            return self._flight_sets[continuous]
        cs, st, bd = self.cs, self.settings, self.boundary
        K, n = cs.K, self.n_states
        caster = casters(cs.env)[0]
        S = int(st.samples)
        nt = int(st.heading_samples) if continuous else 1
        # flight starts: every (bin, heading) x sample x heading sample; state i = b*K + k
        state = np.repeat(np.arange(n), S * nt)
        b = state // K
        k = state % K
        frac = np.tile(np.repeat((np.arange(S) + 0.5) / S, nt), n)
        off = np.tile(((np.arange(nt) + 0.5) / nt - 0.5) * cs.delta_deg, n * S) \
            if continuous else 0.0
        pts, seg = bd.points(b, frac, return_segment=True)
        u = unit(k * cs.delta_deg + off)
        # a start heading into its own wall (u · inward normal < 0) bumps at once: the twin's
        # cast gives ~1e-9 m there (the start sits CONTACT_GAP off the ring); skip the cast
        into = (u * bd.seg_inward[seg]).sum(axis=1) < -_INTO_TOL
        dist = np.zeros(len(pts))
        dist[~into] = _cast(caster, pts[~into], u[~into])
        paths = contact_flights(caster, pts, u, dist, st.contact)   # slides below β (§23)
        land, dist, into = paths.end, paths.clock, into & (paths.clock == 0)
        lb = b.copy()                        # an immediate bump lands in its own bin
        lb[~into] = bd.bin_of(land[~into])
        # flights into another part of C-space thread a knife edge exactly on its axis (§19)
        self.knife_edge_flights = int((bd.part_of_bin[lb] != bd.part_of_bin[b]).sum())
        w = np.full(state.size, 1.0 / (S * nt))
        flight = sp.csr_matrix((w, (state, lb * K + k)), shape=(n, n))
        flight.sum_duplicates()
        n_fwd = flight_steps(dist, cs.h)
        steps = step_table(cs, n_fwd, paths)
        fs = _Flights(flight=flight, flights=(state, lb * K + k, n_fwd + 1, w),
                      reward=steps.reward(state, w, n, cs.P),
                      length=np.bincount(state, weights=w * (n_fwd + 1), minlength=n),
                      mean_flight=float(np.mean(dist)), steps=steps)
        self._flight_sets[continuous] = fs
        return fs

    @classmethod
    def build(cls, cs: CellSpace, settings: EventSettings) -> "EventModel":
        """The model of ``cs`` (cached per environment and settings)."""
        return cached_build(cls, cs, settings)

    def turn_matrix(self, angle_deg: float, noise: TurnNoise = _EXACT) -> sp.csr_matrix:
        """Pre-turn (b, k) → post-turn (b, k + (φ+δ)/Δ) with the docs/model.md §7 probabilities."""
        K = self.cs.K
        steps, probs = noise.turns(K, angle_deg, positive=True)
        i = np.arange(self.n_states)
        b, k = i // K, i % K
        cols = (b[:, None] * K + (k[:, None] + steps[None, :]) % K).ravel()
        M = sp.csr_matrix((np.tile(probs, i.size), (np.repeat(i, steps.size), cols)),
                          shape=(self.n_states, self.n_states))
        M.sum_duplicates()
        return M

    def delay_chain(self, noise: TurnNoise = _EXACT) -> DelayChain:
        """The model as a :class:`planners.timeshare.DelayChain`: the sampled flights with
        their steps (forward steps + the bump step), the flight rewards and the first landing
        (for Gaussian ``noise`` the flights with headings inside their bins, §18).
        """
        fs = self._flight_set(noise.gaussian)
        src, dst, delay, w = fs.flights
        return DelayChain(src=src, dst=dst, delay=delay, weight=w, reward=fs.reward,
                          start=self.start_pre)

    def flight_cells(self, noise: TurnNoise = _EXACT) -> FlightCells:
        """The flights of :meth:`delay_chain` (same ``noise``) and the first flights from the
        cell centres, step by step: what the horizon coverage counts (docs/model.md §17).
        """
        paths, land0 = self._start
        n0 = flight_steps(paths.clock, self.cs.h)
        return FlightCells(steps=self._flight_set(noise.gaussian).steps, start_delay=n0 + 1,
                           start_land=land0, start_steps=step_table(self.cs, n0, paths))

    def chain(self, angle_deg: float, noise: TurnNoise = _EXACT
              ) -> tuple[sp.csr_matrix, np.ndarray]:
        """(transition matrix over contact states, start distribution) of one angle."""
        W = self.turn_matrix(angle_deg, noise)
        T = sp.csr_matrix(self._flight_set(noise.gaussian).flight @ W)
        mu = np.asarray(W.T @ self.start_pre).ravel()
        return T, mu

    def analyse(self, angle_deg: float, noise: TurnNoise = _EXACT) -> AngleCoverage:
        """Limiting distribution over contact states and the coverage q of one angle.

        The chain's closed classes g are weighted by absorption a_g from the cell-centre
        start (first flight, then the first turn); q = Σ_g a_g q_g with q_g = π_gᵀ R
        normalised over the P cells, R the expected counted steps per flight in every cell
        (renewal–reward): the share of a long run's steps, class by class (§10, §17).
        """
        t0 = time.thread_time()
        T, mu = self.chain(angle_deg, noise)
        res = analyse_contact_chain(T, mu, np.arange(self.n_states) // self.cs.K,
                                    method=self.stationary_method)
        fs = self._flight_set(noise.gaussian)
        q = np.zeros(fs.reward.shape[1])
        for idx, a in zip(res.groups, res.absorption):
            qg = np.asarray(fs.reward[idx].T @ res.stationary[idx]).ravel()
            q += a * qg / qg.sum() if qg.sum() > 0 else 0.0
        tot = q.sum()
        if not tot > 0:
            raise UserError("the event model counts no step in a free cell.")
        return AngleCoverage(model=self.name, angle=float(angle_deg), noise=noise,
                             q=q / tot, pi=res.pi, analysis=res,
                             seconds=time.thread_time() - t0, settings=self.settings,
                             steps_per_flight=float(fs.length @ res.pi))
