"""``bouncesim plan``: shortest bouncing plans for one or many (start, goal) queries."""

from __future__ import annotations

import csv
import inspect
import math
import sys
from pathlib import Path

import numpy as np

from bouncesim.robots.noise import parse_noise
from envs import UserError
from planners.cells import CellSpace
from planners.navigation import PLANNERS, Route, make_planner, planner_class
from planners.navigation.feedback import FeedbackConfig
from planners.navigation.reliable import DEFAULT_PARTICLES, DEFAULT_SLACK

from .common import (
    add_contact_arg,
    add_env_args,
    check_fits,
    contact_rule,
    flush_warnings,
    load_env,
    make_cells,
    max_memory,
    parse_angles,
    print_json,
)

__all__ = ["add_planner_args", "make_planner_of", "parse_config", "register", "run"]

EXIT_NO_PATH = 3


def parse_config(text: str, cells: CellSpace, what: str = "start") -> int:
    """A configuration index z, or a pose ``X,Y,DEG`` [m, m, deg] mapped to its free cell.

    >>> import envs
    >>> cs = CellSpace(envs.load("lab"))
    >>> parse_config("8", cs), parse_config("2.55,0.17,90", cs)
    (8, 103)
    """
    s = str(text).strip()
    parts = [t for t in s.replace(";", ",").split(",") if t.strip()]
    if len(parts) == 1:
        try:
            z = int(parts[0])
        except ValueError:
            raise UserError(f"{what} {s!r} is neither a configuration index nor a pose "
                            "X,Y,DEG.") from None
        if not 0 <= z < cells.N:
            raise UserError(f"{what} {z} is out of range: configurations are 0 to "
                            f"{cells.N - 1}.")
        return z
    if len(parts) != 3:
        raise UserError(f"{what} {s!r} must be a configuration index or a pose X,Y,DEG.")
    try:
        x, y, deg = (float(t) for t in parts)
    except ValueError:
        raise UserError(f"{what} pose {s!r} has a part that is not a number.") from None
    if not all(map(math.isfinite, (x, y, deg))):
        raise UserError(f"{what} pose {s!r} has a part that is not a finite number.")
    z = cells.config_of_pose(x, y, deg)
    if z < 0:
        raise UserError(f"{what} pose ({x:g}, {y:g}) is not in a free cell.")
    return z


def add_planner_args(p) -> None:
    """Add ``--angles``, ``--w1``, ``--w2`` and ``--planner`` (a name of
    :data:`planners.navigation.PLANNERS`) to a parser.
    """
    p.add_argument("--angles", required=True, metavar="A,B,...",
                   help="bouncing angles [deg], multiples of 360/K, e.g. 45,90,135")
    p.add_argument("--w1", type=float, default=1.0,
                   help="weight of a step or a same-angle bump (default 1)")
    p.add_argument("--w2", type=float, default=100.0,
                   help="weight of a bump that changes the angle (default 100)")
    p.add_argument("--planner", choices=tuple(PLANNERS), default="step",
                   help="step: the paper's step model (docs/model.md §12, default); exact: "
                   "plans over exact bump poses that a continuous robot follows (§13); "
                   "reliable: the near-optimal exact plan most likely to succeed under "
                   "--noise (§14); feedback: a particle filter re-plans after every bump "
                   "(§15; `plan` prints its plan from the start before any bump)")


def make_planner_of(args, cells: CellSpace | None = None, rng=None, noise=None):
    """The planner of ``--planner`` for the parsed environment, angles and weights, with what
    it needs (its ``needs``): the turn noise of ``--noise`` (or ``noise``), the random source
    ``rng`` (default: a stream of its own from ``--seed``), the contact rule of ``--contact``
    where the command has one. Refused in one sentence above --max-memory, before building.
    """
    if cells is None:
        cells = make_cells(args, load_env(args))
    cls = planner_class(args.planner)
    contact = contact_rule(args) if hasattr(args, "contact") else None
    if contact is not None and "contact" not in cls.needs:
        users = ", ".join(n for n, c in PLANNERS.items() if "contact" in c.needs)
        raise UserError(f"--contact is for the planners that plan for a contact rule "
                        f"({users}); the {args.planner} planner assumes the front-half "
                        "bumper.")
    kw: dict = {}
    if "noise" in cls.needs:
        kw["noise"] = noise if noise is not None else \
            parse_noise(getattr(args, "noise", "none"), cells.delta_deg)
    if "rng" in cls.needs:              # its particles: a stream of their own from --seed
        kw["rng"] = rng if rng is not None else np.random.default_rng([args.seed, 20])
    params = inspect.signature(cls).parameters
    if "contact" in cls.needs and hasattr(args, "contact"):
        # "auto" for a planner that resolves it itself (feedback: the executing body's rule)
        takes_auto = "contact" in params and params["contact"].default == "auto"
        kw["contact"] = "auto" if args.contact == "auto" and takes_auto else contact
    for opt in ("particles", "slack"):
        if opt in params and hasattr(args, opt):
            kw[opt] = getattr(args, opt)
    if "config" in params:
        kw["config"] = FeedbackConfig()
    est = cls.memory_estimate(cells, parse_angles(args.angles))
    check_fits(args, cells, est)
    return make_planner(args.planner, cells, parse_angles(args.angles), w1=args.w1,
                        w2=args.w2, max_memory=max_memory(args), **kw)


def register(sub) -> None:
    """Add the ``plan`` sub-command to the CLI's sub-parsers."""
    p = sub.add_parser(
        "plan", help="shortest bouncing plan from a start to a goal configuration",
        description="Find the minimum-weight observation string from START to GOAL on the "
        "layered roadmap (docs/model.md §12). START and GOAL are configuration indices z = k*P + p "
        "(0-based; the paper's id is z + 1) or poses X,Y,DEG [m, m, deg] mapped to their "
        "cell. Exit status 3 when a single query has no path.",
        epilog="examples:\n  bouncesim plan lab --angles 90,135 --start 8 --goal 0\n"
        "  bouncesim plan lab --angles 45,90,135 --start 2.55,0.17,90 --goal 8 --json\n"
        "  bouncesim plan complex --angles 45,90,135 --pairs queries.csv --json\n"
        "  bouncesim plan complex --angles 45,90,135 --start 8 --goal 900 --planner exact",
        formatter_class=__import__("argparse").RawDescriptionHelpFormatter)
    add_env_args(p)
    add_planner_args(p)
    p.add_argument("--start", metavar="S", help="start: z or X,Y,DEG")
    p.add_argument("--goal", metavar="G", help="goal: z or X,Y,DEG")
    p.add_argument("--pairs", type=Path, metavar="FILE.csv",
                   help="many queries: a CSV with columns start,goal (z or \"X,Y,DEG\")")
    p.add_argument("--json", action="store_true", help="one JSON object per query and line")
    add_contact_arg(p, what=" the exact and reliable planners plan for")
    p.add_argument("--noise", default="none", metavar="SPEC",
                   help="reliable: the rotation noise to plan for, gauss:SIGMA or "
                   "model:eps=E,r=R [deg] (default none)")
    p.add_argument("--particles", type=int, default=DEFAULT_PARTICLES, metavar="N",
                   help=f"reliable: particles per success estimate (default "
                   f"{DEFAULT_PARTICLES})")
    p.add_argument("--slack", type=float, default=DEFAULT_SLACK, metavar="COST",
                   help=f"reliable: candidates cost at most this more than the cheapest "
                   f"(default {DEFAULT_SLACK:g})")
    p.add_argument("--seed", type=int, default=0, help="reliable: seed of the particles")
    p.set_defaults(func=run)


def _read_pairs(path: Path) -> list[tuple[str, str, int]]:
    """The (start, goal, line number) rows of a --pairs file."""
    try:
        with open(path, newline="") as fh:
            reader = csv.DictReader(fh)
            if reader.fieldnames is None or not {"start", "goal"} <= set(reader.fieldnames):
                raise UserError(f"{path} needs the columns start,goal.")
            return [(row["start"], row["goal"], reader.line_num) for row in reader]
    except FileNotFoundError:
        raise UserError(f"no pairs file at {path}.") from None
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        reason = getattr(exc, "strerror", None) or str(exc).rstrip(".")
        raise UserError(f"cannot read the pairs file {path} ({reason}).") from None


def _resolve_row(row, cells: CellSpace, path: Path) -> tuple[int, int]:
    start, goal, line = row
    try:
        if start is None or goal is None or not start.strip() or not goal.strip():
            raise UserError(f"the row has no {'start' if not (start or '').strip() else 'goal'}.")
        return parse_config(start, cells, "start"), parse_config(goal, cells, "goal")
    except UserError as exc:
        raise UserError(f"{path}, line {line}: {exc}") from None


def run(args) -> int:
    """Run ``bouncesim plan`` for one query or a CSV of pairs; exit status (3: no plan)."""
    if args.pairs is None and (args.start is None or args.goal is None):
        raise UserError("give --start and --goal, or --pairs FILE.csv.")
    if args.pairs is not None and (args.start is not None or args.goal is not None):
        raise UserError("give either --start/--goal or --pairs, not both.")
    nav = make_planner_of(args)
    cells = nav.cells
    if args.pairs is None:
        resolved = [(parse_config(args.start, cells, "start"),
                     parse_config(args.goal, cells, "goal"))]
    else:       # every row is checked before any planning; an error names its line
        resolved = [_resolve_row(row, cells, args.pairs) for row in _read_pairs(args.pairs)]
    flush_warnings()
    missing = 0
    for s, g in resolved:
        route = nav.plan(s, g)
        if route is None:
            missing += 1
        if args.json:
            print_json(route.to_json() if route else Route.none_json(s, g, args.planner))
        elif route is None:
            print(f"{s} -> {g}: no path with angles "
                  f"{', '.join(f'{a:g}°' for a in nav.angles)}")
        elif route.plan.is_exact:
            print(f"{s} -> {g}: {route.plan.exact_text()}  (cost {route.cost:.4g}, "
                  f"{route.angles_used} angle(s), {route.plan.bumps} bumps; the zeros are "
                  f"round(flight / h), approximate off the axes)")
            if "p_success_ci" in route.extras:
                lo, hi = route.p_success_ci
                print(f"  p_success {route.p_success:.3f} [{lo:.3f}, {hi:.3f}] under "
                      f"{route.noise} ({route.particles} particles; {route.candidates} "
                      f"candidates, the exact plan's {route.p_exact:.3f})")
        else:
            print(f"{s} -> {g}: {route.plan}  (cost {route.cost:g}, "
                  f"{route.angles_used} angle(s), {len(route.plan)} observations)")
    sys.stdout.flush()
    return EXIT_NO_PATH if (args.pairs is None and missing) else 0
