"""The physics half of Fig. 3: execute the planned observation strings in PyBullet (and in
the kinematic twin), once without noise and then as a seeded batch with rotation noise.

Called by :mod:`experiments.nav_fig3`; writes ``runs.csv`` and per-run traces.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from tqdm import tqdm

from bouncesim import robots
from bouncesim.robots.noise import GaussianNoise, NoNoise
from bouncesim.runs.execute import execute

__all__ = ["execute_fig3", "make_robot", "BACKENDS"]

BACKENDS = ("pybullet", "kinematic")
# The twin's bumper ignores contacts more than this far from the heading, like the PyBullet
# body's ±80° bumper arc: in lab's one-robot-wide bottom corridor a strict front-half bumper
# bumps on every grazing contact after a noisy turn (see docs/readme_physics_twin.md).
TWIN_GLANCE_DEG = 80.0


def make_robot(backend: str, env, noise, rng):
    """:func:`bouncesim.robots.make_robot`, with the twin's bumper arc matched to PyBullet's."""
    if backend not in BACKENDS:
        raise ValueError(f"unknown backend {backend!r}")
    options = {"glance_deg": TWIN_GLANCE_DEG} if backend == "kinematic" else {}
    return robots.make_robot(backend, env, noise=noise, rng=rng, **options)


def execute_fig3(env, cells, routes, table, config, out):
    """Run every plan on every backend: one noise-free run, then ``n`` noisy seeds per level.

    ``config`` is the :class:`experiments.nav_fig3.Config` (its ``quick`` and ``seed``).
    Returns ({(plan, backend): noise-free trace frame}, config additions).
    """
    n_noisy = 3 if config.quick else 20
    sigmas = (2.0,) if config.quick else (2.0, 5.0)
    backends = [b for b in BACKENDS if _available(b)]
    jobs = []
    for (_, row), route in zip(table.iterrows(), routes):
        if route is None:
            continue
        for backend in backends:
            jobs.append((row["plan"], route, backend, "none", NoNoise(), 0))
            for sigma in sigmas:
                for i in range(n_noisy):
                    jobs.append((row["plan"], route, backend, f"gauss:{sigma:g}",
                                 GaussianNoise(sigma), i + 1))
    seeds = np.random.SeedSequence(config.seed).spawn(len(jobs))
    rows, traces = [], {}
    for (plan_label, route, backend, noise_name, noise, rep), ss in zip(
            tqdm(jobs, desc="executing Fig. 3 plans", unit="run"), seeds):
        rng = np.random.default_rng(ss)
        robot = make_robot(backend, env, noise, rng)
        try:
            run = execute(route.plan, robot, start=route.start, goal=route.goal, cells=cells)
        finally:
            robot.close()
        rows.append({"plan": plan_label, "backend": backend, "noise": noise_name,
                     "rep": rep, "seed": config.seed, "seed_entropy": str(ss.entropy),
                     "spawn_key": ss.spawn_key[0],
                     "success": bool(run.success), "reason": run.reason,
                     "final_x": run.final_pose[0], "final_y": run.final_pose[1],
                     "final_heading": run.final_pose[2],
                     "position_error_m": run.position_error,
                     "heading_error_deg": run.heading_error,
                     "deviations": len(run.deviations),
                     "deviation_detail": "; ".join(str(d) for d in run.deviations)})
        if noise_name == "none":
            traces[(plan_label, backend)] = run.trace.to_frame()
            run.trace.to_csv(out / f"trace_{plan_label.replace(' ', '')}_{backend}.csv")
    runs = pd.DataFrame(rows)
    runs.to_csv(out / "runs.csv", index=False)
    summary = (runs.groupby(["plan", "backend", "noise"], sort=False)["success"]
               .agg(["mean", "count"]).rename(columns={"mean": "success_rate", "count": "runs"}))
    summary.to_csv(out / "success_rates.csv")
    print("\nexecution (success = final cell and heading within ±Δ/2 of the goal):")
    print(summary.to_string(float_format=lambda x: f"{x:.2f}"))
    return traces, {"backends": backends, "noisy_runs_per_level": n_noisy,
                    "noise_levels": ["none"] + [f"gauss:{s:g}" for s in sigmas],
                    "twin_glance_deg": TWIN_GLANCE_DEG,
                    "seeding": "numpy SeedSequence(seed).spawn(number of runs), in runs.csv "
                    "order"}


def _available(backend: str) -> bool:
    if backend == "pybullet":
        try:
            import pybullet  # noqa: F401
        except ImportError:
            print("nav_fig3: pybullet is not installed (pip install 'bouncesim[sim]'); "
                  "running the twin only.")
            return False
    return True
