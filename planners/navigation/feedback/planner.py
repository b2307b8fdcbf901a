"""The feedback planner (``"feedback"``, docs/model.md §15): the registry's closed-loop
planner.

:class:`FeedbackPlanner` has the :class:`~planners.navigation.base.Planner` shape. Its
``plan(start, goal)`` is the plan the navigator would fly from a known start before any
bump (the cheapest exact plan from the start pose, §15 "Planning from a pose"); its
``policy(start, goal)`` is a :class:`FeedbackPolicy`, which
:func:`bouncesim.runs.execute.execute` runs: a particle filter re-plans after every bump.

Examples
--------
>>> import envs
>>> from planners.cells import CellSpace
>>> cs = CellSpace(envs.load("lab"))
>>> fb = FeedbackPlanner(cs, [90, 135])
>>> route = fb.plan(8, 0)
>>> route.planner, route.plan.turns, round(route.cost, 6)
('feedback', (90, 90, 90, 90), 12.0)
>>> fb.policy(8, 0).goal
0
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, replace

import numpy as np

from envs import UserError
from envs.motion import ContactParams, unit

from ...cells import CellSpace
from ...plan import Plan
from ...resources import MemoryEstimate
from ..base import Route, check_angles, check_config, check_weights
from ..exact import ExactNavigator
from .config import DEFAULT_MAX_BUMPS
from .filter import FeedbackConfig
from .navigator import FeedbackNavigator

__all__ = ["FeedbackPlanner", "FeedbackPolicy", "combined_turn", "declared_sigma", "declared_turn"]



def declared_turn(noise) -> dict:
    """What the filter assumes about the robot's turns, from a declared noise: ``sigma``
    (:func:`declared_sigma`), the half-ranges ``scale`` and ``bias`` [deg] of an unknown
    factor and offset, and a known ``factor`` and ``offset`` [deg] (a spec's
    ``factor=``/``offset=``, or a body noise model's).

    >>> declared_turn("gauss:2,scale=0.1")
    {'sigma': 2.0, 'scale': 0.1, 'bias': 0.0, 'factor': 1.0, 'offset': 0.0}
    """
    out = {"sigma": 0.0, "scale": 0.0, "bias": 0.0, "factor": 1.0, "offset": 0.0}
    if noise is None:
        return out
    if isinstance(noise, str):
        from ...noise import parse_noise_spec
        spec = parse_noise_spec(noise)
        out.update(scale=spec.noise.scale, bias=spec.noise.bias_deg,
                   factor=1.0 if spec.factor is None else spec.factor,
                   offset=0.0 if spec.offset_deg is None else spec.offset_deg)
        out["sigma"] = declared_sigma(noise)
        return out
    for attr, key in (("scale", "scale"), ("bias_deg", "bias")):
        out[key] = float(getattr(noise, attr, 0.0) or 0.0)
    if getattr(noise, "factor", None) is not None:
        out["factor"] = float(noise.factor)
    if getattr(noise, "offset_deg", None) is not None:
        out["offset"] = float(noise.offset_deg)
    base = getattr(noise, "base", None)
    out["sigma"] = declared_sigma(base if base is not None else noise)
    return out


def combined_turn(cmd: dict, body: dict) -> dict:
    """The turn model (:func:`declared_turn`'s keys) of a body whose own turn errors
    ``body`` act on the turn the declared model ``cmd`` makes of a command: f_b·(f_c·φ + b_c)
    + b_b, so the factors multiply and the offsets add (b_c scaled by f_b); independent
    scatter adds in quadrature, and the half-ranges of unknown factors and offsets add.

    >>> t = combined_turn(declared_turn("gauss:2,offset=1"),
    ...                   declared_turn("gauss:1.5,offset=-1.25"))
    >>> t["sigma"], t["offset"], t["factor"]
    (2.5, -0.25, 1.0)
    """
    fb = body["factor"]
    return {"sigma": math.hypot(fb * cmd["sigma"], body["sigma"]),
            "scale": cmd["scale"] + body["scale"], "bias": cmd["bias"] + body["bias"],
            "factor": cmd["factor"] * fb, "offset": fb * cmd["offset"] + body["offset"]}


def declared_sigma(noise) -> float:
    """The turn noise σ [deg] the filter assumes for a noise model: a Gaussian's σ, the
    standard deviation of the §11 model's offsets, 0 for exact turns; a number is σ itself;
    a spec string is parsed (:func:`planners.noise.parse_noise_spec`; a §11 spec needs its
    quantum, so give the body's noise model instead).

    >>> from planners.noise import TurnNoise
    >>> declared_sigma(None), declared_sigma(2), declared_sigma(TurnNoise.gauss(3.0))
    (0.0, 2.0, 3.0)
    """
    if noise is None:
        return 0.0
    if isinstance(noise, str):
        from ...noise import parse_noise_spec
        spec = parse_noise_spec(noise)
        if spec.kind == "model" and not spec.noise.scatter.exact:
            raise UserError(f"the feedback planner needs the body's noise model for "
                            f"{noise!r} (its error quantum), not the spec.")
        return float(spec.noise.sigma_deg)
    if isinstance(noise, (int, float)):
        return float(noise)
    base = getattr(noise, "base", None)
    if base is not None:                    # a scaled turn: the scatter of its base
        return declared_sigma(base)
    if getattr(noise, "exact", False):
        return 0.0
    if getattr(noise, "sigma_deg", 0.0):
        return float(noise.sigma_deg)
    if hasattr(noise, "offsets"):
        d, p = noise.offsets()
        return float(math.sqrt(np.sum(p * d * d)))
    raise UserError(f"the feedback planner cannot read a turn noise σ from {noise!r}.")


@dataclass(frozen=True, eq=False)
class FeedbackPolicy:
    """A feedback run to ``goal`` (what :func:`bouncesim.runs.execute.execute` runs).

    Attributes
    ----------
    planner : FeedbackPlanner
    goal : int                      goal configuration z
    start : int, (x, y, heading) or None
        Start configuration or pose [m, m, deg]: the belief starts there and simulators are
        placed there; None: the caller's ``execute(start=...)``, and when that is None too
        the start is unknown: the belief starts anywhere (in ``region``), the body where it
        is, and the robot first turns angles that localize (§15).
    region : (x0, y0, x1, y1) or None
        An unknown start's box [m] (default: the whole room).
    max_bumps : int                 give up after this many bumps
    on_belief : callable or None    ``on_belief(event, belief)`` after every filter step
                                    (``"flight"``, ``"turn"``): for tests and plots
    """

    planner: FeedbackPlanner
    goal: int
    start: object = None
    max_bumps: int = DEFAULT_MAX_BUMPS
    on_belief: object = None
    region: tuple | None = None


class FeedbackPlanner:
    """Feedback navigation (``"feedback"``, docs/model.md §15) as a registry planner.

    Parameters
    ----------
    cells : CellSpace
    angles : sequence of float      bouncing angles Φ [deg]
    w1, w2 : float                  §13's weights
    noise : noise model, TurnNoise, float, spec or None
        The declared turn noise: the filter's motion model (:func:`declared_sigma`); not
        applied to the robot, which brings its own. None: exact turns.
    rng : numpy.random.Generator    the filter's and the decision rule's draws (needed to
                                    run a policy; ``plan`` draws nothing)
    contact : ContactParams, None or "auto"
        The contact rule of the filter's motion model and the plan search (§15, §9).
        "auto": ``config.contact`` when set, else the executing body's (resolved when the
        policy runs: :func:`bouncesim.runs.feedback.body_contact`); None: the front-half
        bumper.
    config : FeedbackConfig         its ``turn_sigma_deg`` and ``contact`` are replaced by
                                    the declared noise's σ and the contact rule
    """

    name = "feedback"
    needs = frozenset({"noise", "rng", "contact"})
    closed_loop = True

    def __init__(self, cells: CellSpace, angles: Iterable[float], w1: float = 1.0,
                 w2: float = 100.0, *, noise=None, rng: np.random.Generator | None = None,
                 contact: ContactParams | None | str = "auto",
                 config: FeedbackConfig | None = None) -> None:
        self.cells = cells
        self.angles = check_angles(cells, angles, "the feedback planner")
        self.w1, self.w2 = check_weights(w1, w2)
        if isinstance(contact, str) and contact != "auto":
            raise UserError(f"contact must be 'auto', a ContactParams or None, got {contact!r}.")
        self.noise, self.rng, self.contact = noise, rng, contact
        self.config = config if config is not None else FeedbackConfig()
        self.turn_model = declared_turn(noise)
        self.sigma = self.turn_model["sigma"]

    def resolved(self, body_rule: ContactParams | None = None) -> ContactParams | None:
        """The contact rule the filter and the search use: the planner's own, or for "auto"
        ``config.contact`` when set, else ``body_rule`` (the executing body's).
        """
        if not isinstance(self.contact, str):
            return self.contact
        return self.config.contact if self.config.contact is not None else body_rule

    def navigator(self, goal: int, contact: ContactParams | None,
                  max_bumps: int = DEFAULT_MAX_BUMPS, body_turns=None) -> FeedbackNavigator:
        """The decision rule for ``goal`` under ``contact`` (the declared σ in its config),
        for a run of at most ``max_bumps`` bumps: its value table looks at least that many
        flights ahead (a longer horizon leaves V_t of every shorter one as it was).
        ``body_turns``: the executing body's own turn errors, a noise spec it declares
        (:func:`bouncesim.runs.feedback.body_turns`), on top of the declared noise
        (:func:`combined_turn`).
        """
        t = self.turn_model
        if body_turns is not None:
            t = combined_turn(t, declared_turn(body_turns))
        cfg = replace(self.config, turn_sigma_deg=t["sigma"], contact=contact,
                      turn_scale=t["scale"], turn_bias_deg=t["bias"],
                      turn_factor=t["factor"], turn_offset_deg=t["offset"],
                      value_horizon=max(self.config.value_horizon, int(max_bumps)))
        return FeedbackNavigator(self.cells, self.angles, goal, cfg, self.w1, self.w2)

    def plan(self, start: int, goal: int) -> Route | None:
        """The plan from the start configuration's pose before any bump (§15 "Planning from
        a pose"; the body's contact rule unknown here: ``contact`` or ``config.contact``).
        Its poses are the straight flights' ends. None: no plan from the start.
        """
        cs = self.cells
        s, g = check_config(cs, start, "start"), check_config(cs, goal, "goal")
        x, y, th = cs.pose(s)
        if s == g:
            return Route(s, g, Plan((), (), 0.0, self.name), 0.0, ((x, y, th),), self.name)
        cand = self.navigator(g, self.resolved()).plan_from(x, y, th)
        if cand is None:
            return None
        plan = Plan.exact(cand.angles, cand.flights, cand.final_m, cs.h, planner=self.name)
        poses, pos = [(x, y, th)], np.array([x, y])
        for f, a in zip(plan.flights_m, plan.turns):
            pos = pos + f * unit(th)
            th = (th + a) % 360.0
            poses.append((float(pos[0]), float(pos[1]), th))
        pos = pos + plan.final_m * unit(th)
        poses.append((float(pos[0]), float(pos[1]), th))
        return Route(s, g, plan, float(cand.cost), tuple(poses), self.name)

    def policy(self, start, goal: int, *, max_bumps: int = DEFAULT_MAX_BUMPS,
               on_belief=None, region=None) -> FeedbackPolicy:
        """The feedback run from ``start`` (configuration, pose or None: unknown, anywhere
        in ``region`` (x0, y0, x1, y1) [m] when given) to ``goal``.
        """
        g = check_config(self.cells, goal, "goal")
        if start is not None and isinstance(start, (int, np.integer)):
            start = check_config(self.cells, start, "start")
        if int(max_bumps) < 1:
            raise UserError(f"max_bumps must be at least 1, got {max_bumps}.")
        if region is not None:
            region = tuple(float(v) for v in region)
            if len(region) != 4:
                raise UserError("a start region is a box (x0, y0, x1, y1) [m].")
        return FeedbackPolicy(self, g, start, int(max_bumps), on_belief, region)

    @classmethod
    def memory_estimate(cls, cells: CellSpace, angles,
                        config: FeedbackConfig | None = None) -> MemoryEstimate:
        """Peak memory of a run: the exact planner's tables for the searches from a pose and
        the belief's particles (a few arrays per particle and candidate).
        """
        cfg = config if config is not None else FeedbackConfig()
        base = ExactNavigator.memory_estimate(cells, angles)
        return MemoryEstimate("the feedback planner's searches and belief",
                              base.traced + 200.0 * cfg.particles * (cfg.votes + 4))
