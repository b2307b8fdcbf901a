"""The paper's step model: Algorithm 3's chain over the N configuration cells (docs/model.md §16).

For one bouncing angle φ and rotation noise (ε, r) the robot's motion over the N
configuration cells is a Markov chain: a forward cell moves to its step-table successor with
probability 1; a bump cell (p, k) turns to orientation k + (φ + δ)/Δ with the probabilities of
:class:`~planners.noise.TurnNoise` (r for δ = 0, (1 − r)/(2ε/Δ) for each
δ ∈ {−ε, …, −Δ, Δ, …, ε}). If φ + δ ≡ 0 (mod 360°) the robot keeps its heading and bumps
again at once: that is a valid transition from the bump cell to itself (a self-loop), not an
error. When 2ε ≥ 360° some headings are reached by several δ; their probabilities add up.

- :func:`transition_matrix`: the sparse N × N chain of one angle (CSR, built with numpy
  index arithmetic and :meth:`CellSpace.turn`).
- :class:`StepModel`: the model behind the :class:`~planners.coverage.base.CoverageModel`
  protocol: persistent groups, limiting distribution π and coverage q (π summed over
  orientations) of one angle.

Examples
--------
A 1 × 3 corridor at K = 4 with φ = 180°: facing east or west the robot shuttles along the
corridor forever (one periodic group of 6 configurations); facing north or south it bumps at
once and flips between north and south in its cell (three groups of 2). Every configuration
is persistent and each cell is covered a third of the time:

>>> from envs import Environment
>>> from planners.cells import CellSpace
>>> env = Environment.from_dict({"boundary": [[0, 0], [1.02, 0], [1.02, 0.34], [0, 0.34]],
...                              "robot_radius": 0.17,
...                              "discretization": {"cell_size": 0.34, "orientations": 4}})
>>> res = StepModel(CellSpace(env)).analyse(180)
>>> res.analysis.group_sizes.tolist(), res.q.round(4).tolist()
([6, 2, 2, 2], [0.3333, 0.3333, 0.3333])
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
import scipy.sparse as sp

from envs import UserError

from ..cells import CellSpace
from ..noise import TurnNoise
from ..resources import F64, I32, I64, MemoryEstimate, pipeline
from .base import AngleCoverage
from .markov import analyse_chain, analyse_run_chain
from .timeshare import DelayChain

__all__ = ["StepSettings", "StepModel", "transition_matrix"]

_EXACT = TurnNoise()


def transition_matrix(cs: CellSpace, angle_deg: float, noise: TurnNoise = _EXACT
                      ) -> sp.csr_matrix:
    """The N × N transition matrix of one bouncing angle (CSR, rows sum to 1).

    Forward cells have one entry 1 at their step-table successor; a bump cell (p, k) has an
    entry at (p, k + turn) for every turn of :meth:`TurnNoise.turns` with positive
    probability (duplicates summed). Built with numpy index arithmetic, no per-cell loop.
    """
    steps, probs = noise.turns(cs.K, angle_deg, positive=True)
    fwd = cs.forward
    N = cs.N
    bump = fwd < 0
    z = np.arange(N)
    nper = np.where(bump, steps.size, 1)
    indptr = np.concatenate([[0], np.cumsum(nper)])
    cols = np.empty(indptr[-1], dtype=np.int64)
    vals = np.empty(indptr[-1])
    fwd_pos = indptr[:-1][~bump]
    cols[fwd_pos] = fwd[~bump]
    vals[fwd_pos] = 1.0
    bstart = indptr[:-1][bump]
    bcols = cs.turn(z[bump, None], steps[None, :])
    pos = bstart[:, None] + np.arange(steps.size)[None, :]
    cols[pos] = bcols
    vals[pos] = probs[None, :]
    M = sp.csr_matrix((vals, cols, indptr), shape=(N, N))
    M.sum_duplicates()          # turns that land on the same heading (2ε >= 360°)
    return M


def _bump_matrix(cs: CellSpace, steps: np.ndarray, probs: np.ndarray) -> sp.csr_matrix:
    """Rows of the bump cells only (other rows empty): what analyse_run_chain needs."""
    N = cs.N
    zb = np.flatnonzero(cs.forward < 0)
    cols = cs.turn(zb[:, None], steps[None, :]).ravel()
    rows = np.repeat(zb, steps.size)
    vals = np.tile(probs, zb.size)
    M = sp.csr_matrix((vals, (rows, cols)), shape=(N, N))
    M.sum_duplicates()
    return M


@dataclass(frozen=True)
class StepSettings:
    """The step model has no modelling settings; ``method`` picks the exact solver.

    Attributes
    ----------
    method : {"runs", "matrix"}
        ``"runs"`` (default) solves the chain censored to the bump cells and expands it
        exactly along the forward runs (:func:`planners.coverage.markov.analyse_run_chain`);
        ``"matrix"`` analyses the full N × N matrix
        (:func:`planners.coverage.markov.analyse_chain`).
        Both give the same numbers; "runs" is several times faster on fine grids.
    """

    method: str = "runs"

    def __post_init__(self) -> None:
        if self.method not in ("runs", "matrix"):
            raise UserError(f"the step model's method must be 'runs' or 'matrix', got "
                            f"{self.method!r}.")


@dataclass(eq=False)
class StepModel:
    """The paper's step model of one cell space (:class:`CoverageModel`)."""

    name: ClassVar[str] = "step"
    Settings: ClassVar[type] = StepSettings
    spaces: ClassVar[tuple] = ("positions", "configurations")
    state_kind: ClassVar[str] = "configurations"
    steps_in_flights: ClassVar[bool] = False
    contact_rule: ClassVar[bool] = False
    rest_turns: ClassVar[bool] = False
    summary: ClassVar[str] = ("the paper's chain over configuration cells, snapped to cell "
                              "centres after every step")

    cs: CellSpace
    settings: StepSettings = field(default_factory=StepSettings)

    @classmethod
    def memory_estimate(cls, cells: CellSpace, angles, eps_deg: float = 0.0,
                        settings=None) -> MemoryEstimate:
        """Peak memory of one angle's chain (they are built one after another): the run
        chain over N states and its bump rows (B bumps × the turns of ±ε), with the step
        table (:func:`planners.resources.pipeline`).
        """
        N, K = cells.N, cells.K
        e = abs(float(eps_deg)) / cells.delta_deg if math.isfinite(float(eps_deg)) else 0.0
        turns = min(K, 2 * int(round(e)) + 1)
        fwd = vars(cells).get("forward")
        B = N if fwd is None else int((fwd < 0).sum())
        per_state = 26 * I64         # run chain: succ, end, bindex, prefix sums (x7), pi ...
        per_entry = 3 * I64 + 2 * (I32 + F64) + I64   # bump rows: parts, COO, CSR, Cc
        return pipeline(cells, MemoryEstimate(
            "the coverage chain", N * per_state + B * turns * per_entry, 0.0,
            N * F64 * (1 + len(tuple(angles)))))

    @classmethod
    def build(cls, cs: CellSpace, settings: StepSettings) -> "StepModel":
        """The model of ``cs`` (nothing to precompute beyond ``cs.forward``)."""
        return cls(cs, settings)

    def bump_rate(self, cov: AngleCoverage) -> float:
        """Bumps per step: π summed over the configurations whose step is a bump."""
        bump = (np.asarray(self.cs.forward) < 0).astype(float)
        return float(np.asarray(cov.pi, dtype=float) @ bump)

    def analyse(self, angle_deg: float, noise: TurnNoise = _EXACT) -> AngleCoverage:
        """Persistent groups, limiting distribution (uniform start over the N
        configurations) and coverage of one bouncing angle.
        """
        cs = self.cs
        t0 = time.thread_time()
        steps, probs = noise.turns(cs.K, angle_deg, positive=True)
        if self.settings.method == "matrix":
            res = analyse_chain(transition_matrix(cs, angle_deg, noise))
        else:
            res = analyse_run_chain(cs.forward, _bump_matrix(cs, steps, probs))
        q = res.pi.reshape(cs.K, cs.P).sum(axis=0)
        return AngleCoverage(model=self.name, angle=float(angle_deg), noise=noise, q=q,
                             pi=res.pi, analysis=res, seconds=time.thread_time() - t0,
                             settings=self.settings)

    def turn_matrix(self, angle_deg: float, noise: TurnNoise = _EXACT) -> sp.csr_matrix:
        """The whole one-step chain (the delay chain's flights are the identity)."""
        return transition_matrix(self.cs, angle_deg, noise)

    def delay_chain(self) -> DelayChain:
        """One-step flights; each step counted in its configuration's cell; uniform start."""
        cs = self.cs
        z = np.arange(cs.N)
        reward = sp.csr_matrix((np.ones(cs.N), (z, z % cs.P)), shape=(cs.N, cs.P))
        return DelayChain.stepwise(reward, np.full(cs.N, 1.0 / cs.N))
