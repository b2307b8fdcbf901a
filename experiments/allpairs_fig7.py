"""Figs. 7 and 8 of the paper: how many distinct bouncing angles the shortest plans use,
over all ordered pairs of configurations in `lab` (Fig. 7) and `fig1` (Fig. 8).

    python -m experiments.allpairs_fig7 [--quick] [--angles 45,90,135] [--out results/allpairs_fig7]
"""

from __future__ import annotations

import sys
import time

import numpy as np
import pandas as pd

import envs
from bouncesim.runs.options import parse_angles
from planners.cells import CellSpace
from planners.navigation import Navigator

from .common import experiment_parser, output_dir, write_config

__all__ = ["claims", "main"]


def claims(env_name: str, counts: np.ndarray) -> list[tuple[str, bool]]:
    """The paper's qualitative statements about Figs. 7 and 8, checked on our counts."""
    c = counts
    total = c.sum()
    if env_name == "lab":
        return [("most plans use one angle", bool(np.argmax(c) == 1)),
                ("three angles are used more often than two",
                 bool(len(c) > 3 and c[3] > c[2])),
                ("few plans use no angle (< 5%)", bool(c[0] < 0.05 * total))]
    if env_name == "fig1":
        return [("most plans use three angles", bool(len(c) > 3 and np.argmax(c) == 3))]
    return []


def main(argv=None) -> int:
    p = experiment_parser("allpairs_fig7", __doc__.splitlines()[0])
    p.add_argument("--angles", default="45,90,135",
                   help="bouncing angles [deg] (default 45,90,135)")
    p.add_argument("--envs", default="lab,fig1", help="environments (default lab,fig1)")
    args = p.parse_args(argv)
    from bouncesim.plots import angle_use_bars
    out = output_dir(args.out)
    rows, claim_rows = [], []
    try:
        angles = parse_angles(args.angles)
        for name in args.envs.split(","):
            cells = CellSpace(envs.load(name))
            t0 = time.perf_counter()
            ap = Navigator(cells, angles).all_pairs()
            secs = time.perf_counter() - t0
            counts = ap.histogram()
            for k, n in enumerate(counts):
                rows.append({"env": name, "angles_used": k, "plans": int(n),
                             "fraction": n / counts.sum(), "N": cells.N,
                             "reachable_fraction": ap.reachable_fraction, "seconds": secs})
            for text, ok in claims(name, counts):
                claim_rows.append({"env": name, "claim": text, "holds": ok})
    except envs.UserError as exc:
        print(f"allpairs_fig7: error: {exc}", file=sys.stderr)
        return 2
    table = pd.DataFrame(rows)
    table.to_csv(out / "angles_used.csv", index=False)
    ctab = pd.DataFrame(claim_rows)
    ctab.to_csv(out / "claims.csv", index=False)
    label = ", ".join(f"{a:g}°" for a in angles)
    for name, sub in table.groupby("env", sort=False):
        fig_no = {"lab": "Fig. 7", "fig1": "Fig. 8"}.get(name, name)
        angle_use_bars(sub, out / f"angles_used_{name}.png",
                       title=f"{fig_no} analogue: {name}, Φ = {label}")
        print(f"{name} ({fig_no}), N = {sub['N'].iloc[0]}, reachable "
              f"{sub['reachable_fraction'].iloc[0]:.1%}, {sub['seconds'].iloc[0]:.2f} s")
        print(sub[["angles_used", "plans", "fraction"]].to_string(index=False))
    print("\nthe paper's claims on our layouts:")
    for _, r in ctab.iterrows():
        print(f"  {r['env']:>5}: {r['claim']:<45} {'holds' if r['holds'] else 'does not hold'}")
    write_config(out, {"experiment": "allpairs_fig7", "angles": angles,
                       "envs": args.envs.split(","), "w1": 1.0, "w2": 100.0,
                       "seed": args.seed, "quick": args.quick,
                       "note": "deterministic: the seed is recorded but unused"})
    print(f"wrote {out}/angles_used.csv, claims.csv and bar charts")
    return 0


if __name__ == "__main__":
    sys.exit(main())
