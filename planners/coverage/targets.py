"""Coverage targets b over position or configuration cells: the uniform one, target files
(formats in :data:`TARGET_FORMATS`) and the check every target passes before a mix is fitted.
"""

from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np

from envs import UserError

from ..cells import CellSpace

__all__ = ["SPACES", "TARGET_FORMATS", "TargetError", "uniform_target", "load_target",
           "check_target", "space_size"]

SPACES = ("positions", "configurations")


class TargetError(UserError):
    """A coverage target that cannot be used (unreadable, negative, zero sum, wrong size)."""


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
    n = space_size(cs, space)
    return np.full(n, 1.0 / n)


def space_size(cs: CellSpace, space: str) -> int:
    """P for "positions", N for "configurations" (UserError for any other space)."""
    if space not in SPACES:
        raise UserError(f"target space must be positions or configurations, got {space!r}.")
    return cs.P if space == "positions" else cs.N


def load_target(path: str | Path, cs: CellSpace, space: str = "positions") -> np.ndarray:
    """Read a target file (formats in ``TARGET_FORMATS``) and return it normalised.

    Raises :class:`TargetError` with one sentence for an unreadable file, a malformed or
    out-of-range entry, negative weights, a zero sum or a grid of the wrong shape.
    """
    path = Path(path)
    n = space_size(cs, space)
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


def check_target(target, cs: CellSpace, space: str = "positions") -> np.ndarray:
    """The target b over ``space``, normalised: uniform when ``target`` is None, else the
    given weights (:class:`TargetError` unless there is one finite non-negative weight per
    cell of the space and their sum is positive).
    """
    n = space_size(cs, space)
    if target is None:
        return uniform_target(cs, space)
    b = np.asarray(target, dtype=float).ravel()
    if b.size != n:
        raise TargetError(f"the target has {b.size} entries; the {space} space has {n}.")
    if not np.all(np.isfinite(b)) or (b < 0).any() or not b.sum() > 0:
        raise TargetError("the target must be non-negative with a positive sum.")
    return b / b.sum()
