"""Occupancy-grid maps to environments: read, threshold, clean, trace, simplify, snap.

A ROS ``map_server`` map (a YAML file naming an image, docs/model.md §3) or a plain
occupancy image becomes an env dict (docs/model.md §2) in five steps:

1. **read** the image and its metadata (:func:`read_map`);
2. **threshold** it as ``map_server`` does (:func:`threshold`): occupied, free or unknown;
   unknown counts as not free;
3. **clean** (:func:`clean`): flip pixels that at most one of their four neighbours agrees
   with (:func:`despeckle`: specks, one-pixel spurs and notches), keep the largest
   4-connected free region and fill its holes of at most ``min_area`` pixels;
4. **trace** the region's outline with marching squares at level ½ (sub-pixel, on the
   pixel edges) and **simplify** it with Douglas-Peucker at ``tolerance`` (one pixel), then
   refit every edge to its contour points (sub-pixel edges, sharp corners)
   (:func:`trace`): the outer ring is the boundary W, the holes are the obstacles;
5. optionally **snap** the free space onto the cell grid (:func:`envs.map_import.snap`);
   :func:`envs.map_import.build_env` runs the steps and builds the env dict.

Pixel convention. The image is an array ``img[row, col]`` with row 0 the *top* row. The
map's origin (x0, y0, yaw) is the pose of the lower-left corner of the lower-left pixel, as
in ROS. Pixel (row, col) of an H-row image covers, before the yaw rotation about the origin,
x ∈ [x0 + col·res, x0 + (col+1)·res] and y ∈ [y0 + (H−1−row)·res, y0 + (H−row)·res]; its
centre is (x0 + (col + ½)·res, y0 + (H − row − ½)·res).

Examples
--------
A 4 x 3 pixel image, 0.5 m pixels: the free 2 x 1 block in the top row, left
(row 0, columns 0-1) is x ∈ [0, 1], y ∈ [1, 1.5] m:

>>> import numpy as np
>>> free = np.zeros((3, 4), bool); free[0, 0:2] = True
>>> poly = trace(free, resolution=0.5, origin=(0.0, 0.0, 0.0), tolerance=0.0)
>>> [round(v, 6) for v in poly.bounds]
[0.0, 1.0, 1.0, 1.5]
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import shapely
from shapely.geometry import Polygon

from .errors import UserError

__all__ = ["TOLERANCE_PX", "YAML_KEYS", "OccupancyMap", "clean", "despeckle",
           "hausdorff_to_raster", "largest_part", "read_image", "read_map", "threshold",
           "trace"]

# The keys a ROS (map_server) map YAML must have; ``mode`` is optional (default trinary).
YAML_KEYS = ("image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh")
# Douglas-Peucker tolerance [px] (docs/readme_maps.md: 1 and 1.5 px measured); with the
# edge refit it also bounds how far a vertex may move (2 x) and which short edges go (1 x).
TOLERANCE_PX = 1.0
_MODES = ("trinary", "scale", "raw")
_INSTALL = "pip install bouncesim[maps]"


@dataclass(frozen=True)
class OccupancyMap:
    """A thresholded occupancy grid with its placement in the world.

    Parameters
    ----------
    free, occupied : ndarray of bool, shape (H, W)
        Free and occupied pixels (neither: unknown); row 0 is the top of the image.
    resolution : float
        Pixel edge [m].
    origin : tuple of float
        (x0 [m], y0 [m], yaw [rad]): pose of the lower-left pixel's lower-left corner.
    source : str
        File name the map was read from (no folder).
    """

    free: np.ndarray
    occupied: np.ndarray
    resolution: float
    origin: tuple[float, float, float]
    source: str = ""


# ----------------------------------------------------------------------------- reading
def read_image(path: str | Path) -> np.ndarray:
    """An image file as an array: (H, W) grey values, or (H, W, C) with colour/alpha.

    PGM, PNG and whatever else Pillow reads; a :class:`UserError` when the file is missing or
    is not an image.
    """
    try:
        from PIL import Image, UnidentifiedImageError
    except ImportError:  # pragma: no cover - the extra is installed in development
        raise UserError(f"reading map images needs Pillow ({_INSTALL}).") from None
    path = Path(path)
    try:
        with Image.open(path) as im:
            im.load()
            if im.mode == "P":
                im = im.convert("RGBA" if "transparency" in im.info else "RGB")
            elif im.mode in ("1", "CMYK", "YCbCr", "HSV", "LAB"):
                im = im.convert("L" if im.mode == "1" else "RGB")
            arr = np.asarray(im)
    except FileNotFoundError:
        raise UserError(f"no map image at {path}.") from None
    except (UnidentifiedImageError, OSError, ValueError, SyntaxError) as exc:
        reason = getattr(exc, "strerror", None) or "not an image Pillow can read"
        raise UserError(f"cannot read the map image {path} ({reason}).") from None
    if arr.dtype.kind == "i" and arr.size and arr.min() >= 0 and arr.max() <= 65535:
        arr = arr.astype(np.uint16)          # Pillow opens 16-bit greys as 32-bit integers
    if arr.ndim not in (2, 3) or min(arr.shape[:2]) < 1:
        raise UserError(f"the map image {path} is not a 2-D image.")
    return arr


def _occupancy(img: np.ndarray, negate: bool, mode: str) -> tuple[np.ndarray, np.ndarray]:
    """(p, known): occupancy probability p per pixel, as map_server computes it, and
    whether the pixel is known (not transparent, and in raw mode a value 0-100).
    """
    known = np.ones(img.shape[:2], dtype=bool)
    if img.ndim == 3:
        channels = img.shape[2]
        if channels in (2, 4):                  # alpha channel: transparent is unknown
            alpha = img[..., -1].astype(float)
            known = alpha >= np.iinfo(img.dtype).max if img.dtype.kind in "ui" else alpha >= 1
            img = img[..., :-1]
        value = img.astype(float).mean(axis=2)  # map_server averages the colour channels
    else:
        value = img.astype(float)
    if mode == "raw":
        known &= value <= 100
        return value / 100.0, known
    vmax = float(np.iinfo(img.dtype).max) if img.dtype.kind in "ui" else 1.0
    v = value / vmax
    return (v if negate else 1.0 - v), known


def threshold(img: np.ndarray, *, negate: bool = False, occupied_thresh: float = 0.65,
              free_thresh: float = 0.196, mode: str = "trinary"
              ) -> tuple[np.ndarray, np.ndarray]:
    """(free, occupied) boolean masks of an image, by ROS ``map_server``'s rules.

    p = (255 − value)/255 (p = value/255 with ``negate``; colour channels averaged; in
    ``raw`` mode p = value/100 and values above 100 are unknown); occupied when
    p > occupied_thresh, free when p < free_thresh, unknown otherwise (and where the alpha
    channel is transparent). ``scale`` mode thresholds like ``trinary``.

    >>> img = np.array([[0, 254, 205]], dtype=np.uint8)   # black, white, ROS grey
    >>> [m.tolist() for m in threshold(img)]
    [[[False, True, False]], [[True, False, False]]]
    """
    if mode not in _MODES:
        raise UserError(f"unknown map mode {mode!r}; known are {', '.join(_MODES)}.")
    p, known = _occupancy(np.asarray(img), bool(negate), mode)
    return known & (p < free_thresh), known & (p > occupied_thresh)


def _num(data: dict, key: str, where: str) -> float:
    v = data[key]
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise UserError(f"{where}: {key} must be a number, got {v!r}.")
    return float(v)


def read_map(path: str | Path, *, resolution: float | None = None,
             origin: tuple[float, ...] | None = None, negate: bool = False) -> OccupancyMap:
    """Read a ROS map YAML (with its image) or a plain occupancy image, and threshold it.

    Parameters
    ----------
    path : str or Path
        A ``.yaml``/``.yml`` map file (keys :data:`YAML_KEYS`, optional ``mode``; ``image``
        relative to the YAML's folder), or an image (black occupied, white free).
    resolution : float, optional
        Pixel edge [m] of a plain image (required for one); overrides nothing in a YAML.
    origin : tuple of float, optional
        (x0, y0) or (x0, y0, yaw [rad]) of a plain image (default (0, 0, 0)).
    negate : bool
        For a plain image: white is occupied.
    """
    path = Path(path)
    if path.suffix.lower() in (".yaml", ".yml"):
        return _read_yaml(path)
    if resolution is None:
        raise UserError(f"{path.name} is a plain image: give its pixel size with --resolution.")
    if not (math.isfinite(resolution) and resolution > 0):
        raise UserError(f"--resolution must be a positive number of metres, got {resolution}.")
    o = tuple(float(v) for v in (origin or (0.0, 0.0)))
    if len(o) not in (2, 3) or not all(map(math.isfinite, o)):
        raise UserError("--origin must be X,Y or X,Y,YAW (finite numbers).")
    free, occ = threshold(read_image(path), negate=negate)
    return OccupancyMap(free, occ, float(resolution), (o + (0.0,))[:3], path.name)


def _read_yaml(path: Path) -> OccupancyMap:
    import yaml
    try:
        data = yaml.safe_load(path.read_text())
    except FileNotFoundError:
        raise UserError(f"no map file at {path}.") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise UserError(f"cannot read the map file {path} "
                        f"({getattr(exc, 'strerror', None) or 'not text'}).") from None
    except yaml.YAMLError:
        raise UserError(f"{path} is not valid YAML.") from None
    if not isinstance(data, dict):
        raise UserError(f"{path} does not hold a ROS map (a YAML mapping with "
                        f"{', '.join(YAML_KEYS)}).")
    missing = [k for k in YAML_KEYS if k not in data]
    if missing:
        raise UserError(f"{path.name} lacks the ROS map key(s) {', '.join(missing)}.")
    res = _num(data, "resolution", path.name)
    if res <= 0:
        raise UserError(f"{path.name}: resolution must be positive, got {res:g}.")
    org = data["origin"]
    if not (isinstance(org, list) and len(org) in (2, 3) and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
            for v in org)):
        raise UserError(f"{path.name}: origin must be [x, y, yaw] (numbers), got {org!r}.")
    occ_t, free_t = _num(data, "occupied_thresh", path.name), _num(data, "free_thresh", path.name)
    mode = str(data.get("mode", "trinary"))
    img_path = path.parent / str(data["image"])
    negate = data["negate"]
    if negate not in (0, 1):                 # 0, 1, true or false (YAML booleans are 0/1)
        raise UserError(f"{path.name}: negate must be 0 or 1, got {negate!r}.")
    free, occ = threshold(read_image(img_path), negate=bool(negate),
                          occupied_thresh=occ_t, free_thresh=free_t, mode=mode)
    o = tuple(float(v) for v in org)
    return OccupancyMap(free, occ, res, (o + (0.0,))[:3], path.name)


# ----------------------------------------------------------------------------- raster steps
def despeckle(mask: np.ndarray, passes: int = 2) -> np.ndarray:
    """Flip every pixel that at most one of its four neighbours agrees with, ``passes`` times.

    This removes isolated specks, one-pixel spurs sticking out of an outline and one-pixel
    notches cut into it (salt-and-pepper noise), and leaves alone every pixel on a straight
    or staircase edge and at a right-angled corner (each has at least two agreeing
    neighbours); only the tip of a corner sharper than 90° can lose a pixel per pass. Unlike
    a 3 x 3 median filter (which also cuts every corner) or an opening/closing (which rounds
    every corner to the structuring element), it keeps the outline of clean shapes exact.

    >>> m = np.zeros((5, 6), bool); m[1:4, 1:4] = True; m[2, 4] = True   # a spur
    >>> despeckle(m).astype(int)
    array([[0, 0, 0, 0, 0, 0],
           [0, 1, 1, 1, 0, 0],
           [0, 1, 1, 1, 0, 0],
           [0, 1, 1, 1, 0, 0],
           [0, 0, 0, 0, 0, 0]])
    """
    from scipy import ndimage
    m = np.asarray(mask, dtype=bool).copy()
    cross = np.array([[0, 1, 0], [1, 0, 1], [0, 1, 0]])
    for _ in range(passes):
        n_true = ndimage.correlate(m.astype(np.int8), cross, mode="nearest")
        flip = np.where(m, n_true, 4 - n_true) <= 1
        if not flip.any():
            break
        m ^= flip
    return m


def clean(free: np.ndarray, min_area: int = 4, passes: int = 2) -> tuple[np.ndarray, int]:
    """(region, filled): the cleaned free region, and how many of its pixels were not free.

    Three steps: :func:`despeckle` (``passes`` times); keep the largest 4-connected free
    region (free specks elsewhere, and rooms not connected to the main one, go); fill its
    holes of at most ``min_area`` pixels (pepper clusters that survived; real obstacles are
    larger). Holes are 8-connected (the dual of 4-connected free space, and what marching
    squares with ``fully_connected="low"`` traces). Area filtering, unlike an opening or a
    closing, leaves the outline of every larger shape untouched (corners included).

    A 2 x 2 hole is filled; a pixel at the image's edge is not a hole:

    >>> f = np.ones((6, 6), bool); f[2:4, 2:4] = False; f[0, 5] = False
    >>> region, filled = clean(f, min_area=4)
    >>> int(region.sum()), filled
    (35, 4)
    """
    from scipy import ndimage
    free = np.asarray(free, dtype=bool)
    smooth = despeckle(free, passes) if passes else free
    labels, n = ndimage.label(smooth)                    # 4-connectivity
    if n == 0:
        raise UserError("the map has no free region (no pixel below free_thresh).")
    sizes = np.bincount(labels.ravel())
    sizes[0] = 0
    region = labels == int(np.argmax(sizes))
    holes, m = ndimage.label(~np.pad(region, 1), structure=np.ones((3, 3), int))
    holes = holes[1:-1, 1:-1]
    hsizes = np.bincount(holes.ravel(), minlength=m + 1)
    small = hsizes <= min_area
    small[0] = False
    edge = np.unique(np.concatenate([holes[0], holes[-1], holes[:, 0], holes[:, -1]]))
    small[edge] = False                                  # touches the image edge: not a hole
    region |= small[holes]
    return region, int((region & ~free).sum())


def _to_world(uv: np.ndarray, resolution: float, origin) -> np.ndarray:
    """Pixel-frame points (u, v) [px] (u = col + ½, v = H − row − ½) to world (x, y) [m]."""
    x0, y0, yaw = origin
    c, s = math.cos(yaw), math.sin(yaw)
    u, v = uv[:, 0] * resolution, uv[:, 1] * resolution
    return np.stack([x0 + c * u - s * v, y0 + s * u + c * v], axis=1)


def trace(region: np.ndarray, resolution: float, origin, tolerance: float | None = None,
          refine: bool = True) -> Polygon:
    """The polygon (with holes) of a free region [m], traced and simplified.

    Marching squares (:func:`skimage.measure.find_contours`) at level ½ on the padded mask
    (``fully_connected="low"``: free 4-connected, walls 8-connected) puts the outline on the
    pixel edges, with each pixel corner cut by a half-pixel chamfer. Each ring is simplified
    by Douglas-Peucker at ``tolerance`` [m] (default :data:`TOLERANCE_PX` pixels); with
    ``refine``, every simplified edge is then replaced by the least-squares line through the
    contour points it stands for, and every vertex by the intersection of its two lines
    (sub-pixel edges, sharp corners; a vertex moves at most 2 · tolerance). The outer ring is
    the largest;
    the others are holes. Should the refined rings cross, shapely's topology-preserving
    simplification of the unrefined outline is used instead.

    Parameters
    ----------
    region : ndarray of bool, shape (H, W)
        One 4-connected free region (row 0 at the top).
    resolution : float
        Pixel edge [m].
    origin : tuple
        (x0, y0, yaw) of the lower-left pixel corner [m, m, rad].
    tolerance : float, optional
        Simplification tolerance [m].
    refine : bool
        Fit the edges (default) or keep the Douglas-Peucker vertices.
    """
    try:
        from skimage import measure
    except ImportError:  # pragma: no cover
        raise UserError(f"tracing map outlines needs scikit-image ({_INSTALL}).") from None
    region = np.asarray(region, dtype=bool)
    H = region.shape[0]
    tol = TOLERANCE_PX if tolerance is None else float(tolerance) / resolution   # [px]
    raw, fitted = [], []
    for c in measure.find_contours(np.pad(region, 1).astype(float), 0.5,
                                   fully_connected="low"):
        uv = np.stack([c[:, 1] - 0.5, H + 0.5 - c[:, 0]], axis=1)    # see _to_world
        if len(uv) < 4:
            continue
        ring = Polygon(_to_world(uv, resolution, origin))
        if ring.area <= 0:
            continue
        raw.append(ring)
        simple = measure.approximate_polygon(uv, tol) if tol > 0 else uv
        if refine and tol > 0:
            simple = _refine_ring(uv[:-1], simple[:-1], tol)
        fitted.append(Polygon(_to_world(np.asarray(simple), resolution, origin))
                      if len(simple) >= 3 else None)
    if not raw:
        raise UserError("the map has no free region large enough to trace.")
    order = sorted(range(len(raw)), key=lambda i: raw[i].area, reverse=True)
    outer = raw[order[0]]
    inner = [i for i in order[1:] if outer.contains(raw[i].representative_point())]
    rings = [fitted[i] for i in [order[0]] + inner]
    if all(r is not None and r.is_valid for r in rings):
        poly = Polygon(rings[0].exterior, [r.exterior for r in rings[1:]])
        if poly.is_valid and all(rings[0].contains(r) for r in rings[1:]):
            return poly
    poly = Polygon(outer.exterior, [raw[i].exterior for i in inner]).buffer(0)
    tol_m = tol * resolution
    return largest_part(shapely.simplify(poly, tol_m, preserve_topology=True).buffer(0))


def _fit_line(pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(centroid, unit direction) of the total-least-squares line through points."""
    c = pts.mean(axis=0)
    _, _, vt = np.linalg.svd(pts - c, full_matrices=False)
    return c, vt[0]


def _refine_ring(ring: np.ndarray, simple: np.ndarray, tol: float,
                 min_edge: float = 4.0) -> np.ndarray:
    """Sub-pixel vertices of a simplified ring [px].

    Each simplified edge is refitted to the contour points between its end vertices (those
    within one pixel of an end left out: the chamfers); consecutive edges less than 5° apart
    are merged and refitted; each vertex is the intersection of its two edge lines. An edge
    shorter than ``min_edge`` px whose neighbours' lines meet within ``tol`` of its line is
    a cut corner and goes; any other vertex whose intersection would move it more than
    2 · tol stays where Douglas-Peucker put it.
    """
    where = {tuple(p): i for i, p in enumerate(ring)}
    idx = [where[tuple(p)] for p in simple]
    edges = [(idx[k], idx[(k + 1) % len(idx)]) for k in range(len(idx))]
    reach = 2.0 * tol
    sin5 = math.sin(math.radians(5.0))

    def fit(e):
        a, b = e
        seg = ring[a:b + 1] if b > a else np.concatenate([ring[a:], ring[:b + 1]])
        ends = np.minimum(np.linalg.norm(seg - seg[0], axis=1),
                          np.linalg.norm(seg - seg[-1], axis=1))
        core = seg[ends >= 1.0]
        c, d = _fit_line(core if len(core) >= 2 else seg)
        return c, (d if np.dot(d, ring[b] - ring[a]) >= 0 else -d)

    def meet(l0, l1):
        (c0, d0), (c1, d1) = l0, l1
        cross = d0[0] * d1[1] - d0[1] * d1[0]
        if cross * cross < sin5 * sin5 or np.dot(d0, d1) < -0.999:
            return None
        return c0 + ((c1 - c0)[0] * d1[1] - (c1 - c0)[1] * d1[0]) / cross * d0

    for _ in range(2 * len(edges) + 1):
        m = len(edges)
        if m < 3:
            return simple
        lines = [fit(e) for e in edges]
        change = False
        for k in range(m):
            l0, l1 = lines[k - 1], lines[k]
            parallel = abs(l0[1][0] * l1[1][1] - l0[1][1] * l1[1][0]) < sin5 and \
                np.dot(l0[1], l1[1]) > 0
            a, b = edges[k]
            short = np.linalg.norm(ring[b] - ring[a]) < min_edge
            if parallel:                                  # merge edges k-1 and k
                merged = (edges[k - 1][0], edges[k][1])
                edges = [e for i, e in enumerate(edges) if i not in (k, (k - 1) % m)]
                edges.insert(max(k - 1, 0) if k else len(edges), merged)
                change = True
                break
            if short and m > 3:
                p = meet(lines[k - 1], lines[(k + 1) % m])
                c, d = lines[k]
                if p is not None and abs(d[0] * (p - c)[1] - d[1] * (p - c)[0]) <= tol:
                    del edges[k]                          # a cut corner
                    change = True
                    break
        if not change:
            break
    out = []
    for k in range(len(edges)):
        v = (ring[edges[k - 1][1]] + ring[edges[k][0]]) / 2   # the DP vertex (or cut corner)
        p = meet(lines[k - 1], lines[k])
        out.append(p if p is not None and np.linalg.norm(p - v) <= reach else v)
    return np.asarray(out)


def largest_part(geom) -> Polygon:
    """The largest polygon of a geometry (itself when it is one)."""
    if isinstance(geom, Polygon):
        return geom
    parts = [g for g in shapely.get_parts(geom) if isinstance(g, Polygon)]
    if not parts:
        raise UserError("the map has no free region large enough to trace.")
    return max(parts, key=lambda p: p.area)


def _edge_points(region: np.ndarray, step: float = 0.25) -> np.ndarray:
    """Points every ``step`` px along the pixel edges between the region and the rest, in
    the pixel frame (u, v) [px] of :func:`_to_world`.
    """
    m = np.pad(np.asarray(region, bool), 1)
    H = region.shape[0]
    ts = np.arange(0.0, 1.0, step)
    pts = []
    # vertical edges: between columns c-1 and c of the padded array, at u = c - 1
    r, c = np.nonzero(m[:, 1:] != m[:, :-1])
    for t in ts:
        pts.append(np.stack([c.astype(float), H - (r - 1) - t], axis=1))
    # horizontal edges: between rows r and r+1 of the padded array, at v = H - r
    r, c = np.nonzero(m[1:, :] != m[:-1, :])
    for t in ts:
        pts.append(np.stack([c - 1 + t, (H - r).astype(float)], axis=1))
    return np.concatenate(pts)


def hausdorff_to_raster(geom, region: np.ndarray, resolution: float, origin,
                        step: float = 0.25) -> float:
    """Hausdorff distance [m] between the boundary of ``geom`` and the pixel edges of
    ``region`` (both sampled every ``step`` pixels, so within step/2 px of the exact value).
    """
    from scipy.spatial import cKDTree
    raster = _to_world(_edge_points(region, step), resolution, origin)
    lines = shapely.segmentize(geom.boundary, step * resolution)
    poly = shapely.get_coordinates(lines)
    d1 = cKDTree(poly).query(raster)[0].max()
    d2 = cKDTree(raster).query(poly)[0].max()
    return float(max(d1, d2))
