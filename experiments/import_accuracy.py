"""Accuracy of the map import: traced outlines against the polygons the maps were drawn from.

Each known free space (three synthetic 10 m x 10 m maps: a rectangle with a rectangular
pillar, a hexagonal room with a hexagonal pillar, an L-room with a slanted wall; and the
catalogue's ``studio``) is rasterised at 0.05 m (a pixel is free when its centre is inside),
salt-and-pepper noise flips a fraction of the pixels, and the map is cleaned
(:func:`envs.raster.clean`) and traced by three tracers:

- ``marching+refit`` (what import-map does): marching squares, Douglas-Peucker, edge refit;
- ``marching``: marching squares and Douglas-Peucker only;
- ``pixel-edges``: the union of the kept pixels' squares (the exact pixel-edge polygon that
  ``rasterio.features.shapes`` returns; rasterio itself is not a dependency), then
  Douglas-Peucker (shapely, topology-preserving).

Outputs (under ``--out``, default results/import_accuracy/): ``accuracy.csv`` (shape, noise,
seed, tracer, tolerance [px], IoU and Hausdorff distance [px] to the original polygon,
vertices, obstacles, seconds) and ``config.json``. ``--quick``: noise 0 and 2 %, one seed,
τ = 1 px.

    python -m experiments.import_accuracy            # 6 seeds x 4 noise levels
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass

import numpy as np
import pandas as pd
import shapely
from shapely.geometry import Polygon, box

from envs.raster import clean, largest_part, trace
from experiments.common import experiment_parser, output_dir, write_config
from experiments.example_map import room

__all__ = ["SHAPES", "TRACERS", "Config", "main", "run", "summary"]

NAME = "import_accuracy"
RES = 0.05


def _hexagon(cx, cy, radius, rot_deg) -> Polygon:
    a = np.radians(rot_deg) + np.arange(6) * np.pi / 3
    return Polygon(np.c_[cx + radius * np.cos(a), cy + radius * np.sin(a)])


SHAPES = {
    "rect_pillar": box(0.5, 0.5, 8.5, 6.5).difference(box(3.0, 2.0, 4.5, 3.5)),
    "hex_room_hex_pillar": _hexagon(5, 5, 4.3, 10).difference(_hexagon(5.3, 4.6, 1.0, 25)),
    "L_slanted_wall": Polygon([(0.6, 0.6), (8.6, 0.6), (8.6, 3.4), (4.2, 4.6), (4.2, 8.4),
                               (0.6, 8.4)]),
    "studio": shapely.affinity.translate(room(), 0.5, 0.5),
}


@dataclass(frozen=True)
class Config:
    """Noise fractions, seeds per noise level, tolerances [px], root seed, output folder."""

    quick: bool = False
    noises: tuple[float, ...] = (0.0, 0.01, 0.02, 0.05)
    seeds: int = 6
    tolerances: tuple[float, ...] = (1.0, 1.5)
    seed: int = 0
    out: str = f"results/{NAME}"


def _rasterize(free: Polygon) -> np.ndarray:
    c, r = np.meshgrid(np.arange(200), np.arange(200))
    return shapely.contains_xy(free, (c + 0.5) * RES, (200 - r - 0.5) * RES)


def _pixel_edges(region: np.ndarray, tol: float) -> Polygon:
    """Union of the region's pixels (row runs merged first), simplified at ``tol`` [m]."""
    boxes = []
    n = region.shape[0]
    for r in range(n):
        row = np.concatenate([[False], region[r], [False]]).astype(np.int8)
        starts, ends = np.nonzero(np.diff(row) == 1)[0], np.nonzero(np.diff(row) == -1)[0]
        boxes += list(shapely.box(starts * RES, (n - r - 1) * RES, ends * RES, (n - r) * RES))
    poly = largest_part(shapely.union_all(boxes))
    return largest_part(shapely.simplify(poly, tol, preserve_topology=True))


TRACERS = ("marching+refit", "marching", "pixel-edges")


def _trace(name: str, region: np.ndarray, tol: float) -> Polygon:
    if name == "pixel-edges":
        return _pixel_edges(region, tol)
    return trace(region, RES, (0.0, 0.0, 0.0), tol, refine=name == "marching+refit")


def run(config: Config) -> pd.DataFrame:
    """Every (shape, noise, seed, tracer, tolerance): the accuracy row; writes the CSV."""
    rows = []
    root = np.random.SeedSequence(config.seed)
    trace(np.ones((3, 3), bool), RES, (0.0, 0.0, 0.0))      # import scikit-image untimed
    for shape, truth in SHAPES.items():
        mask = _rasterize(truth)
        for noise in config.noises:
            seeds = root.spawn(config.seeds if noise else 1)
            for k, ss in enumerate(seeds):
                rng = np.random.default_rng(ss)
                img = np.where(rng.random(mask.shape) < noise, ~mask, mask)
                region, _ = clean(img)
                for tol in config.tolerances:
                    for name in TRACERS:
                        t0 = time.perf_counter()
                        poly = _trace(name, region, tol * RES)
                        dt = time.perf_counter() - t0
                        rows.append({
                            "shape": shape, "noise": noise, "seed": k, "tracer": name,
                            "tolerance_px": tol,
                            "iou": poly.intersection(truth).area / poly.union(truth).area,
                            "hausdorff_px": shapely.hausdorff_distance(
                                poly.boundary, truth.boundary, densify=0.01) / RES,
                            "vertices": sum(len(r.coords) - 1 for r in
                                            (poly.exterior, *poly.interiors)),
                            "obstacles": len(poly.interiors), "seconds": dt})
    df = pd.DataFrame(rows)
    out = output_dir(config.out)
    df.to_csv(out / "accuracy.csv", index=False)
    write_config(out, asdict(config))
    return df


def summary(df: pd.DataFrame) -> pd.DataFrame:
    """Worst IoU, worst and mean Hausdorff [px], mean vertices and time per tracer."""
    return df.groupby(["tracer", "tolerance_px", "noise"]).agg(
        iou_min=("iou", "min"), hausdorff_max_px=("hausdorff_px", "max"),
        hausdorff_mean_px=("hausdorff_px", "mean"), vertices=("vertices", "mean"),
        ms=("seconds", lambda s: 1000 * s.mean())).round(4)


def main(argv: list[str] | None = None) -> int:
    """Command line: ``--quick``, ``--seed``, ``--out``."""
    p = experiment_parser(NAME, __doc__.split("\n\n")[0])
    args = p.parse_args(argv)
    q = args.quick
    config = Config(quick=q, seeds=1 if q else 6, seed=args.seed, out=str(args.out),
                    noises=(0.0, 0.02) if q else Config.noises,
                    tolerances=(1.0,) if q else Config.tolerances)
    with pd.option_context("display.width", 160, "display.max_rows", 200,
                           "display.max_columns", 20):
        print(summary(run(config)))
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
