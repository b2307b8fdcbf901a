"""One entry point for the coverage models: the registry, the mix design and the time-shared
prediction, written once against the :class:`~planners.coverage.base.CoverageModel` protocol.

- :data:`MODELS`: name → model class (``"step"``: the paper's Algorithm 3 on the
  configuration-cell chain, docs/model.md §7 and §16; ``"sampled"``: Hsu's generalized cell mapping;
  ``"event"``: exact flights between binned contact points, recommended,
  ``docs/model_continuous.md``). All three predict the step-sampled coverage of docs/model.md §22
  (what :class:`bouncesim.robots.kinematic.KinematicBatch` measures), one probability per cell.
- :func:`model_for`: a model of a cell space (settings checked; the continuous models' flights
  are built once per environment and settings and shared).
- :func:`design_mix`: every angle's coverage, the target and the best mix α, as a
  :class:`~planners.coverage.mix.MixDesign` carrying the :class:`PolicyMix` to execute.
- :func:`timeshared_coverage`: the coverage of a mix executed in epochs (docs/model.md §19).

>>> import envs
>>> from planners.cells import CellSpace
>>> cs = CellSpace(envs.load("lab"))
>>> design = design_mix(model_for(cs, "step"), [90, 135], TurnNoise(45, 0.9))
>>> design.model, design.mix.angles, round(float(design.alpha.sum()), 12)
('step', (90.0, 135.0), 1.0)
>>> timeshared_coverage(model_for(cs, "step"), design.mix, epoch=50).converged
True
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from envs import UserError

from ..cells import CellSpace
from ..noise import TurnNoise
from ..plan import PolicyMix
from .base import CoverageModel
from .event import EventModel
from .horizon import PARALLEL_MAX, fit_horizon_mix, horizon_of
from .mix import MixDesign, solve_mix
from .sampled import SampledModel
from .step import StepModel
from .targets import check_target, space_size
from .timeshare import TimeSharedCoverage, default_threads, note_threads, timeshared

__all__ = ["MODELS", "analyses", "check_model", "default_settings", "model_for", "check_angles",
           "design_mix", "timeshared_coverage"]

_EXACT = TurnNoise()

MODELS: dict = {cls.name: cls for cls in (StepModel, SampledModel, EventModel)}


def check_model(name: str) -> str:
    """Return ``name`` after checking it is a key of :data:`MODELS` (UserError otherwise)."""
    if name not in MODELS:
        raise UserError(f"coverage model must be one of {', '.join(MODELS)}, got {name!r}.")
    return name


def default_settings(name: str) -> Any:
    """The recommended settings record of a model."""
    return MODELS[check_model(name)].Settings()


def _settings(name: str, settings):
    cls = MODELS[name].Settings
    if settings is None:
        return cls()
    if isinstance(settings, dict):
        try:
            return cls(**settings)
        except TypeError:
            names = ", ".join(cls.__dataclass_fields__)
            raise UserError(f"the {name} model's settings are {names}; got "
                            f"{', '.join(settings)}.") from None
    if not isinstance(settings, cls):
        raise UserError(f"the {name} model takes {cls.__name__} settings, got "
                        f"{type(settings).__name__}.")
    return settings


def model_for(cs: CellSpace, name: str = "step", settings: Any = None) -> CoverageModel:
    """The coverage model ``name`` of ``cs``.

    Parameters
    ----------
    cs : CellSpace
    name : str          a key of :data:`MODELS`
    settings : the model's settings record or a dict of its fields, optional
        Default: the recommended settings (:func:`default_settings`). Bad values raise a
        one-sentence :class:`UserError`.
    """
    name = check_model(name)
    return MODELS[name].build(cs, _settings(name, settings))


def check_angles(K: int, angles: Iterable[float], noise: TurnNoise) -> tuple:
    """The angles as floats after checking them and ε against K (before any heavy work)."""
    angles = tuple(float(a) for a in angles)
    if not angles:
        raise UserError("coverage needs at least one bouncing angle.")
    for a in angles:
        noise.turns(K, a)
    return angles


def analyses(model: CoverageModel, angles, noise: TurnNoise = _EXACT,
             also: Iterable[Callable[[], Any]] = ()) -> Iterator:
    """Every angle's :meth:`analyse`, in order: the first alone (it builds what the angles
    share, e.g. the event model's Gaussian flights), the others on
    :func:`~planners.coverage.timeshare.default_threads` threads (scipy's products and solves
    release the GIL); the same results as one after the other.

    ``also``: more work (calls without arguments, e.g. the horizon runs of
    :meth:`~planners.coverage.horizon.Horizon.tasks`) done on the same threads, from the
    start, so that a core the analyses leave idle takes it (design_mix with a horizon); all
    of it is done when the last analysis has been yielded.
    """
    angles, also = list(angles), list(also)
    if not angles:
        return
    k = default_threads()
    if k <= 1 or (len(angles) == 1 and not also):
        yield model.analyse(angles[0], noise)
        yield from (model.analyse(a, noise) for a in angles[1:])
        for call in also:
            call()
        return
    with ThreadPoolExecutor(max_workers=k, thread_name_prefix="analyse") as pool:
        first = pool.submit(model.analyse, angles[0], noise)
        side = [pool.submit(call) for call in also]
        yield first.result()
        rest = [pool.submit(model.analyse, a, noise) for a in angles[1:]]
        for f in rest:
            yield f.result()
        for f in side:
            f.result()
    note_threads(k)


def design_mix(model: CoverageModel, angles: Iterable[float], noise: TurnNoise = _EXACT,
               target: ArrayLike | None = None, space: str = "positions",
               progress: Callable[[Iterable], Iterable] | None = None,
               horizon: int | None = None, epoch: int | None = None,
               start=None, objective: str = "tv", **time_options):
    """Algorithm 3 on any model: every angle's coverage, and the mix that best meets a target
    (``objective="tv"``), or that covers the room fastest (``"cover90"``) or keeps the worst
    idleness lowest (``"idleness"``).

    Parameters
    ----------
    model : CoverageModel        e.g. ``model_for(cs, "event")``
    angles : sequence of float   bouncing angles [deg], multiples of Δ
    noise : TurnNoise            rotation noise (ε, r); default exact turns
    target : array_like, optional
        b over the space (normalised here); default uniform.
    space : {"positions", "configurations"}
        Fit Aα to b over position cells (A's columns are q) or over configurations (π);
        configurations only for models whose states are the configurations (``step``).
    progress : callable, optional   wraps the iterable of the angles' analyses, in order
                                    (e.g. ``tqdm``; they run in parallel, :func:`analyses`)
    horizon : int, optional
        Fit α to the coverage expected over the first ``horizon`` steps (docs/model.md §20)
        instead of the limit; positions only. The per-angle limits are still in
        ``per_angle``.
    epoch : int, optional
        With a horizon: steps per epoch of the executed mix (docs/model.md §21). Then q_T(α) is
        not linear in α: the linear fit on the angles' q_T is the start of an SLSQP on the
        simplex (scipy, finite-difference gradient) of ‖q_T(α) − b‖₂², reported in
        ``convergence``. Without it (or with epoch ≥ horizon) each run keeps one angle and
        the fit is the exact linear one.
    start : optional   start of the horizon (:func:`~planners.coverage.horizon.start_distribution`)
    objective : {"tv", "cover90", "idleness"}
        ``"tv"``: the fit above. ``"cover90"``, ``"idleness"``: the α of the simplex grid that
        minimises the mean time to cover 90 % of the room (runs that do not, counted at the
        horizon) or the mean worst idleness over ``horizon`` steps (default 20 000) of the mix
        in epochs of ``epoch`` steps (default 1000), sampled from the model's chain
        (:func:`planners.coverage.time_design.design_for_time`, docs/model.md §20b; the
        target, space and start do not apply).
    **time_options : robots, runs, grid, rng, progress of :func:`design_for_time`

    Returns
    -------
    MixDesign   (``.alpha``, ``.residual``, ``.tv``, ``.per_angle`` and ``.mix``, the
                :class:`PolicyMix` for :func:`bouncesim.runs.execute.execute`); a
                :class:`~planners.coverage.time_design.TimeDesign` (``.alpha``, ``.value``,
                ``.mix``, every candidate's value) for a time objective
    """
    if objective != "tv":
        from .time_design import design_for_time
        if target is not None or space != "positions" or start is not None:
            raise UserError("a time objective covers the whole room from the uniform start: "
                            "drop the target, space and start.")
        return design_for_time(model, check_angles(model.cs.K, angles, noise), noise,
                               objective, horizon=horizon or 20_000, epoch=epoch or 1000,
                               **time_options)
    if time_options:
        raise UserError(f"design_mix takes {', '.join(sorted(time_options))} with a time "
                        "objective only (objective='cover90' or 'idleness').")
    cs = model.cs
    space_size(cs, space)
    if space not in model.spaces:
        raise UserError(f"the {model.name} coverage model predicts coverage over position "
                        "cells only; use --target-space positions.")
    angles = check_angles(cs.K, angles, noise)
    b = check_target(target, cs, space)
    if horizon is not None and space == "positions" and int(horizon) <= PARALLEL_MAX:
        # the angles' runs over the horizon go on the analyses' threads from the start (the
        # fit below finds them done); a mix in epochs runs its own recursion in the fit;
        # longer horizons run in the fit, where the limits settle them (docs/model.md §20)
        also = horizon_of(model).tasks(angles, int(horizon), noise=noise, start=start)
    else:
        also = ()
    it = analyses(model, angles, noise, also)
    per = tuple(progress(it) if progress else it)
    A = np.column_stack([a.q if space == "positions" else a.pi for a in per])
    if horizon is None:
        fit = solve_mix(A, b)
        return MixDesign(model=model.name, angles=angles, noise=noise, space=space,
                         per_angle=per, target=b, alpha=fit.alpha, residual=fit.residual,
                         tv=fit.tv, mixed=fit.mixed, method=fit.method)
    if space != "positions":
        raise UserError("a horizon predicts coverage over position cells only; use "
                        "--target-space positions.")
    return fit_horizon_mix(horizon_of(model), angles, noise, b, int(horizon), epoch, per,
                           start=start)


def timeshared_coverage(model: CoverageModel, mix: PolicyMix, epoch: int = 1000, *,
                        noise: TurnNoise | None = None, **kw) -> TimeSharedCoverage:
    """Predicted coverage of a policy mix executed in epochs of ``epoch`` steps (docs/model.md §19).

    docs/model.md §16's Σ α_i q_i assumes every epoch reaches its angle's limiting distribution;
    this follows the model's own chain through the epochs instead
    (:mod:`planners.coverage.timeshare`), through the protocol's
    :meth:`~CoverageModel.delay_chain` and :meth:`~CoverageModel.turn_matrix`, so it works for
    every model.

    Parameters
    ----------
    model : CoverageModel
    mix : PolicyMix         angles, α and the rotation noise (ε, r), e.g. ``design.mix``
    epoch : int             steps per epoch
    noise : TurnNoise, optional   the rotation noise (default the mix's ε, r and σ); pass one
                            with a body's own turn errors (§11b) to predict that body
    **kw : tol, max_epochs, progress (see :meth:`planners.coverage.timeshare.TimeShared.run`)
    """
    noise = noise if noise is not None else mix.noise
    angles = check_angles(model.cs.K, mix.angles, noise)
    turns = [model.turn_matrix(a, noise) for a in angles]
    # the event model's flights depend on the noise (Gaussian or a body's turns, §11a, §11b)
    chain = (model.delay_chain(noise, angles) if model.steps_in_flights
             else model.delay_chain())
    return timeshared(chain, turns, mix.alpha, epoch, **kw)
