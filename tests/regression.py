"""Golden numbers for the CI regression (tests/test_regression.py) and the command that
regenerates them.

    python -m tests.regression            # recompute and compare, print the differences
    python -m tests.regression --write    # overwrite tests/golden/*.json (review the diff!)

Three golden files:

- ``coverage.json``: the predicted coverage q of every angle, the policy mix α (targets
  over positions and over configurations) and the mix's time-shared coverage in 1000-step
  epochs (:mod:`planners.coverage.timeshare`) of fixed settings. Any drift beyond ``ATOL`` fails.
- ``plans.json``: the shortest plans (observation strings and costs) of a fixed set of
  (start, goal) queries, and whether each plan reaches its goal when executed without noise
  in the kinematic twin (and, for the Fig. 3 plans, in PyBullet).
- ``tv.json``: TV between predicted and simulated coverage on a small environment with a
  fixed seed, with the noise floor measured when the file was written: the largest TV
  between independent seeds at the same step count. The twin (10^5 steps) is compared with
  the step and the event model; PyBullet with what ``bouncesim validate --backend pybullet``
  compares: the event model with PyBullet's contact rule (docs/model.md §9) against
  validate's own batches (``simulate_trial``: a ``PyBulletBatch`` of 16 robots that ignore
  each other, with fast-forward, docs/model.md Appendix C), two batches of 16 × 750 counted steps
  per seed (24 000 steps) at 75°. Budget: the PyBullet test may cost at most 1.5× the CPU
  time of the one it replaced (four single-robot runs of 250 steps against the step model,
  about 30 s CPU), so 45 s; it takes about 41 s, and the floor fell from 0.16 to the value
  in tv.json. Shown to fail: the same PyBullet histogram is TV 0.190 from the event model
  without the contact rule and 0.229 from the step model (allowed: up to 0.124).
  The test allows the TV to move by at most ``TV_SLACK`` (1.5) noise floors either way. Why
  the floor is the right unit: by the triangle inequality, re-sampling the simulation (another
  seed, or a harmless change in how random numbers are drawn) moves TV(q, q̂) by at most
  TV(q̂, q̂'), which is what the floor measures; the extra half covers floors estimated from
  only a few seed pairs. A change of the planner, the chain or the simulator that moves
  coverage by more than sampling noise fails, and so does an improvement (regenerate the file
  to record it).

The settings are small on purpose: the twin's comparison runs in seconds, PyBullet's in
well under a minute.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

import envs
from envs.motion import PYBULLET_CONTACT, ContactParams
from planners.cells import CellSpace
from planners.coverage import TurnNoise, design_mix, model_for, timeshared_coverage
from planners.metrics import tv_distance
from planners.navigation import Navigator

__all__ = ["COVERAGE_SETTINGS", "MIX_EPOCH", "PLAN_QUERIES", "TV_SETTING", "TV_SLACK", "GOLDEN_DIR",
           "compute_coverage", "compute_plans", "compute_tv", "load", "main"]

GOLDEN_DIR = Path(__file__).resolve().parent / "golden"
ATOL = {"step": 1e-9,      # exact sparse linear algebra
        "event": 1e-6,     # the event model's power iteration stops at an L1 error < 1e-6
        "timeshared": 1e-6}   # float32 products, deterministic stopping rule
MIX_EPOCH = 1000        # steps per epoch of the time-shared mix
TV_SLACK = 1.5          # allowed |TV − golden TV| in units of the stored noise floor

# (name, env, orientations, angles, eps, r, model)
COVERAGE_SETTINGS = [
    ("lab-72-table1", "lab", 72, (30.0, 75.0, 315.0), 5.0, 0.8, "step"),
    ("complex-72-table1", "complex", 72, (30.0, 75.0, 315.0), 5.0, 0.8, "step"),
    ("fig1-8-45-90-135", "fig1", 8, (45.0, 90.0, 135.0), 45.0, 0.9, "step"),
    ("lab-72-table1-event", "lab", 72, (30.0, 75.0, 315.0), 5.0, 0.8, "event"),
    ("fig1-72-table1-event", "fig1", 72, (30.0, 75.0, 315.0), 5.0, 0.8, "event"),
]

# (env, angles, [(start z, goal z), ...]): Fig. 3's two queries, then fixed samples.
PLAN_QUERIES = [
    ("lab", (90.0, 135.0), [(8, 0), (103, 8)]),
    ("lab", (45.0, 90.0, 135.0), [(0, 47), (20, 5), (100, 300), (383, 17), (250, 60)]),
    ("fig1", (45.0, 90.0, 135.0), [(0, 53), (10, 400), (200, 31), (431, 0), (77, 123)]),
]
PYBULLET_PLANS = 2      # the first queries (Fig. 3) are also executed in PyBullet

TV_SETTING = {"env": "lab", "orientations": 72, "angles": (30.0, 75.0, 315.0), "eps": 5.0,
              "r": 0.8, "twin_robots": 100, "twin_steps_per_robot": 1000,
              "twin_burn_in": 2000, "seed": 2024, "models": ("step", "event"),
              "floor_seeds": (1, 2, 3, 4), "pybullet_angle": 75.0, "pybullet_model": "event",
              "pybullet_contact": (PYBULLET_CONTACT.beta_deg, PYBULLET_CONTACT.slide_friction),
              "pybullet_batches": 2, "pybullet_robots": 16, "pybullet_steps": 750,
              "pybullet_burn_in": 50, "pybullet_seeds": (11, 12, 13, 14)}
"""PyBullet: per seed, ``pybullet_batches`` batches (validate's sweep trials, trial i seeded
as the sweep seeds it) of ``pybullet_robots`` robots × ``pybullet_steps`` counted steps after
``pybullet_burn_in``, against ``pybullet_model`` with the contact rule (β [deg], μ)."""


# ----------------------------------------------------------------------------- compute
def compute_coverage() -> dict:
    out = {}
    for name, env_name, K, angles, eps, r, model in COVERAGE_SETTINGS:
        cs = CellSpace(envs.load(env_name, orientations=K))
        noise = TurnNoise(eps, r)
        pos = design_mix(model_for(cs, model), angles, noise)
        entry = {"env": env_name, "orientations": K, "angles": list(angles), "eps": eps,
                 "r": r, "model": model, "alpha": pos.alpha.tolist(),
                 "q": {f"{a:g}": ac.q.tolist() for a, ac in zip(angles, pos.per_angle)},
                 "mix_epochs": timeshared_coverage(model_for(cs, model), pos.mix,
                                                   epoch=MIX_EPOCH).q.tolist()}
        if model == "step":
            conf = design_mix(model_for(cs), angles, noise, space="configurations")
            entry["alpha_configurations"] = conf.alpha.tolist()
        out[name] = entry
    return out


def _execute(env, cells, route, backend: str) -> bool:
    from bouncesim.runs.execute import execute
    if backend == "twin":
        from bouncesim.robots.kinematic import KinematicRobot
        robot = KinematicRobot(env, glance_deg=80)
    else:
        from bouncesim.robots.pybullet import PyBulletRobot
        robot = PyBulletRobot(env)
    with robot:
        run = execute(route.plan, robot, start=route.start, goal=route.goal, cells=cells)
    return bool(run.success)


def compute_plans(pybullet: bool = True) -> list[dict]:
    rows, done_pb = [], 0
    for env_name, angles, queries in PLAN_QUERIES:
        env = envs.load(env_name)
        cells = CellSpace(env)
        nav = Navigator(cells, angles)
        for s, g in queries:
            route = nav.plan(s, g)
            row = {"env": env_name, "angles": list(angles), "start": s, "goal": g,
                   "plan": None if route is None else str(route.plan),
                   "cost": None if route is None else route.cost}
            if route is not None:
                row["twin_success"] = _execute(env, cells, route, "twin")
                if done_pb < PYBULLET_PLANS:
                    row["pybullet_success"] = (_execute(env, cells, route, "pybullet")
                                               if pybullet else None)
                    done_pb += 1
            rows.append(row)
    return rows



def twin_histogram(cs: CellSpace, angle: float, seed: int) -> np.ndarray:
    from bouncesim.robots.kinematic import KinematicBatch
    from bouncesim.robots.noise import SteppedNoise
    s = TV_SETTING
    res = KinematicBatch(cs.env, s["twin_robots"], np.random.default_rng(seed), cells=cs).run(
        angle, s["twin_steps_per_robot"], noise=SteppedNoise(s["eps"], s["r"], cs.delta_deg),
        burn_in=s["twin_burn_in"])
    return res.counts


def pybullet_histogram(cs: CellSpace, angle: float, seed: int) -> np.ndarray:
    """PyBullet's step-sampled visit histogram at ``angle`` [deg]: the sum of
    ``pybullet_batches`` trials of ``bouncesim validate --backend pybullet``'s own trial
    function, seeded as its sweep seeds trial i of root seed ``seed``.
    """
    from bouncesim.commands.validate import simulate_trial
    from bouncesim.runs.sweep import trial_seed
    s = TV_SETTING
    params = {"env": s["env"], "cell_size": None, "orientations": cs.K,
              "angles": repr(float(angle)), "alpha": "1.0", "eps": float(s["eps"]),
              "r": float(s["r"]), "backend": "pybullet", "robots": s["pybullet_robots"],
              "steps": s["pybullet_steps"], "burn_in": s["pybullet_burn_in"],
              "epoch": MIX_EPOCH, "speed": 0.3,
              "contact": " ".join(repr(float(x)) for x in s["pybullet_contact"])}
    counts = np.zeros(cs.P, dtype=np.int64)
    for i in range(s["pybullet_batches"]):
        res = simulate_trial(params, np.random.default_rng(trial_seed(seed, i)))
        counts += np.array(res["counts"].split(), dtype=np.int64)
    return counts


def compute_tv(pybullet: bool = True, floors: bool = True, twin: bool = True) -> dict:
    """TV(predicted, simulated) per angle (and the noise floors when ``floors``): the twin
    against every model of ``TV_SETTING["models"]`` (keys ``twin`` for the step model,
    ``twin_<model>`` for the others; skipped without ``twin``), PyBullet against
    ``pybullet_model`` with PyBullet's contact rule (key ``pybullet``).
    """
    s = TV_SETTING
    cs = CellSpace(envs.load(s["env"], orientations=s["orientations"]))
    noise = TurnNoise(s["eps"], s["r"])
    out = {"setting": {k: (list(v) if isinstance(v, tuple) else v) for k, v in s.items()},
           "pybullet": {}}
    preds = {m: design_mix(model_for(cs, m), s["angles"], noise)
             for m in (s["models"] if twin else ())}
    for a_i, a in enumerate(s["angles"] if twin else ()):
        hist = twin_histogram(cs, a, s["seed"])
        floor = None
        if floors:
            h = [twin_histogram(cs, a, sd) for sd in s["floor_seeds"]]
            floor = max(tv_distance(h[i], h[j]) for i in range(len(h)) for j in range(i))
        for m, pr in preds.items():
            entry = {"tv": tv_distance(pr.per_angle[a_i].q, hist)}
            if floor is not None:
                entry["noise_floor"] = floor
            out.setdefault("twin" if m == "step" else f"twin_{m}", {})[f"{a:g}"] = entry
    if pybullet:
        a = s["pybullet_angle"]
        contact = ContactParams(*s["pybullet_contact"])
        q = model_for(cs, s["pybullet_model"], {"contact": contact}).analyse(a, noise).q
        entry = {"tv": tv_distance(q, pybullet_histogram(cs, a, s["pybullet_seeds"][0]))}
        if floors:
            h = [pybullet_histogram(cs, a, sd) for sd in s["pybullet_seeds"]]
            entry["noise_floor"] = max(tv_distance(h[i], h[j]) for i in range(len(h))
                                       for j in range(i))
        out["pybullet"][f"{a:g}"] = entry
    return out


# ----------------------------------------------------------------------------- files
FILES = {"coverage": compute_coverage, "plans": compute_plans, "tv": compute_tv}


def load(name: str):
    return json.loads((GOLDEN_DIR / f"{name}.json").read_text())


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m tests.regression",
                                description="Recompute the CI regression's golden numbers; "
                                "compare with tests/golden/*.json or overwrite them.")
    p.add_argument("--write", action="store_true", help="overwrite the golden files")
    p.add_argument("--only", choices=sorted(FILES), action="append",
                   help="just this file (repeatable)")
    args = p.parse_args(argv)
    GOLDEN_DIR.mkdir(exist_ok=True)
    status = 0
    for name in args.only or sorted(FILES):
        new = FILES[name]()
        path = GOLDEN_DIR / f"{name}.json"
        text = json.dumps(new, indent=1, sort_keys=True) + "\n"
        if args.write:
            path.write_text(text)
            print(f"wrote {path.name}")
        elif not path.exists() or json.loads(path.read_text()) != json.loads(text):
            print(f"{path.name}: differs from the recomputed numbers (run with --write to "
                  "accept them after review)")
            status = 1
        else:
            print(f"{path.name}: unchanged")
    return status


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
