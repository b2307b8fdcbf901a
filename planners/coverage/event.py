"""The event (bump-to-bump) coverage model: exact flights between contacts.

The paper's step model (:mod:`planners.coverage.step`) snaps the robot to a cell centre after
every step, so at fine headings a robot 20° off an axis never drifts across rows. The event
model keeps the continuous geometry where it matters: the robot's state is observed only at
its contacts with the walls, and the flight from one contact to the next is an exact straight
line cast against the walls (the same caster, contact conventions and step rule as the
kinematic twin: :mod:`envs.motion`). Only the contact *point* is binned (by arc length along
the C-space boundary; a contact in a concave corner has the corner's own bin, whose flights
start in the corner); the heading stays exact on the Δ = 360°/K grid (starts are
cell-centre headings θ_k and every turn φ + δ is a multiple of Δ).

The definition is docs/model.md §17; its measured accuracy ``docs/model_continuous.md``.
:class:`EventSettings` (bin length, samples per bin); the contact bins are
:class:`planners.boundary.Boundary`'s (the C-space rings cut into bins, point → (ring, arc
length)); :class:`EventModel` (flights, step rewards and start built once;
:meth:`EventModel.analyse`: one angle's chain, limit and coverage q).

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

from envs import UserError
from envs.contact import REST_FLIGHT, contact_flights
from envs.motion import ContactParams, casters, drive_distance, flight_steps, unit

from ..boundary import Boundary, bins_estimate
from ..cells import CellSpace
from ..noise import TurnNoise
from ..resources import MemoryEstimate, pipeline
from .base import AngleCoverage, cached_build
from .event_flights import FlightCells, StepTable, step_table
from .stationary import analyse_contact_chain
from .timeshare import DelayChain

__all__ = ["EventSettings", "EventModel", "flight_steps", "analyse_contact_chain"]

_EXACT = TurnNoise()

_CHUNK = 8192            # rays per vectorised cast (memory: chunk x walls floats)
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
        Gaussian noise only (docs/model.md §11a): flight headings per heading bin, spread
        evenly inside it at θ_k + ((l + ½)/n_θ − ½)Δ, each crossed with the ``samples``
        start points. Grid noise keeps the exact heading θ_k.
    contact : envs.motion.ContactParams, optional
        The contact rule of docs/model.md §9 (default None: every contact bumps, §17).
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


def _landing_heading(paths, k: np.ndarray, delta_deg: float, K: int,
                     rest: np.ndarray | None = None, rest_deg: float = 0.0):
    """The heading each flight lands with, on the grid: (lo, hi, t), the flight landing with
    heading index lo with probability 1 − t and hi = lo + 1 with t. A flight keeps its own
    ``k`` (t = 0) unless it slid into the wall (a rule with ``turn_in``, docs/model.md §9):
    its bump heading θ then lies between two grid headings, θ/Δ = lo + t, and is split
    between them linearly. The flights marked in ``rest`` (no length: a bump from rest)
    land turned by ``rest_deg``, the body's extra turn after such a bump (§11b, §17),
    split in the same way.
    """
    k = np.asarray(k, dtype=np.int64)
    lo, t = k.copy(), np.zeros(k.size)
    turned = np.flatnonzero(np.any(paths.u_end != paths.u, axis=1))
    if turned.size:
        x = np.degrees(np.arctan2(paths.u_end[turned, 1], paths.u_end[turned, 0])) / delta_deg
        lo[turned] = np.floor(x).astype(np.int64) % K
        t[turned] = x - np.floor(x)
    if rest is not None and rest_deg != 0:
        at = np.flatnonzero(rest)
        x = lo[at] + t[at] + rest_deg / delta_deg
        lo[at] = np.floor(x).astype(np.int64) % K
        t[at] = x - np.floor(x)
    return lo, (lo + 1) % K, t


def _split_landings(state, lb, K, w, n_fwd, steps, heading):
    """The flights with a split landing heading (:func:`_landing_heading`) as two flights
    each: (src, dst, n_fwd, weight, steps) with the second halves appended (their counted
    steps repeated under the new flight indices).
    """
    lo, hi, t = heading
    two = np.flatnonzero(t > 0)
    src = np.concatenate([state, state[two]])
    dst = np.concatenate([lb * K + lo, lb[two] * K + hi[two]])
    wt = np.concatenate([w * (1.0 - t), w[two] * t[two]])
    if two.size == 0:
        return src, dst, n_fwd, wt, steps
    new = np.full(state.size, -1, dtype=np.int64)
    new[two] = state.size + np.arange(two.size)
    rows = np.flatnonzero(new[steps.flight] >= 0)
    steps = StepTable(flight=np.concatenate([steps.flight, new[steps.flight[rows]]]
                                            ).astype(np.int32),
                      offset=np.concatenate([steps.offset, steps.offset[rows]]),
                      cell=np.concatenate([steps.cell, steps.cell[rows]]))
    return src, dst, np.concatenate([n_fwd, n_fwd[two]]), wt, steps


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
    knife_edge_flights : int      sampled flights (last set built) that pass a knife edge (§10)
    stationary_method : str
        "krylov" (default), "aggregation" or "power": how classes above 20000 states are
        solved (:func:`analyse_contact_chain`).
    """

    name: ClassVar[str] = "event"
    Settings: ClassVar[type] = EventSettings
    spaces: ClassVar[tuple] = ("positions",)
    state_kind: ClassVar[str] = "contact states (bin, heading)"
    steps_in_flights: ClassVar[bool] = True
    contact_rule: ClassVar[bool] = True
    rest_turns: ClassVar[bool] = True
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
        self.boundary = bd = Boundary(env, st.bin_length, corners=True)
        nb = bd.n_bins
        self.n_states = n = nb * K
        caster = casters(env)[0]
        uk = unit(np.arange(K) * cs.delta_deg)
        self._flight_sets: dict = {}
        self._use(self._flight_set(False, 0.0))
        # first flights from the cell centres (uniform over the N configurations)
        p0 = np.tile(np.arange(cs.P), K)
        k0 = np.repeat(np.arange(K), cs.P)
        c0 = cs.centres[p0]
        d0 = _cast(caster, c0, uk[k0])
        paths0 = contact_flights(caster, c0, uk[k0], d0, st.contact)
        lb0 = bd.bin_of(paths0.end)
        lo, hi, t = _landing_heading(paths0, k0, cs.delta_deg, K)
        s0 = lb0 * K + np.where(t < 0.5, lo, hi)     # a first flight: the nearest heading
        self.start_pre = np.bincount(s0, minlength=n) / float(p0.size)
        self._start = (paths0, s0)                  # for flight_cells
        self.build_seconds = time.perf_counter() - t0

    def _use(self, fs: "_Flights") -> None:
        self.flight, self.flights, self.reward = fs.flight, fs.flights, fs.reward
        self.length, self.mean_flight = fs.length, fs.mean_flight

    def _flights_for(self, noise: TurnNoise, angles=None) -> "_Flights":
        """The flight set of ``noise``: continuous headings for Gaussian noise or a body's
        errors, with the body's extra turn after a bump from rest (:meth:`_flight_set`) in
        the sense the bumps by ``angles`` spin (``TurnNoise.rest_for``).
        """
        return self._flight_set(noise.gaussian, noise.rest_for(angles))

    def _flight_set(self, continuous: bool, rest_deg: float = 0.0) -> "_Flights":
        """The sampled flights: from the exact grid headings θ_k (grid noise, docs/model.md
        §17), or with ``continuous`` from ``heading_samples`` headings spread evenly inside
        each heading bin, θ_k + ((l + ½)/n_θ − ½)Δ (Gaussian noise, §11a). A flight shorter
        than :data:`envs.contact.REST_FLIGHT` (its start heads into its wall: a bump from
        rest) lands turned by ``rest_deg`` (a body that turns further after one, §11b). Cached.
        """
        key = (bool(continuous), float(rest_deg))
        if key in self._flight_sets:
            return self._flight_sets[key]
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
        # cast gives ~1e-9 m there (the start sits CONTACT_GAP off the ring); skip the cast.
        # A corner bin's start touches two walls: into either one bumps at once.
        into = (u * bd.seg_inward[seg]).sum(axis=1) < -_INTO_TOL
        corner = bd.corner_of_bin[b]
        at = np.flatnonzero(corner >= 0)
        other = bd.seg_inward[bd.corner_seg[corner[at], 1]]
        into[at] |= (u[at] * other).sum(axis=1) < -_INTO_TOL
        dist = np.zeros(len(pts))
        dist[~into] = _cast(caster, pts[~into], u[~into])
        paths = contact_flights(caster, pts, u, dist, st.contact)   # slides below β (§9)
        land, dist, into = paths.end, paths.clock, into & (paths.clock == 0)
        lb = b.copy()                        # an immediate bump lands in its own bin
        lb[~into] = bd.bin_of(land[~into])
        # flights into another part of C-space thread a knife edge exactly on its axis (§10)
        self.knife_edge_flights = int((bd.part_of_bin[lb] != bd.part_of_bin[b]).sum())
        n_fwd = flight_steps(dist, cs.h)
        src, to, n_fwd, w, steps = _split_landings(
            state, lb, K, np.full(state.size, 1.0 / (S * nt)), n_fwd,
            step_table(cs, n_fwd, paths),
            _landing_heading(paths, k, cs.delta_deg, K, paths.clock < REST_FLIGHT, rest_deg))
        flight = sp.csr_matrix((w, (src, to)), shape=(n, n))
        flight.sum_duplicates()
        fs = _Flights(flight=flight, flights=(src, to, n_fwd + 1, w),
                      reward=steps.reward(src, w, n, cs.P),
                      length=np.bincount(src, weights=w * (n_fwd + 1), minlength=n),
                      mean_flight=float(np.mean(dist)), steps=steps)
        self._flight_sets[key] = fs
        return fs

    @classmethod
    def memory_estimate(cls, cells: CellSpace, angles, eps_deg: float = 0.0,
                        settings=None) -> MemoryEstimate:
        """Peak memory of the sampled flights (contact bins · K · samples, about 45 float
        and int arrays over them) and the boundary's bin tables and cast grids, with the
        step table (fitted to tracemalloc peaks on lab, fig1 and complex at K = 8–72: 342 B
        per flight and 3.4 kB per bin, since the bin lookup is compiled).
        """
        bins = bins_estimate(cells.env, float(getattr(settings, "bin_length", 0.03)),
                             corners=True)
        flights = float(bins) * cells.K * int(getattr(settings, "samples", 2))
        return pipeline(cells, MemoryEstimate("the event coverage model",
                                              flights * 350 + bins * 4_000))

    @classmethod
    def build(cls, cs: CellSpace, settings: EventSettings) -> "EventModel":
        """The model of ``cs`` (cached per environment and settings)."""
        return cached_build(cls, cs, settings)

    def turn_matrix(self, angle_deg: float, noise: TurnNoise = _EXACT) -> sp.csr_matrix:
        """Pre-turn (b, k) → post-turn (b, k + (φ+δ)/Δ) with the docs/model.md §16 probabilities.

        Built in CSR form directly (no COO sort): every row of heading k has the same
        columns (k + steps) mod K, sorted, in every bin; offsets that wrap onto one heading
        add up.
        """
        K, n = self.cs.K, self.n_states
        steps, probs = noise.turns(K, angle_deg, positive=True)
        steps, inv = np.unique(np.asarray(steps) % K, return_inverse=True)
        probs = np.bincount(inv.reshape(-1), probs, len(steps))
        kc = (np.arange(K)[:, None] + steps[None, :]) % K              # (K, S)
        order = np.argsort(kc, axis=1, kind="stable")
        kc, kp = np.take_along_axis(kc, order, 1), probs[order]
        indices = (np.arange(n // K)[:, None, None] * K + kc[None]).reshape(-1)
        data = np.broadcast_to(kp[None], (n // K, K, len(steps))).reshape(-1)
        return sp.csr_matrix((data, indices, np.arange(n + 1) * len(steps)), shape=(n, n))

    def delay_chain(self, noise: TurnNoise = _EXACT, angles=None) -> DelayChain:
        """The model as a :class:`planners.coverage.timeshare.DelayChain`: the sampled flights with
        their steps (forward steps + the bump step), the flight rewards and the first landing
        (for Gaussian ``noise`` the flights with headings inside their bins, §11a).
        """
        fs = self._flights_for(noise, angles)
        src, dst, delay, w = fs.flights
        return DelayChain(src=src, dst=dst, delay=delay, weight=w, reward=fs.reward,
                          start=self.start_pre)

    def flight_cells(self, noise: TurnNoise = _EXACT, angles=None) -> FlightCells:
        """The flights of :meth:`delay_chain` (same ``noise``) and the first flights from the
        cell centres, step by step: what the horizon coverage counts (docs/model.md §20).
        """
        paths, land0 = self._start
        n0 = flight_steps(paths.clock, self.cs.h)
        return FlightCells(steps=self._flights_for(noise, angles).steps, start_delay=n0 + 1,
                           start_land=land0, start_steps=step_table(self.cs, n0, paths))

    def chain(self, angle_deg: float, noise: TurnNoise = _EXACT
              ) -> tuple[sp.csr_matrix, np.ndarray]:
        """(transition matrix over contact states, start distribution) of one angle."""
        W = self.turn_matrix(angle_deg, noise)
        T = sp.csr_matrix(self._flights_for(noise, [angle_deg]).flight @ W)
        mu = np.asarray(W.T @ self.start_pre).ravel()
        return T, mu

    def bump_rate(self, cov: AngleCoverage) -> float:
        """Bumps per step: one per flight, 1 / (mean steps per flight)."""
        return 1.0 / float(cov.steps_per_flight)

    def analyse(self, angle_deg: float, noise: TurnNoise = _EXACT) -> AngleCoverage:
        """Limiting distribution over contact states and the coverage q of one angle.

        The chain's closed classes g are weighted by absorption a_g from the cell-centre
        start (first flight, then the first turn); q = Σ_g a_g q_g with q_g = π_gᵀ R
        normalised over the P cells, R the expected counted steps per flight in every cell
        (renewal–reward): the share of a long run's steps, class by class (§17, §20).
        """
        t0 = time.thread_time()
        T, mu = self.chain(angle_deg, noise)
        res = analyse_contact_chain(T, mu, np.arange(self.n_states) // self.cs.K,
                                    method=self.stationary_method)
        fs = self._flights_for(noise, [angle_deg])
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
