"""The contact rule's slides for many flights: plain-Python ``advance`` per flight (the
reference, with legs) against the compiled kernel (``contact_flights(legs=False)``), in the
same run on the same flights.

    python -m benchmarks.bench_slides [--env lab] [--flights 900] [--repeat 5]

The flights are those a feedback decision under PyBullet's rule flies: bump poses of random
flights, turned by each bouncing angle with 2° of noise. Prints the time per call (best of
``--repeat``), how many flights slid, and the largest difference of ends and clocks.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import envs
from envs.contact import contact_flights
from envs.motion import PYBULLET_CONTACT, casters
from planners.navigation.feedback.observe import flights


def _best(fn, repeat: int) -> tuple[float, object]:
    best, out = np.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def main(argv=None) -> None:
    """Time both paths on the same flights and print the table."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--env", default="lab", help="catalogue map (default lab)")
    ap.add_argument("--flights", type=int, default=900, help="flights per call (default 900)")
    ap.add_argument("--repeat", type=int, default=5, help="calls per path (best of)")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    env = envs.load(args.env)
    caster = casters(env)[0]
    rng = np.random.default_rng(args.seed)
    poses = np.array([env.random_pose(rng) for _ in range(args.flights)])
    D, u, _ = flights(caster, poses[:, :2], poses[:, 2], bearings=False)
    bump = poses[:, :2] + D[:, None] * u
    head = poses[:, 2] + rng.choice([45.0, 90.0, 135.0], len(poses)) + rng.normal(0, 2, len(poses))
    D, u, _ = flights(caster, bump, head, bearings=False)
    contact_flights(caster, bump, u, D, PYBULLET_CONTACT, legs=False)      # compile first
    t_py, ref = _best(lambda: contact_flights(caster, bump, u, D, PYBULLET_CONTACT),
                      args.repeat)
    t_nb, fast = _best(lambda: contact_flights(caster, bump, u, D, PYBULLET_CONTACT,
                                               legs=False), args.repeat)
    same = bool((ref.slid == fast.slid).all())
    d_end = float(np.abs(ref.end - fast.end).max())
    d_clock = float(np.abs(ref.clock - fast.clock).max())
    print(f"{args.env}: {len(bump)} flights under PyBullet's rule, {int(ref.slid.sum())} slid")
    print(f"{'path':<34s}{'ms per call':>12s}")
    print(f"{'advance per flight (Python, legs)':<34s}{1e3 * t_py:>12.2f}")
    print(f"{'compiled kernel (no legs)':<34s}{1e3 * t_nb:>12.2f}")
    print(f"speed-up {t_py / t_nb:.1f}x; same slides: {same}; "
          f"max |end| diff {d_end:.1e} m, max |clock| diff {d_clock:.1e} m")


if __name__ == "__main__":
    main()
