"""The sampled coverage model: Hsu's generalized cell mapping over configuration cells.

Every configuration cell (p, k) is represented by a deterministic stratified lattice of
sample poses: m × m points spread over the position cell's square (those where the robot
fits; the cell centre if none does) times ``theta_samples`` headings spread over
[θ_k − Δ/2, θ_k + Δ/2]. Each sample makes one exact continuous step with the kinematic
twin's rule (:func:`envs.motion.step`: forward h when at least h − STEP_TOL is free, else a
move to contact and a turn by φ + δ with the docs/model.md §11 noise) and is mapped to the
configuration cell it ends in; the fractions give the row of (p, k) in a sparse N × N chain,
analysed with :mod:`planners.coverage.markov` (uniform start over the N configurations, as
docs/model.md §16). Coverage counts steps where the twin counts them: a forward step in its
start cell, a bump step in the cell of the contact point (steps in no free cell are
dropped; a sample that ends in a cell that is not free is sent to the nearest free cell for
the chain).

This is the established route for continuous dynamics; it re-randomises the position inside
the cell at every step, which the event model avoids (``docs/model_continuous.md``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
import scipy.sparse as sp

from envs import UserError
from envs.motion import casters, drive_distance, step, unit

from ..cells import CellSpace
from ..noise import TurnNoise
from ..resources import GEOM_NATIVE, MemoryEstimate, pipeline
from .base import AngleCoverage, cached_build
from .markov import analyse_chain
from .timeshare import DelayChain

__all__ = ["SampledSettings", "SampledModel"]

_EXACT = TurnNoise()


@dataclass(frozen=True)
class SampledSettings:
    """Settings of the sampled model.

    Attributes
    ----------
    grid : int            m: an m × m lattice of sample points per position cell
    theta_samples : int   sample headings per orientation cell
    """

    grid: int = 3
    theta_samples: int = 2

    def __post_init__(self) -> None:
        for name in ("grid", "theta_samples"):
            v = getattr(self, name)
            if int(v) != v or v < 1:
                raise UserError(f"{name} must be a positive integer, got {v}.")


@dataclass(eq=False)
class SampledModel:
    """The angle-independent part (sample steps) of the sampled model of one environment.

    Attributes
    ----------
    fwd : csr (N, N)        forward samples' destination fractions (rows of bump-only cells
                            are empty)
    bump_frac : (N,)        fraction of each cell's samples that bump
    bump_dest : csr (N, P)  bump samples' contact cells (fractions of all samples)
    reward : csr (N, P)     counted steps per step from each cell (≤ 1 per row)
    """

    name: ClassVar[str] = "sampled"
    Settings: ClassVar[type] = SampledSettings
    spaces: ClassVar[tuple] = ("positions",)
    state_kind: ClassVar[str] = "configurations"
    steps_in_flights: ClassVar[bool] = False
    contact_rule: ClassVar[bool] = False
    rest_turns: ClassVar[bool] = False
    summary: ClassVar[str] = ("generalized cell mapping: each configuration cell's "
                              "transitions from a lattice of exact continuous steps")

    cs: CellSpace
    settings: SampledSettings = field(default_factory=SampledSettings)

    def __post_init__(self) -> None:
        t0 = time.perf_counter()
        cs, st = self.cs, self.settings
        env, P, K, h = cs.env, cs.P, cs.K, cs.h
        m, nt = int(st.grid), int(st.theta_samples)
        off = (np.arange(m) + 0.5) / m - 0.5
        ox, oy = np.meshgrid(off, off, indexing="ij")
        lat = np.column_stack([ox.ravel(), oy.ravel()]) * h                # (m², 2)
        pts = cs.centres[:, None, :] + lat[None]                           # (P, m², 2)
        free = env.points_free(pts.reshape(-1, 2)).reshape(P, m * m)
        pp, jj = np.nonzero(free)
        none = np.flatnonzero(~free.any(axis=1))
        pos_p = np.concatenate([pp, none])                                 # sample -> cell
        pos_xy = np.concatenate([pts[pp, jj], cs.centres[none]])
        dth = ((np.arange(nt) + 0.5) / nt - 0.5) * cs.delta_deg
        # all samples: (position sample, orientation k, heading offset)
        ns, nk = len(pos_p), K * nt
        si = np.repeat(np.arange(ns), nk)
        kk = np.tile(np.repeat(np.arange(K), nt), ns)
        th = kk * cs.delta_deg + np.tile(dth, K * ns)
        p = pos_p[si]
        z = kk * P + p
        w = 1.0 / np.bincount(z, minlength=cs.N)[z]                        # per-cell weight
        xy = pos_xy[si]
        u = unit(th)
        local = casters(env, h)[1]
        free_d = np.empty(len(xy))
        for s in range(0, len(xy), 65536):
            free_d[s:s + 65536] = local.cast(xy[s:s + 65536], u[s:s + 65536])
        move, bump = step(drive_distance(free_d), h)          # the twin's step rule
        end = xy + move[:, None] * u
        dest = cs.cell_of_point(end)
        counted = np.where(bump, dest, p)
        out = dest < 0
        dest[out] = _nearest_free(cs, end[out])
        f = ~bump
        self.fwd = sp.csr_matrix((w[f], (z[f], kk[f] * P + dest[f])), shape=(cs.N, cs.N))
        self.bump_frac = np.bincount(z[bump], weights=w[bump], minlength=cs.N)
        self.bump_dest = sp.csr_matrix((w[bump], (z[bump], dest[bump])), shape=(cs.N, P))
        ok = counted >= 0
        self.reward = sp.csr_matrix((w[ok], (z[ok], counted[ok])), shape=(cs.N, P))
        for M in (self.fwd, self.bump_dest, self.reward):
            M.sum_duplicates()
        self.n_samples = len(xy)
        self.build_seconds = time.perf_counter() - t0

    @classmethod
    def memory_estimate(cls, cells: CellSpace, angles, eps_deg: float = 0.0,
                        settings=None) -> MemoryEstimate:
        """Peak memory of the sampled flights (N · grid² · θ samples, about 75 float and int
        arrays over them) and their shapely points, with the step table.
        """
        grid = int(getattr(settings, "grid", 3))
        nt = int(getattr(settings, "theta_samples", 2))
        samples = float(cells.N) * grid * grid * nt
        return pipeline(cells, MemoryEstimate("the sampled coverage model", samples * 600,
                                              cells.P * grid * grid * GEOM_NATIVE))

    @classmethod
    def build(cls, cs: CellSpace, settings: SampledSettings) -> "SampledModel":
        """The model of ``cs`` (cached per environment and settings)."""
        return cached_build(cls, cs, settings)

    def chain(self, angle_deg: float, noise: TurnNoise = _EXACT) -> sp.csr_matrix:
        """The N × N transition matrix of one angle."""
        cs = self.cs
        steps, probs = noise.turns(cs.K, angle_deg, positive=True)
        B = self.bump_dest.tocoo()
        rows = np.repeat(B.row, steps.size)
        landed = cs.z(B.col, B.row // cs.P)            # (contact cell, heading before the turn)
        cols = cs.turn(landed[:, None], steps[None, :]).ravel()
        vals = (B.data[:, None] * probs[None, :]).ravel()
        T = self.fwd + sp.csr_matrix((vals, (rows, cols)), shape=(cs.N, cs.N))
        T = sp.csr_matrix(T)
        T.sum_duplicates()
        return T

    turn_matrix = chain          # the delay chain's flights are the identity

    def delay_chain(self) -> DelayChain:
        """One-step flights; rewards where the twin counts each sample's step; uniform start."""
        return DelayChain.stepwise(self.reward, np.full(self.cs.N, 1.0 / self.cs.N))

    def bump_rate(self, cov: AngleCoverage) -> float:
        """Bumps per step: π weighted by each configuration's bumping fraction."""
        return float(np.asarray(cov.pi, dtype=float) @ np.asarray(self.bump_frac, dtype=float))

    def analyse(self, angle_deg: float, noise: TurnNoise = _EXACT) -> AngleCoverage:
        """Limiting distribution (uniform start over N) and coverage of one angle."""
        t0 = time.thread_time()
        res = analyse_chain(self.chain(angle_deg, noise))
        q = np.asarray(self.reward.T @ res.pi).ravel()
        if not q.sum() > 0:
            raise UserError("the sampled model counts no step in a free cell.")
        return AngleCoverage(model=self.name, angle=float(angle_deg), noise=noise,
                             q=q / q.sum(), pi=res.pi, analysis=res,
                             seconds=time.thread_time() - t0, settings=self.settings)


def _nearest_free(cs: CellSpace, pts: np.ndarray) -> np.ndarray:
    """Nearest free position cell (by centre distance) of each point."""
    out = np.empty(len(pts), dtype=np.int64)
    for s in range(0, len(pts), 4096):
        d = ((pts[s:s + 4096, None, :] - cs.centres[None]) ** 2).sum(-1)
        out[s:s + 4096] = np.argmin(d, axis=1)
    return out if len(pts) else np.zeros(0, dtype=np.int64)

