"""Compare a re-run's CSV tables with stored ones (``results/canonical/<name>/``).

    python -m experiments.compare results/canonical/coverage_table1 results/coverage_table1
    python -m experiments.coverage_table1 --compare results/canonical/coverage_table1

Every ``*.csv`` of the stored folder must exist in the new one with the same columns and
rows; numbers agree within ``rtol``/``atol`` (numpy ``isclose``), anything else exactly. Time
columns (``seconds``, ``*_s``, ``wall*``) are skipped: they measure the machine, not the
result. Exit status 0 when everything agrees, 1 with one line per difference otherwise.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from envs import UserError

__all__ = ["RTOL", "ATOL", "add_compare_arg", "compare_folders", "main", "report"]

RTOL = 1e-6
"""Relative tolerance of a numeric cell (float sums in another order agree to about 1e-12)."""
ATOL = 1e-9
"""Absolute tolerance of a numeric cell."""


def _timing(column: str) -> bool:
    c = column.lower()
    return c in ("seconds", "time_s") or c.endswith("_s") or c.startswith("wall")


def _show(value) -> str:
    """A cell as a reader wants it: numbers plainly, text quoted."""
    return repr(value.item() if isinstance(value, np.generic) else value)


def _compare_table(old: pd.DataFrame, new: pd.DataFrame, name: str, rtol: float,
                   atol: float) -> list[str]:
    if list(old.columns) != list(new.columns):
        return [f"{name}: columns differ: {list(old.columns)} against {list(new.columns)}"]
    if len(old) != len(new):
        return [f"{name}: {len(old)} rows stored, {len(new)} now"]
    out = []
    for col in old.columns:
        if _timing(col):
            continue
        a, b = old[col], new[col]
        if pd.api.types.is_numeric_dtype(a) and pd.api.types.is_numeric_dtype(b):
            x, y = a.to_numpy(dtype=float), b.to_numpy(dtype=float)
            bad = ~np.isclose(x, y, rtol=rtol, atol=atol, equal_nan=True)
        else:
            both_missing = (a.isna() & b.isna()).to_numpy()
            bad = (a.astype(str) != b.astype(str)).to_numpy() & ~both_missing
        for i in np.flatnonzero(bad)[:3]:
            out.append(f"{name}: row {i}, {col}: stored {_show(a.iloc[i])}, "
                       f"now {_show(b.iloc[i])}")
        if bad.sum() > 3:
            out.append(f"{name}: {col}: {int(bad.sum()) - 3} more rows differ")
    return out


def compare_folders(stored, new, rtol: float = RTOL, atol: float = ATOL) -> list[str]:
    """The differences between every CSV of folder ``stored`` and its namesake in ``new``
    (an empty list: they agree); :class:`UserError` when ``stored`` has no CSV.
    """
    stored, new = Path(stored), Path(new)
    tables = sorted(stored.glob("*.csv"))
    if not tables:
        raise UserError(f"{stored} has no CSV tables to compare with.")
    out = []
    for path in tables:
        other = new / path.name
        if not other.is_file():
            out.append(f"{path.name}: missing in {new}")
            continue
        out += _compare_table(pd.read_csv(path), pd.read_csv(other), path.name, rtol, atol)
    return out


def report(stored, new, rtol: float = RTOL, atol: float = ATOL, file=None) -> int:
    """Print the comparison of :func:`compare_folders`; exit status 0 (agree) or 1."""
    file = file or sys.stdout
    diffs = compare_folders(stored, new, rtol, atol)
    n = len(list(Path(stored).glob("*.csv")))
    if not diffs:
        print(f"compare: {new} agrees with {stored} ({n} table(s), rtol {rtol:g}, "
              f"atol {atol:g}).", file=file)
        return 0
    print(f"compare: {new} differs from {stored}:", file=file)
    for line in diffs:
        print(f"  {line}", file=file)
    return 1


def add_compare_arg(p: argparse.ArgumentParser, name: str) -> None:
    """``--compare DIR``: after the run, compare its tables with those stored in DIR."""
    p.add_argument("--compare", type=Path, metavar="DIR", default=None,
                   help=f"after the run, compare its CSV tables with a stored run's (e.g. "
                   f"results/canonical/{name}); exit status 1 if they differ")


def main(argv=None) -> int:
    """``python -m experiments.compare STORED NEW``; exit status 0, 1 (differ) or 2."""
    p = argparse.ArgumentParser(prog="python -m experiments.compare",
                                description=__doc__.splitlines()[0])
    p.add_argument("stored", type=Path, help="the stored results (e.g. results/canonical/X)")
    p.add_argument("new", type=Path, help="the re-run's output folder")
    p.add_argument("--rtol", type=float, default=RTOL, help=f"relative tolerance ({RTOL:g})")
    p.add_argument("--atol", type=float, default=ATOL, help=f"absolute tolerance ({ATOL:g})")
    args = p.parse_args(argv)
    try:
        return report(args.stored, args.new, args.rtol, args.atol)
    except UserError as exc:
        print(f"compare: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
