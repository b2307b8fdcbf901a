"""The counted steps of the event model's flights, step by step (docs/model.md §17, §20).

A flight of the event model (:mod:`planners.coverage.event`) leaves a contact (or, for the
first flight of a run, a cell centre) at point s with heading u, runs a free length d [m] and
makes n_fwd = :func:`envs.motion.flight_steps` forward steps and one bump step. Forward step
m = 0 … n_fwd − 1 is counted in the cell of s + m·h·u, the bump step in the cell of s + d·u;
steps in no free cell are dropped (§8). :func:`step_table` lists every counted step with its
flight and its offset m (the bump step has offset n_fwd), once: the event model sums it into
its renewal rewards (:meth:`StepTable.reward`), and the horizon coverage of
:mod:`planners.coverage.horizon` counts each step at the time it happens
(:meth:`EventModel.flight_cells <planners.coverage.event.EventModel.flight_cells>`).

A flight of 0.76 m from x = 0.17 m along +x in a row of 0.34 m cells (h = 0.34 m): two
forward steps in cells 0 and 1, the bump step at x = 0.93 m in cell 2:

>>> import envs
>>> from planners.cells import CellSpace
>>> cs = CellSpace(envs.Environment.from_dict({"boundary": [[0, 0], [1.1, 0], [1.1, 0.4],
...     [0, 0.4]], "robot_radius": 0.17, "discretization": {"cell_size": 0.34}}))
>>> t = step_table(cs, [2], StraightFlights(np.array([[0.17, 0.2]]), np.array([[1.0, 0.0]]),
...                                        np.array([0.76])))
>>> t.flight.tolist(), t.offset.tolist(), t.cell.tolist()
([0, 0, 0], [0, 1, 2], [0, 1, 2])
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .timeshare import DelayChain

__all__ = ["StepTable", "FlightCells", "StartedChain", "StraightFlights", "started_chain",
           "step_table"]


@dataclass(frozen=True, eq=False)
class StepTable:
    """Every counted step of a set of flights (steps in no free cell left out).

    Attributes
    ----------
    flight : (C,) int32 index of the step's flight in its set
    offset : (C,) int32 forward step m = 0 … n_fwd − 1, or n_fwd for the bump step: a flight
                        leaving at step t makes this step at t + 1 + offset
    cell : (C,) int32   position cell P of the step
    """

    flight: np.ndarray
    offset: np.ndarray
    cell: np.ndarray

    def reward(self, owner, weight, n: int, P: int) -> sp.csr_matrix:
        """Renewal rewards (n, P): expected counted steps per cell of a flight leaving each of
        n states, flight f leaving state ``owner[f]`` with probability ``weight[f]``.
        """
        owner, weight = np.asarray(owner), np.asarray(weight, dtype=float)
        R = sp.csr_matrix((weight[self.flight], (owner[self.flight], self.cell)), shape=(n, P))
        R.sum_duplicates()
        return R


@dataclass(frozen=True, eq=False)
class FlightCells:
    """The event model's flights step by step, as a horizon needs them (docs/model.md §20).

    Attributes
    ----------
    steps : StepTable          counted steps of the flights of the model's delay chain
                               (``flight`` indexes its src/dst/delay/weight arrays)
    start_delay : (N,) int     steps (bump step included) of the first flight from the centre
                               of configuration z = k·P + p's cell at heading θ_k
    start_land : (N,) int      its landing (pre-turn) contact state
    start_steps : StepTable    counted steps of those first flights (``flight`` = z)
    """

    steps: StepTable
    start_delay: np.ndarray
    start_land: np.ndarray
    start_steps: StepTable


@dataclass(frozen=True, eq=False)
class StraightFlights:
    """Flights along straight lines: from ``start`` (F, 2) [m] along unit headings ``u``
    (F, 2) for ``clock`` (F,) [m] (the free length: the drive to the bump).

    :func:`step_table` reads a flight's path through :meth:`points` and :attr:`end` only, so
    any path with the same three members (a flight that slides along a wall) counts alike.
    """

    start: np.ndarray
    u: np.ndarray
    clock: np.ndarray

    @property
    def end(self) -> np.ndarray:
        """(F, 2) the bump positions [m]."""
        return self.start + self.clock[:, None] * self.u

    def points(self, idx, s) -> np.ndarray:
        """(k, 2) the points [m] at distance ``s`` [m] along flights ``idx``."""
        return self.start[idx] + np.asarray(s, dtype=float)[:, None] * self.u[idx]


def step_table(cs, n_fwd, paths) -> StepTable:
    """The counted steps of flights with ``n_fwd`` (F,) forward steps along ``paths`` (e.g.
    :class:`StraightFlights`; see the module docstring), on the cell space ``cs``.
    """
    n_fwd = np.asarray(n_fwd, dtype=np.int64)
    idx = np.repeat(np.arange(n_fwd.size), n_fwd)
    m = np.arange(idx.size) - np.repeat(np.cumsum(n_fwd) - n_fwd, n_fwd)
    cells = np.concatenate([cs.cell_of_point(paths.points(idx, m * cs.h)),
                            cs.cell_of_point(paths.end)])
    flight = np.concatenate([idx, np.arange(n_fwd.size)])
    offset = np.concatenate([m, n_fwd])
    ok = cells >= 0                          # int32: the model keeps its tables (~10⁷ steps)
    return StepTable(flight=flight[ok].astype(np.int32), offset=offset[ok].astype(np.int32),
                     cell=cells[ok].astype(np.int32))


@dataclass(frozen=True, eq=False)
class StartedChain:
    """A model's delay chain as a run from the start steps through it (docs/model.md §20),
    every counted step of every flight listed.

    Attributes
    ----------
    chain : DelayChain   the model's flights; for a model with flights (the event model) also
                         the first flights from the cell centres, one on each of N extra
                         states (``offset + z``: configuration z's first flight, weight 1);
                         ``start`` is zero (a run's start is given separately)
    steps : StepTable    counted steps of every flight of ``chain`` (``flight`` indexes its
                         src/dst/delay/weight arrays)
    offset : int         index of configuration 0's start state: a run from configuration z
                         departs from state offset + z at step −1 (0 for the one-step models,
                         whose states are the N configurations)
    """

    chain: DelayChain
    steps: StepTable
    offset: int


def started_chain(model, noise, angles=None) -> StartedChain:
    """The delay chain of ``model`` (turn noise ``noise``; the event model's flights depend on
    it only for Gaussian noise, §11a) with the first flights of a run and each flight's counted
    steps: what the horizon coverage (docs/model.md §20) and the cover times (§20a) step
    through.

    For the one-step models (step, sampled) a state's flight is split into one flight per cell
    its reward counts a step in (weight: that reward), and one flight that counts nothing for
    the rest of the weight (a dropped step): the same expected counts, and each flight's step
    in one cell, as the cover times need it.
    """
    cs = model.cs
    if not model.steps_in_flights:
        base = model.delay_chain()
        R = sp.coo_matrix(base.reward)
        n = base.n
        rest = np.clip(1.0 - np.bincount(R.row, weights=R.data, minlength=n), 0.0, None)
        drop = np.flatnonzero(rest > 1e-12)
        keep = R.data > 0
        src = np.concatenate([R.row[keep], drop]).astype(np.int64)
        weight = np.concatenate([R.data[keep], rest[drop]])
        weight = weight / np.bincount(src, weights=weight, minlength=n)[src]
        F = int(keep.sum())
        steps = StepTable(flight=np.arange(F, dtype=np.int32),
                          offset=np.zeros(F, dtype=np.int32),
                          cell=R.col[keep].astype(np.int32))
        chain = DelayChain(src=src, dst=src.copy(), delay=np.ones(src.size, dtype=np.int64),
                           weight=weight, reward=steps.reward(src, weight, n, cs.P),
                           start=np.zeros(n))
        return StartedChain(chain=chain, steps=steps, offset=0)
    base, fc = model.delay_chain(noise, angles), model.flight_cells(noise, angles)
    n, F = base.n, base.src.size
    nt = n + cs.N
    src = np.concatenate([base.src, n + np.arange(cs.N)])
    weight = np.concatenate([base.weight, np.ones(cs.N)])
    steps = StepTable(flight=np.concatenate([fc.steps.flight, F + fc.start_steps.flight]),
                      offset=np.concatenate([fc.steps.offset, fc.start_steps.offset]),
                      cell=np.concatenate([fc.steps.cell, fc.start_steps.cell]))
    chain = DelayChain(src=src, dst=np.concatenate([base.dst, fc.start_land]),
                       delay=np.concatenate([base.delay, fc.start_delay]), weight=weight,
                       reward=steps.reward(src, weight, nt, cs.P), start=np.zeros(nt))
    return StartedChain(chain=chain, steps=steps, offset=n)
