"""``bouncesim allpairs``: Algorithm 2 over every ordered pair of configurations."""

from __future__ import annotations

import json
import time

import numpy as np
import pandas as pd

from envs import UserError
from planners.navigation import PLANNERS, planner_class

from .common import (
    add_env_args,
    add_figures_arg,
    add_output,
    check_fits,
    flush_warnings,
    max_memory,
    report_written,
    writable_path,
    write_config,
)
from .plan import add_planner_args, make_planner_of

__all__ = ["histogram_frame", "register", "run"]


def register(sub) -> None:
    """Add the ``allpairs`` sub-command to the CLI's sub-parsers."""
    p = sub.add_parser(
        "allpairs", help="shortest plans for every ordered pair and the angle-use histogram",
        description="Run Algorithm 2 (docs/model.md §12): the weight matrix L (-1 where "
        "unreachable) and the number of distinct angles each shortest plan uses. Writes "
        "weights.npy, angles_used.csv, summary.json, config.json and angles_used.png (or "
        ".svg/.pdf with --figures) to --out.")
    add_env_args(p)
    add_planner_args(p)
    add_output(p, "--out", folder=True, required=True, metavar="DIR", help="output folder")
    add_figures_arg(p)
    p.set_defaults(func=run)


def histogram_frame(counts: np.ndarray) -> pd.DataFrame:
    """Table (angles_used, plans, fraction) of a histogram of plans by distinct angles used."""
    total = counts.sum()
    return pd.DataFrame({"angles_used": np.arange(len(counts)), "plans": counts,
                         "fraction": counts / total if total else counts * 0.0})


def run(args) -> int:
    """Run ``bouncesim allpairs``: weights, angle use and figure files; exit status."""
    if not hasattr(planner_class(args.planner), "all_pairs"):
        have = ", ".join(n for n, c in PLANNERS.items() if hasattr(c, "all_pairs"))
        raise UserError(f"the {args.planner} planner has no all-pairs search ({have} do).")
    nav = make_planner_of(args)
    limit = max_memory(args)
    check_fits(args, nav.cells, nav.memory_estimate(nav.cells, nav.angles, task="allpairs"),
               what="all pairs")
    out = writable_path(args.out, "--out", folder=True)
    flush_warnings()
    t0 = time.perf_counter()
    ap = nav.all_pairs(max_memory=limit)
    elapsed = time.perf_counter() - t0
    np.save(out / "weights.npy", ap.weights)
    hist = histogram_frame(ap.histogram())
    hist.to_csv(out / "angles_used.csv", index=False)
    summary = {"env": nav.cells.env.name, "N": nav.cells.N, "P": nav.cells.P,
               "K": nav.cells.K, "angles": list(nav.angles), "w1": args.w1, "w2": args.w2,
               "pairs": nav.cells.N * (nav.cells.N - 1),
               "reachable_fraction": ap.reachable_fraction,
               "histogram": hist["plans"].tolist(), "seconds": round(elapsed, 3)}
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    config = write_config(out, args, nav.cells.env)
    from bouncesim.plots import angle_use_bars
    figure = out / f"angles_used.{args.figures}"
    angle_use_bars(hist, figure,
                   title=f"{nav.cells.env.name}: angles used per shortest plan "
                   f"(Φ = {', '.join(f'{a:g}°' for a in nav.angles)})")
    print(hist.to_string(index=False))
    print(f"reachable pairs: {ap.reachable_fraction:.1%} of {summary['pairs']}; "
          f"{elapsed:.2f} s")
    report_written([out / "weights.npy", out / "angles_used.csv", out / "summary.json", config,
                    figure], args)
    return 0
