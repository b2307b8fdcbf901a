"""Compare the simulated histograms of two ``bouncesim validate --out`` folders, or of one
folder with the uniform target.

    python -m experiments.validate_compare RUNS_A RUNS_B      # e.g. a team with --interact bump
                                                              # against the same with off
    python -m experiments.validate_compare RUNS_A             # TV to the uniform target

Each folder's trials (``runs.csv`` and every ``round*/runs.csv``) are pooled per policy, as
validate pools them (docs/model.md §22). Printed per policy: the TV between the two pooled
histograms (or, with one folder, between its histogram and the uniform distribution over
the position cells: what a mix designed for the uniform target delivers), and each
folder's noise floor over random splits of its trials (validate's ``floor_splits``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from envs import UserError
from planners.metrics import floors, tv_distance

__all__ = ["main", "pooled_runs", "compare"]


def pooled_runs(folder: Path) -> dict:
    """Per policy label: (counts (trials, P), half (trials,)) of a validate folder."""
    files = [folder / "runs.csv"] + sorted(folder.glob("round*/runs.csv"))
    if not files[0].exists():
        raise UserError(f"{folder} holds no runs.csv of bouncesim validate.")
    table = pd.concat([pd.read_csv(f, dtype={"policy": str}) for f in files if f.exists()],
                      ignore_index=True)
    out = {}
    for lab, sub in table.groupby("policy", sort=False):
        counts = np.array([np.array(c.split(), dtype=float) for c in sub.counts])
        out[str(lab)] = (counts, sub.half.to_numpy())
    return out


def compare(a: Path, b: Path | None = None, seed: int = 0) -> pd.DataFrame:
    """One row per policy of ``a`` (and ``b``): tv (A against B, or A against uniform),
    floor_a and floor_b (mean TV over random splits of each folder's trials).
    """
    ra = pooled_runs(a)
    rb = pooled_runs(b) if b is not None else None
    rows = []
    for lab, (ca, ha) in ra.items():
        if rb is not None and lab not in rb:
            continue
        qa = ca.sum(axis=0)
        other = rb[lab][0].sum(axis=0) if rb is not None else np.ones_like(qa)
        if other.size != qa.size:
            raise UserError(f"policy {lab}: the folders count {qa.size} and {other.size} "
                            f"cells; compare runs of one map.")
        row = {"policy": lab, "tv": float(tv_distance(qa, other)),
               "floor_a": floors(ca, ha, np.random.default_rng(seed))[1]}
        if rb is not None:
            row["floor_b"] = floors(*rb[lab], np.random.default_rng(seed))[1]
        rows.append(row)
    return pd.DataFrame(rows)


def main(argv=None) -> int:
    """Command line: ``python -m experiments.validate_compare RUNS_A [RUNS_B]``."""
    p = argparse.ArgumentParser(prog="python -m experiments.validate_compare",
                                description=__doc__.split("\n\n")[0])
    p.add_argument("a", type=Path, help="a validate --out folder")
    p.add_argument("b", type=Path, nargs="?", default=None,
                   help="a second one (default: compare A with the uniform target)")
    p.add_argument("--seed", type=int, default=0, help="seed of the random splits")
    args = p.parse_args(argv)
    try:
        table = compare(args.a, args.b, args.seed)
    except UserError as e:
        print(f"validate_compare: error: {e}", file=sys.stderr)
        return 2
    print(table.to_string(index=False, float_format=lambda v: f"{v:.3f}"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
