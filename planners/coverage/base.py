"""What every coverage model is: the :class:`CoverageModel` protocol and its one per-angle
record, :class:`AngleCoverage`.

A model is built once per cell space and settings (its angle-independent part: step table,
flights, rewards) and then answers for any bouncing angle and :class:`TurnNoise`:

- :meth:`CoverageModel.analyse`: the angle's chain, its limiting distribution and the
  predicted step-sampled coverage q over the P position cells (docs/model.md §16, §22);
- :meth:`CoverageModel.turn_matrix` and :meth:`CoverageModel.delay_chain`: the model as a
  delay chain (:mod:`planners.coverage.timeshare`), so a policy mix run in epochs
  (docs/model.md §21) is predicted the same way for every model.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Any, ClassVar, Protocol, runtime_checkable

import numpy as np
import scipy.sparse as sp

from ..cells import CellSpace
from ..noise import NoiseView, TurnNoise
from .markov import ChainAnalysis
from .timeshare import DelayChain

__all__ = ["AngleCoverage", "CoverageModel", "cached_build", "clear_cache",
           "group_cells"]


@dataclass(frozen=True, eq=False)
class AngleCoverage(NoiseView):
    """Predicted long-run coverage of one bouncing angle under one model.

    Attributes
    ----------
    model : str                 the model's registry name ("step", "sampled", "event")
    angle : float               bouncing angle φ [deg]
    noise : TurnNoise           the rotation noise (``eps`` and ``r`` read through it)
    q : (P,) ndarray            predicted step-sampled coverage over position cells (sum 1)
    pi : ndarray                limiting distribution over the model's states: the N
                                configurations z = k·P + p (step, sampled) or the contact
                                states bin·K + k (event)
    analysis : ChainAnalysis    closed classes, absorption, π of the model's chain
    seconds : float             CPU time [s] of the thread that analysed this angle (the
                                shared set-up excluded; angles may run in parallel)
    settings : frozen dataclass the model's settings
    steps_per_flight : float    event model: mean steps per bump-to-bump flight under π
                                (dropped ones included); 1 for the one-step models
    """

    model: str
    angle: float
    noise: TurnNoise
    q: np.ndarray
    pi: np.ndarray
    analysis: ChainAnalysis
    seconds: float = 0.0
    settings: Any = None
    steps_per_flight: float = 1.0

    @property
    def groups(self) -> tuple:
        """The persistent groups (closed classes) of the angle's chain."""
        return self.analysis.groups

    @property
    def group_sizes(self) -> np.ndarray:
        """Number of states in each persistent group."""
        return self.analysis.group_sizes

    @property
    def transient_fraction(self) -> float:
        """Fraction of the states that are transient."""
        return self.analysis.transient_fraction

    def summary(self) -> dict:
        """JSON-ready numbers: model, groups, their sizes and weights, transient fraction."""
        return {"model": self.model, "angle": _num(self.angle),
                "persistent_groups": self.analysis.n_groups,
                "group_sizes": [int(s) for s in self.group_sizes],
                "group_weights": [float(a) for a in self.analysis.absorption],
                "transient_fraction": float(self.transient_fraction)}


@runtime_checkable
class CoverageModel(Protocol):
    """A coverage model of one cell space (see the module docstring).

    Attributes
    ----------
    name : str                  registry name (:data:`planners.coverage.MODELS`)
    Settings : type             its frozen settings dataclass (defaults = recommended)
    spaces : tuple of str       target spaces its ``pi`` supports ("positions" always;
                                "configurations" when its states are the N configurations)
    state_kind : str            what its chain states (``group_sizes``,
                                ``transient_fraction``) count
    steps_in_flights : bool     its steps come in flights of several steps (delays D > 1,
                                docs/model.md §19) whose headings Gaussian noise moves off
                                the Δ grid (§11a); False: one step per transition
    contact_rule : bool         it models the body's contact rule (docs/model.md §9)
    rest_turns : bool           it turns a bump from rest by the body's own rest shift
                                (``TurnNoise.body_rest_deg``, docs/model.md §11b); False:
                                every bump alike
    cs : CellSpace
    settings : Settings
    """

    name: ClassVar[str]
    Settings: ClassVar[type]
    spaces: ClassVar[tuple]
    state_kind: ClassVar[str]
    steps_in_flights: ClassVar[bool]
    contact_rule: ClassVar[bool]
    rest_turns: ClassVar[bool]
    cs: CellSpace
    settings: Any

    def analyse(self, angle_deg: float, noise: TurnNoise) -> AngleCoverage:
        """Chain, limiting distribution and coverage of one angle."""

    def turn_matrix(self, angle_deg: float, noise: TurnNoise) -> sp.csr_matrix:
        """W_φ over the states of :meth:`delay_chain` (row-stochastic)."""

    def delay_chain(self) -> DelayChain:
        """The angle-independent part as a delay chain (flights, rewards, start)."""

    def bump_rate(self, cov: AngleCoverage) -> float:
        """Bumps per counted step the model predicts for one angle's coverage ``cov``."""

    @classmethod
    def memory_estimate(cls, cells: CellSpace, angles, eps_deg: float = 0.0,
                        settings=None):
        """Peak memory of the model's chains (:mod:`planners.resources`)."""


def group_cells(model: CoverageModel, cov: AngleCoverage) -> np.ndarray:
    """Number of position cells of each persistent group of ``cov``: the cells in which the
    group's states count steps (the model's delay-chain reward), i.e. where the group's
    long-run coverage is positive. Comparable across models, unlike ``group_sizes``.
    """
    R = sp.csr_matrix(model.delay_chain().reward)
    return np.array([int((np.asarray(R[g].sum(axis=0)).ravel() > 0).sum()) for g in cov.groups],
                    dtype=np.int64)


@lru_cache(maxsize=2)
def _cached(cls, env, settings):
    return cls(CellSpace(env), settings)


def cached_build(cls, cs: CellSpace, settings):
    """``cls(cs, settings)`` for a model with a costly angle-independent part (flights,
    samples), cached per (model, environment, settings): the angles of a pipeline and its
    time-shared prediction share one set of flights.
    """
    return _cached(cls, cs.env, settings)


def clear_cache() -> None:
    """Forget the cached models (benchmarks time the build)."""
    _cached.cache_clear()


def _num(x: float):
    x = float(x)
    return int(round(x)) if math.isclose(x, round(x), abs_tol=1e-9) else x
