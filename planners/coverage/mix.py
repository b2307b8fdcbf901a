"""The policy mix: α = argmin ‖Aα − b‖₂ over the probability simplex (docs/model.md §16), and the
record of a designed mix, :class:`MixDesign`, which carries the :class:`PolicyMix` that
:func:`bouncesim.runs.execute.execute` runs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import minimize

from ..metrics import tv_distance
from ..noise import NoiseView, TurnNoise
from ..plan import PolicyMix

__all__ = ["MixFit", "MixDesign", "solve_mix"]


@dataclass(frozen=True)
class MixFit:
    """The best simplex mix of the columns of A for a target b (what :func:`solve_mix` gives).

    Attributes
    ----------
    alpha : ndarray (m,)
        Probabilities of the m angles (α ≥ 0, Σα = 1).
    residual : float
        ‖Aα − b‖₂, the Euclidean norm (not squared) of the mismatch.
    tv : float
        Total-variation distance ½‖Aα − b‖₁ between the mixed coverage and the target
        (both sum to 1).
    mixed : ndarray (n,)
        Aα.
    method : str
        ``"enumeration"`` (exact KKT over all supports) or ``"slsqp"``.
    """

    alpha: np.ndarray
    residual: float
    tv: float
    mixed: np.ndarray
    method: str


_ENUM_MAX = 12


def _kkt_on_support(G: np.ndarray, c: np.ndarray, S: np.ndarray) -> np.ndarray:
    """Minimiser of αᵀGα − 2cᵀα over {α_S : Σ α_S = 1} (α = 0 off S), by the KKT system."""
    k = S.size
    K = np.zeros((k + 1, k + 1))
    K[:k, :k] = G[np.ix_(S, S)]
    K[:k, k] = 1.0
    K[k, :k] = 1.0
    rhs = np.concatenate([c[S], [1.0]])
    sol = np.linalg.lstsq(K, rhs, rcond=None)[0]    # lstsq: G_SS may be singular
    return sol[:k]


def solve_mix(A: ArrayLike, b: ArrayLike) -> MixFit:
    """α = argmin ‖Aα − b‖₂ subject to α ≥ 0, Σα = 1.

    Parameters
    ----------
    A : array_like (n, m)
        Column i is the coverage (or limiting distribution) of angle i.
    b : array_like (n,)
        Target, same length as A's columns.

    Notes
    -----
    For m ≤ 12 the solution is exact: every support S ⊆ {1…m} is tried, the
    equality-constrained least squares on S is solved from its KKT system
    [[A_SᵀA_S, 1], [1ᵀ, 0]] [α_S; λ] = [A_Sᵀb; 1], infeasible candidates (some α_i < 0)
    are dropped, and the best feasible one is kept. The optimum's support is among those
    tried and, on it, the optimum solves the KKT system, so this finds the global minimum
    (at most 2¹² − 1 systems of size ≤ 13, computed from the m × m Gram matrix, so the
    cost does not grow with n beyond forming AᵀA). If A_S is rank deficient the minimum
    norm KKT solution is used; a smaller support then reaches the same value, so the
    optimum is still found. Ties go to the smaller support. For m > 12 scipy's SLSQP
    solves the same problem and the result is polished by the KKT solve on its support.

    >>> solve_mix([[1, 0], [0, 1]], [0.25, 0.75]).alpha.round(12).tolist()
    [0.25, 0.75]
    >>> solve_mix([[1, 0], [0, 1]], [1.5, -0.5]).alpha.tolist()   # clipped to a vertex
    [1.0, 0.0]
    """
    A = np.asarray(A, dtype=float)
    if A.ndim == 1:
        A = A[:, None]
    b = np.asarray(b, dtype=float).ravel()
    n, m = A.shape
    if b.shape != (n,):
        raise ValueError(f"the target has {b.size} entries, the columns of A have {n}.")
    if m == 0:
        raise ValueError("a policy mix needs at least one angle.")
    G = A.T @ A
    c = A.T @ b
    bb = float(b @ b)

    def obj(al):
        return float(al @ G @ al - 2 * c @ al + bb)

    scale = max(bb, float(np.abs(G).max()), 1e-300)
    if m <= _ENUM_MAX:
        best, best_val = None, np.inf
        masks = sorted(range(1, 2 ** m), key=lambda s: (bin(s).count("1"), s))
        idx = np.arange(m)
        for mask in masks:
            S = idx[(mask >> idx) & 1 == 1]
            aS = _kkt_on_support(G, c, S)
            if aS.min() < -1e-10:
                continue
            al = np.zeros(m)
            al[S] = np.clip(aS, 0.0, None)
            al /= al.sum()
            v = obj(al)
            if v < best_val - 1e-13 * scale:
                best, best_val = al, v
        alpha, method = best, "enumeration"
    else:
        res = minimize(obj, np.full(m, 1.0 / m), jac=lambda al: 2 * (G @ al - c),
                       method="SLSQP", bounds=[(0.0, 1.0)] * m,
                       constraints=[{"type": "eq", "fun": lambda al: al.sum() - 1.0,
                                     "jac": lambda al: np.ones_like(al)}],
                       options={"ftol": 1e-15, "maxiter": 1000})
        alpha = np.clip(res.x, 0.0, None)
        alpha /= alpha.sum()
        S = np.flatnonzero(alpha > 1e-9)
        aS = _kkt_on_support(G, c, S)
        if aS.min() >= 0:
            cand = np.zeros(m)
            cand[S] = aS / aS.sum()
            if obj(cand) <= obj(alpha):
                alpha = cand
        method = "slsqp"
    mixed = A @ alpha
    diff = mixed - b
    return MixFit(alpha=alpha, residual=float(np.linalg.norm(diff)),
                  tv=tv_distance(mixed, b, normalise=False), mixed=mixed, method=method)


@dataclass(frozen=True, eq=False)
class MixDesign(NoiseView):
    """A policy mix designed on a coverage model: per-angle coverage, target, α and the
    :class:`PolicyMix` to execute.

    Attributes
    ----------
    model : str                   the model's registry name
    angles : tuple of float       bouncing angles [deg]
    noise : TurnNoise             rotation noise (ε, r) the predictions assume
    space : str                   "positions" (A's columns are q) or "configurations" (π)
    per_angle : tuple of AngleCoverage
    target : ndarray              b over the space (sums to 1)
    alpha : ndarray (m,)          the mix (α ≥ 0, Σα = 1)
    residual : float              ‖Aα − b‖₂ (2-norm, not squared)
    tv : float                    ½‖Aα − b‖₁, the promised TV to the target
    mixed : ndarray               Aα over the space (for a horizon: q_T(α), as executed)
    method : str                  the solver (see :func:`solve_mix`; "slsqp-horizon" when a
                                  horizon with epochs made the fit non-linear)
    horizon : int or None         T [steps] the mix was designed for (docs/model.md §20);
                                  None: the limit
    epoch : int or None           steps per epoch the horizon fit assumed (None: one angle
                                  per run, linear in α)
    columns : ndarray or None     (P, m) the angles' coverage over the horizon (A's columns)
    convergence : dict or None    horizon fit with epochs: iterations, projected gradient
                                  norm, objective, SLSQP status and message
    """

    model: str
    angles: tuple
    noise: TurnNoise
    space: str
    per_angle: tuple
    target: np.ndarray
    alpha: np.ndarray
    residual: float
    tv: float
    mixed: np.ndarray
    method: str
    horizon: int | None = None
    epoch: int | None = None
    columns: np.ndarray | None = None
    convergence: dict | None = None

    @property
    def mix(self) -> PolicyMix:
        """The designed mix as the executor takes it (angles, α and the noise designed for:
        ε, r, σ).
        """
        return PolicyMix(self.angles, tuple(self.alpha.tolist()), self.noise.eps_deg,
                         self.noise.r, self.noise.sigma_deg)

    @property
    def A(self) -> np.ndarray:
        """The matrix the mix was fitted on: one column per angle (q, q_T or π)."""
        if self.columns is not None:
            return self.columns
        cols = [a.q if self.space == "positions" else a.pi for a in self.per_angle]
        return np.column_stack(cols)

    def mixed_q(self) -> np.ndarray:
        """Mixed coverage over position cells, Σ α_i q_i (for a horizon: q_T(α))."""
        if self.horizon is not None:
            return self.mixed
        return np.column_stack([a.q for a in self.per_angle]) @ self.alpha
