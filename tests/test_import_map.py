"""``bouncesim import-map`` and envs.raster / envs.map_import (docs/model.md §3).

The maps are rasterised here, independently of the code under test, from known shapely
polygons (a pixel is free when its centre is inside); accuracy is then measured with shapely
against the original polygon: IoU >= 0.99 and Hausdorff <= 1.5 px on synthetic maps with
salt-and-pepper noise, and the done-when check (IoU >= 0.98, Hausdorff <= 0.06 m) on a
ROS-style PGM + YAML map, followed by ``info``, ``plan`` and ``coverage`` on the result.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest
import shapely
from PIL import Image
from shapely.geometry import Polygon, box

import envs
from bouncesim.cli import main
from envs.map_import import build_env
from envs.raster import OccupancyMap, despeckle, read_map, threshold

RES = 0.05


def hexagon(cx, cy, radius, rot_deg=0.0) -> Polygon:
    a = np.radians(rot_deg) + np.arange(6) * np.pi / 3
    return Polygon(np.c_[cx + radius * np.cos(a), cy + radius * np.sin(a)])


SHAPES = {
    "rectangle with a rectangular pillar":
        box(0.5, 0.5, 8.5, 6.5).difference(box(3.0, 2.0, 4.5, 3.5)),
    "hexagonal room with a hexagonal pillar":
        hexagon(5, 5, 4.3, 10).difference(hexagon(5.3, 4.6, 1.0, 25)),
    "L-room with a slanted wall":
        Polygon([(0.6, 0.6), (8.6, 0.6), (8.6, 3.4), (4.2, 4.6), (4.2, 8.4), (0.6, 8.4)]),
}


def rasterize(free: Polygon, res: float, origin=(0.0, 0.0), size=(10.0, 10.0)) -> np.ndarray:
    """Free mask (row 0 = top): pixel centres inside ``free``; ROS's pixel convention."""
    ncols, nrows = int(round(size[0] / res)), int(round(size[1] / res))
    c, r = np.meshgrid(np.arange(ncols), np.arange(nrows))
    x = origin[0] + (c + 0.5) * res
    y = origin[1] + (nrows - r - 0.5) * res
    return shapely.contains_xy(free, x, y)


def salt_and_pepper(mask: np.ndarray, fraction: float, rng) -> np.ndarray:
    flip = rng.random(mask.shape) < fraction
    return np.where(flip, ~mask, mask)


def iou(a, b) -> float:
    return a.intersection(b).area / a.union(b).area


def hausdorff(a, b) -> float:
    return shapely.hausdorff_distance(a.boundary, b.boundary, densify=0.01)


def ros_image(free_mask: np.ndarray, wall_mask=None) -> np.ndarray:
    """map_saver's grey levels: free 254, occupied 0, unknown 205."""
    img = np.full(free_mask.shape, 205, np.uint8)
    if wall_mask is not None:
        img[wall_mask] = 0
    img[free_mask] = 254
    return img


def write_ros(tmp_path, img, name="room", res=RES, origin=(0.0, 0.0, 0.0), **keys):
    Image.fromarray(img).save(tmp_path / f"{name}.pgm")
    fields = {"image": f"{name}.pgm", "resolution": res, "origin": list(origin),
              "negate": 0, "occupied_thresh": 0.65, "free_thresh": 0.196, **keys}
    fields = {k: v for k, v in fields.items() if v is not None}
    path = tmp_path / f"{name}.yaml"
    path.write_text("".join(f"{k}: {json.dumps(v)}\n" for k, v in fields.items()))
    return path


# ----------------------------------------------------------------------------- thresholds
def test_threshold_follows_map_server_rules():
    # p = (255 - v)/255: occupied when p > 0.65, i.e. v < 89.25; free when p < 0.196, i.e.
    # v > 205.02; in between (205 included) unknown
    img = np.array([[0, 89, 90, 205, 206, 255]], np.uint8)
    free, occ = threshold(img)
    assert occ[0].tolist() == [True, True, False, False, False, False]
    assert free[0].tolist() == [False, False, False, False, True, True]
    # negate: p = v/255, so white is occupied: occupied when v > 165.75, free when v < 49.98
    free, occ = threshold(img, negate=True)
    assert occ[0].tolist() == [False, False, False, True, True, True]
    assert free[0].tolist() == [True, False, False, False, False, False]
    # colour channels are averaged; a transparent pixel is unknown
    rgba = np.array([[[255, 255, 255, 255], [255, 255, 255, 0], [0, 0, 90, 255]]], np.uint8)
    free, occ = threshold(rgba)
    assert free[0].tolist() == [True, False, False] and occ[0].tolist() == [False, False, True]
    # raw mode: the value is the occupancy in percent; above 100 unknown
    free, occ = threshold(np.array([[0, 19, 66, 100, 255]], np.uint8), mode="raw")
    assert free[0].tolist() == [True, True, False, False, False]
    assert occ[0].tolist() == [False, False, True, True, False]


def test_despeckle_removes_specks_spurs_and_notches_but_not_corners():
    clean = np.zeros((12, 14), bool)
    clean[2:10, 2:12] = True
    noisy = clean.copy()
    noisy[5, 12] = True      # a one-pixel spur on the east wall
    noisy[2, 6] = False      # a one-pixel notch in the north wall
    noisy[6, 6] = False      # a pepper speck inside
    noisy[11, 7] = True      # a salt speck outside
    assert np.array_equal(despeckle(noisy), clean)
    assert np.array_equal(despeckle(clean), clean)            # corners stay


# ----------------------------------------------------------------------------- accuracy
@pytest.mark.parametrize("name", list(SHAPES))
@pytest.mark.parametrize("noise,seed", [(0.0, 0), (0.02, 1), (0.02, 2)])
def test_synthetic_maps_within_targets(name, noise, seed):
    truth = SHAPES[name]
    mask = salt_and_pepper(rasterize(truth, RES), noise, np.random.default_rng(seed))
    omap = OccupancyMap(mask, ~mask, RES, (0.0, 0.0, 0.0), "synthetic.png")
    data, report = build_env(omap, robot_radius=0.17)
    env = envs.Environment.from_dict(data)
    assert iou(env.free_space, truth) >= 0.99
    assert hausdorff(env.free_space, truth) <= 1.5 * RES
    assert len(env.obstacles) == len(truth.interiors)
    # the report, checked against an independent construction of the raster's outline
    # (the union of the kept pixels' squares, the raster's exact free region)
    region_px = rasterize(env.free_space, RES).sum()
    assert abs(report.area - env.free_space.area) < 1e-9
    assert report.area_change == pytest.approx(report.area / report.raster_area - 1)
    assert abs(report.region_pixels - region_px) <= 0.02 * region_px
    assert report.vertices == sum(len(p.exterior.coords) - 1
                                  for p in (env.boundary, *env.obstacles))


def test_report_hausdorff_matches_the_pixel_squares():
    truth = SHAPES["L-room with a slanted wall"]
    mask = rasterize(truth, RES)
    omap = OccupancyMap(mask, ~mask, RES, (0.0, 0.0, 0.0), "l.png")
    data, report = build_env(omap)
    rows, cols = np.nonzero(mask)
    nrows = mask.shape[0]
    squares = shapely.union_all(shapely.box(cols * RES, (nrows - rows - 1) * RES,
                                            (cols + 1) * RES, (nrows - rows) * RES))
    env = envs.Environment.from_dict(data)
    # the report samples both outlines every quarter pixel: within an eighth of a pixel
    assert report.hausdorff == pytest.approx(hausdorff(env.free_space, squares), abs=RES / 8)
    assert report.raster_area == pytest.approx(squares.area)


# ----------------------------------------------------------------------------- conventions
def test_yaml_origin_rows_and_negate(tmp_path):
    # an asymmetric shape (an L with a notch) away from the origin, on a coarse grid; any
    # flip of rows or columns, or an origin at a pixel centre, would move it visibly
    res, origin = 0.1, (-1.2, 0.7)
    world = Polygon([(-1.0, 1.0), (1.5, 1.0), (1.5, 1.8), (0.2, 1.8), (0.2, 3.3), (-1.0, 3.3)])
    mask = rasterize(world, res, origin, size=(3.0, 3.0))
    img = np.where(mask, 255, 0).astype(np.uint8)          # negated: white is occupied ...
    img = 255 - img                                         # ... so free pixels are black
    yaml_path = write_ros(tmp_path, img, res=res, origin=(*origin, 0.0), negate=1,
                          occupied_thresh=0.9, free_thresh=0.1)
    data, _ = build_env(read_map(yaml_path))
    env = envs.Environment.from_dict(data)
    assert iou(env.free_space, world) >= 0.97
    assert hausdorff(env.free_space, world) <= 0.75 * res
    # the bounding box to within a pixel's sampling error
    assert np.allclose(env.bounds, world.bounds, atol=0.5 * res)


def test_yaw_rotates_about_the_origin(tmp_path):
    world = Polygon([(0.2, 0.2), (2.6, 0.2), (2.6, 1.0), (1.0, 1.0), (1.0, 1.8), (0.2, 1.8)])
    mask = rasterize(world, RES, size=(3.0, 2.0))
    yaml_path = write_ros(tmp_path, ros_image(mask, ~mask), origin=(1.0, -2.0, math.pi / 2))
    env = envs.Environment.from_dict(build_env(read_map(yaml_path))[0])
    # rotate by 90° about (0, 0), then shift by (1, -2): (x, y) -> (1 - y, -2 + x)
    expected = Polygon([(1 - y, -2 + x) for x, y in world.exterior.coords])
    assert iou(env.free_space, expected) >= 0.99


def test_plain_image_with_resolution_and_origin(tmp_path):
    local = SHAPES["L-room with a slanted wall"]
    world = shapely.affinity.translate(local, 5.0, -3.0)
    mask = rasterize(world, RES, origin=(5.0, -3.0))
    Image.fromarray(np.where(mask, 255, 0).astype(np.uint8)).save(tmp_path / "plain.png")
    out = tmp_path / "plain.json"
    rc = main(["import-map", str(tmp_path / "plain.png"), "--resolution", str(RES),
               "--origin", "5,-3", "--out", str(out)])
    assert rc == 0
    assert iou(envs.load(out).free_space, world) >= 0.99
    assert iou(envs.load(out).free_space, local) < 0.5      # the origin was applied


# ----------------------------------------------------------------------------- errors
def _err(capsys, argv):
    rc = main(argv)
    err = capsys.readouterr().err.strip().splitlines()
    return rc, err


def test_errors_are_one_sentence_exit_2(tmp_path, capsys):
    good = write_ros(tmp_path, ros_image(rasterize(box(1, 1, 4, 4), RES, size=(5, 5))))
    out = str(tmp_path / "env.json")
    # unreadable image
    (tmp_path / "junk.pgm").write_text("this is not an image")
    yaml_bad_image = tmp_path / "junk.yaml"
    yaml_bad_image.write_text(good.read_text().replace("room.pgm", "junk.pgm"))
    # missing YAML keys
    yaml_missing = tmp_path / "missing.yaml"
    yaml_missing.write_text("".join(line + "\n" for line in good.read_text().splitlines()
                                    if not line.startswith(("free_thresh", "negate"))))
    # no free region: an all-occupied image
    black = write_ros(tmp_path, np.zeros((20, 20), np.uint8), name="black")
    cases = {yaml_bad_image: "cannot read the map image",
             yaml_missing: "lacks the ROS map key(s) negate, free_thresh",
             black: "no free region",
             tmp_path / "nowhere.yaml": "no map file"}
    for path, words in cases.items():
        rc, err = _err(capsys, ["import-map", str(path), "--out", out])
        assert rc == 2 and len(err) == 1, (path, err)
        assert err[0].startswith("bouncesim: error: ") and words in err[0], err
    # a plain image without --resolution; an unwritable --out, refused before any work
    rc, err = _err(capsys, ["import-map", str(tmp_path / "room.pgm"), "--out", out])
    assert rc == 2 and len(err) == 1 and "--resolution" in err[0]
    rc, err = _err(capsys, ["import-map", str(yaml_bad_image), "--out", str(tmp_path)])
    assert rc == 2 and len(err) == 1 and "is a folder" in err[0]


# ----------------------------------------------------------------------------- snapping
def test_snap_puts_walls_on_the_cell_grid(tmp_path, capsys):
    truth = SHAPES["L-room with a slanted wall"]
    mask = rasterize(truth, RES)
    yaml_path = write_ros(tmp_path, ros_image(mask, ~mask))
    plain, snapped = tmp_path / "plain.json", tmp_path / "snapped.json"
    assert main(["import-map", str(yaml_path), "--out", str(plain)]) == 0
    h = 0.5
    capsys.readouterr()
    assert main(["import-map", str(yaml_path), "--out", str(snapped), "--snap",
                 "--cell-size", str(h), "--robot-radius", "0.25", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    env, before = envs.load(snapped), envs.load(plain)
    x0, y0 = env.origin
    for poly in (env.boundary, *env.obstacles):
        xy = np.asarray(poly.exterior.coords)
        assert np.allclose(np.round((xy[:, 0] - x0) / h), (xy[:, 0] - x0) / h, atol=1e-6)
        assert np.allclose(np.round((xy[:, 1] - y0) / h), (xy[:, 1] - y0) / h, atol=1e-6)
    # whole cells only; and with h = 2r every cell of the snapped free space is a free cell
    assert env.free_space.area / h**2 == pytest.approx(round(env.free_space.area / h**2))
    assert report["free_cells"] == round(env.free_space.area / h**2)
    # the report says how far the walls moved, and how much of the free space changed
    assert report["snap_hausdorff"] == pytest.approx(hausdorff(env.free_space,
                                                               before.free_space), abs=0.02)
    assert report["snap_hausdorff"] <= h
    assert report["snap_iou"] == pytest.approx(iou(env.free_space, before.free_space), 1e-6)
    assert iou(env.free_space, truth) >= 0.9


# ----------------------------------------------------------------------------- done when
def test_done_when_ros_map_imports_and_plans(tmp_path, capsys):
    """A ROS PGM + YAML of a non-rectilinear room with a pillar, walls around it and unknown
    space outside: IoU >= 0.98 and Hausdorff <= 0.06 m with the original, then info, plan
    and coverage run on the imported env.
    """
    room = Polygon([(0.3, 0.4), (3.9, 0.4), (4.6, 2.2), (3.2, 3.6), (0.3, 3.6)])
    pillar = hexagon(1.8, 2.0, 0.45, 15)
    truth = room.difference(pillar)
    origin = (-0.5, -0.2)
    free = rasterize(truth, RES, origin, size=(5.6, 4.4))
    walls = rasterize(room.buffer(0.15, join_style="mitre"), RES, origin, size=(5.6, 4.4))
    yaml_path = write_ros(tmp_path, ros_image(free, walls & ~free), name="pentagon",
                          origin=(*origin, 0.0), mode="trinary")
    out = tmp_path / "pentagon.json"
    assert main(["import-map", str(yaml_path), "--out", str(out), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    env = envs.load(out)
    assert len(env.obstacles) == 1
    assert iou(env.free_space, truth) >= 0.98
    assert hausdorff(env.free_space, truth) <= 0.06
    assert report["hausdorff"] <= 0.06 and abs(report["area_change"]) < 0.01

    assert main(["info", str(out), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["P"] == report["free_cells"] > 40 and info["K"] == 8
    # z = 0 (the lowest-left free cell facing east) to z = 1, the next free cell
    assert main(["plan", str(out), "--angles", "45,90,135", "--start", "0", "--goal", "1",
                 "--json"]) == 0
    plan = json.loads(capsys.readouterr().out)
    assert plan["plan"] is not None and plan["cost"] > 0
    assert main(["coverage", str(out), "--angles", "90,135", "--eps", "45", "--no-plots",
                 "--json"]) == 0
    cov = json.loads(capsys.readouterr().out)
    assert cov["P"] == info["P"] and sum(cov["alpha"]) == pytest.approx(1.0)


# ----------------------------------------------------------------------------- catalogue
def test_catalogue_studio_is_reproduced_by_its_script(tmp_path):
    from experiments.example_map import Config, room, run
    run(Config(out=tmp_path))
    for rel in ("studio.json", "maps/studio.pgm", "maps/studio.yaml"):
        assert (tmp_path / rel).read_bytes() == (envs.CATALOG_DIR / rel).read_bytes(), rel
    env = envs.load("studio")
    assert iou(env.free_space, room()) >= 0.98
    assert hausdorff(env.free_space, room()) <= 0.06


def test_accuracy_experiment_quick(tmp_path):
    from experiments import import_accuracy
    assert import_accuracy.main(["--quick", "--out", str(tmp_path)]) == 0
    df = pd.read_csv(tmp_path / "accuracy.csv")
    assert json.loads((tmp_path / "config.json").read_text())["quick"] is True
    assert set(df["tracer"]) == set(import_accuracy.TRACERS)
    assert len(df) == len(import_accuracy.SHAPES) * 2 * len(import_accuracy.TRACERS)
    ours = df[(df["tracer"] == "marching+refit") & (df["noise"] == 0)]
    assert (ours["iou"] >= 0.99).all() and (ours["hausdorff_px"] <= 1.5).all()


def test_sixteen_bit_images_and_bad_values(tmp_path, capsys):
    # a 16-bit PGM is scaled by 65535: 60000 is free (p = 0.084), 30000 unknown, 0 occupied
    img = np.zeros((40, 40), np.uint16)
    img[5:35, 5:35] = 60000
    img[15:20, 15:20] = 30000
    yaml_path = write_ros(tmp_path, img, name="deep")
    env = envs.Environment.from_dict(build_env(read_map(yaml_path))[0])
    expected = box(0.25, 0.25, 1.75, 1.75).difference(box(0.75, 1.0, 1.0, 1.25))
    assert iou(env.free_space, expected) >= 0.99
    out = str(tmp_path / "env.json")
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml_path.read_text().replace("negate: 0", 'negate: "no"'))
    for argv, words in [([str(bad)], "negate must be 0 or 1"),
                        ([str(yaml_path), "--tolerance", "-1"], "tolerance"),
                        ([str(yaml_path), "--min-area", "-1"], "speck area")]:
        rc, err = _err(capsys, ["import-map", *argv, "--out", out])
        assert rc == 2 and len(err) == 1 and words in err[0], err
