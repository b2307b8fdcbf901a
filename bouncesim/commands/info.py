"""``bouncesim info ENV``: sizes of the cell model."""

from __future__ import annotations

from envs.diagnostics import diagnose

from .common import add_env_args, load_env, make_cells, print_json


def register(sub) -> None:
    """Add the ``info`` sub-command to the CLI's sub-parsers."""
    p = sub.add_parser("info", help="print the cell model's sizes (P, N, K, ...)",
                       description="Load ENV and print the number of free position cells P, "
                       "configurations N = K*P, orientations K, cell size, bounds and radius, "
                       "and the map's warnings (docs/model.md section 4a).")
    add_env_args(p)
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=run)


def run(args) -> int:
    """Run ``bouncesim info``: print the cell model's sizes; exit status."""
    env = load_env(args, warnings=False)        # listed below instead
    cs = make_cells(args, env)
    warnings = diagnose(env)
    info = {"name": env.name, "P": cs.P, "N": cs.N, "K": cs.K, "cell_size": env.cell_size,
            "bounds": list(env.bounds), "robot_radius": env.robot_radius,
            "grid": list(env.grid_shape)}
    if args.json:
        print_json({**info, "warnings": [w.to_json() for w in warnings]})
    else:
        for k, v in info.items():
            print(f"{k:>13}: {v}")
        print(f"{'warnings':>13}: {len(warnings) or 'none'}")
        for w in warnings:
            print(f"{'':>13}  [{w.code}] {w.message}")
    return 0
