"""Feedback navigation's decision time per bump under turn noise (docs/model.md §15): the
decision rule as it was (the reference search and scoring), the same rule on the fast search,
and the guided search, run on the same pairs and seeds in one process.

    python -m benchmarks.bench_feedback [--env lab] [--sigmas 0,2,5] [--pairs 10] [--seed 0]
                                        [--rules reference,fast,guided,before,contact,value]
                                        [--contact off|pybullet]

For each σ, ``--pairs`` seeded feedback runs in the kinematic twin with Gaussian turn noise σ
(the filter told σ) per rule:

- ``reference``: ``FeedbackConfig(reference=True)``, the plain search (every cast over every
  wall) and one plan scored after another: the rule and the code before the speed-up;
- ``fast``: ``FeedbackConfig(guided=False)``, the same rule on the fast search and the
  batched scoring (the same decisions as ``reference``: the table says how many runs differ);
- ``guided``: ``FeedbackConfig(guided=True)``, the search guided by the cost to go (§15);
- ``before``: ``FeedbackConfig(final_min=0.0)``, the default before the final drive needed
  half the belief's mass in the goal cell (§15): it stopped whenever any mass did;
- ``contact``: ``FeedbackConfig(contact=PYBULLET_CONTACT)``, the filter, search and scores
  under PyBullet's contact rule (§15, §9);
- ``value``, ``value-contact``: ``FeedbackConfig(decision="value")``, deciding by the
  closed-loop value (§15 "Deciding by value"; the default under turn noise), without and with
  PyBullet's contact rule. The rules above it decide by scored plans (``decision="plan"``).

``--contact pybullet`` gives the twin PyBullet's contact rule (glancing contacts slide); every
rule but ``contact`` keeps the front-half bumper model whatever the body (so ``fast`` is the
default before the navigator learned the body's rule).

Printed per σ and rule: decisions, runs that reached the goal, and the decision time per bump
in CPU time of this process (filter update, planning, scoring, final drive): median, 95th
percentile and maximum, and the share within the 30 ms target; then the one-time set-up of a
navigator (contact bins and, for ``guided``, the cost to go) and one cold exact query
(``ExactNavigator.plan``, the open-loop planner) for scale. CPU time, because on a shared
machine wall time is mostly waiting; compare rules within one run.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

import numpy as np

import envs
from bouncesim.robots.kinematic import KinematicRobot
from bouncesim.robots.noise import GaussianNoise
from bouncesim.runs.execute import navigate_feedback
from envs.motion import PYBULLET_CONTACT
from planners.cells import CellSpace
from planners.navigation.exact import ExactNavigator
from planners.navigation.feedback import FeedbackConfig, FeedbackNavigator

TARGET_MS = 30.0
ANGLES = (45.0, 90.0, 135.0)
_PLAN = FeedbackConfig(decision="plan")
RULES = {"reference": replace(_PLAN, reference=True), "fast": replace(_PLAN, guided=False),
         "guided": replace(_PLAN, guided=True),
         "before": replace(_PLAN, final_min=0.0),
         "contact": replace(_PLAN, guided=False, contact=PYBULLET_CONTACT),
         "value": FeedbackConfig(decision="value"),
         "value-contact": FeedbackConfig(decision="value", contact=PYBULLET_CONTACT)}


def _floats(text: str) -> tuple:
    return tuple(float(v) for v in text.split(",") if v.strip())


def main(argv=None) -> None:
    """Run the benchmark and print the table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--env", default="lab")
    ap.add_argument("--sigmas", type=_floats, default=(0.0, 2.0, 5.0),
                    help="Gaussian turn noise levels [deg], comma-separated")
    ap.add_argument("--pairs", type=int, default=10)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--rules", default=",".join(RULES),
                    help="decision rules to time, comma-separated: " + ", ".join(RULES))
    ap.add_argument("--contact", choices=("off", "pybullet"), default="off",
                    help="the twin's contact rule (default off: the front-half bumper)")
    args = ap.parse_args(argv)
    rules = [r.strip() for r in args.rules.split(",") if r.strip()]
    unknown = [r for r in rules if r not in RULES]
    if unknown:
        ap.error(f"unknown rule {unknown[0]!r}; choose from {', '.join(RULES)}")
    env = envs.load(args.env)
    cells = CellSpace(env)
    body = PYBULLET_CONTACT if args.contact == "pybullet" else None
    rng = np.random.default_rng(args.seed)
    pairs = []
    while len(pairs) < args.pairs:
        s, g = (int(v) for v in rng.integers(0, cells.N, 2))
        if s != g and ExactNavigator(cells, ANGLES, contact=body).plan(s, g) is not None:
            pairs.append((s, g))
    print(f"{args.env}, {len(pairs)} pairs, twin contact rule {args.contact}, "
          f"CPU time per decision [ms]")
    print(f"{'σ':>4s} {'rule':10s}{'decisions':>10s}{'reached':>9s}{'median':>8s}{'p95':>8s}"
          f"{'max':>8s}{'<= 30 ms':>10s}  same as reference")
    for sigma in args.sigmas:
        noise = GaussianNoise(sigma)
        done = {}
        for rule in rules:
            cpu, ok, runs = [], 0, []
            for i, (s, g) in enumerate(pairs):
                run = navigate_feedback(KinematicRobot(env, noise, i, contact=body), env, s, g,
                                        noise, np.random.default_rng([args.seed, i]),
                                        angles=ANGLES, cells=cells, config=RULES[rule],
                                        contact=RULES[rule].contact)
                cpu += list(run.decision_cpu_ms)
                ok += bool(run.success)
                runs.append((run.plan.exact_text(), run.final_pose))
            done[rule] = runs
            v = np.asarray(cpu)
            same = ""
            if rule != "reference" and "reference" in done:
                diff = sum(a != b for a, b in zip(runs, done["reference"]))
                same = f"{len(runs) - diff}/{len(runs)} runs"
            print(f"{sigma:4g} {rule:10s}{len(v):10d}{ok:9d}{np.median(v):8.1f}"
                  f"{np.percentile(v, 95):8.1f}{v.max():8.1f}{np.mean(v <= TARGET_MS):10.1%}"
                  f"  {same}")
    setup = {}
    for rule in rules:
        cfg = replace(RULES[rule], turn_sigma_deg=max(args.sigmas))
        c0 = time.process_time()
        for _, g in pairs[:3]:
            fnav = FeedbackNavigator(cells, ANGLES, g, cfg)
            if fnav.by_value:
                _ = fnav.value
        setup[rule] = 1e3 * (time.process_time() - c0) / min(3, len(pairs))
    query = []
    for s, g in pairs:
        c0 = time.process_time()
        ExactNavigator(cells, ANGLES).plan(s, g)          # cold: a fresh navigator
        query.append(1e3 * (time.process_time() - c0))
    print(f"navigator set-up per goal at σ = {max(args.sigmas):g}° (before the robot moves; "
          "the value's transitions, built for the runs above, are cached per map), CPU [ms]: " +
          ", ".join(f"{r} {t:.0f}" for r, t in setup.items()))
    print(f"one cold exact query, CPU [ms]: median {np.median(query):.1f}, "
          f"max {max(query):.1f}")


if __name__ == "__main__":
    main()
