"""The rotation noise of a bump turn (docs/model.md §7, §18), validated once and shared by every
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

Gaussian turn noise (docs/model.md §18): the turn is φ + N(0, σ²), on the K grid the Gaussian
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
bodies of :mod:`bouncesim.robots.noise`): :func:`parse_noise_spec`.

>>> parse_noise_spec("model:eps=5,r=0.8")
NoiseSpec(kind='model', noise=TurnNoise(eps_deg=5.0, r=0.8, sigma_deg=0.0), delta_deg=None)
>>> parse_noise_spec("gauss:sigma=2").noise, parse_noise_spec("off").kind
(TurnNoise(eps_deg=0.0, r=1.0, sigma_deg=2.0), 'none')
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy.special import ndtr, ndtri

from envs import UserError

from .cells import angle_steps

__all__ = ["NOISE_FORMS", "NoiseSpec", "NoiseView", "R_RESOLUTION", "TurnNoise",
           "as_commands", "parse_noise_spec"]


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

GAUSS_TAIL = 1e-6
"""Gaussian noise on the K grid: offsets are kept out to the smallest ±M whose two tails
beyond (M + ½)Δ hold at most this much probability; the kept ones are renormalised."""


@dataclass(frozen=True)
class TurnNoise:
    """docs/model.md §7 rotation noise: exact with probability ``r``, else off by a uniform non-zero
    multiple of Δ within ±``eps_deg``; or, with ``sigma_deg`` > 0, the Gaussian noise of
    docs/model.md §18 (:meth:`gauss`).

    Parameters
    ----------
    eps_deg : float   error range ε [deg], non-negative (a multiple of Δ where it is used)
    r : float         reliability in [0, 1]: probability of turning by exactly φ
    sigma_deg : float standard deviation σ [deg] of a Gaussian turn error (default 0: none);
                      σ > 0 requires ε = 0 and r = 1 (one noise kind at a time)

    Bad values raise a one-sentence :class:`envs.UserError` here, once; whether ε is a
    multiple of Δ = 360°/K is checked where K is known (:meth:`quanta`).
    """

    eps_deg: float = 0.0
    r: float = 1.0
    sigma_deg: float = 0.0

    @classmethod
    def gauss(cls, sigma_deg: float) -> "TurnNoise":
        """Gaussian turn noise: the turn is φ + N(0, σ²) [deg] (docs/model.md §18)."""
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
        return spec.noise

    def __post_init__(self) -> None:
        for name, what in (("eps_deg", "error range eps"), ("r", "reliability r"),
                           ("sigma_deg", "Gaussian noise sigma")):
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

    @property
    def exact(self) -> bool:
        """True when no turn is ever perturbed (σ = 0, and ε = 0 or r = 1)."""
        return self.sigma_deg == 0 and (self.eps_deg == 0 or self.r == 1.0)

    @property
    def gaussian(self) -> bool:
        """True for Gaussian noise (σ > 0): headings leave the Δ grid (docs/model.md §18)."""
        return self.sigma_deg > 0

    def __str__(self) -> str:
        if self.gaussian:
            return f"gauss:{_fmt(self.sigma_deg)}"
        return "none" if self.exact else f"model:eps={_fmt(self.eps_deg)},r={_fmt(self.r)}"

    # ------------------------------------------------------------------ support over K
    def quanta(self, K: int | None = None, *, delta_deg: float | None = None) -> int:
        """ε / Δ at K orientations (Δ = 360°/K), or for an error quantum ``delta_deg`` [deg]
        (UserError unless ε is a whole multiple of Δ, below 360° for K).
        """
        if K is not None:
            return angle_steps(self.eps_deg, K, what="error range eps", allow_zero=True)
        if delta_deg is None:
            raise TypeError("quanta() needs K or delta_deg.")
        return _quanta_of(self.eps_deg, delta_deg)

    def support(self, K: int | None = None, *, delta_deg: float | None = None
                ) -> tuple[np.ndarray, np.ndarray]:
        """Offsets δ/Δ = −ε/Δ … ε/Δ [quanta] and their probabilities (sum 1), at K
        orientations or for the quantum ``delta_deg`` (see :meth:`quanta`).

        Zero-probability offsets (r = 1 with ε > 0, or r = 0) are kept. Gaussian noise: the
        discretised Gaussian of docs/model.md §18 (offsets ±M, tails beyond ±(M + ½)Δ of at
        most :data:`GAUSS_TAIL` dropped and the rest renormalised).
        """
        if self.gaussian:
            delta = 360.0 / K if K is not None else delta_deg
            if delta is None:
                raise TypeError("support() needs K or delta_deg.")
            return _gauss_support(self.sigma_deg, float(delta))
        return _support(self.quanta(K, delta_deg=delta_deg), self.r)

    def turns(self, K: int, angle_deg: float, positive: bool = False
              ) -> tuple[np.ndarray, np.ndarray]:
        """Turns of one bump commanded as ``angle_deg`` (a multiple of Δ in (0°, 360°)):
        (φ + δ)/Δ mod K [orientation steps] and their probabilities, one per offset of
        :meth:`support`; with ``positive`` only those with positive probability.
        """
        s = angle_steps(angle_deg, K)
        d, p = self.support(K)
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
        multiple of it.
        """
        c = as_commands(commanded_deg, n)
        if self.gaussian:
            return c + rng.normal(0.0, self.sigma_deg, size=c.shape)
        m = self.quanta(delta_deg=delta_deg)
        if m == 0 or self.r == 1.0:
            return c
        size = c.shape
        wrong = rng.random(size) >= self.r
        k = rng.integers(1, m + 1, size=size)
        sign = np.where(rng.random(size) < 0.5, -1, 1)
        return c + np.where(wrong, sign * k * delta_deg, 0.0)


def _support(m: int, r: float) -> tuple[np.ndarray, np.ndarray]:
    if m == 0:
        return np.array([0]), np.array([1.0])
    d = np.arange(-m, m + 1)
    return d, np.where(d == 0, r, (1.0 - r) / (2 * m))


def _gauss_support(sigma: float, delta: float) -> tuple[np.ndarray, np.ndarray]:
    """Offsets −M … M [quanta] and Φ((j + ½)Δ/σ) − Φ((j − ½)Δ/σ), renormalised (§18)."""
    if not (math.isfinite(delta) and delta > 0):
        raise UserError(f"the noise quantum delta must be positive, got {delta:g}°.")
    z = -float(ndtri(GAUSS_TAIL / 2))                    # 2·(1 − Φ(z)) = GAUSS_TAIL
    m = max(0, math.ceil(z * sigma / delta - 0.5))
    m = min(m, 1_000_000)                                # wraps the circle many times
    d = np.arange(-m, m + 1)
    p = ndtr((d + 0.5) * delta / sigma) - ndtr((d - 0.5) * delta / sigma)
    return d, p / p.sum()


def _quanta_of(eps_deg: float, delta_deg: float) -> int:
    """ε / Δ for an arbitrary quantum Δ [deg] > 0 (UserError unless a whole number)."""
    if not (math.isfinite(delta_deg) and delta_deg > 0):
        raise UserError(f"the noise quantum delta must be positive, got {delta_deg:g}°.")
    m = eps_deg / delta_deg
    if abs(m - round(m)) > 1e-9 * max(1.0, m):
        raise UserError(f"error range eps = {eps_deg:g}° is not a multiple of the "
                        f"orientation step {delta_deg:g}°.")
    return int(round(m))


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


NOISE_FORMS = "use none, gauss:SIGMA or model:eps=E,r=R (degrees)"
"""The accepted forms, as error messages name them."""


@dataclass(frozen=True)
class NoiseSpec:
    """A parsed noise spec (:func:`parse_noise_spec`).

    Attributes
    ----------
    kind : str            ``"none"``, ``"gauss"`` or ``"model"`` (the word the spec used)
    noise : TurnNoise     the turn noise
    delta_deg : float or None
        ``model`` only: the error quantum Δ [deg] the spec sets (``delta=D``); None: the
        environment's 360°/K
    """

    kind: str
    noise: TurnNoise
    delta_deg: float | None = None


_KINDS = {"": "none", "none": "none", "off": "none", "exact": "none",
          "gauss": "gauss", "gaussian": "gauss", "normal": "gauss",
          "model": "model", "stepped": "model"}


def parse_noise_spec(text) -> NoiseSpec:
    """A noise spec in the one grammar, parsed (case and spaces ignored).


    - ``none`` (also ``off``, ``exact`` or empty): exact turns;
    - ``gauss:SIGMA`` (also ``gauss:sigma=SIGMA``; ``gaussian``, ``normal``): Gaussian turn
      noise N(0, σ²) [deg] (docs/model.md §18);
    - ``model:eps=E,r=R`` (also ``stepped:``), optionally ``,delta=D``: the §7 model with
      error range ε [deg] and reliability r; D [deg] sets a simulated body's error quantum
      (default: the environment's Δ = 360°/K).

    Raises :class:`envs.UserError` (one sentence naming the accepted forms) on anything else.
    """
    s = str(text).strip().lower().replace(" ", "")
    word, colon, rest = s.partition(":")
    kind = _KINDS.get(word)
    if kind is None or (kind == "none" and colon):
        raise UserError(f"unknown noise {text!r}; {NOISE_FORMS}.")
    if kind == "none":
        return NoiseSpec("none", TurnNoise())
    if kind == "gauss":
        try:
            sigma = float(rest.removeprefix("sigma="))
        except ValueError:
            raise UserError(f"noise {text!r} needs a number of degrees after '{word}:'; "
                            f"{NOISE_FORMS}.") from None
        return NoiseSpec("gauss", TurnNoise.gauss(sigma))
    params: dict = {}
    for tok in rest.split(","):
        key, eq, val = tok.partition("=")
        if not eq or key not in {"eps", "r", "delta"} or key in params:
            raise UserError(f"noise {text!r} is not understood; {NOISE_FORMS}.")
        try:
            params[key] = float(val)
        except ValueError:
            raise UserError(f"noise parameter {key} in {text!r} is not a number.") from None
    if not {"eps", "r"} <= set(params):
        raise UserError(f"noise {text!r} needs both eps and r; {NOISE_FORMS}.")
    delta = params.get("delta")
    if delta is not None and not (math.isfinite(delta) and delta > 0):
        raise UserError(f"the noise quantum delta must be positive, got {delta:g}°.")
    return NoiseSpec("model", TurnNoise(params["eps"], params["r"]), delta)
