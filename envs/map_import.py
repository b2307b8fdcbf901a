"""Occupancy maps to env dicts: the cell size, snapping walls to the grid, the import report.

:func:`build_env` runs the steps of :mod:`envs.raster` (clean, trace) on a read map, can
snap the walls onto the cell grid (:func:`snap`), validates the result as an
:class:`~envs.Environment` and reports what the import did (:class:`ImportReport`):
docs/model.md §3, docs/readme_maps.md.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import shapely
from shapely.geometry import Polygon

from .environment import Environment
from .errors import UserError
from .raster import OccupancyMap, clean, hausdorff_to_raster, largest_part, read_map, trace

__all__ = ["ImportReport", "build_env", "env_json", "import_map", "snap", "suggest_cell_size"]


@dataclass(frozen=True)
class ImportReport:
    """What an import did, in numbers.

    Parameters
    ----------
    pixels : tuple of int
        (rows, columns) of the image.
    resolution : float
        Pixel edge [m].
    free_pixels, region_pixels : int
        Free pixels after thresholding; pixels of the kept region after cleaning.
    filled_pixels : int
        Pixels of the region that were not free before the cleaning (specks, notches).
    raster_area, area : float
        Area of the kept raster region and of the env's free space E [m²].
    area_change : float
        area / raster_area − 1.
    vertices : int
        Vertices of the boundary plus the obstacles (each ring counted once).
    obstacles : int
        Number of obstacle polygons.
    hausdorff : float
        Hausdorff distance between the walls of E and the kept region's pixel edges [m].
    snapped : bool
        Whether the walls were snapped onto the cell grid.
    snap_hausdorff, snap_iou : float or None
        With ``snapped``: how far snapping moved the walls [m] (Hausdorff distance between the
        walls before and after), and the IoU of the free space before and after.
    cell_size : float
        The env's cell size h [m].
    free_cells : int
        Free position cells P at that cell size (docs/model.md §4).
    """

    pixels: tuple[int, int]
    resolution: float
    free_pixels: int
    region_pixels: int
    filled_pixels: int
    raster_area: float
    area: float
    area_change: float
    vertices: int
    obstacles: int
    hausdorff: float
    snapped: bool
    snap_hausdorff: float | None
    snap_iou: float | None
    cell_size: float
    free_cells: int


# ----------------------------------------------------------------------------- the cell grid
def suggest_cell_size(robot_radius: float) -> float:
    """The cell size to use [m]: the robot's diameter 2r, the paper's choice (docs/model.md
    §2's default), with which a cell next to a grid-line wall has its centre exactly r away.

    >>> suggest_cell_size(0.17)
    0.34
    """
    return 2.0 * float(robot_radius)


def snap(free: Polygon, cell_size: float, shifts: int = 4) -> tuple[Polygon, tuple]:
    """(snapped, (x0, y0)): the free space rebuilt from whole cells of a square grid, with
    its walls on the grid lines.

    A cell belongs to the snapped free space when at least half of its area is free. The
    grid's origin is tried at ``shifts`` × ``shifts`` offsets (multiples of h/shifts from the
    lower-left corner of the free space's bounding box); the one with the largest IoU with
    ``free`` wins. The largest connected piece is kept; the returned origin (x0, y0) [m] is
    the lower-left corner of its bounding box, a grid point.
    """
    h = float(cell_size)
    bx0, by0, bx1, by1 = free.bounds
    shapely.prepare(free)
    best = None
    for sx in range(shifts):
        for sy in range(shifts):
            gx, gy = bx0 - sx * h / shifts, by0 - sy * h / shifts
            nx, ny = math.ceil((bx1 - gx) / h - 1e-9), math.ceil((by1 - gy) / h - 1e-9)
            ii, jj = np.meshgrid(np.arange(nx), np.arange(ny))
            boxes = shapely.box(gx + ii.ravel() * h, gy + jj.ravel() * h,
                                gx + (ii.ravel() + 1) * h, gy + (jj.ravel() + 1) * h)
            frac = shapely.area(shapely.intersection(boxes, free)) / (h * h)
            keep = boxes[frac >= 0.5 - 1e-9]
            if len(keep) == 0:
                continue
            # snap the corners to exact multiples so that the union has no slivers
            cand = largest_part(shapely.set_precision(shapely.union_all(keep), h * 1e-6))
            iou = cand.intersection(free).area / cand.union(free).area
            if best is None or iou > best[0] + 1e-12:
                best = (iou, cand)
    if best is None:
        raise UserError(f"no cell of {h:g} m is at least half free; use a smaller cell size.")
    poly = shapely.simplify(best[1], 0)                  # drop collinear grid vertices
    return poly, tuple(poly.bounds[:2])


# ----------------------------------------------------------------------------- env dict
def env_json(data: dict) -> str:
    """An env dict as JSON text, one [x, y] vertex per line.

    >>> print(env_json({"boundary": [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]}), end="")
    {
     "boundary": [
      [0.0, 0.0],
      [1.0, 0.0],
      [0.0, 1.0]
     ]
    }
    """
    text = json.dumps(data, indent=1, ensure_ascii=False)
    num = r"(-?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?)"
    return re.sub(r"\[\s+" + num + r",\s+" + num + r"\s+\]", r"[\1, \2]", text) + "\n"


def _ring(coords) -> list:
    return [[round(float(x), 6), round(float(y), 6)] for x, y in list(coords)[:-1]]


def build_env(omap: OccupancyMap, *, robot_radius: float = 0.17, cell_size: float | None = None,
              orientations: int = 8, snap_walls: bool = False, tolerance: float | None = None,
              min_area: int = 4, name: str | None = None) -> tuple[dict, ImportReport]:
    """(env dict, report): the environment of an occupancy map (docs/model.md §2, §3).

    Parameters
    ----------
    omap : OccupancyMap
        From :func:`envs.raster.read_map`.
    robot_radius : float
        r [m].
    cell_size : float, optional
        h [m]; default :func:`suggest_cell_size`.
    orientations : int
        K.
    snap_walls : bool
        Rebuild the free space from whole cells (:func:`snap`), walls on the grid lines.
    tolerance : float, optional
        Simplification tolerance [m] (default :data:`envs.raster.TOLERANCE_PX` pixels).
    min_area : int
        Fill not-free specks of at most this many pixels inside the free region.
    name : str, optional
        The env's name (default: the map file's stem).
    """
    if not (isinstance(robot_radius, (int, float)) and robot_radius > 0):
        raise UserError(f"the robot radius must be a positive number of metres, "
                        f"got {robot_radius!r}.")
    h = suggest_cell_size(robot_radius) if cell_size is None else float(cell_size)
    if not (math.isfinite(h) and h > 0):
        raise UserError(f"the cell size must be a positive number of metres, got {h!r}.")
    if tolerance is not None and not (math.isfinite(tolerance) and tolerance >= 0):
        raise UserError(f"the tolerance must be a non-negative number of metres, "
                        f"got {tolerance!r}.")
    if isinstance(min_area, bool) or not isinstance(min_area, int) or min_area < 0:
        raise UserError(f"the minimum speck area must be a whole number of pixels >= 0, "
                        f"got {min_area!r}.")
    region, filled = clean(omap.free, min_area)
    res = omap.resolution
    poly = trace(region, res, omap.origin, tolerance)
    raster_area = float(region.sum()) * res * res
    haus = hausdorff_to_raster(poly, region, res, omap.origin)
    snap_h = snap_iou = None
    if snap_walls:
        snapped, _ = snap(poly, h)
        snap_h = float(shapely.hausdorff_distance(snapped.boundary, poly.boundary,
                                                  densify=0.05))
        snap_iou = float(snapped.intersection(poly).area / snapped.union(poly).area)
        poly = snapped
        haus = hausdorff_to_raster(poly, region, res, omap.origin)
    poly = shapely.orient_polygons(poly) if hasattr(shapely, "orient_polygons") else \
        shapely.geometry.polygon.orient(poly)
    stem = Path(omap.source).stem or "map"
    x0, y0, yaw = omap.origin
    data = {
        "name": name or stem,
        "description": (f"Imported from the occupancy map {omap.source} "
                        f"({omap.free.shape[1]} x {omap.free.shape[0]} pixels of {res:g} m) "
                        "by bouncesim import-map" + (", walls snapped to the cell grid"
                                                     if snap_walls else "") + "."),
        "boundary": _ring(poly.exterior.coords),
        "obstacles": [_ring(r.coords) for r in poly.interiors],
        "robot_radius": float(robot_radius),
        "discretization": {"cell_size": h, "orientations": int(orientations)},
    }
    env = Environment.from_dict(data)
    report = ImportReport(
        pixels=tuple(int(v) for v in omap.free.shape), resolution=res,
        free_pixels=int(omap.free.sum()), region_pixels=int(region.sum()),
        filled_pixels=filled, raster_area=raster_area, area=float(env.free_space.area),
        area_change=float(env.free_space.area / raster_area - 1.0),
        vertices=len(data["boundary"]) + sum(len(o) for o in data["obstacles"]),
        obstacles=len(data["obstacles"]), hausdorff=haus, snapped=bool(snap_walls),
        snap_hausdorff=snap_h, snap_iou=snap_iou, cell_size=h,
        free_cells=int(env.grid_centres_free().sum()))
    data["meta"] = {"import": {"map": omap.source, "resolution": res,
                               "origin": [x0, y0, yaw], "snap": bool(snap_walls),
                               "hausdorff_m": round(haus, 6),
                               "area_change": round(report.area_change, 6)}}
    return data, report



def import_map(path: str | Path, *, resolution: float | None = None, origin=None,
               negate: bool = False, **options) -> tuple[Environment, ImportReport]:
    """(environment, report) of an occupancy map file: :func:`envs.raster.read_map` then
    :func:`build_env` (``options`` are its keywords), in one call for notebooks.

    Examples
    --------
    >>> from importlib.resources import files
    >>> env, report = import_map(files("envs") / "catalog" / "maps" / "studio.yaml")
    >>> env.name, report.obstacles, report.hausdorff < 0.06
    ('studio', 1, True)
    """
    omap = read_map(path, resolution=resolution, origin=origin, negate=negate)
    data, report = build_env(omap, **options)
    return Environment.from_dict(data), report
