"""Coverage by bouncing policies: the paper's Algorithm 3 (docs/model.md §7).

For one bouncing angle φ, error range ε and reliability r the robot's motion over the N
configuration cells is a Markov chain: a forward cell moves to its step-table successor with
probability 1; a bump cell (p, k) turns to orientation k + (φ + δ)/Δ with probability r for
δ = 0 and (1 − r)/(2ε/Δ) for each δ ∈ {−ε, …, −Δ, Δ, …, ε} (ε = 0: δ = 0 surely).
If φ + δ ≡ 0 (mod 360°) the robot keeps its heading and bumps again at once: that is a valid
transition from the bump cell to itself (a self-loop), not an error. When 2ε ≥ 360° some
headings are reached by several δ; their probabilities add up.

- :func:`bump_turns`: the orientation offsets and probabilities of one bump.
- :func:`transition_matrix`: the sparse N × N chain of one angle (CSR, built with numpy
  index arithmetic).
- :func:`analyse_angle`: persistent groups, limiting distribution π and coverage q (π summed
  over orientations) of one angle, as an :class:`AngleCoverage` record.
- :func:`solve_mix`: the policy mix α = argmin ‖Aα − b‖ over the probability simplex.
- :func:`uniform_target`, :func:`load_target`: the target b over position or configuration
  cells.
- :func:`coverage_pipeline`: all angles, the mix and the target in one
  :class:`CoverageResult`.

Examples
--------
A 1 × 3 corridor at K = 4 with φ = 180°: facing east or west the robot shuttles along the
corridor forever (one periodic group of 6 configurations); facing north or south it bumps at
once and flips between north and south in its cell (three groups of 2). Every configuration
is persistent and each cell is covered a third of the time:

>>> from envs import Environment
>>> from planners.cells import CellSpace
>>> env = Environment.from_dict({"boundary": [[0, 0], [1.02, 0], [1.02, 0.34], [0, 0.34]],
...                              "robot_radius": 0.17,
...                              "discretization": {"cell_size": 0.34, "orientations": 4}})
>>> res = analyse_angle(CellSpace(env), 180)
>>> res.analysis.group_sizes.tolist(), res.q.round(4).tolist()
([6, 2, 2, 2], [0.3333, 0.3333, 0.3333])
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from envs import UserError

from .cells import CellSpace, angle_steps
from .markov import ChainAnalysis, analyse_chain, analyse_run_chain

__all__ = ["AngleCoverage", "ChainSummary", "MixResult", "CoverageResult", "TargetError",
           "bump_turns", "transition_matrix", "analyse_angle", "solve_mix", "uniform_target",
           "load_target", "coverage_pipeline", "check_reliability", "tv_distance"]

SPACES = ("positions", "configurations")


class TargetError(UserError):
    """A coverage target that cannot be used (unreadable, negative, zero sum, wrong size)."""


# ---------------------------------------------------------------------------- the chain
def check_reliability(r: float) -> float:
    """Return r as float after checking 0 <= r <= 1 (UserError otherwise)."""
    try:
        rf = float(r)
    except (TypeError, ValueError):
        raise UserError(f"reliability r must be a number in [0, 1], got {r!r}.") from None
    if not (0.0 <= rf <= 1.0):
        raise UserError(f"reliability r must lie in [0, 1], got {r}.")
    return rf


def bump_turns(K: int, angle_deg: float, eps_deg: float = 0.0, r: float = 1.0
               ) -> tuple[np.ndarray, np.ndarray]:
    """Orientation offsets and probabilities of one bump (docs/model.md §7).

    Parameters
    ----------
    K : int
        Orientations (Δ = 360°/K).
    angle_deg : float
        Bouncing angle φ [deg], a multiple of Δ in (0°, 360°).
    eps_deg : float
        Error range ε [deg], a multiple of Δ (0 allowed).
    r : float
        Reliability in [0, 1]: probability of turning by exactly φ.

    Returns
    -------
    steps : ndarray of int
        Turn in orientation steps, (φ + δ)/Δ mod K, one per δ = −ε … ε (Δ apart).
    probs : ndarray of float
        Their probabilities (sum 1). Zero-probability turns (r = 1 with ε > 0, or r = 0) are
        kept here and dropped by :func:`transition_matrix`.

    >>> bump_turns(8, 90, 45, 0.5)
    (array([1, 2, 3]), array([0.25, 0.5 , 0.25]))
    >>> bump_turns(360, 30, 0, 0.8)           # ε = 0: r plays no role
    (array([30]), array([1.]))
    """
    s = angle_steps(angle_deg, K)
    e = angle_steps(eps_deg, K, what="error range eps", allow_zero=True)
    r = check_reliability(r)
    if e == 0:
        return np.array([s % K]), np.array([1.0])
    d = np.arange(-e, e + 1)
    probs = np.where(d == 0, r, (1.0 - r) / (2 * e))
    return (s + d) % K, probs


def transition_matrix(cs: CellSpace, angle_deg: float, eps_deg: float = 0.0,
                      r: float = 1.0) -> sp.csr_matrix:
    """The N × N transition matrix of one bouncing angle (CSR, rows sum to 1).

    Forward cells have one entry 1 at their step-table successor; a bump cell (p, k) has an
    entry at (p, k + turn) for every turn of :func:`bump_turns` with positive probability
    (duplicates summed). Built with numpy index arithmetic, no per-cell loop.
    """
    steps, probs = bump_turns(cs.K, angle_deg, eps_deg, r)
    keep = probs > 0
    steps, probs = steps[keep], probs[keep]
    fwd = cs.forward
    N, P, K = cs.N, cs.P, cs.K
    bump = fwd < 0
    z = np.arange(N)
    p, k = z % P, z // P
    nper = np.where(bump, steps.size, 1)
    indptr = np.concatenate([[0], np.cumsum(nper)])
    cols = np.empty(indptr[-1], dtype=np.int64)
    vals = np.empty(indptr[-1])
    fwd_pos = indptr[:-1][~bump]
    cols[fwd_pos] = fwd[~bump]
    vals[fwd_pos] = 1.0
    bstart = indptr[:-1][bump]
    bcols = ((k[bump, None] + steps[None, :]) % K) * P + p[bump, None]
    pos = bstart[:, None] + np.arange(steps.size)[None, :]
    cols[pos] = bcols
    vals[pos] = probs[None, :]
    M = sp.csr_matrix((vals, cols, indptr), shape=(N, N))
    M.sum_duplicates()          # turns that land on the same heading (2ε >= 360°)
    return M


class ChainSummary:
    """Read-only views of a coverage record's ``analysis`` (a ChainAnalysis) and its
    ``angle``, shared by every coverage model's per-angle record."""

    @property
    def groups(self) -> tuple:
        return self.analysis.groups

    @property
    def group_sizes(self) -> np.ndarray:
        return self.analysis.group_sizes

    @property
    def transient_fraction(self) -> float:
        return self.analysis.transient_fraction

    def summary(self) -> dict:
        """JSON-ready numbers: groups, their sizes and weights, transient fraction."""
        return {"angle": _num(self.angle), "persistent_groups": self.analysis.n_groups,
                "group_sizes": [int(s) for s in self.group_sizes],
                "group_weights": [float(a) for a in self.analysis.absorption],
                "transient_fraction": float(self.transient_fraction)}


@dataclass(frozen=True, eq=False)
class AngleCoverage(ChainSummary):
    """Long-run behaviour of one bouncing angle.

    Attributes
    ----------
    angle, eps : float     bouncing angle φ and error range ε [deg]
    r : float              reliability
    analysis : ChainAnalysis
        Persistent groups, absorption weights, limiting distribution π over the N
        configurations (see :mod:`planners.markov`).
    q : ndarray (P,)
        Coverage: π summed over orientations, one probability per position cell.
    """

    angle: float
    eps: float
    r: float
    analysis: ChainAnalysis
    q: np.ndarray

    @property
    def pi(self) -> np.ndarray:
        return self.analysis.pi


def analyse_angle(cs: CellSpace, angle_deg: float, eps_deg: float = 0.0, r: float = 1.0,
                  method: str = "runs") -> AngleCoverage:
    """Persistent groups, limiting distribution and coverage of one bouncing angle.

    Parameters
    ----------
    cs : CellSpace
    angle_deg, eps_deg : float
        Bouncing angle φ and error range ε [deg], multiples of Δ = 360°/K.
    r : float
        Reliability in [0, 1].
    method : {"runs", "matrix"}
        ``"runs"`` (default) solves the chain censored to the bump cells and expands it
        exactly along the forward runs (:func:`planners.markov.analyse_run_chain`);
        ``"matrix"`` analyses the full N × N matrix (:func:`planners.markov.analyse_chain`).
        Both give the same numbers; "runs" is several times faster on fine grids.
    """
    steps, probs = bump_turns(cs.K, angle_deg, eps_deg, r)
    if method == "matrix":
        res = analyse_chain(transition_matrix(cs, angle_deg, eps_deg, r))
    elif method == "runs":
        res = analyse_run_chain(cs.forward, _bump_matrix(cs, steps, probs))
    else:
        raise ValueError(f"method must be 'runs' or 'matrix', got {method!r}.")
    q = res.pi.reshape(cs.K, cs.P).sum(axis=0)
    return AngleCoverage(angle=float(angle_deg), eps=float(eps_deg), r=float(r), analysis=res,
                         q=q)


def _bump_matrix(cs: CellSpace, steps: np.ndarray, probs: np.ndarray) -> sp.csr_matrix:
    """Rows of the bump cells only (other rows empty): what analyse_run_chain needs."""
    keep = probs > 0
    steps, probs = steps[keep], probs[keep]
    N, P, K = cs.N, cs.P, cs.K
    zb = np.flatnonzero(cs.forward < 0)
    p, k = zb % P, zb // P
    cols = (((k[:, None] + steps[None, :]) % K) * P + p[:, None]).ravel()
    rows = np.repeat(zb, steps.size)
    vals = np.tile(probs, zb.size)
    M = sp.csr_matrix((vals, (rows, cols)), shape=(N, N))
    M.sum_duplicates()
    return M


# ---------------------------------------------------------------------------- the mix
@dataclass(frozen=True)
class MixResult:
    """The policy mix that best matches a target.

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


def solve_mix(A, b) -> MixResult:
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
        from scipy.optimize import minimize
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
    return MixResult(alpha=alpha, residual=float(np.linalg.norm(diff)),
                     tv=float(0.5 * np.abs(diff).sum()), mixed=mixed, method=method)


# ---------------------------------------------------------------------------- targets
TARGET_FORMATS = """\
Target files (--target FILE), weights need not be normalised:
  * positions, long form: a CSV with a header row naming the columns p and weight (others
    ignored), one row per position cell p = 0..P-1 (cells not listed get weight 0);
  * positions, image-like grid: numbers only (commas or whitespace), one text line per grid
    row with the top row first (as the map looks), rows x columns = the env's grid shape
    (`bouncesim info ENV` prints it as "grid: [rows, columns]"); entries at cells that are
    not free are ignored (write 0, nan or - there);
  * configurations (--target-space configurations): a CSV with columns z and weight,
    z = k*P + p = 0..N-1 (unlisted configurations get weight 0).
All weights must be non-negative with a positive sum; lines starting with # are ignored."""


def uniform_target(cs: CellSpace, space: str = "positions") -> np.ndarray:
    """The uniform target over the P position cells or the N configuration cells."""
    n = _space_size(cs, space)
    return np.full(n, 1.0 / n)


def _space_size(cs: CellSpace, space: str) -> int:
    if space not in SPACES:
        raise UserError(f"target space must be positions or configurations, got {space!r}.")
    return cs.P if space == "positions" else cs.N


def load_target(path, cs: CellSpace, space: str = "positions") -> np.ndarray:
    """Read a target file (formats in ``TARGET_FORMATS``) and return it normalised.

    Raises :class:`TargetError` with one sentence for an unreadable file, a malformed or
    out-of-range entry, negative weights, a zero sum or a grid of the wrong shape.
    """
    path = Path(path)
    n = _space_size(cs, space)
    try:
        text = path.read_text()
    except FileNotFoundError:
        raise TargetError(f"no target file at {path}.") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise TargetError(f"cannot read the target file {path} ({exc}).") from None
    lines = [ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        raise TargetError(f"the target file {path} is empty.")
    first = [t for t in lines[0].replace(",", " ").replace(";", " ").split() if t]
    key = "p" if space == "positions" else "z"
    if first and all(_is_word(t) for t in first):          # a header row: long form
        w = _read_long(path, "\n".join(lines), key, n)
    elif space == "configurations":
        raise TargetError(f"a configuration target needs a CSV with columns z and weight; "
                          f"{path} has no header row.")
    else:
        w = _read_grid(path, lines, cs)
    if not np.all(np.isfinite(w)):
        raise TargetError(f"the target file {path} has a weight that is not a finite number.")
    if (w < 0).any():
        bad = int(np.flatnonzero(w < 0)[0])
        raise TargetError(f"the target file {path} has a negative weight ({w[bad]:g} at "
                          f"{key} = {bad}).")
    total = float(w.sum())
    if not total > 0:
        raise TargetError(f"the target weights in {path} sum to zero.")
    return w / total


def _is_word(tok: str) -> bool:
    """A token that is not a number (nor nan / - for an empty grid cell)."""
    try:
        float(tok)
        return False
    except ValueError:
        return tok.strip().lower() not in {"", "nan", "-"}


def _read_long(path: Path, text: str, key: str, n: int) -> np.ndarray:
    reader = csv.DictReader(io.StringIO(text))
    cols = [c.strip().lower() for c in (reader.fieldnames or [])]
    reader.fieldnames = cols
    if key not in cols or "weight" not in cols:
        raise TargetError(f"the target file {path} needs columns {key} and weight, "
                          f"found {', '.join(cols)}.")
    w = np.zeros(n)
    seen = set()
    for line, row in enumerate(reader, start=2):
        try:
            i = float(row[key])
            val = float(row["weight"])
        except (TypeError, ValueError):
            raise TargetError(f"line {line} of {path} does not hold a number in columns "
                              f"{key} and weight.") from None
        if not i.is_integer() or not 0 <= i < n:
            raise TargetError(f"{key} = {row[key]} on line {line} of {path} is outside "
                              f"0..{n - 1}.")
        if int(i) in seen:
            raise TargetError(f"{key} = {int(i)} is listed twice in {path}.")
        seen.add(int(i))
        w[int(i)] = val
    return w


def _read_grid(path: Path, lines: list, cs: CellSpace) -> np.ndarray:
    rows = []
    for ln in lines:
        toks = [t for t in ln.replace(",", " ").replace(";", " ").split() if t]
        try:
            rows.append([float("nan") if t == "-" else float(t) for t in toks])
        except ValueError:
            raise TargetError(f"the target grid {path} has an entry that is not a number "
                              f"({ln.strip()!r}).") from None
    nrows, ncols = cs.env.grid_shape
    shape = (len(rows), max(len(r) for r in rows))
    if any(len(r) != shape[1] for r in rows) or shape != (nrows, ncols):
        found = "ragged rows" if any(len(r) != shape[1] for r in rows) else \
            f"{shape[0]} x {shape[1]}"
        raise TargetError(f"the target grid {path} must have {nrows} rows x {ncols} columns "
                          f"(the env's grid), found {found}.")
    grid = np.array(rows)[::-1]            # file: top row first; grid: row j from the bottom
    ij = cs.cells_ij
    return grid[ij[:, 1], ij[:, 0]]


# ---------------------------------------------------------------------------- pipeline
@dataclass(frozen=True, eq=False)
class CoverageResult:
    """Coverage of every angle, the target and the best policy mix.

    Attributes
    ----------
    angles : tuple of float       bouncing angles [deg]
    eps : float                   error range ε [deg]
    r : float                     reliability
    space : str                   "positions" (A columns are q) or "configurations" (π)
    per_angle : tuple of AngleCoverage
    target : ndarray              b over the chosen space (sums to 1)
    mix : MixResult
    """

    angles: tuple
    eps: float
    r: float
    space: str
    per_angle: tuple
    target: np.ndarray
    mix: MixResult

    @property
    def alpha(self) -> np.ndarray:
        return self.mix.alpha

    @property
    def A(self) -> np.ndarray:
        cols = [a.q if self.space == "positions" else a.pi for a in self.per_angle]
        return np.column_stack(cols)

    def mixed_q(self) -> np.ndarray:
        """Mixed coverage over position cells, Σ α_i q_i."""
        return np.column_stack([a.q for a in self.per_angle]) @ self.alpha


def coverage_pipeline(cs: CellSpace, angles, eps_deg: float = 0.0, r: float = 1.0,
                      target=None, space: str = "positions", method: str = "runs",
                      progress=None, model: str = "step", model_settings=None
                      ) -> CoverageResult:
    """Algorithm 3: chains for all angles, their limiting distributions, and the best mix.

    Parameters
    ----------
    cs : CellSpace
    angles : sequence of float
        Bouncing angles [deg], multiples of Δ.
    eps_deg : float
        Error range ε [deg] (multiple of Δ).
    r : float
        Reliability in [0, 1].
    target : array_like, optional
        b over the space (normalised here); default uniform.
    space : {"positions", "configurations"}
    method : {"runs", "matrix"}
        See :func:`analyse_angle`.
    progress : callable, optional
        Wraps the iterable of angles (e.g. ``tqdm``).
    model : {"step", "sampled", "event"}
        Coverage model (:mod:`planners.coverage_models`); default the paper's step model.
        The continuous models work over position cells only (their per-angle records are
        :class:`planners.coverage_models.ModelCoverage`).
    model_settings : settings record of the model, optional
    """
    if model != "step":
        from .coverage_models import check_model
        check_model(model)
        if space != "positions":
            raise UserError(f"the {model} coverage model predicts coverage over position "
                            "cells only; use --target-space positions.")
    angles = tuple(float(a) for a in angles)
    if not angles:
        raise UserError("coverage needs at least one bouncing angle.")
    for a in angles:                            # validate everything before the heavy work
        bump_turns(cs.K, a, eps_deg, r)
    n = _space_size(cs, space)
    if target is None:
        b = uniform_target(cs, space)
    else:
        b = np.asarray(target, dtype=float).ravel()
        if b.size != n:
            raise TargetError(f"the target has {b.size} entries; the {space} space has {n}.")
        if not np.all(np.isfinite(b)) or (b < 0).any() or not b.sum() > 0:
            raise TargetError("the target must be non-negative with a positive sum.")
        b = b / b.sum()
    it = progress(angles) if progress else angles
    if model == "step":
        per = tuple(analyse_angle(cs, a, eps_deg, r, method=method) for a in it)
    else:
        from .coverage_models import predict_coverage
        per = tuple(predict_coverage(cs, a, eps_deg, r, model=model, settings=model_settings)
                    for a in it)
    A = np.column_stack([a.q if space == "positions" else a.pi for a in per])
    mix = solve_mix(A, b)
    return CoverageResult(angles=angles, eps=float(eps_deg), r=float(r), space=space,
                          per_angle=per, target=b, mix=mix)


def tv_distance(a, b) -> float:
    """Total-variation distance ½ Σ |a/Σa − b/Σb| between two non-negative vectors (counts
    or probabilities; each is normalised first).

    >>> tv_distance([1, 0], [0.5, 0.5]), tv_distance([2, 2], [1, 1])
    (0.5, 0.0)
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    return 0.5 * float(np.abs(a / a.sum() - b / b.sum()).sum())


def _num(x: float):
    x = float(x)
    return int(round(x)) if math.isclose(x, round(x), abs_tol=1e-9) else x
