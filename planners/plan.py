"""Plans (observation strings) and policy mixes: what the planners hand to a robot.

A :class:`Plan` is a sequence of labels: 0 for a forward step of one cell, or a bouncing
angle [deg] for a bump followed by an in-place CCW turn by that angle (docs/model.md §12). It prints
in the paper's form and parses from both that form and the plain one.

A plan from a planner (:class:`planners.navigation.Route`) also carries the expected length of
every flight before a bump (``flights_m``) and of the final drive by the clock (``final_m``).
An *exact* plan (docs/model.md §13, :mod:`planners.navigation.exact`) runs by its angles: its
flights are exact and its labels are the paper's form with zeros = round(flight / h), exact
along the axes and approximate off them (a diagonal step of the step model moves √2·h); its
text form appends the flights: ``00 90° 0 | flights 0.68 0.34 m | final 0.34 m``. A step-model
plan runs by its observation string; its flights are the step model's run lengths (§21), marked
``exact_flights=False``, and its text form is the paper's.

Examples
--------
>>> p = Plan.parse("000000 135° 135° 00000 90°")
>>> p.labels
(0, 0, 0, 0, 0, 0, 135, 135, 0, 0, 0, 0, 0, 90)
>>> str(p)
'000000 135° 135° 00000 90°'
>>> Plan.parse("0 0 135 90").plain()
'0 0 135 90'
>>> str(Plan(()))                     # the empty plan: start == goal
'(empty plan)'
>>> p.angles_used, p.steps, p.bumps
(2, 11, 3)
>>> e = Plan.exact([90, 135], [0.68, 0.0], 0.3, h=0.34)
>>> str(e), e.turns
('00 90° 135° 0', (90, 135))
>>> e.exact_text()
'00 90° 135° 0 | flights 0.68 0 m | final 0.3 m'
>>> Plan.parse(e.exact_text()) == e
True
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

from envs import UserError

from .noise import TurnNoise

__all__ = ["Plan", "PlanParseError", "PolicyMix"]


class PlanParseError(UserError):
    """Text that is not an observation string."""


def _num(x: float) -> int | float:
    x = float(x)
    return int(round(x)) if abs(x - round(x)) < 1e-9 else x


def _metres(v: float) -> str:
    """A length [m] to 1e-9 m (the contact gap) without trailing zeros."""
    return f"{float(v):.9f}".rstrip("0").rstrip(".")


def _length(v, what: str) -> float:
    try:
        f = float(v)
    except (TypeError, ValueError):
        raise PlanParseError(f"{what} {v!r} is not a number.") from None
    if not (math.isfinite(f) and f >= 0):
        raise PlanParseError(f"{what} {v} is not a non-negative length in metres.")
    return f


@dataclass(frozen=True)
class Plan:
    """An observation string: 0 = forward step, angle [deg] = bump then turn CCW by it.

    Attributes
    ----------
    labels : tuple        0 = forward step, else a bouncing angle [deg]
    flights_m : tuple of float or None
        Exact plans only: the expected length [m] of the flight before each bump (one per
        angle, in order); None for a step-model plan.
    final_m : float or None
        Exact plans only: the final drive by the clock [m] after the last turn.
    planner : str or None  the planner that made it (a :data:`planners.navigation.PLANNERS`
                           name), or None (unknown, e.g. a hand-written plan)
    exact_flights : bool   True (default): the flights are exact and the plan runs by its
                           angles (§13); False: they are the step model's run lengths and the
                           plan runs by its observation string (§21)
    """

    labels: tuple
    flights_m: tuple | None = None
    final_m: float | None = None
    planner: str | None = None
    exact_flights: bool = True

    def __post_init__(self) -> None:
        labs = []
        for v in self.labels:
            try:
                f = float(v)
            except (TypeError, ValueError):
                raise PlanParseError(f"plan label {v!r} is not a number.") from None
            if not (0 <= f < 360):                  # also NaN and infinities
                raise PlanParseError(f"plan label {v} is not 0 or an angle in (0°, 360°).")
            labs.append(_num(f))
        object.__setattr__(self, "labels", tuple(labs))
        if (self.flights_m is None) != (self.final_m is None):
            raise PlanParseError("an exact plan needs both its flights and its final drive.")
        if self.flights_m is not None:
            flights = tuple(_length(v, "flight length") for v in self.flights_m)
            if len(flights) != self.bumps:
                raise PlanParseError(f"an exact plan needs one flight length per angle: "
                                     f"{len(flights)} flights for {self.bumps} angles.")
            object.__setattr__(self, "flights_m", flights)
            object.__setattr__(self, "final_m", _length(self.final_m, "final drive"))

    @classmethod
    def exact(cls, turns, flights_m, final_m: float, h: float, planner: str = "exact") -> Plan:
        """An exact plan from its bouncing angles [deg] in order, the flight [m] before each
        bump and the final drive [m]; the labels get zeros = round(flight / h) (h [m]: the
        cell size), exact along the axes and approximate off them.
        """
        turns, flights = list(turns), list(flights_m)
        if len(turns) != len(flights):
            raise PlanParseError(f"an exact plan needs one flight length per angle: "
                                 f"{len(flights)} flights for {len(turns)} angles.")
        labels: list = []
        for a, f in zip(turns, flights):
            labels.extend([0] * int(round(_length(f, "flight length") / h)))
            labels.append(a)
        labels.extend([0] * int(round(_length(final_m, "final drive") / h)))
        return cls(tuple(labels), tuple(flights), float(final_m), planner)

    @classmethod
    def with_flights(cls, plan: Plan, flights_m, final_m: float, planner: str) -> Plan:
        """A step-model ``plan`` with the run lengths of its segments [m] (docs/model.md
        §21, :func:`planners.measures.step_flights`): it still runs by its observation string.
        """
        return cls(plan.labels, tuple(flights_m), float(final_m), planner, exact_flights=False)

    @property
    def is_exact(self) -> bool:
        """True when the plan carries exact flights (it runs by its angles, §13)."""
        return self.flights_m is not None and self.exact_flights

    @property
    def turns(self) -> tuple:
        """The bouncing angles [deg] in the order the robot turns them (repeats kept)."""
        return tuple(v for v in self.labels if v != 0)

    # ------------------------------------------------------------------ parsing/printing
    @classmethod
    def parse(cls, text: str) -> Plan:
        """Parse the paper's form (``000000 135° 90°``) or the plain one (``0 0 135 90``).

        A token of zeros only (``000``) is that many steps; any other number is an angle,
        with or without a degree sign.
        """
        if isinstance(text, Plan):
            return text
        s = str(text).strip()
        if "|" in s:
            return cls._parse_exact(s)
        if s in {"", "(empty plan)"}:
            return cls(())
        labels: list = []
        for tok in re.split(r"[\s,]+", s):
            if not tok:
                continue
            t = tok.replace("°", "").replace("deg", "")
            if re.fullmatch(r"0+", t) and "°" not in tok:
                labels.extend([0] * len(t))
                continue
            try:
                labels.append(float(t))
            except ValueError:
                raise PlanParseError(
                    f"{tok!r} in plan {s!r} is neither a run of zeros nor an angle.") from None
        return cls(tuple(labels))

    @classmethod
    def _parse_exact(cls, s: str) -> Plan:
        head, *parts = (t.strip() for t in s.split("|"))
        base = cls.parse(head)
        found: dict = {}
        for part in parts:
            m = re.fullmatch(r"(flights|final)\b(.*?)(?:\s*m)?", part)
            if m is None or m.group(1) in found:
                raise PlanParseError(f"{part!r} in plan {s!r} is not 'flights F1 F2 ... m' or "
                                     "'final F m'.")
            found[m.group(1)] = [t for t in re.split(r"[\s,]+", m.group(2)) if t]
        if set(found) != {"flights", "final"} or len(found["final"]) != 1:
            raise PlanParseError(f"exact plan {s!r} needs '| flights ... m | final F m'.")
        return cls(base.labels, tuple(found["flights"]), found["final"][0], "exact")

    def exact_text(self, decimals: int | None = None) -> str:
        """The paper's form followed by the exact flights and the final drive [m] (for a
        plan without flights, the paper's form alone). Lengths are written to 1e-9 m (the
        contact gap), or with ``decimals`` rounded for reading (a figure's title).

        >>> Plan.exact([90, 90], [0.0, 2.719999999], 0.339999999, 0.34).exact_text(2)
        '90° 00000000 90° 0 | flights 0 2.72 m | final 0.34 m'
        >>> Plan.exact([90], [10.2], 0.0, 3.4).exact_text(decimals=0)
        '000 90° | flights 10 m | final 0 m'
        """
        if decimals is not None and (int(decimals) != decimals or decimals < 0):
            raise ValueError(f"decimals must be a whole number >= 0, got {decimals!r}.")
        if not self.is_exact:
            return str(self)
        head = "" if not self.labels else str(self)

        def metres(v) -> str:
            if decimals is None:
                return _metres(v)
            text = f"{float(v):.{int(decimals)}f}"     # no trailing zeros after the point
            return text.rstrip("0").rstrip(".") if "." in text else text
        flights = " ".join(metres(v) for v in self.flights_m)
        return (f"{head} | flights {flights} m | final {metres(self.final_m)} m".replace(
            "flights  m", "flights m")).strip()

    def to_json(self) -> dict:
        """JSON fields of the plan: ``plan`` (labels), ``plan_text`` (the paper's form; zeros
        = round(flight / h) for exact plans, approximate off the axes), ``planner``,
        ``angles`` (the bouncing angles in order), ``flights_m`` and ``final_m`` (None for a
        plan without flights) and ``exact_flights`` (whether it runs by its angles).
        """
        return {"plan": self.to_list(), "plan_text": str(self), "planner": self.planner,
                "angles": list(self.turns),
                "flights_m": None if self.flights_m is None else list(self.flights_m),
                "final_m": self.final_m, "exact_flights": self.is_exact}

    @classmethod
    def from_json(cls, data: dict) -> Plan:
        """The plan of :meth:`to_json`'s fields (``plan`` labels, or ``plan_text``); a plan
        with flights runs by its angles unless ``exact_flights`` is false.
        """
        labels = data.get("plan")
        base = cls.parse(data.get("plan_text") or "") if labels is None else cls(tuple(labels))
        return cls(base.labels, data.get("flights_m"), data.get("final_m"),
                   data.get("planner"), bool(data.get("exact_flights", True)))

    def __str__(self) -> str:
        if not self.labels:
            return "(empty plan)"
        out: list[str] = []
        zeros = 0
        for v in self.labels:
            if v == 0:
                zeros += 1
                continue
            if zeros:
                out.append("0" * zeros)
                zeros = 0
            out.append(f"{v}°")
        if zeros:
            out.append("0" * zeros)
        return " ".join(out)

    def plain(self) -> str:
        """Space-separated labels: ``0 0 135 90``."""
        return " ".join(str(v) for v in self.labels)

    # ------------------------------------------------------------------ properties
    def __len__(self) -> int:
        return len(self.labels)

    def __iter__(self):
        return iter(self.labels)

    @property
    def steps(self) -> int:
        """Number of forward steps (zeros)."""
        return sum(1 for v in self.labels if v == 0)

    @property
    def bumps(self) -> int:
        """Number of bumps (angles)."""
        return sum(1 for v in self.labels if v != 0)

    @property
    def angles(self) -> tuple:
        """The distinct bouncing angles used, in order of first use [deg]."""
        return tuple(dict.fromkeys(v for v in self.labels if v != 0))

    @property
    def angles_used(self) -> int:
        """Number of distinct bouncing angles in the plan (docs/model.md §12)."""
        return len(self.angles)

    def segments(self) -> list[tuple[int, int | float | None]]:
        """The plan as (zeros before, angle) pairs; a trailing run has angle None.

        >>> Plan.parse("00 90° 135° 000").segments()
        [(2, 90), (0, 135), (3, None)]
        """
        out: list = []
        zeros = 0
        for v in self.labels:
            if v == 0:
                zeros += 1
            else:
                out.append((zeros, v))
                zeros = 0
        if zeros:
            out.append((zeros, None))
        return out

    def to_list(self) -> list:
        """The observation labels as a list (0 = step, else the angle [deg])."""
        return list(self.labels)


@dataclass(frozen=True)
class PolicyMix:
    """A policy mix: bouncing angles [deg] with probabilities alpha and the turn noise it
    was designed for.

    Attributes
    ----------
    angles : tuple of float   bouncing angles [deg]
    alpha : tuple of float    probabilities (non-negative, sum 1)
    eps : float               error range ε [deg] (docs/model.md §11)
    r : float                 reliability in [0, 1]
    sigma : float             Gaussian turn noise σ [deg] (docs/model.md §11a; 0: none; σ > 0
                              excludes ε > 0 with r < 1, as :class:`planners.noise.TurnNoise`)
    """

    angles: tuple
    alpha: tuple
    eps: float = 0.0
    r: float = 1.0
    sigma: float = 0.0

    def __post_init__(self) -> None:
        angles = tuple(float(a) for a in self.angles)
        alpha = tuple(float(a) for a in self.alpha)
        if len(angles) != len(alpha) or not angles:
            raise UserError("a policy mix needs one probability per angle.")
        if any(a < -1e-12 for a in alpha) or abs(sum(alpha) - 1) > 1e-6:
            raise UserError("policy-mix probabilities must be non-negative and sum to 1.")
        if not 0 <= self.r <= 1:
            raise UserError(f"reliability r must lie in [0, 1], got {self.r}.")
        if self.eps < 0:
            raise UserError(f"error range eps must be non-negative, got {self.eps}.")
        object.__setattr__(self, "angles", angles)
        object.__setattr__(self, "alpha", tuple(max(a, 0.0) for a in alpha))
        object.__setattr__(self, "sigma", self.noise.sigma_deg)    # checks the combination

    @property
    def noise(self) -> TurnNoise:
        """The mix's turn noise (ε, r, σ) as a :class:`~planners.noise.TurnNoise`."""
        return TurnNoise(self.eps, self.r, self.sigma)
