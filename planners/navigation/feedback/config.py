"""The feedback navigator's parameters (docs/model.md §15): the filter's motion and
observation models with their declared error rates, and the decision rule's settings.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from envs import UserError
from envs.motion import CENTRE_ZONE_DEG, ContactParams

__all__ = ["FeedbackConfig", "DEFAULT_MAX_BUMPS"]

DEFAULT_MAX_BUMPS = 80
"""A feedback run gives up after this many bumps (the value table looks as far ahead). 80,
not 40: at σ = 2° and 5° the runs that needed more than 40 bumps reach the goal without the
median run's bumps changing (docs/readme_feedback.md, "The bump budget")."""


# ============================================================================ configuration
@dataclass(frozen=True)
class FeedbackConfig:
    """Parameters of the filter and the decision rule (docs/model.md §15).

    Attributes
    ----------
    particles : int            n, particles of the belief
    turn_sigma_deg : float     declared turn noise σ [deg] (Gaussian per turn)
    turn_scale, turn_bias_deg : float
        the declared half-ranges of an unknown constant turn factor f (within 1 ± scale) and
        offset b [deg] (within ± bias): a commanded turn φ is f·φ + b plus the noise. Each
        particle carries its own f and b (uniform within the ranges at the start), so the
        filter estimates them as it estimates the pose (:meth:`ParticleFilter.turn_estimate`)
    turn_factor, turn_offset_deg : float
        the centre of those ranges: a known factor and offset (default 1 and 0)
    sigma_floor_deg : float    [deg] added in quadrature to σ, so that resampled copies
                               spread and small unmodelled turn errors stay covered
    dist_sigma_m, dist_sigma_rel : float
        distance reading error σ_d = dist_sigma_m + dist_sigma_rel · d [m]
    centre_zone_deg : float    [deg] contacts within ± this of the heading close both
                               switches (the twin's ``CENTRE_ZONE_DEG``)
    side_blur_deg : float      [deg] width of the soft side boundary
    side_union : float         in a corner (several walls touched), the weight of the
                               twin's convention (every switch any wall selects closes)
                               against one wall's reading (a body that reads one point)
    p_side : float             the declared rate of wrong bumper-side readings: a reading is
                               one of the two others with this probability (a real bumper's
                               switches in a corner are no more predictable than either
                               convention); no side reading can zero the belief
    p_phantom : float          the declared rate of phantom bumps: the bumper closes with no
                               wall, the robot stopped mid-flight (the reading is uniform
                               over the flight, the side any of the three)
    p_miss : float             the declared rate of missed bumps: the robot pushed on
                               against the wall until the drive's timeout
    p_lost : float             prior probability that the belief has lost track at a
                               reading: the weight of the re-initialised component mixed in
                               (the posterior's share is p_lost·m_r / ((1 − p_lost)·m_b +
                               p_lost·m_r), m the readings' marginal likelihoods)
    surprise : float           a re-initialised component is tried only when the belief's
                               marginal likelihood of a reading is below this fraction of
                               the best possible one
    consistent_z : float       a particle counts as fitting a reading (reported, not used to
                               weigh) within this many σ_d and with the side it predicts
    resample_ess : float       resample when ESS < this · n
    reinit_sigma_deg : float   [deg] heading spread of the local re-initialisation
    global_particles : int     particles of a belief that starts anywhere (unknown start),
                               kept until it has localized
    localized_mass : float     the belief has localized when this share of its weight lies
                               within h/2 of its mean position and Δ/2 of its mean heading
    jitter_deg, jitter_m : float
        while an unknown start has not localized, every resampled copy is moved by
        N(0, jitter_deg²) in heading and N(0, jitter_m²) in position (a regularised filter:
        copies of one pose explore around it instead of staying identical)
    votes : int                poses planned from after every bump
    max_settled : int          a search from one pose gives up after this many settled
                               states (a pose without a plan settles them all: the slowest
                               decisions)
    slack : float              plans within this of the cheapest (§13's cost) are candidates
    per_pose : int             at most this many candidates (cheapest first) per pose
    eval_particles : int       particles pushed through each candidate plan
    margin_m : float           [m] the final stop prefers points this deep in the goal cell
    edge_guard : float         plans avoid flights that bump at once when turned by ± this
                               many turn spreads (knife edges along a touched wall; 0: off)
    clearance_m : float        [m] plans avoid flights (after a turn) that pass a wall corner
                               closer than this plus s·tan(turn spread) at distance s along
                               the flight without touching it: a corner a metre-scale error
                               or one turn spread of heading would touch (0 with no spread:
                               off; the default 5 mm keeps µm tolerances from deciding)
    final_min : float          after the last turn the robot stops in the goal cell only
                               when the belief's mass there is at least this; else it flies
                               on to the next bump and decides again (0: whenever any mass
                               does, the rule before)
    correct_heading : bool     extension, off by default: command each turn as its angle
                               less the belief's mean heading offset from the Δ grid
    guided : bool              off by default: searches from a pose are guided by the cost
                               to go of the contact-state graph (§15), not by §13's bound
    reference : bool           the straightforward search (unguided) and scoring instead of
                               the fast ones (for benchmarks and tests)
    decision : str             how the next angle is chosen: "plan" (plans from particles'
                               poses, scored by their open-loop success), "value" (the
                               closed-loop value of the noisy contact-state chain weighed over
                               the belief, :mod:`planners.navigation.feedback.value`) or
                               "auto" (default: "value" when a turn error is declared,
                               :attr:`value_sigma_deg` > 0, or the contact rule turns the
                               body into the wall, which plans do not follow; else "plan")
    gamma : float              the value's discount per bump (in (0, 1])
    value_horizon : int        flights the value table looks ahead (more are clipped; the
                               default: the bump budget, :data:`DEFAULT_MAX_BUMPS`; a run
                               with a larger budget looks as far as its budget)
    heading_step_deg : float   [deg] the value table's heading grid
    value_nodes : int          equally likely flights per state and angle, each with its own
                               turn error and start point along the bin
    stop_extra : float         the value table's stops assume this many more turn errors
                               of the value's σ in quadrature (√(1 + stop_extra²)·σ): at a
                               bump the belief knows the heading only to about the last
                               turn's spread, as a flight's length barely depends on its
                               heading near normal incidence (0: a stop from a known state,
                               the rule before; "Deciding by value" in docs/model.md §15)
    value_particles : int      particles a value decision draws from the belief (0: as
                               many as the belief has; the rule before drew 64)
    stop_at_bump : bool        the value table's stops also succeed when the final drive
                               runs into its flight's bump inside the goal cell (a goal on
                               a wall or in a corner), as the belief's final drive does
                               (the rule before: False)
    body_turns : bool          add the executing body's declared turn errors (its
                               ``turn_errors`` noise spec,
                               :func:`bouncesim.runs.feedback.body_turns`) to the declared
                               noise (False: ignore them)
    contact : ContactParams or None
        the body's contact rule (docs/model.md §9) in the filter's motion model, the plan
        search's flights and the scores: a flight whose contact lies outside the bumper arc
        slides on to its bump, and only contacts inside the arc press the bumper. None
        (default): the front-half bumper (§15 as before, bitwise)
    """

    particles: int = 300
    turn_sigma_deg: float = 0.0
    turn_scale: float = 0.0
    turn_bias_deg: float = 0.0
    turn_factor: float = 1.0
    turn_offset_deg: float = 0.0
    sigma_floor_deg: float = 0.0
    dist_sigma_m: float = 0.01
    dist_sigma_rel: float = 0.01
    centre_zone_deg: float = CENTRE_ZONE_DEG
    side_blur_deg: float = 1.0
    side_union: float = 0.5
    p_side: float = 0.05
    p_phantom: float = 0.01
    p_miss: float = 0.01
    p_lost: float = 0.01
    surprise: float = 0.01
    consistent_z: float = 5.0
    resample_ess: float = 0.5
    reinit_sigma_deg: float = 10.0
    global_particles: int = 6000
    localized_mass: float = 0.9
    jitter_deg: float = 1.0
    jitter_m: float = 0.005
    votes: int = 2
    max_settled: int = 3000
    slack: float = 0.0
    per_pose: int = 1
    eval_particles: int = 64
    margin_m: float = 0.02
    edge_guard: float = 2.0
    clearance_m: float = 0.005
    final_min: float = 0.5
    correct_heading: bool = False
    guided: bool = False
    reference: bool = False
    decision: str = "auto"
    gamma: float = 0.98
    value_horizon: int = DEFAULT_MAX_BUMPS
    heading_step_deg: float = 1.0
    value_nodes: int = 7
    stop_extra: float = 1.0
    value_particles: int = 0
    stop_at_bump: bool = True
    body_turns: bool = True
    contact: ContactParams | None = None

    def __post_init__(self) -> None:
        for name in ("particles", "votes", "per_pose", "eval_particles", "global_particles",
                     "max_settled", "value_horizon", "value_nodes"):
            v = getattr(self, name)
            if int(v) != v or v < 1:
                raise UserError(f"feedback {name} must be a positive whole number, got {v}.")
        for name in ("turn_sigma_deg", "sigma_floor_deg", "dist_sigma_m", "dist_sigma_rel", "slack",
                     "centre_zone_deg", "side_blur_deg", "reinit_sigma_deg", "margin_m",
                     "edge_guard", "jitter_deg", "jitter_m", "turn_scale", "turn_bias_deg",
                     "clearance_m", "stop_extra"):
            v = float(getattr(self, name))
            if not (math.isfinite(v) and v >= 0):
                raise UserError(f"feedback {name} must be a non-negative number, got {v}.")
        if int(self.value_particles) != self.value_particles or self.value_particles < 0:
            raise UserError(f"feedback value_particles must be a whole number >= 0, got "
                            f"{self.value_particles}.")
        if self.dist_sigma_m <= 0:
            raise UserError("feedback dist_sigma_m must be positive.")
        if not 0 <= self.final_min <= 1:
            raise UserError("feedback final_min must lie in [0, 1].")
        if not (math.isfinite(self.turn_factor) and self.turn_factor > 0):
            raise UserError("feedback turn_factor must be positive.")
        if not math.isfinite(self.turn_offset_deg):
            raise UserError("feedback turn_offset_deg must be finite.")
        if not 0 < self.localized_mass <= 1:
            raise UserError("feedback localized_mass must lie in (0, 1].")
        for name in ("p_side", "p_phantom", "p_miss", "p_lost", "surprise", "side_union"):
            v = float(getattr(self, name))
            if not 0 <= v < 1:
                raise UserError(f"feedback {name} must lie in [0, 1), got {v}.")
        if self.p_side > 2 / 3:
            raise UserError("feedback p_side above 2/3 would make a wrong side likelier than "
                            "the right one.")
        if self.p_phantom + self.p_miss >= 1:
            raise UserError("feedback p_phantom + p_miss must stay below 1.")
        if not 0 < self.resample_ess <= 1:
            raise UserError("feedback resample_ess must lie in (0, 1].")
        if self.decision not in ("auto", "plan", "value"):
            raise UserError(f"feedback decision must be auto, plan or value, got "
                            f"{self.decision!r}.")
        if not 0 < self.gamma <= 1:
            raise UserError("feedback gamma must lie in (0, 1].")
        if not (math.isfinite(self.heading_step_deg) and 0 < self.heading_step_deg <= 45):
            raise UserError("feedback heading_step_deg must lie in (0, 45].")
        if self.contact is not None and not isinstance(self.contact, ContactParams):
            raise UserError(f"feedback contact must be a ContactParams or None, got "
                            f"{self.contact!r}.")

    @property
    def turn_spread_deg(self) -> float:
        """[deg] the heading spread the filter adds per turn: √(σ² + σ_floor²)."""
        return math.hypot(self.turn_sigma_deg, self.sigma_floor_deg)

    @property
    def value_sigma_deg(self) -> float:
        """[deg] the turn error the value table assumes: the turn spread with the residual of
        an unknown factor and offset added in quadrature, as uniform errors over a tenth of
        their ranges (the commands correct for the filter's estimates, which learn a factor
        within ±10 % to about 1 % in a few bumps: a 135° turn is then off by about 1.35°).
        """
        return math.sqrt(self.turn_spread_deg ** 2 + (13.5 * self.turn_scale) ** 2 / 3
                         + (self.turn_bias_deg / 10) ** 2 / 3)
