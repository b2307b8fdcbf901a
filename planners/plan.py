"""Plans (observation strings) and policy mixes: what the planners hand to a robot.

A :class:`Plan` is a sequence of labels: 0 for a forward step of one cell, or a bouncing
angle [deg] for a bump followed by an in-place CCW turn by that angle (docs/model.md §6). It prints
in the paper's form and parses from both that form and the plain one.

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
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from envs import UserError

__all__ = ["Plan", "PlanParseError", "PolicyMix"]


class PlanParseError(UserError):
    """Text that is not an observation string."""


def _num(x: float) -> int | float:
    x = float(x)
    return int(round(x)) if abs(x - round(x)) < 1e-9 else x


@dataclass(frozen=True)
class Plan:
    """An observation string: 0 = forward step, angle [deg] = bump then turn CCW by it."""

    labels: tuple

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
        """Number of distinct bouncing angles in the plan (docs/model.md §6)."""
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
    """A policy mix: bouncing angles [deg] with probabilities alpha and the noise model.

    Attributes
    ----------
    angles : tuple of float   bouncing angles [deg]
    alpha : tuple of float    probabilities (non-negative, sum 1)
    eps : float               error range ε [deg] (docs/model.md §7)
    r : float                 reliability in [0, 1]
    """

    angles: tuple
    alpha: tuple
    eps: float = 0.0
    r: float = 1.0

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
