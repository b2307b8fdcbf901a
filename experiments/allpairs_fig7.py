"""Figs. 7 and 8 of the paper: how many distinct bouncing angles the shortest plans use,
over all ordered pairs of configurations in `lab` (Fig. 7) and `fig1` (Fig. 8).

    python -m experiments.allpairs_fig7 [--quick] [--angles 45,90,135] [--out results/allpairs_fig7]

``--quick`` computes `lab` only (unless ``--envs`` says otherwise).
"""

from __future__ import annotations

import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import pandas as pd

import envs
from bouncesim.runs.options import parse_angles
from planners.cells import CellSpace
from planners.navigation import Navigator

from .common import experiment_parser, name_list, output_dir, run_main, write_config
from .compare import add_compare_arg

__all__ = ["Config", "claims", "main", "run"]


@dataclass(frozen=True)
class Config:
    """Parameters of one allpairs_fig7 run (written to ``config.json``).

    Attributes
    ----------
    angles : tuple of float   bouncing angles Φ [deg]
    envs : tuple of str       environments (catalogue names or env files)
    w1, w2 : float            roadmap weights: step or same-angle bump, angle change
    quick : bool              recorded; ``main`` turns it into ``envs = ("lab",)``
    seed : int                recorded only: the computation is deterministic
    out : Path                output folder
    """

    angles: tuple[float, ...] = (45.0, 90.0, 135.0)
    envs: tuple[str, ...] = ("lab", "fig1")
    w1: float = 1.0
    w2: float = 100.0
    quick: bool = False
    seed: int = 0
    out: Path = Path("results") / "allpairs_fig7"


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


def run(config: Config) -> Path:
    """All pairs in every environment: angles_used.csv, claims.csv, bar charts, config.json.

    Raises :class:`envs.UserError` for a bad environment; returns the output folder.
    """
    from bouncesim.plots import angle_use_bars
    out = output_dir(config.out)
    rows, claim_rows = [], []
    for name in config.envs:
        cells = CellSpace(envs.load(name))
        t0 = time.perf_counter()
        ap = Navigator(cells, config.angles, config.w1, config.w2).all_pairs()
        secs = time.perf_counter() - t0
        counts = ap.histogram()
        for k, n in enumerate(counts):
            rows.append({"env": name, "angles_used": k, "plans": int(n),
                         "fraction": n / counts.sum(), "N": cells.N,
                         "reachable_fraction": ap.reachable_fraction, "seconds": secs})
        for text, ok in claims(name, counts):
            claim_rows.append({"env": name, "claim": text, "holds": ok})
    table = pd.DataFrame(rows)
    table.to_csv(out / "angles_used.csv", index=False)
    ctab = pd.DataFrame(claim_rows, columns=["env", "claim", "holds"])
    ctab.to_csv(out / "claims.csv", index=False)
    label = ", ".join(f"{a:g}°" for a in config.angles)
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
    write_config(out, {"experiment": "allpairs_fig7", **asdict(config),
                       "note": "deterministic: the seed is recorded but unused"})
    print(f"wrote {out}/angles_used.csv, claims.csv and bar charts")
    return out


def main(argv=None) -> int:
    """Parse the command line into a :class:`Config` and :func:`run` it (exit status)."""
    p = experiment_parser("allpairs_fig7", __doc__.splitlines()[0])
    add_compare_arg(p, "allpairs_fig7")
    p.add_argument("--angles", default="45,90,135",
                   help="bouncing angles [deg] (default 45,90,135)")
    p.add_argument("--envs", default=None,
                   help="environments (default lab,fig1; lab with --quick)")
    args = p.parse_args(argv)
    import matplotlib
    matplotlib.use("Agg")                      # this script writes files only
    names = args.envs or ("lab" if args.quick else "lab,fig1")
    return run_main("allpairs_fig7", lambda: Config(
        angles=tuple(parse_angles(args.angles)), envs=name_list(names), quick=args.quick,
        seed=args.seed, out=args.out), run, args.compare)


if __name__ == "__main__":
    sys.exit(main())
