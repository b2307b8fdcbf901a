"""``bouncesim import-map MAP --out ENV.json``: an occupancy-grid map as an environment.

Reads a ROS ``map_server`` map (YAML + PGM/PNG) or a plain occupancy image, thresholds,
cleans, traces and simplifies it (:mod:`envs.raster`), optionally snaps the walls onto the
cell grid, and writes an env file (docs/model.md §2, §3; docs/readme_maps.md).
"""

from __future__ import annotations

import argparse
from dataclasses import asdict

from envs import Environment, UserError
from envs.diagnostics import diagnose
from envs.map_import import build_env, env_json
from envs.raster import TOLERANCE_PX, read_map

from .common import add_output, print_json, warn

__all__ = ["format_report", "register", "run"]


def register(sub) -> None:
    """Add the ``import-map`` sub-command to the CLI's sub-parsers."""
    p = sub.add_parser(
        "import-map", help="turn an occupancy-grid map (ROS YAML + PGM/PNG) into an env file",
        description="Read MAP (a ROS map_server YAML naming its image, or a plain occupancy "
        "image with --resolution), threshold it as map_server does (unknown counts as wall), "
        "remove salt-and-pepper specks, trace the largest free region with sub-pixel "
        "accuracy, simplify it and write the env file: its outline is the boundary, its "
        "holes the obstacles (docs/model.md §3).",
        epilog="examples:\n  bouncesim import-map office.yaml --out office.json\n"
        "  bouncesim import-map scan.png --resolution 0.05 --origin -2,-1.5 --snap "
        "--out scan.json --json",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("map", metavar="MAP", help="a ROS map YAML, or an image (PGM, PNG, ...)")
    add_output(p, "--out", required=True, metavar="ENV.json", help="env file to write")
    p.add_argument("--resolution", type=float, default=None, metavar="M",
                   help="pixel size [m] of a plain image (a YAML gives its own)")
    p.add_argument("--origin", default=None, metavar="X,Y[,YAW]",
                   help="a plain image's lower-left corner [m] (and yaw [rad]); default 0,0")
    p.add_argument("--negate", action="store_true",
                   help="a plain image is white for occupied (a YAML says 'negate')")
    p.add_argument("--robot-radius", type=float, default=0.17, metavar="M",
                   help="robot radius r [m] (default 0.17, the Create 2)")
    p.add_argument("--cell-size", type=float, default=None, metavar="M",
                   help="cell size h [m] (default: the suggested 2r, the robot's diameter)")
    p.add_argument("--orientations", type=int, default=8, metavar="K",
                   help="number of orientations K (default 8)")
    p.add_argument("--snap", action="store_true",
                   help="put the walls on the cell grid: the free space becomes the cells "
                   "at least half free (the step model's walls, docs/model.md §7)")
    p.add_argument("--tolerance", type=float, default=None, metavar="M",
                   help=f"simplification tolerance [m] (default {TOLERANCE_PX:g} x the pixel size)")
    p.add_argument("--min-area", type=int, default=4, metavar="PIXELS",
                   help="fill not-free specks of at most this many pixels inside the free "
                   "region (default 4)")
    p.add_argument("--name", default=None, help="the env's name (default: the map's name)")
    p.add_argument("--json", action="store_true", help="print the report as one JSON object")
    p.set_defaults(func=run)


def _origin(text: str | None):
    if text is None:
        return None
    try:
        return tuple(float(t) for t in text.replace(";", ",").split(",") if t.strip())
    except ValueError:
        raise UserError(f"--origin {text!r} must be X,Y or X,Y,YAW (numbers).") from None


def format_report(report) -> str:
    """The import report as an aligned text table."""
    r = report
    rows = [("pixels", f"{r.pixels[1]} x {r.pixels[0]} at {r.resolution:g} m"),
            ("free region", f"{r.region_pixels} pixels ({r.filled_pixels} filled by cleaning)"),
            ("vertices", f"{r.vertices} ({r.obstacles} obstacle(s))"),
            ("area", f"{r.area:.4g} m² (raster {r.raster_area:.4g} m², "
                     f"change {100 * r.area_change:+.2f}%)"),
            ("Hausdorff", f"{r.hausdorff:.4f} m to the raster "
                          f"({r.hausdorff / r.resolution:.2f} pixels)")]
    if r.snapped:
        rows.append(("snap", f"walls moved up to {r.snap_hausdorff:.4f} m, "
                             f"IoU {r.snap_iou:.4f} with the unsnapped free space"))
    rows.append(("cells", f"h = {r.cell_size:g} m, P = {r.free_cells} free position cells"))
    return "\n".join(f"{k:>12}: {v}" for k, v in rows)


def run(args) -> int:
    """Run ``bouncesim import-map``: read, convert, write the env file; exit status."""
    out = args.out                          # checked before the work (add_output)
    omap = read_map(args.map, resolution=args.resolution, origin=_origin(args.origin),
                    negate=args.negate)
    data, report = build_env(omap, robot_radius=args.robot_radius, cell_size=args.cell_size,
                             orientations=args.orientations, snap_walls=args.snap,
                             tolerance=args.tolerance, min_area=args.min_area, name=args.name)
    out.write_text(env_json(data))
    for w in diagnose(Environment.from_dict(data)):
        warn(w.message)
    if args.json:
        print_json({"out": str(out), **asdict(report)})
    else:
        print(f"wrote {out}")
        print(format_report(report))
    return 0
