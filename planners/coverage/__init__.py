"""Coverage by bouncing policies: the paper's Algorithm 3 (docs/model.md §16) and the models that
predict what a continuous robot covers, behind one interface.

Layout (imports flow down this list; nothing imports upwards):

- :mod:`.noise`: :class:`TurnNoise`, the §11 rotation noise (ε, r), validated once; its
  support over K and a seeded sampler (the simulators' ``SteppedNoise`` delegates to it).
- :mod:`.targets`: target b over position or configuration cells (files, uniform, checks).
- :mod:`.base`: the :class:`CoverageModel` protocol and its one per-angle record,
  :class:`AngleCoverage`.
- :mod:`.step`, :mod:`.sampled`, :mod:`.event`: the three models (:class:`StepModel`,
  :class:`SampledModel`, :class:`EventModel`); :mod:`.event_flights`: the event model's
  flights step by step (its rewards and the horizon's counts).
- :mod:`.mix`: :func:`solve_mix` (α over the simplex) and :class:`MixDesign`.
- :mod:`.horizon`: coverage over the first T steps and the time to the limit (§20).
- :mod:`.api`: the registry :data:`MODELS`, :func:`model_for`, :func:`design_mix` and
  :func:`timeshared_coverage`.

>>> import envs
>>> from planners.cells import CellSpace
>>> cs = CellSpace(envs.load("lab"))
>>> model = model_for(cs, "step")                       # or "sampled", "event"
>>> design = design_mix(model, [90, 135], TurnNoise(eps_deg=45, r=0.9))
>>> design.mix                                          # what bouncesim.runs.execute.execute runs
PolicyMix(angles=(90.0, 135.0), alpha=(...), eps=45.0, r=0.9, sigma=0.0)
>>> design.per_angle[0].q.shape, design.tv < 1
((48,), True)
"""

from __future__ import annotations

from ..noise import TurnNoise
from .api import (
    MODELS,
    analyses,
    check_angles,
    check_model,
    default_settings,
    design_mix,
    model_for,
    timeshared_coverage,
)
from .base import AngleCoverage, CoverageModel, clear_cache, group_cells
from .event import EventModel, EventSettings, flight_steps
from .horizon import (
    Horizon,
    HorizonCoverage,
    horizon_coverage,
    horizon_of,
)
from .mix import MixDesign, MixFit, solve_mix
from .sampled import SampledModel, SampledSettings
from .step import StepModel, StepSettings, transition_matrix
from .targets import SPACES, TARGET_FORMATS, TargetError, load_target, uniform_target
from .to_limit import steps_to_limit, steps_to_limit_each

__all__ = ["MODELS", "AngleCoverage", "analyses", "CoverageModel", "EventModel", "EventSettings",
           "MixDesign", "MixFit", "SampledModel", "SampledSettings", "SPACES", "StepModel",
           "StepSettings", "TARGET_FORMATS", "TargetError", "TurnNoise", "check_angles",
           "check_model", "clear_cache", "default_settings", "design_mix", "flight_steps",
           "group_cells", "Horizon", "HorizonCoverage", "horizon_coverage", "horizon_of",
           "load_target",
           "model_for", "solve_mix", "steps_to_limit", "steps_to_limit_each",
           "timeshared_coverage", "transition_matrix", "uniform_target"]
