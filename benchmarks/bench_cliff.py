"""The event model's stationary solve: the default method against the one before it (and,
optionally, the plain power iteration), with the horizon coverage's cost.

    python -m benchmarks.bench_cliff                       # office maps + the catalogue
    python -m benchmarks.bench_cliff --maps complex        # default against the one before
    python -m benchmarks.bench_cliff --maps complex --power-first 0   # ... aggregation alone
    python -m benchmarks.bench_cliff --maps office-pinhole --power-max 20000   # + power alone

For every map at K = 360 (angles 30°, 75°, 315°, ε = 5°, r = 0.8): the event model's build
CPU time, then per method the CPU time of the three chains (``time.process_time``) and the
largest over the angles of the residual ‖πT − π‖₁, the L1 distance between the two
methods' π, and the CPU time of the three angles' horizon coverage at T = 2000 (one
:class:`~planners.coverage.Horizon`, docs/model.md §20); the load average is printed with
every row. Methods (docs/model.md §17): the default (BiCGSTAB, then
aggregation–disaggregation from its answer) and the one before it (``--power-first`` damped
power iterations, 3000 unless told, then the aggregation from that iterate; 0: the
aggregation alone from the uniform vector, the method before the power-first decision);
with ``--power-max N`` also the plain power iteration capped at N iterations per class (the
method before the aggregation; its result is then not converged: marked ``*``).
Maps: the two-room office of :mod:`envs.generated` with a door one robot wide
(``office``, a knife edge: the rooms are separate classes), 0.1 µm wider (``office-pinhole``:
the rooms are joined by the few flights along the door's axis, a slowly mixing class), and
0.40 m wide (``office-wide``), and the catalogue maps.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

import planners.coverage.stationary as stationary
from envs.generated import load_map
from planners.cells import CellSpace
from planners.coverage import Horizon, TurnNoise, clear_cache, model_for

ANGLES = (30.0, 75.0, 315.0)
NOISE = TurnNoise(5.0, 0.8)
HORIZON = 2000


def run_method(model, method: str, power_first: int):
    """(CPU time [s], π per angle, residual per angle, largest class) of the three chains."""
    model.stationary_method = method
    stationary._POWER_FIRST = power_first
    c0 = time.process_time()
    acs = [model.analyse(a, NOISE) for a in ANGLES]
    cpu = time.process_time() - c0
    res = []
    for a, ac in zip(ANGLES, acs):
        T, _ = model.chain(a, NOISE)
        res.append(float(np.abs(T.T @ ac.pi - ac.pi).sum()))
    big = max(int(max(ac.group_sizes)) for ac in acs)
    return cpu, [ac.pi for ac in acs], res, big


def main(argv=None) -> int:
    """Run the benchmark and print its table (exit status)."""
    ap = argparse.ArgumentParser(prog="python -m benchmarks.bench_cliff",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("--maps", default="office,office-pinhole,office-wide,lab,fig1,complex")
    ap.add_argument("--orientations", type=int, default=360)
    ap.add_argument("--power-first", type=int, default=stationary._POWER_FIRST,
                    help="power iterations the method before tries before its aggregation "
                    f"(default {stationary._POWER_FIRST}; 0 makes it the aggregation alone)")
    ap.add_argument("--power-max", type=int, default=0,
                    help="also run the plain power iteration, capped at this many iterations "
                    "per class (default 0: not run)")
    args = ap.parse_args(argv)
    first0, max0 = stationary._POWER_FIRST, stationary._POWER_MAX
    power = args.power_max > 0
    print(f"K = {args.orientations}, angles 30/75/315, eps 5°, r 0.8; default: BiCGSTAB, "
          f"then aggregation; before: ≤ {args.power_first} power iterations, then aggregation"
          + (f"; power alone capped at {args.power_max} iterations" if power else "")
          + "; times in CPU seconds")
    cols = ["map", "P", "states", "largest class", "build", "default", "before",
            "residual default", "residual before", "L1(default − before)"]
    if power:
        cols += ["power alone", "residual power", "L1(default − power)"]
    cols += [f"horizon T={HORIZON}", "load"]
    print("| " + " | ".join(cols) + " |")
    print("|" + "---|" * len(cols))
    try:
        for name in args.maps.split(","):
            clear_cache()
            cs = CellSpace(load_map(name, args.orientations))
            c0 = time.process_time()
            model = model_for(cs, "event")
            build = time.process_time() - c0
            td, pd, rd, big = run_method(model, "krylov", first0)
            ta, pa, ra, _ = run_method(model, "aggregation", args.power_first)
            row = [name, cs.P, model.n_states, big, f"{build:.1f}", f"{td:.1f}", f"{ta:.1f}",
                   f"{max(rd):.1e}", f"{max(ra):.1e}",
                   f"{max(float(np.abs(x - y).sum()) for x, y in zip(pd, pa)):.1e}"]
            if power:
                stationary._POWER_MAX = args.power_max
                tp, pp, rp, _ = run_method(model, "power", args.power_first)
                flag = "*" if max(rp) > 1e-5 else ""
                row += [f"{tp:.1f}{flag}", f"{max(rp):.1e}",
                        f"{max(float(np.abs(x - y).sum()) for x, y in zip(pd, pp)):.1e}"]
            c0 = time.process_time()
            hz = Horizon(model)                     # one recursion for the three angles
            for a in ANGLES:
                hz.coverage([a], HORIZON, noise=NOISE)
            row += [f"{time.process_time() - c0:.1f}", f"{os.getloadavg()[0]:.1f}"]
            print("| " + " | ".join(str(v) for v in row) + " |", flush=True)
    finally:
        stationary._POWER_FIRST, stationary._POWER_MAX = first0, max0
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
