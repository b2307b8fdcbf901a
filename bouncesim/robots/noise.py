"""Seeded rotation-noise models for simulated turns (docs/model.md §16, §21).

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
- :class:`SteppedNoise`: the docs/model.md §11 model. Exact with probability ``r``; otherwise
  the turn is off by a uniform non-zero multiple of Δ in [−ε, ε]. It is the coverage models'
  :class:`planners.coverage.TurnNoise` at a fixed quantum Δ, and samples through it.
- :class:`GaussianNoise`: commanded + N(0, σ²).
- :class:`ScaledNoise`: another model applied to a scaled and offset command, f·φ + b; f and
  b known (``factor=F``, ``offset=O``) or drawn once per body within 1 ± S and ±B
  (``scale=S``, ``bias=B``).

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
>>> m = parse_noise("gauss:0,factor=1.08")
>>> m, m.sample(np.random.default_rng(0), 90.0)
(ScaledNoise(base=GaussianNoise(sigma_deg=0.0), factor=1.08, offset_deg=None, scale=0.0, \
bias_deg=0.0), 97.2)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from envs import UserError
from planners.noise import TurnNoise, parse_noise_spec, spec_text
from planners.noise import as_commands as _commands
from planners.turn_offsets import body_errors

if TYPE_CHECKING:
    from planners.plan import PolicyMix

__all__ = ["NoiseModel", "NoNoise", "SteppedNoise", "GaussianNoise", "BodyErrors", "ScaledNoise",
           "body_noise", "parse_noise", "noise_for_mix", "noise_and_rng"]


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

    @property
    def needs_rng(self) -> bool:
        """True when sampling draws random numbers (default: unless :attr:`exact`)."""
        return not self.exact


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
    """The docs/model.md §11 rotation model.

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
        """Executed turns [deg] for the commanded ones under the §16 model."""
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


@dataclass(frozen=True)
class BodyErrors(NoiseModel):
    """A body's own turn errors on top of a base model (docs/model.md §11b): every bump by φ
    spins ρ = wrap180(φ) and is the base's draw plus sign(ρ)·``offset_deg`` +
    (``factor`` − 1)·ρ + N(0, ``sigma_deg``²) [deg] (the body lags in the sense it spins,
    :func:`planners.turn_offsets.body_errors`), drawn after the base's. ``rest_deg``: how much
    further the body spins after a bump from rest (no flight since its last turn), in the
    sense of its spin; the draws here do not know the flight, so a simulation that does adds
    it (:class:`~bouncesim.robots.kinematic.KinematicBatch`).
    """

    base: NoiseModel
    sigma_deg: float
    offset_deg: float
    factor: float = 1.0
    rest_deg: float = 0.0

    def sample_many(self, rng, commanded, n=None) -> np.ndarray:
        """The base's executed turns [deg] plus the body's error."""
        t = self.base.sample_many(rng, commanded, n)
        return t + body_errors(rng, commanded, np.shape(t), self.sigma_deg, self.offset_deg,
                               self.factor)

    def __str__(self) -> str:
        return (f"{self.base} + body gauss:{self.sigma_deg:g},offset={self.offset_deg:g}"
                + (f",factor={self.factor:g}" if self.factor != 1.0 else "")
                + (f",rest={self.rest_deg:g}" if self.rest_deg else ""))


@dataclass(frozen=True)
class ScaledNoise(NoiseModel):
    """A turn with a constant factor f and offset b [deg]: commanded φ becomes
    ``base.sample(rng, f·φ + b)``, i.e. the base model's noise is drawn on the scaled and
    offset command (for Gaussian and exact bases: f·φ + b + δ).

    f and b are known (``factor``, ``offset_deg``) or unknown within ``factor`` ± ``scale``
    and ``offset_deg`` ± ``bias_deg`` (the centres 1 and 0 when not given): then the body
    draws them, uniformly, once per rng: at its first turn (or
    :meth:`draw`), from that rng, factor first, before the base's draw; every later turn with
    the same rng keeps them. A body's randomness thus comes only from its rng (the same seed
    gives the same f and b), and one model shared by several bodies (each with its own rng,
    as :class:`~bouncesim.robots.pybullet.PyBulletBatch` has) gives each its own f and b; the
    robots of a :class:`~bouncesim.robots.kinematic.KinematicBatch` share one rng, hence one
    f and b. The model keeps a reference to every rng it drew for.

    Parameters
    ----------
    base : NoiseModel        the scatter (default exact turns)
    factor : float or None   known factor F > 0, or the centre of an unknown one; None: 1
    offset_deg : float or None
        known offset O [deg], or the centre of an unknown one; None: 0
    scale : float            half-range S in [0, 0.5) of an unknown factor (within F ± S)
    bias_deg : float         half-range B >= 0 [deg] of an unknown offset (within O ± B)

    Examples
    --------
    >>> m = parse_noise("gauss:2,scale=0.1")
    >>> str(m), m.exact, m.drawn_factor
    ('gauss:2,scale=0.1', False, None)
    >>> rng = np.random.default_rng(0)
    >>> x = m.sample_many(rng, 90.0, 3)
    >>> f = m.drawn_factor; 0.9 <= f <= 1.1 and m.draw(rng) == (f, 0.0)
    True
    """

    base: NoiseModel = field(default_factory=NoNoise)
    factor: float | None = None
    offset_deg: float | None = None
    scale: float = 0.0
    bias_deg: float = 0.0
    _draws: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not hasattr(self.base, "sample_many"):
            raise UserError(f"the base of a scaled turn must be a noise model, got "
                            f"{self.base!r}.")
        for name in ("factor", "offset_deg", "scale", "bias_deg"):
            v = getattr(self, name)
            if v is None and name in ("factor", "offset_deg"):
                continue
            try:
                v = float(v)
            except (TypeError, ValueError):
                raise UserError(f"turn parameter {name} must be a number, got {v!r}.") \
                    from None
            if not math.isfinite(v):
                raise UserError(f"turn parameter {name} must be finite, got {v}.")
            object.__setattr__(self, name, v)
        TurnNoise(scale=self.scale, bias_deg=self.bias_deg)      # checks S and B
        if self.factor is not None and self.factor <= 0:
            raise UserError(f"the turn factor F must be positive, got {self.factor:g}.")

    @property
    def _unknown(self) -> bool:
        return self.scale > 0 or self.bias_deg > 0

    @property
    def _known(self) -> tuple[float, float]:
        return (1.0 if self.factor is None else self.factor,
                0.0 if self.offset_deg is None else self.offset_deg)

    @property
    def exact(self) -> bool:
        """True only with f = 1, b = 0 known and an exact base."""
        return (not self._unknown and self._known == (1.0, 0.0)
                and bool(getattr(self.base, "exact", False)))

    @property
    def needs_rng(self) -> bool:
        """True when f or b is drawn, or the base draws."""
        return self._unknown or bool(getattr(self.base, "needs_rng",
                                             not getattr(self.base, "exact", False)))

    def draw(self, rng: np.random.Generator | None) -> tuple[float, float]:
        """(f, b [deg]) of the body drawing from ``rng``: the known values, or those drawn
        from ``rng`` at its first call (f ~ U[1 − S, 1 + S], then b ~ U[−B, B]) and kept.
        """
        if not self._unknown:
            return self._known
        if rng is None:
            raise UserError("a robot whose turn scale or bias is unknown needs an rng (a numpy "
                            "Generator or an int seed) to draw it.")
        got = self._draws.get(id(rng))
        if got is None:
            f, b = self._known                              # the centres
            if self.scale > 0:
                f = float(rng.uniform(f - self.scale, f + self.scale))
            if self.bias_deg > 0:
                b = float(rng.uniform(b - self.bias_deg, b + self.bias_deg))
            got = self._draws[id(rng)] = (rng, f, b)       # the rng kept: its id stays unique
        self._draws[None] = got
        return got[1], got[2]

    def drawn(self, rng: np.random.Generator | None = None) -> tuple[float, float] | None:
        """(f, b [deg]) of the body drawing from ``rng`` (None: of the body that turned
        last), without drawing: None before its first turn; the known values when both are
        known.
        """
        if not self._unknown:
            return self._known
        got = self._draws.get(None if rng is None else id(rng))
        return None if got is None else (got[1], got[2])

    @property
    def drawn_factor(self) -> float | None:
        """The factor f of the body that turned last (None before any turn unless known)."""
        d = self.drawn()
        return None if d is None else d[0]

    @property
    def drawn_offset_deg(self) -> float | None:
        """The offset b [deg] of the body that turned last (None before any turn unless
        known).
        """
        d = self.drawn()
        return None if d is None else d[1]

    def sample(self, rng, commanded_deg: float) -> float:
        """The actual turn [deg]: the base's draw on f·commanded + b."""
        f, b = self.draw(rng)
        return float(self.base.sample(rng, f * float(commanded_deg) + b))

    def sample_many(self, rng, commanded, n=None) -> np.ndarray:
        """Actual turns [deg]: the base's draws on f·commanded + b (f and b the same for all)."""
        c = _commands(commanded, n)
        f, b = self.draw(rng)
        return np.asarray(self.base.sample_many(rng, f * c + b), dtype=float)

    def __str__(self) -> str:
        return spec_text(str(self.base), scale=self.scale, bias_deg=self.bias_deg,
                         factor=self.factor, offset_deg=self.offset_deg)


def _with_turn_error(base: NoiseModel, *, factor: float | None = None,
                     offset_deg: float | None = None, scale: float = 0.0,
                     bias_deg: float = 0.0) -> NoiseModel:
    """``base`` wrapped in a :class:`ScaledNoise` unless f = 1 and b = 0 are known."""
    if (factor is None or factor == 1.0) and (offset_deg is None or offset_deg == 0.0) \
            and scale == 0 and bias_deg == 0:
        return base
    return ScaledNoise(base, factor, offset_deg, scale, bias_deg)


def parse_noise(text: str, delta_deg: float | None = None) -> NoiseModel:
    """A simulated body's noise model from a spec in the one grammar
    (:func:`planners.noise.parse_noise_spec`): ``none`` | ``gauss:SIGMA`` |
    ``model:eps=E,r=R`` (optionally ``,delta=D``; by default Δ is ``delta_deg``, the
    environment's 360°/K), each optionally followed by the turn keys: ``scale=S``,
    ``bias=B`` (the body draws f within 1 ± S and b within ±B once, at its first turn), the
    known ``factor=F``, ``offset=O`` (``none:factor=F``), or both (f within F ± S, b within
    O ± B), giving a :class:`ScaledNoise` (the
    plain model when f = 1 and b = 0 are known).

    Raises
    ------
    UserError
        One sentence naming the accepted forms.

    Examples
    --------
    >>> parse_noise("none:factor=0.92,offset=1")
    ScaledNoise(base=NoNoise(), factor=0.92, offset_deg=1.0, scale=0.0, bias_deg=0.0)
    >>> parse_noise("gauss:1,factor=1")
    GaussianNoise(sigma_deg=1.0)
    """
    spec = parse_noise_spec(text)
    scatter = spec.noise.scatter
    if spec.kind == "none":
        base: NoiseModel = NoNoise()
    elif spec.kind == "gauss":
        base = GaussianNoise(scatter.sigma_deg)
    else:
        base = body_noise(scatter, spec.delta_deg if spec.delta_deg is not None else delta_deg)
    return _with_turn_error(base, factor=spec.factor, offset_deg=spec.offset_deg,
                            scale=spec.noise.scale, bias_deg=spec.noise.bias_deg)


def body_noise(noise: TurnNoise, delta_deg: float | None) -> NoiseModel:
    """The noise model of a simulated body for a :class:`~planners.noise.TurnNoise`: exact
    turns, Gaussian σ, or the §11 model at the error quantum Δ = ``delta_deg`` [deg]; with a
    scale or bias, that model in a :class:`ScaledNoise` that draws f and b once per body.

    >>> body_noise(TurnNoise(sigma_deg=2, scale=0.1), None)
    ScaledNoise(base=GaussianNoise(sigma_deg=2.0), factor=None, offset_deg=None, scale=0.1, \
bias_deg=0.0)
    """
    if noise.has_body:
        scatter = replace(noise, body_sigma_deg=0.0, body_offset_deg=0.0, body_factor=1.0,
                          body_rest_deg=0.0)
        return BodyErrors(body_noise(scatter, delta_deg), noise.body_sigma_deg,
                          noise.body_offset_deg, noise.body_factor, noise.body_rest_deg)
    if not noise.unbiased:
        return _with_turn_error(body_noise(noise.scatter, delta_deg), scale=noise.scale,
                                bias_deg=noise.bias_deg)
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
    """The noise model of a :class:`planners.plan.PolicyMix` (its ε and r, §11, or its
    Gaussian σ, §11a) at Δ [deg].

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
    (its ``exact`` property, when it has one, says it never perturbs a turn; its
    ``needs_rng``, when it has one, whether it draws random numbers: a known turn factor
    perturbs every turn without them). ``rng`` is a numpy Generator, an int seed, or None. A
    body whose noise draws needs an rng: seeding is never implicit.

    >>> noise_and_rng(None, None)
    (NoNoise(), None)
    >>> noise_and_rng(GaussianNoise(2.0), None)          # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    envs.errors.UserError: a robot with rotation noise needs an rng (a numpy Generator or ...
    """
    noise = noise if noise is not None else NoNoise()
    if rng is None:
        if getattr(noise, "needs_rng", not getattr(noise, "exact", False)):   # any sampler
            raise UserError("a robot with rotation noise needs an rng (a numpy Generator or an "
                            "int seed).")
        return noise, None
    return noise, rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
