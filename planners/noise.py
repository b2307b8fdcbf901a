"""The rotation noise of a bump turn (docs/model.md §11, §11a), validated once and shared by every
model.

A bump turn commanded as φ is exact with probability r; otherwise it is off by δ, drawn
uniformly from the non-zero multiples of Δ = 360°/K in [−ε, ε]: each of the 2ε/Δ values has
probability (1 − r)/(2ε/Δ). ε = 0 means exact turns whatever r is. If φ + δ ≡ 0 (mod 360°)
the robot keeps its heading and bumps again at once (a valid self-loop); if 2ε ≥ 360° several
δ reach the same heading and their probabilities add up where the models build matrices.

>>> noise = TurnNoise(eps_deg=45, r=0.5)
>>> noise.support(8)                       # offsets in orientation steps, probabilities
(array([-1,  0,  1]), array([0.25, 0.5 , 0.25]))
>>> noise.turns(8, 90)                     # a 90° bump at K = 8: 1, 2 or 3 steps CCW
(array([1, 2, 3]), array([0.25, 0.5 , 0.25]))
>>> TurnNoise(0, 0.8).turns(360, 30)       # ε = 0: r plays no role
(array([30]), array([1.]))
>>> sorted(set(TurnNoise(2, 0.0).sample(np.random.default_rng(1), 90.0, 1000,
...                                     delta_deg=1).tolist()))
[88.0, 89.0, 91.0, 92.0]

Gaussian turn noise (docs/model.md §11a): the turn is φ + N(0, σ²), on the K grid the Gaussian
integrated over each orientation bin, Φ((j + ½)Δ/σ) − Φ((j − ½)Δ/σ) for j steps:

>>> g = TurnNoise.gauss(1.0)
>>> d, p = g.support(360)                  # Δ = 1°: offsets −5 … 5
>>> d[[0, -1]].tolist(), p[5].round(4), p[6].round(4), g.exact, str(g)
([-5, 5], np.float64(0.3829), np.float64(0.2417), False, 'gauss:1')
>>> TurnNoise(-5, 0.8)
Traceback (most recent call last):
...
envs.errors.UserError: error range eps -5° must be non-negative.

One grammar for every noise spec (the CLI's ``--noise``, the coverage models, the simulated
bodies of :mod:`bouncesim.robots.noise`), with the turn keys a planner declares (an unknown
factor ``scale=S`` and offset ``bias=B``) or a simulated body knows (``factor=F``,
``offset=O``): :func:`parse_noise_spec`; the coverage models refuse ``scale`` and ``bias``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike

from envs import UserError

from .cells import angle_steps
from .measures import wrap180
from .turn_offsets import body_errors, gauss_support, quanta_of, spin_sign, stepped_support

__all__ = ["NOISE_FORMS", "NoiseSpec", "NoiseView", "R_RESOLUTION", "SCALE_MAX", "TURN_KEYS",
           "TurnNoise", "as_commands", "parse_noise_spec", "spec_text"]


def as_commands(commanded, n: int | None) -> np.ndarray:
    """Commanded turns [deg] as a float array: ``n`` copies of a scalar, or the array itself
    (whose length must then be ``n`` when ``n`` is given).
    """
    c = np.asarray(commanded, dtype=float)
    if n is not None:
        c = np.broadcast_to(c, (int(n),) if c.ndim == 0 else c.shape)
        if c.shape[0] != int(n):
            raise ValueError(f"n = {n} does not match {c.shape[0]} commands.")
    return np.array(c, dtype=float)


def _fmt(x: float) -> str:
    return f"{x:g}"


R_RESOLUTION = 1e-9
"""Reliabilities closer than this to 0 or 1 (but not equal) are refused."""

SCALE_MAX = 0.5
"""The half-range S of an unknown turn factor (``scale=S``) must lie in [0, SCALE_MAX)."""


@dataclass(frozen=True)
class TurnNoise:
    """docs/model.md §11 rotation noise: exact with probability ``r``, else off by a uniform
    non-zero multiple of Δ within ±``eps_deg``; or, with ``sigma_deg`` > 0, the Gaussian noise
    of docs/model.md §11a (:meth:`gauss`).

    Parameters
    ----------
    eps_deg : float   error range ε [deg], non-negative (a multiple of Δ where it is used)
    r : float         reliability in [0, 1]: probability of turning by exactly φ
    sigma_deg : float standard deviation σ [deg] of a Gaussian turn error (default 0: none);
                      σ > 0 requires ε = 0 and r = 1 (one noise kind at a time)
    scale : float     half-range S of the turn's constant factor f, unknown within 1 ± S for a
                      whole run (default 0: f = 1); S in [0, 0.5)
    bias_deg : float  half-range B [deg] of the turn's constant offset b, unknown within ±B for
                      a whole run (default 0: b = 0); B >= 0
    body_sigma_deg, body_offset_deg : float
                      the executing body's own turn errors, known (docs/model.md §11b): every
                      counter-clockwise spin also adds N(body_offset, body_sigma²) [deg], e.g.
                      MuJoCo's measured 1.26° short with 0.6° of scatter (:meth:`with_body`),
                      and a clockwise spin the mirror image (a body lags in the sense it
                      spins). Default 0: none. The coverage models use them; with either set,
                      headings leave the Δ grid as under Gaussian noise (:attr:`gaussian`).
    body_factor, body_rest_deg : float
                      the body's known turn factor F (default 1: a spin by ρ adds (F − 1)·ρ to
                      the error), and how much further [deg] it spins after a bump from rest
                      than after a flight (default 0; the event model's zero-length flights,
                      docs/model.md §11b, §17).

    A bump by φ spins the body by ρ = wrap180(φ), the shorter way (docs/model.md §21): a
    body's error on it has mean sign(ρ)·O + (F − 1)·ρ (:meth:`body_mean_deg`).

    A run turns by f·φ + b plus the scatter (ε, r or σ). Scale and bias are what a planner or
    filter declares (navigation); the coverage models assume an unbiased turn and refuse them
    (:meth:`support`, :meth:`turns`, :meth:`quanta`; :attr:`scatter` drops them). A
    simulated body draws f and b once per run (:class:`bouncesim.robots.noise.ScaledNoise`).

    Bad values raise a one-sentence :class:`envs.UserError` here, once; whether ε is a
    multiple of Δ = 360°/K is checked where K is known (:meth:`quanta`). The repr leaves out
    ``scale`` and ``bias_deg`` when they are 0.
    """

    eps_deg: float = 0.0
    r: float = 1.0
    sigma_deg: float = 0.0
    scale: float = 0.0
    bias_deg: float = 0.0
    body_sigma_deg: float = 0.0
    body_offset_deg: float = 0.0
    body_factor: float = 1.0
    body_rest_deg: float = 0.0

    @classmethod
    def gauss(cls, sigma_deg: float) -> "TurnNoise":
        """Gaussian turn noise: the turn is φ + N(0, σ²) [deg] (docs/model.md §11a)."""
        return cls(sigma_deg=sigma_deg)

    @classmethod
    def from_spec(cls, text: str) -> "TurnNoise":
        """The noise of a spec in the one grammar (:func:`parse_noise_spec`): ``none``,
        ``gauss:SIGMA`` or ``model:eps=E,r=R`` [deg]. A spec's own quantum (``delta=D``) is
        for a simulated body; a model's quantum is its Δ = 360°/K, so it is refused here.

        >>> TurnNoise.from_spec("gauss:3"), TurnNoise.from_spec("model:eps=5,r=0.8")
        (TurnNoise(eps_deg=0.0, r=1.0, sigma_deg=3.0), TurnNoise(eps_deg=5.0, r=0.8, sigma_deg=0.0))
        """
        spec = parse_noise_spec(text)
        if spec.delta_deg is not None:
            raise UserError(f"noise {text!r} sets delta, the error quantum of a simulated "
                            "body; a coverage model's quantum is its orientation step.")
        if spec.factor is not None or spec.offset_deg is not None:
            raise UserError(f"noise {text!r} sets factor or offset, a simulated body's known "
                            "turn error; a planner declares an unknown one with scale=S and "
                            "bias=B.")
        return spec.noise

    def __post_init__(self) -> None:
        for name, what in (("eps_deg", "error range eps"), ("r", "reliability r"),
                           ("sigma_deg", "Gaussian noise sigma"), ("scale", "turn scale"),
                           ("bias_deg", "turn bias"), ("body_sigma_deg", "the body's turn sigma"),
                           ("body_offset_deg", "the body's turn offset"),
                           ("body_factor", "the body's turn factor"),
                           ("body_rest_deg", "the body's turn after a bump from rest")):
            v = getattr(self, name)
            try:
                v = float(v)
            except (TypeError, ValueError):
                raise UserError(f"{what} must be a number, got {v!r}.") from None
            if not math.isfinite(v):
                raise UserError(f"{what} must be finite, got {v}.")
            object.__setattr__(self, name, v)
        if self.eps_deg < 0:
            raise UserError(f"error range eps {_fmt(self.eps_deg)}° must be non-negative.")
        if not 0.0 <= self.r <= 1.0:
            raise UserError(f"reliability r must lie in [0, 1], got {_fmt(self.r)}.")
        if 0.0 < min(self.r, 1.0 - self.r) < R_RESOLUTION:
            # a turn probability this small next to its complement joins persistent groups
            # by edges of no numerical weight: the chain's solves become singular
            raise UserError(f"reliability r must be 0, 1 or within [{R_RESOLUTION:g}, "
                            f"1 - {R_RESOLUTION:g}], got {_fmt(self.r)}.")
        if self.sigma_deg < 0:
            raise UserError(f"Gaussian noise sigma {_fmt(self.sigma_deg)}° must be "
                            f"non-negative.")
        if self.sigma_deg > 0 and (self.eps_deg != 0 or self.r != 1.0):
            raise UserError("Gaussian noise (sigma) cannot be combined with eps and r; "
                            "give one noise kind.")
        if not 0.0 <= self.scale < SCALE_MAX:
            raise UserError(f"turn scale S (the factor's unknown half-range) must lie in "
                            f"[0, {SCALE_MAX:g}), got {_fmt(self.scale)}.")
        if self.bias_deg < 0:
            raise UserError(f"turn bias B (the offset's unknown half-range) must be "
                            f"non-negative, got {_fmt(self.bias_deg)}°.")
        if self.body_sigma_deg < 0:
            raise UserError(f"the body's turn sigma must be non-negative, got "
                            f"{_fmt(self.body_sigma_deg)}°.")
        if not 0.5 < self.body_factor < 1.5:
            raise UserError(f"the body's turn factor must lie in (0.5, 1.5), got "
                            f"{_fmt(self.body_factor)}.")

    def with_body(self, errors: str | None, rest: str | None = None) -> "TurnNoise":
        """The noise with a body's own turn errors added (:attr:`body_sigma_deg`,
        :attr:`body_offset_deg`, :attr:`body_factor`), from the spec the body declares (its
        ``turn_errors``, ``gauss:S,offset=O(,factor=F)``;
        :func:`bouncesim.runs.feedback.body_turns`); None: unchanged. A declared ``bias=B``
        (how far the offset may be from O in another room or at another angle, which a
        feedback filter learns online) is not a turn error of the coverage chain: the chain
        takes the offset O (docs/model.md §11b).

        ``rest``: its errors after a bump from rest; :attr:`body_rest_deg` is the difference
        of the two offsets (the factor and scatter are those of ``errors``).

        >>> TurnNoise(5, 0.8).with_body("gauss:0.6,offset=-1.26")
        TurnNoise(eps_deg=5.0, r=0.8, sigma_deg=0.0, body_sigma_deg=0.6, body_offset_deg=-1.26)
        >>> TurnNoise(5, 0.8).with_body("gauss:0.6,offset=-1.26,bias=0.5").body_offset_deg
        -1.26
        >>> TurnNoise().with_body("gauss:0.6,offset=-1.1,factor=0.998", rest="gauss:0.3,"
        ...                       "offset=-0.4").body_rest_deg
        0.7
        """
        if errors is None:
            if rest is not None:
                raise UserError("a body's turns after a bump from rest need those after a flight.")
            return self
        spec, at_rest = self._body_spec(errors), self._body_spec(rest)
        offset = float(spec.offset_deg or 0.0)
        return replace(self, body_sigma_deg=float(spec.noise.sigma_deg),
                       body_offset_deg=offset,
                       body_factor=float(spec.factor if spec.factor is not None else 1.0),
                       body_rest_deg=0.0 if at_rest is None else
                       round(float(at_rest.offset_deg or 0.0) - offset, 10))

    @staticmethod
    def _body_spec(errors: str | None):
        if errors is None:
            return None
        spec = parse_noise_spec(errors)
        if spec.kind == "model" or spec.noise.scale:
            raise UserError(f"a body declares its turn errors as gauss:S,offset=O(,factor=F)"
                            f"(,bias=B), got {errors!r}.")
        return spec

    def body_mean_deg(self, angle_deg: float = 0.0) -> float:
        """The mean of the body's own error [deg] on a bump by ``angle_deg``: the body spins
        ρ = wrap180(φ), the shorter way, and lags in that sense, sign(ρ)·O + (F − 1)·ρ
        (:attr:`body_offset_deg`, :attr:`body_factor`; docs/model.md §11b).

        >>> TurnNoise(body_offset_deg=-1.0, body_factor=0.998).body_mean_deg(100)
        -1.2
        >>> TurnNoise(body_offset_deg=-1.0, body_factor=0.998).body_mean_deg(300)   # ρ = −60°
        1.12
        """
        rho = wrap180(float(angle_deg))
        return round(spin_sign(rho) * self.body_offset_deg + (self.body_factor - 1.0) * rho, 12)

    def rest_for(self, angles=None) -> float:
        """How much further [deg] the body spins after a bump from rest, on bumps by
        ``angles`` [deg]: :attr:`body_rest_deg` in the sense of their spins ρ = wrap180(φ)
        (docs/model.md §11b); None: a counter-clockwise spin's. Angles that spin both ways
        cannot share one value: a one-sentence UserError when the body has a rest turn.

        >>> n = TurnNoise(body_rest_deg=0.7)
        >>> n.rest_for([30, 75]), n.rest_for([315])
        (0.7, -0.7)
        """
        if angles is None or self.body_rest_deg == 0:
            return self.body_rest_deg
        senses = {spin_sign(wrap180(float(a))) for a in np.atleast_1d(angles)}
        if len(senses) > 1:
            raise UserError(f"a body's turns after a bump from rest differ by the sense of the "
                            f"spin; angles {sorted(float(a) for a in np.atleast_1d(angles))} "
                            f"spin both ways (the shorter way), so give them one at a time.")
        return senses.pop() * self.body_rest_deg

    @property
    def has_body(self) -> bool:
        """True when a body's own turn errors are added (:meth:`with_body`)."""
        return (self.body_sigma_deg > 0 or self.body_offset_deg != 0
                or self.body_factor != 1.0 or self.body_rest_deg != 0)

    def __repr__(self) -> str:
        extra = "".join(f", {name}={getattr(self, name)!r}" for name, default in (
            ("scale", 0), ("bias_deg", 0), ("body_sigma_deg", 0), ("body_offset_deg", 0),
            ("body_factor", 1), ("body_rest_deg", 0)) if getattr(self, name) != default)
        return (f"TurnNoise(eps_deg={self.eps_deg!r}, r={self.r!r}, "
                f"sigma_deg={self.sigma_deg!r}{extra})")

    @property
    def unbiased(self) -> bool:
        """True when the turn has no unknown scale or bias (S = B = 0)."""
        return self.scale == 0 and self.bias_deg == 0

    @property
    def scatter(self) -> "TurnNoise":
        """The scatter alone (ε, r or σ), without the scale and bias.

        >>> TurnNoise(5, 0.8, scale=0.1, bias_deg=2).scatter
        TurnNoise(eps_deg=5.0, r=0.8, sigma_deg=0.0)
        """
        return self if self.unbiased else replace(self, scale=0.0, bias_deg=0.0)

    @property
    def exact(self) -> bool:
        """True when no turn is ever perturbed (σ = 0, ε = 0 or r = 1, and S = B = 0)."""
        return self._scatter_exact and self.unbiased

    @property
    def _scatter_exact(self) -> bool:
        return self.sigma_deg == 0 and (self.eps_deg == 0 or self.r == 1.0) and not self.has_body

    def _refuse_bias(self) -> None:
        if not self.unbiased:
            raise UserError("the coverage models assume an unbiased turn; scale and bias are "
                            f"for navigation (got {self}).")

    @property
    def gaussian(self) -> bool:
        """True for Gaussian noise (σ > 0) or a body's own turn errors: headings leave the Δ
        grid (docs/model.md §11a, §11b).
        """
        return self.sigma_deg > 0 or self.has_body

    def __str__(self) -> str:
        if self.sigma_deg > 0:
            base = f"gauss:{_fmt(self.sigma_deg)}"
        else:
            base = ("none" if self.eps_deg == 0 or self.r == 1.0
                    else f"model:eps={_fmt(self.eps_deg)},r={_fmt(self.r)}")
        body = (f" + body gauss:{_fmt(self.body_sigma_deg)},offset={_fmt(self.body_offset_deg)}"
                + (f",factor={_fmt(self.body_factor)}" if self.body_factor != 1.0 else "")
                + (f",rest={_fmt(self.body_rest_deg)}" if self.body_rest_deg else "")
                if self.has_body else "")
        return spec_text(base, scale=self.scale, bias_deg=self.bias_deg) + body

    # ------------------------------------------------------------------ support over K
    def quanta(self, K: int | None = None, *, delta_deg: float | None = None) -> int:
        """ε / Δ at K orientations (Δ = 360°/K), or for an error quantum ``delta_deg`` [deg]
        (UserError unless ε is a whole multiple of Δ, below 360° for K; and with a scale or
        bias, which the coverage models do not model).
        """
        self._refuse_bias()
        if K is not None:
            return angle_steps(self.eps_deg, K, what="error range eps", allow_zero=True)
        if delta_deg is None:
            raise TypeError("quanta() needs K or delta_deg.")
        return quanta_of(self.eps_deg, delta_deg)

    def support(self, K: int | None = None, *, delta_deg: float | None = None,
                angle_deg: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """Offsets δ/Δ = −ε/Δ … ε/Δ [quanta] and their probabilities (sum 1), at K
        orientations or for the quantum ``delta_deg`` (see :meth:`quanta`).

        Zero-probability offsets (r = 1 with ε > 0, or r = 0) are kept. Gaussian noise: the
        discretised Gaussian of docs/model.md §11a (offsets ±M, tails beyond ±(M + ½)Δ of at
        most :data:`planners.turn_offsets.GAUSS_TAIL` dropped and the rest renormalised). A
        scale or bias is refused (UserError): the coverage models assume an unbiased turn. A
        body's own errors (:attr:`has_body`) are added with their mean at the turn
        ``angle_deg`` [deg] (:meth:`body_mean_deg`).
        """
        self._refuse_bias()
        delta = 360.0 / K if K is not None else delta_deg
        if self.sigma_deg > 0:
            if delta is None:
                raise TypeError("support() needs K or delta_deg.")
            d, p = gauss_support(self.sigma_deg, float(delta))
        else:
            d, p = stepped_support(self.quanta(K, delta_deg=delta_deg), self.r)
        if not self.has_body:
            return d, p
        db, pb = gauss_support(self.body_sigma_deg, float(delta), self.body_mean_deg(angle_deg))
        total = d[:, None] + db[None, :]
        m = int(np.abs(total).max())
        out = np.zeros(2 * m + 1)
        np.add.at(out, (total + m).ravel(), (p[:, None] * pb[None, :]).ravel())
        return np.arange(-m, m + 1), out

    def turns(self, K: int, angle_deg: float, positive: bool = False
              ) -> tuple[np.ndarray, np.ndarray]:
        """Turns of one bump commanded as ``angle_deg`` (a multiple of Δ in (0°, 360°)):
        (φ + δ)/Δ mod K [orientation steps] and their probabilities, one per offset of
        :meth:`support`; with ``positive`` only those with positive probability (a scale or
        bias is refused, as by :meth:`support`).
        """
        self._refuse_bias()
        s = angle_steps(angle_deg, K)
        d, p = self.support(K, angle_deg=angle_deg)
        steps = (s + d) % K
        if positive:
            keep = p > 0
            return steps[keep], p[keep]
        return steps, p

    # ------------------------------------------------------------------ sampling
    def sample(self, rng: np.random.Generator, commanded_deg: ArrayLike, n: int | None = None,
               *, delta_deg: float) -> np.ndarray:
        """Actual turns [deg] of commanded turns [deg]: ``n`` draws for a scalar command, or
        one per array element. Randomness comes only from ``rng``.

        ``delta_deg`` is the error quantum Δ [deg] (the environment's 360°/K); ε must be a
        multiple of it. A scale or bias is refused (UserError): the draws here are independent
        turns, while f and b are constant over a run (a simulated body draws them:
        :class:`bouncesim.robots.noise.ScaledNoise`).
        """
        if not self.unbiased:
            raise UserError(f"TurnNoise.sample draws independent turns, not a run's constant "
                            f"scale and bias (got {self}); sample the scatter or the body's "
                            f"noise model (bouncesim.robots.noise.parse_noise).")
        c = as_commands(commanded_deg, n)
        if self.has_body:               # the scatter, then the body's own error (BodyErrors)
            t = replace(self, body_sigma_deg=0.0, body_offset_deg=0.0, body_factor=1.0,
                        body_rest_deg=0.0).sample(rng, c, delta_deg=delta_deg)
            return t + body_errors(rng, c, t.shape, self.body_sigma_deg, self.body_offset_deg,
                                   self.body_factor)
        if self.sigma_deg > 0:
            return c + rng.normal(0.0, self.sigma_deg, size=c.shape)
        m = self.quanta(delta_deg=delta_deg)
        if m == 0 or self.r == 1.0:
            return c
        size = c.shape
        wrong = rng.random(size) >= self.r
        k = rng.integers(1, m + 1, size=size)
        sign = np.where(rng.random(size) < 0.5, -1, 1)
        return c + np.where(wrong, sign * k * delta_deg, 0.0)


class NoiseView:
    """``eps`` and ``r`` of a record that holds its rotation noise as ``noise``."""

    noise: TurnNoise

    @property
    def eps(self) -> float:
        """Error range ε of the rotation noise [deg]."""
        return self.noise.eps_deg

    @property
    def r(self) -> float:
        """Reliability r of the rotation noise (probability of an exact turn)."""
        return self.noise.r


TURN_KEYS = ("scale", "bias", "factor", "offset")
"""The keys every kind of noise spec takes after its own (:func:`parse_noise_spec`)."""

NOISE_FORMS = ("use none, gauss:SIGMA or model:eps=E,r=R (degrees), each optionally followed "
               "by scale=S,bias=B (a turn factor unknown within 1 ± S, 0 <= S < 0.5, and an "
               "offset unknown within ±B degrees) and factor=F,offset=O (known ones, or the "
               "centres of those ranges), e.g. gauss:2,scale=0.1 or none:factor=1.08")
"""The accepted forms, as error messages name them."""


def spec_text(base: str, *, scale: float = 0.0, bias_deg: float = 0.0,
              factor: float | None = None, offset_deg: float | None = None) -> str:
    """A noise spec's text: ``base`` (``none``, ``gauss:SIGMA`` or ``model:eps=E,r=R``) with
    the turn keys that are set (non-zero scale and bias, given factor and offset).

    >>> spec_text("gauss:2", scale=0.1), spec_text("none", factor=0.92, offset_deg=1)
    ('gauss:2,scale=0.1', 'none:factor=0.92,offset=1')
    """
    keys = [f"{k}={_fmt(v)}" for k, v, use in (
        ("scale", scale, scale != 0), ("bias", bias_deg, bias_deg != 0),
        ("factor", factor, factor is not None), ("offset", offset_deg, offset_deg is not None))
        if use]
    if not keys:
        return base
    return base + (":" if ":" not in base else ",") + ",".join(keys)


@dataclass(frozen=True)
class NoiseSpec:
    """A parsed noise spec (:func:`parse_noise_spec`).

    Attributes
    ----------
    kind : str            ``"none"``, ``"gauss"`` or ``"model"`` (the word the spec used)
    noise : TurnNoise     the turn noise (with the declared ``scale`` and ``bias_deg``)
    delta_deg : float or None
        ``model`` only: the error quantum Δ [deg] the spec sets (``delta=D``); None: the
        environment's 360°/K
    factor : float or None
        A simulated body's known turn factor F (``factor=F``); None: none given (1, or
        unknown within the noise's scale)
    offset_deg : float or None
        A simulated body's known turn offset O [deg] (``offset=O``); None: none given

    The repr leaves out ``factor`` and ``offset_deg`` when they are None; ``str()`` is the
    spec in the grammar.
    """

    kind: str
    noise: TurnNoise
    delta_deg: float | None = None
    factor: float | None = None
    offset_deg: float | None = None

    def __repr__(self) -> str:
        extra = "".join(f", {name}={getattr(self, name)!r}" for name in ("factor", "offset_deg")
                        if getattr(self, name) is not None)
        return (f"NoiseSpec(kind={self.kind!r}, noise={self.noise!r}, "
                f"delta_deg={self.delta_deg!r}{extra})")

    def __str__(self) -> str:
        n = self.noise
        if self.kind == "model":
            base = f"model:eps={_fmt(n.eps_deg)},r={_fmt(n.r)}"
            if self.delta_deg is not None:
                base += f",delta={_fmt(self.delta_deg)}"
        elif self.kind == "gauss":
            base = f"gauss:{_fmt(n.sigma_deg)}"
        else:
            base = "none"
        return spec_text(base, scale=n.scale, bias_deg=n.bias_deg, factor=self.factor,
                         offset_deg=self.offset_deg)


_KINDS = {"": "none", "none": "none", "off": "none", "exact": "none",
          "gauss": "gauss", "gaussian": "gauss", "normal": "gauss",
          "model": "model", "stepped": "model"}

_OWN_KEYS = {"none": (), "gauss": ("sigma",), "model": ("eps", "r", "delta")}


def parse_noise_spec(text) -> NoiseSpec:
    """A noise spec in the one grammar, parsed (case and spaces ignored).

    - ``none`` (also ``off``, ``exact`` or empty): exact turns;
    - ``gauss:SIGMA`` (also ``gauss:sigma=SIGMA``; ``gaussian``, ``normal``): Gaussian turn
      noise N(0, σ²) [deg] (docs/model.md §11a);
    - ``model:eps=E,r=R`` (also ``stepped:``), optionally ``,delta=D``: the §11 model with
      error range ε [deg] and reliability r; D [deg] sets a simulated body's error quantum
      (default: the environment's Δ = 360°/K).

    Every kind then takes the turn keys (:data:`TURN_KEYS`), comma-separated after its own
    (keys in any order; ``none`` takes them after a colon or a comma: ``none:factor=1.08``,
    ``none,factor=1.08``): ``scale=S`` (the turn's constant factor f unknown within 1 ± S,
    0 <= S < 0.5) and ``bias=B`` (its constant offset b unknown within ±B [deg], B >= 0), in
    :attr:`NoiseSpec.noise`; and a known ``factor=F`` (F > 0) and ``offset=O`` [deg], in
    :attr:`NoiseSpec.factor` and :attr:`NoiseSpec.offset_deg`. Given together, F and O are
    the centres of the unknown ranges: f within F ± S, b within O ± B (a body that declares
    its turns ``gauss:0.55,offset=-0.77,bias=0.5``: 0.77° short, give or take 0.5°). E.g.
    ``gauss:2,scale=0.1``, ``gauss:sigma=2,scale=0.1,bias=1``,
    ``model:eps=5,r=0.8,scale=0.05``, ``gauss:0,factor=1.08``.

    Raises :class:`envs.UserError` (one sentence naming the accepted forms) on anything else.

    >>> parse_noise_spec("model:eps=5,r=0.8,delta=1,bias=2,factor=0.92")
    NoiseSpec(kind='model', noise=TurnNoise(eps_deg=5.0, r=0.8, sigma_deg=0.0, bias_deg=2.0), \
delta_deg=1.0, factor=0.92)
    >>> parse_noise_spec("gauss:0.55,offset=-0.77,bias=0.5")
    NoiseSpec(kind='gauss', noise=TurnNoise(eps_deg=0.0, r=1.0, sigma_deg=0.55, bias_deg=0.5), \
delta_deg=None, offset_deg=-0.77)
    """
    s = str(text).strip().lower().replace(" ", "")
    cut = min((i for i in (s.find(":"), s.find(",")) if i >= 0), default=len(s))
    word, sep, rest = s[:cut], s[cut:cut + 1], s[cut + 1:]
    kind = _KINDS.get(word)
    if kind is None or (sep == "," and kind != "none") or \
            (kind == "none" and sep and not (word and rest)):
        raise UserError(f"unknown noise {text!r}; {NOISE_FORMS}.")
    allowed = _OWN_KEYS[kind] + TURN_KEYS
    params: dict = {}
    for i, tok in enumerate(rest.split(",") if (rest or kind != "none") else ()):
        key, eq, val = tok.partition("=")
        if not eq and kind == "gauss" and i == 0:
            key, val = "sigma", tok                       # gauss:SIGMA
        elif not eq or key not in allowed:
            raise UserError(f"noise {text!r} is not understood; {NOISE_FORMS}.")
        if key in params:
            raise UserError(f"noise {text!r} gives {key} twice; {NOISE_FORMS}.")
        try:
            params[key] = float(val)
        except ValueError:
            if key == "sigma":
                raise UserError(f"noise {text!r} needs a number of degrees after '{word}:'; "
                                f"{NOISE_FORMS}.") from None
            raise UserError(f"noise parameter {key} in {text!r} is not a number; "
                            f"{NOISE_FORMS}.") from None
    if kind == "gauss" and "sigma" not in params:
        raise UserError(f"noise {text!r} needs a number of degrees after '{word}:'; "
                        f"{NOISE_FORMS}.")
    if kind == "model" and not {"eps", "r"} <= set(params):
        raise UserError(f"noise {text!r} needs both eps and r; {NOISE_FORMS}.")
    delta = params.get("delta")
    if delta is not None and not (math.isfinite(delta) and delta > 0):
        raise UserError(f"the noise quantum delta must be positive, got {delta:g}°.")
    scale, bias = params.get("scale", 0.0), params.get("bias", 0.0)
    if not 0.0 <= scale < SCALE_MAX:
        raise UserError(f"the turn scale S must lie in [0, {SCALE_MAX:g}), got {scale:g}; "
                        f"{NOISE_FORMS}.")
    if not (math.isfinite(bias) and bias >= 0):
        raise UserError(f"the turn bias B must be a non-negative number of degrees, got "
                        f"{bias:g}; {NOISE_FORMS}.")
    factor, offset = params.get("factor"), params.get("offset")
    if factor is not None and not (math.isfinite(factor) and factor > 0):
        raise UserError(f"the turn factor F must be a positive number, got {factor:g}; "
                        f"{NOISE_FORMS}.")
    if offset is not None and not math.isfinite(offset):
        raise UserError(f"the turn offset O must be a finite number of degrees, got "
                        f"{offset:g}; {NOISE_FORMS}.")
    noise = TurnNoise(params.get("eps", 0.0), params.get("r", 1.0), params.get("sigma", 0.0),
                      scale, bias)
    return NoiseSpec(kind, noise, delta, factor, offset)
