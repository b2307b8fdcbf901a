"""One entry point for the coverage models: the paper's step model and two continuous ones.

- ``"step"``: the paper's Algorithm 3 on the configuration-cell chain
  (:func:`planners.coverage.analyse_angle`, docs/model.md §5 and §7), bit-identical here.
- ``"sampled"``: Hsu's generalized cell mapping (:mod:`planners.sampled_model`): each
  configuration cell's transition probabilities from a lattice of exact continuous steps.
- ``"event"``: the bump-to-bump model (:mod:`planners.event_model`): exact flights between
  binned contact points, occupancy by renewal–reward. Recommended (``docs/model_continuous.md``).

All three predict the step-sampled coverage of docs/model.md §9 (what
:class:`bouncesim.robots.kinematic.KinematicBatch` measures), one probability per position cell.

>>> import envs
>>> from planners.cells import CellSpace
>>> cs = CellSpace(envs.load("lab"))
>>> res = predict_coverage(cs, 90, model="step")
>>> res.model, res.q.shape, round(float(res.q.sum()), 12)
('step', (48,), 1.0)
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from envs import UserError

from .cells import CellSpace
from .coverage import ChainSummary
from .event_model import EventModel, EventSettings
from .markov import ChainAnalysis
from .sampled_model import SampledModel, SampledSettings

__all__ = ["MODELS", "StepSettings", "EventSettings", "SampledSettings", "ModelCoverage",
           "default_settings", "predict_coverage", "model_for", "check_model",
           "timeshared_coverage"]

MODELS = ("step", "sampled", "event")


@dataclass(frozen=True)
class StepSettings:
    """The step model has no settings (``method`` picks the exact solver, same numbers).

    Attributes
    ----------
    method : {"runs", "matrix"}   see :func:`planners.coverage.analyse_angle`
    """

    method: str = "runs"


_SETTINGS = {"step": StepSettings, "sampled": SampledSettings, "event": EventSettings}


def check_model(model: str) -> str:
    """Return ``model`` after checking it is one of :data:`MODELS` (UserError otherwise)."""
    if model not in MODELS:
        raise UserError(f"coverage model must be one of {', '.join(MODELS)}, got {model!r}.")
    return model


def default_settings(model: str):
    """The recommended settings record of a model."""
    return _SETTINGS[check_model(model)]()


def _settings(model: str, settings):
    cls = _SETTINGS[model]
    if settings is None:
        return cls()
    if isinstance(settings, dict):
        try:
            return cls(**settings)
        except TypeError:
            names = ", ".join(cls.__dataclass_fields__)
            raise UserError(f"the {model} model's settings are {names}; got "
                            f"{', '.join(settings)}.") from None
    if not isinstance(settings, cls):
        raise UserError(f"the {model} model takes {cls.__name__} settings, got "
                        f"{type(settings).__name__}.")
    return settings


@dataclass(frozen=True, eq=False)
class ModelCoverage(ChainSummary):
    """Predicted long-run coverage of one bouncing angle under one model.

    Attributes
    ----------
    model : str                 "step", "sampled" or "event"
    settings : frozen dataclass the model's settings
    angle, eps : float          φ, ε [deg]
    r : float                   reliability
    q : (P,) ndarray            predicted step-sampled coverage over position cells (sum 1)
    pi : ndarray                limiting distribution over the model's states: the N
                                configurations (step, sampled) or the n_bins·K contact states
                                (event; state = bin·K + k)
    analysis : ChainAnalysis    closed classes, absorption, π of the model's chain
    seconds : float             CPU time [s] of this angle (shared set-up excluded)
    detail : object             the model's own record (AngleCoverage, SampledCoverage or
                                EventCoverage)
    """

    model: str
    settings: object
    angle: float
    eps: float
    r: float
    q: np.ndarray
    pi: np.ndarray
    analysis: ChainAnalysis
    seconds: float
    detail: object

    def summary(self) -> dict:
        """JSON-ready numbers: model, groups, their sizes and weights, transient fraction."""
        return {"model": self.model, **super().summary()}


@lru_cache(maxsize=2)
def _model_cached(env, model: str, settings):
    cs = CellSpace(env)
    return EventModel(cs, settings) if model == "event" else SampledModel(cs, settings)


def model_for(cs: CellSpace, model: str, settings=None):
    """The angle-independent part of a continuous model (cached per environment and
    settings; the three angles of a pipeline share one set of flights)."""
    model = check_model(model)
    if model == "step":
        raise UserError("the step model has no precomputed part; use predict_coverage.")
    return _model_cached(cs.env, model, _settings(model, settings))


def predict_coverage(cs: CellSpace, angle_deg: float, eps_deg: float = 0.0, r: float = 1.0,
                     model: str = "step", settings=None, rng=None) -> ModelCoverage:
    """Predicted long-run step-sampled coverage of one bouncing angle.

    Parameters
    ----------
    cs : CellSpace
    angle_deg, eps_deg : float
        Bouncing angle φ and error range ε [deg], multiples of Δ = 360°/K.
    r : float
        Reliability in [0, 1].
    model : {"step", "sampled", "event"}
    settings : settings record of the model (or a dict of its fields), optional
        Default: the recommended settings (:func:`default_settings`).
    rng : numpy.random.Generator, optional
        Unused: all three models are deterministic (lattice samples); accepted so that a
        randomised variant can be added without changing the signature.

    Returns
    -------
    ModelCoverage
    """
    from .coverage import analyse_angle, bump_turns
    model = check_model(model)
    st = _settings(model, settings)
    bump_turns(cs.K, angle_deg, eps_deg, r)            # validate before any heavy work
    t0 = time.process_time()
    if model == "step":
        det = analyse_angle(cs, angle_deg, eps_deg, r, method=st.method)
        return ModelCoverage(model=model, settings=st, angle=det.angle, eps=det.eps, r=det.r,
                             q=det.q, pi=det.pi, analysis=det.analysis,
                             seconds=time.process_time() - t0, detail=det)
    m = model_for(cs, model, st)
    t0 = time.process_time()
    det = m.analyse(angle_deg, eps_deg, r)
    return ModelCoverage(model=model, settings=st, angle=det.angle, eps=det.eps, r=det.r,
                         q=det.q, pi=det.pi, analysis=det.analysis,
                         seconds=time.process_time() - t0, detail=det)


def timeshared_coverage(cs: CellSpace, angles, alpha, eps_deg: float = 0.0, r: float = 1.0,
                        epoch: int = 1000, model: str = "step", settings=None, **kw):
    """Predicted coverage of a policy mix executed in epochs of ``epoch`` steps (docs/model.md §8).

    docs/model.md §7's Σ α_i q_i assumes every epoch reaches its angle's limiting distribution; this
    follows the model's own chain through the epochs instead (:mod:`planners.timeshare`).

    Parameters
    ----------
    cs : CellSpace
    angles : sequence of float     bouncing angles [deg]
    alpha : sequence of float      their weights (normalised)
    eps_deg, r : float             rotation noise (docs/model.md §7)
    epoch : int                    steps per epoch
    model : {"step", "sampled", "event"}
    settings : the model's settings, optional
    **kw : tol, max_epochs, progress (see :meth:`planners.timeshare.TimeShared.run`)

    Returns
    -------
    planners.timeshare.TimeSharedCoverage

    >>> import envs
    >>> cs = CellSpace(envs.load("lab"))
    >>> res = timeshared_coverage(cs, [90, 135], [0.5, 0.5], epoch=50)
    >>> res.converged, res.q.shape
    (True, (48,))
    """
    import scipy.sparse as sp

    from .coverage import bump_turns, transition_matrix
    from .timeshare import DelayChain, timeshared
    model = check_model(model)
    st = _settings(model, settings)
    angles = [float(a) for a in angles]
    for a in angles:
        bump_turns(cs.K, a, eps_deg, r)            # validate before any heavy work
    if model == "step":
        z = np.arange(cs.N)
        reward = sp.csr_matrix((np.ones(cs.N), (z, z % cs.P)), shape=(cs.N, cs.P))
        chain = DelayChain.stepwise(reward, np.full(cs.N, 1.0 / cs.N))
        turns = [transition_matrix(cs, a, eps_deg, r) for a in angles]
    else:
        m = model_for(cs, model, st)
        if model == "sampled":
            chain = DelayChain.stepwise(m.reward, np.full(cs.N, 1.0 / cs.N))
            turns = [m.chain(a, eps_deg, r) for a in angles]
        else:
            chain = m.delay_chain()
            turns = [m.turn_matrix(a, eps_deg, r) for a in angles]
    return timeshared(chain, turns, alpha, epoch, **kw)
