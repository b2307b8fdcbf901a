"""Seeded rotation-noise models for simulated turns (docs/model.md §7-8).

A noise model maps a commanded in-place turn [deg] to the turn the body actually makes.
Every model is a frozen dataclass with

- ``sample(rng, commanded_deg) -> float``: one actual turn [deg];
- ``sample_many(rng, commanded, n=None) -> ndarray``: many at once (``commanded`` a scalar
  with ``n`` draws, or an array of commands, one draw each).

Randomness comes only from the ``rng`` argument (a :class:`numpy.random.Generator`): the same
seed gives the same turns.

Models
------
- :class:`NoNoise`: exact turns.
- :class:`SteppedNoise`: the docs/model.md §7 model. Exact with probability ``r``; otherwise
  the turn is off by a uniform non-zero multiple of Δ in [−ε, ε]. It is the coverage models'
  :class:`planners.coverage.TurnNoise` at a fixed quantum Δ, and samples through it.
- :class:`GaussianNoise`: commanded + N(0, σ²).

Examples
--------
>>> import numpy as np
>>> NoNoise().sample(np.random.default_rng(0), 90.0)
90.0
>>> m = SteppedNoise(eps_deg=2, r=0.0, delta_deg=1)
>>> sorted(set(m.sample_many(np.random.default_rng(1), 90.0, 1000).tolist()))
[88.0, 89.0, 91.0, 92.0]
>>> parse_noise("model:eps=5,r=0.8", delta_deg=1.0)
SteppedNoise(eps_deg=5.0, r=0.8, delta_deg=1.0)
>>> parse_noise("gauss:2")
GaussianNoise(sigma_deg=2.0)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from envs import UserError
from planners.noise import TurnNoise, parse_noise_spec
from planners.noise import as_commands as _commands

if TYPE_CHECKING:
    from planners.plan import PolicyMix

__all__ = ["NoiseModel", "NoNoise", "SteppedNoise", "GaussianNoise", "body_noise",
           "parse_noise", "noise_for_mix", "noise_and_rng"]


class NoiseModel:
    """Base class: a rotation-noise model (subclasses are frozen dataclasses)."""

    def sample(self, rng: np.random.Generator, commanded_deg: float) -> float:
        """The actual turn [deg] for one commanded turn [deg]."""
        return float(self.sample_many(rng, commanded_deg, 1)[0])

    def sample_many(self, rng: np.random.Generator, commanded, n: int | None = None
                    ) -> np.ndarray:
        """Actual turns [deg]: ``n`` draws for a scalar command, or one per array element."""
        raise NotImplementedError

    @property
    def exact(self) -> bool:
        """True when the model never perturbs a turn."""
        return False


@dataclass(frozen=True)
class NoNoise(NoiseModel):
    """Exact turns: the body turns by exactly the commanded angle."""

    def sample(self, rng, commanded_deg: float) -> float:
        """The commanded turn [deg], unchanged."""
        return float(commanded_deg)

    def sample_many(self, rng, commanded, n=None) -> np.ndarray:
        """The commanded turns [deg] as an array, unchanged."""
        return _commands(commanded, n)

    @property
    def exact(self) -> bool:
        """Always True: no noise."""
        return True

    def __str__(self) -> str:
        return "none"


@dataclass(frozen=True)
class SteppedNoise(NoiseModel):
    """The docs/model.md §7 rotation model.

    With probability ``r`` the turn is exact; otherwise it is off by δ drawn uniformly from
    {−ε, …, −Δ, Δ, …, ε} (non-zero multiples of Δ), i.e. each such δ has probability
    (1 − r) / (2ε/Δ). ε = 0 means exact turns whatever r is.

    Parameters
    ----------
    eps_deg : float    error range ε [deg], a non-negative multiple of ``delta_deg``
    r : float          reliability in [0, 1]
    delta_deg : float  the error quantum Δ [deg] (the environment's 360°/K)
    """

    eps_deg: float
    r: float
    delta_deg: float
    turn: TurnNoise = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        for name in ("eps_deg", "r", "delta_deg"):
            v = getattr(self, name)
            try:
                v = float(v)
            except (TypeError, ValueError):
                raise UserError(f"noise parameter {name} must be a number, got {v!r}.") \
                    from None
            if not math.isfinite(v):
                raise UserError(f"noise parameter {name} must be finite, got {v}.")
            object.__setattr__(self, name, v)
        if self.delta_deg <= 0:
            raise UserError(f"the noise quantum delta must be positive, got {self.delta_deg:g}°.")
        turn = TurnNoise(self.eps_deg, self.r)          # checks eps >= 0 and 0 <= r <= 1
        object.__setattr__(self, "turn", turn)
        object.__setattr__(self, "_m", turn.quanta(delta_deg=self.delta_deg))

    @property
    def m(self) -> int:
        """Number of error quanta on each side: ε / Δ."""
        return self._m

    @property
    def exact(self) -> bool:
        """True when no turn is ever perturbed (ε below Δ, or r = 1)."""
        return self.m == 0 or self.r == 1.0

    def offsets(self) -> tuple[np.ndarray, np.ndarray]:
        """The support δ [deg] and its probabilities (δ = 0 first)."""
        d, p = self.turn.support(delta_deg=self.delta_deg)
        order = np.argsort(d != 0, kind="stable")       # δ = 0 first, then −m … −1, 1 … m
        return d[order] * self.delta_deg, p[order]

    def sample_many(self, rng, commanded, n=None) -> np.ndarray:
        """Executed turns [deg] for the commanded ones under the §7 model."""
        return self.turn.sample(rng, commanded, n, delta_deg=self.delta_deg)

    def __str__(self) -> str:
        return f"model:eps={self.eps_deg:g},r={self.r:g}"


@dataclass(frozen=True)
class GaussianNoise(NoiseModel):
    """Turn error δ ~ N(0, σ²) [deg] added to every commanded turn.

    Parameters
    ----------
    sigma_deg : float   standard deviation σ [deg], non-negative
    """

    sigma_deg: float

    def __post_init__(self) -> None:
        try:
            s = float(self.sigma_deg)
        except (TypeError, ValueError):
            raise UserError(f"Gaussian noise sigma must be a number of degrees, "
                            f"got {self.sigma_deg!r}.") from None
        if not math.isfinite(s) or s < 0:
            raise UserError(f"Gaussian noise sigma must be a non-negative number of degrees, "
                            f"got {s:g}.")
        object.__setattr__(self, "sigma_deg", s)

    @property
    def exact(self) -> bool:
        """True when σ = 0."""
        return self.sigma_deg == 0

    def sample_many(self, rng, commanded, n=None) -> np.ndarray:
        """Executed turns [deg]: commanded plus Gaussian noise of standard deviation σ."""
        c = _commands(commanded, n)
        if self.exact:
            return c
        return c + rng.normal(0.0, self.sigma_deg, size=c.shape)

    def __str__(self) -> str:
        return f"gauss:{self.sigma_deg:g}"


def parse_noise(text: str, delta_deg: float | None = None) -> NoiseModel:
    """A simulated body's noise model from a spec in the one grammar
    (:func:`planners.noise.parse_noise_spec`): ``none`` | ``gauss:SIGMA`` |
    ``model:eps=E,r=R`` (optionally ``,delta=D``; by default Δ is ``delta_deg``, the
    environment's 360°/K).

    Raises
    ------
    UserError
        One sentence naming the accepted forms.
    """
    spec = parse_noise_spec(text)
    if spec.kind == "none":
        return NoNoise()
    if spec.kind == "gauss":
        return GaussianNoise(spec.noise.sigma_deg)
    return body_noise(spec.noise, spec.delta_deg if spec.delta_deg is not None else delta_deg)


def body_noise(noise: TurnNoise, delta_deg: float | None) -> NoiseModel:
    """The noise model of a simulated body for a :class:`~planners.noise.TurnNoise`: exact
    turns, Gaussian σ, or the §7 model at the error quantum Δ = ``delta_deg`` [deg].
    """
    if noise.gaussian:
        return GaussianNoise(noise.sigma_deg)
    if noise.exact:
        return NoNoise()
    if delta_deg is None:
        raise UserError("the model noise needs the orientation step delta (give delta=D).")
    m = noise.eps_deg / delta_deg if delta_deg > 0 else 0.0
    if delta_deg > 0 and abs(m - round(m)) > 1e-9 * max(1.0, abs(m)):
        raise UserError(f"model noise eps = {noise.eps_deg:g}° is not a multiple of the "
                        f"orientation step {delta_deg:g}°; use a multiple or more orientations "
                        f"(e.g. --orientations 360).")
    return SteppedNoise(noise.eps_deg, noise.r, delta_deg)


def noise_for_mix(mix: PolicyMix, delta_deg: float) -> NoiseModel:
    """The noise model of a :class:`planners.plan.PolicyMix` (its ε and r, §7, or its
    Gaussian σ, §18) at Δ [deg].

    >>> from planners.plan import PolicyMix
    >>> noise_for_mix(PolicyMix((90.0,), (1.0,), sigma=3.0), 1.0)
    GaussianNoise(sigma_deg=3.0)
    """
    return body_noise(mix.noise, delta_deg)


def noise_and_rng(noise: NoiseModel | None, rng) -> tuple[NoiseModel, np.random.Generator | None]:
    """The rotation noise and random source of a simulated body: the one constructor contract
    of :class:`~bouncesim.robots.kinematic.KinematicRobot`,
    :class:`~bouncesim.robots.pybullet.PyBulletRobot` and
    :class:`~bouncesim.robots.create2.OIEmulator`.

    ``noise`` None means exact turns; any object with ``sample(rng, commanded_deg)`` will do
    (its ``exact`` property, when it has one, says it never perturbs a turn). ``rng`` is a numpy
    Generator, an int seed, or None. A body with rotation noise needs an rng: seeding is never
    implicit.

    >>> noise_and_rng(None, None)
    (NoNoise(), None)
    >>> noise_and_rng(GaussianNoise(2.0), None)          # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    envs.errors.UserError: a robot with rotation noise needs an rng (a numpy Generator or ...
    """
    noise = noise if noise is not None else NoNoise()
    if rng is None:
        if not getattr(noise, "exact", False):      # any object with sample(rng, deg)
            raise UserError("a robot with rotation noise needs an rng (a numpy Generator or an "
                            "int seed).")
        return noise, None
    return noise, rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
