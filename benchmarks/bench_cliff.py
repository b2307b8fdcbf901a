"""The event model's stationary solve: aggregation–disaggregation against the power iteration.

    python -m benchmarks.bench_cliff                       # office maps + the catalogue
    python -m benchmarks.bench_cliff --maps office-pinhole --power-max 20000
    python -m benchmarks.bench_cliff --maps complex --power-first 0   # aggregation alone

For every map at K = 360 (angles 30°, 75°, 315°, ε = 5°, r = 0.8): the event model's build
time, then per method the wall time of the three chains and the largest over the angles of
the residual ‖πT − π‖₁ and of the L1 distance between the two methods' π (docs/model.md §10).
Maps: the two-room office of :mod:`envs.generated` with a door one robot wide
(``office``, a knife edge: the rooms are separate classes), 0.1 µm wider (``office-pinhole``:
the rooms are joined by the few flights along the door's axis, a slowly mixing class), and
0.40 m wide (``office-wide``), and the catalogue maps. The power iteration is the method
before the fix (:func:`planners.coverage.event._power_stationary`), capped at
``--power-max`` iterations per class (its result is then not converged: marked ``*``).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import planners.coverage.event as event
from envs.generated import load_map
from planners.cells import CellSpace
from planners.coverage import TurnNoise, clear_cache, model_for

ANGLES = (30.0, 75.0, 315.0)
NOISE = TurnNoise(5.0, 0.8)


def run_method(model, method: str):
    """(wall time [s], π per angle, residual per angle) of the three chains with ``method``."""
    model.stationary_method = method
    w0 = time.perf_counter()
    acs = [model.analyse(a, NOISE) for a in ANGLES]
    wall = time.perf_counter() - w0
    pis = [ac.pi for ac in acs]
    model.largest_class = max(int(max(ac.group_sizes)) for ac in acs)
    res = []
    for a, pi in zip(ANGLES, pis):
        T, _ = model.chain(a, NOISE)
        res.append(float(np.abs(T.T @ pi - pi).sum()))
    return wall, pis, res


def main(argv=None) -> int:
    """Run the benchmark and print its table (exit status)."""
    ap = argparse.ArgumentParser(prog="python -m benchmarks.bench_cliff",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("--maps", default="office,office-pinhole,office-wide,lab,fig1,complex")
    ap.add_argument("--orientations", type=int, default=360)
    ap.add_argument("--power-max", type=int, default=20000,
                    help="iteration cap of the power iteration per class (default 20000)")
    ap.add_argument("--power-first", type=int, default=event._POWER_FIRST,
                    help="power iterations the default method tries before its aggregation "
                    f"(default {event._POWER_FIRST}; 0: the aggregation alone, the method "
                    "before docs/model.md §10's power-first decision)")
    args = ap.parse_args(argv)
    event._POWER_MAX = args.power_max
    event._POWER_FIRST = args.power_first
    print(f"K = {args.orientations}, angles 30/75/315, eps 5°, r 0.8; power capped at "
          f"{args.power_max} iterations")
    print("| map | P | states | largest class | build [s] | aggregation [s] | power [s] "
          "| residual agg | residual power | L1(π_agg − π_power) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name in args.maps.split(","):
        clear_cache()
        cs = CellSpace(load_map(name, args.orientations))
        w0 = time.perf_counter()
        model = model_for(cs, "event")
        build = time.perf_counter() - w0
        ta, pa, ra = run_method(model, "aggregation")
        tp, pp, rp = run_method(model, "power")
        big = model.largest_class
        diff = max(float(np.abs(x - y).sum()) for x, y in zip(pa, pp))
        flag = "*" if max(rp) > 1e-5 else ""
        print(f"| {name} | {cs.P} | {model.n_states} | {big} | {build:.1f} | {ta:.1f} | "
              f"{tp:.1f}{flag} | {max(ra):.1e} | {max(rp):.1e} | {diff:.1e} |", flush=True)
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
