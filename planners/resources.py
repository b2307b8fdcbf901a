"""Pre-flight memory estimates: refuse a job in one sentence before it allocates.

Every estimate is read off the arrays the code allocates (the byte counts below name them),
at the moment of each stage's peak, plus the native memory that Python's allocator does not
see (one GEOS geometry per point or segment checked, scipy's Dijkstra heap). A pipeline's
peak is the largest stage peak plus what the earlier stages keep (the step table, the
roadmap's CSR matrix).

Stages and the sizes they scale with:

- the grid (environment validation and ``CellSpace.index_grid``): rows x columns points;
- the step table (``CellSpace.forward``): N = K * P configurations;
- the roadmap (``Roadmap.graph``): E = 2 m F + (m^2 + m) B edges (F forward moves, B bumps;
  before the step table exists, F, B <= N), m = number of bouncing angles;
- single-source searches (``Navigator.plan``): (m + 1) N nodes each, up to the cache size;
- all pairs (``Navigator.all_pairs``): N x (m + 1) N distances and predecessors;
- coverage chains: the step model's run chain (N states, B * turns bump entries), the
  sampled model's samples (N * grid^2 * theta_samples) and the event model's flights
  (contact bins * K * samples).

Not included: the fill-in of scipy's sparse LU factorisation when a coverage chain's closed
class is solved directly (it depends on the chain's structure, not on its size alone).

Examples
--------
>>> parse_memory("500M"), parse_memory("2G"), parse_memory("1.5GiB"), parse_memory("4096")
(524288000, 2147483648, 1610612736, 4096)
>>> import envs
>>> from planners.cells import CellSpace
>>> cs = CellSpace(envs.load("complex", orientations=100000))
>>> check_memory(cs, [45, 90], task="plan")  # doctest: +ELLIPSIS
Traceback (most recent call last):
...
envs.errors.UserError: planning in complex with N = 18300000 configurations needs about ...
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass

from envs import UserError

__all__ = ["DEFAULT_MAX_MEMORY", "MemoryEstimate", "TASKS", "all_pairs_bytes", "chain_bytes",
           "available_memory", "check_memory", "estimate", "format_bytes",
           "grid_bytes", "max_grid_cells", "memory_warning", "parse_memory", "roadmap_bytes",
           "search_bytes", "step_table_bytes"]

DEFAULT_MAX_MEMORY = 4 * 2**30          # 4 GiB
TASKS = ("cells", "plan", "allpairs", "coverage")

# Bytes per element of the arrays named in each estimate.
_I64 = _F64 = 8
_I32 = 4
_BOOL = 1
_GEOM_PY = 64           # a shapely geometry: 8 in the object array + a 56-byte Python object
_GEOM_NATIVE = 230      # its GEOS point or 2-point line string (measured RSS, shapely 2)
_HEAP_NATIVE = 48       # scipy's Dijkstra: one Fibonacci-heap node per graph node
_SEARCH_CACHE = 64      # Navigator's default cache of single-source searches
_EVENT_PER_FLIGHT = 800     # event model: ~100 float/int arrays over its sampled flights
_EVENT_PER_BIN = 25_000     # event model: the boundary's bin tables and ray-cast grids
_SAMPLED_PER_SAMPLE = 600   # sampled model: ~75 float/int arrays over its samples

_UNITS = {"": 1, "B": 1, "K": 2**10, "KB": 2**10, "KIB": 2**10, "M": 2**20, "MB": 2**20,
          "MIB": 2**20, "G": 2**30, "GB": 2**30, "GIB": 2**30, "T": 2**40, "TB": 2**40,
          "TIB": 2**40}


def parse_memory(text) -> int:
    """A memory size in bytes from ``500M``, ``2G``, ``1.5GiB``, ``4096`` (binary units)."""
    if isinstance(text, (int, float)) and not isinstance(text, bool):
        value, unit = float(text), ""
    else:
        m = re.fullmatch(r"\s*([0-9]*\.?[0-9]+(?:[eE][+-]?[0-9]+)?)\s*([A-Za-z]*)\s*",
                         str(text))
        if not m or m.group(2).upper() not in _UNITS:
            raise UserError(f"--max-memory takes a size such as 500M or 2G, got {text!r}.")
        value, unit = float(m.group(1)), m.group(2).upper()
    out = value * _UNITS[unit]
    if not (math.isfinite(out) and out > 0):
        raise UserError(f"--max-memory must be a positive size such as 500M or 2G, "
                        f"got {text!r}.")
    return int(out)


def format_bytes(n: float) -> str:
    """``1536 -> '1.5 KiB'`` (binary units, two or three significant digits)."""
    n = float(n)
    for unit in ("B", "KiB", "MiB", "GiB", "TiB"):
        if abs(n) < 1024 or unit == "TiB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.3g} {unit}"
        n /= 1024
    return f"{n:.3g} TiB"  # pragma: no cover


@dataclass(frozen=True)
class MemoryEstimate:
    """Estimated peak memory of a stage or a pipeline.

    Attributes
    ----------
    what : str      what is built
    traced : float  bytes in numpy arrays and Python objects (what ``tracemalloc`` counts)
    native : float  bytes in native buffers Python's allocator does not see (GEOS, heaps)
    keep : float    bytes the stage leaves behind for the next one
    """

    what: str
    traced: float
    native: float = 0.0
    keep: float = 0.0

    @property
    def total(self) -> float:
        """Traced plus native bytes: the whole estimated peak."""
        return self.traced + self.native


def grid_bytes(rows: int, cols: int) -> MemoryEstimate:
    """Validation of the cell grid (``Environment.grid_centres_free``) and ``index_grid``."""
    n = float(rows) * float(cols)
    per = (2 * _I64              # np.mgrid rows and columns
           + 2 * 2 * _F64        # x and y with their temporaries
           + 2 * _F64            # the stacked points
           + _GEOM_PY            # shapely.points
           + _F64 + 2 * _BOOL    # covers, distance, the result
           + _I64 + _BOOL)       # index_grid and its free mask
    return MemoryEstimate("the cell grid", n * per, n * _GEOM_NATIVE, n * _I64)


def step_table_bytes(N: int) -> MemoryEstimate:
    """``CellSpace.forward`` at N configurations, peak inside ``segments_free``."""
    per = (3 * 2 * _F64          # centres c, headings uu, ends d (N x 2 each)
           + _I64 + _BOOL        # destination cells, the ok mask
           + 2 * 2 * _F64        # c[ok], d[ok]
           + _GEOM_PY)           # one shapely point (then one line string) per move
    return MemoryEstimate("the step table", N * per, N * _GEOM_NATIVE, N * _I64)


def roadmap_bytes(N: int, m: int, forward=None) -> MemoryEstimate:
    """``Roadmap.graph``: E edges in row/col/weight parts, concatenated, COO, CSR."""
    E = _edges(N, m, forward)
    per = (3 * _I64              # the rows, cols, vals parts
           + 3 * _I64            # concatenated
           + 2 * _I32 + _F64     # scipy's COO (int32 indices)
           + _I32 + _F64)        # the CSR matrix
    nodes = (m + 1) * N
    return MemoryEstimate("the roadmap", E * per, 0.0,
                          E * (_I32 + _F64) + (nodes + 1) * _I32)


def search_bytes(N: int, m: int, searches: int = 1) -> MemoryEstimate:
    """Single-source Dijkstra runs kept by ``Navigator`` (distances float64, predecessors
    int32 per node; the heap is native).
    """
    nodes = (m + 1) * N
    return MemoryEstimate("the searches", searches * nodes * (_F64 + _I32),
                          nodes * _HEAP_NATIVE)


def all_pairs_bytes(N: int, m: int) -> MemoryEstimate:
    """``AllPairs``: the multi-source Dijkstra's (N, (m + 1) N) distances and predecessors,
    then the pointer jumping's per-(source, layer node) arrays.
    """
    nodes = (m + 1) * N
    M = m * N
    traced = (N * nodes * (_F64 + _I32)                   # dist, pred
              + N * M * (_I64 + 3 * _BOOL                 # parent, has_parent, bump, pred < 0
                         + _I64 + _BOOL + _I32            # anc, mask, depth
                         + _I64 + _BOOL                   # live, isin
                         + 2 * _I32))                     # pred % N % P
    return MemoryEstimate("all pairs", traced, nodes * _HEAP_NATIVE)


def chain_bytes(cells, angles, eps_deg: float = 0.0, model: str = "step",
                settings=None) -> MemoryEstimate:
    """One coverage chain (the largest of the angles'; they are built one after another)."""
    N, P, K = cells.N, cells.P, cells.K
    if model == "step":
        e = abs(float(eps_deg)) / cells.delta_deg if math.isfinite(float(eps_deg)) else 0.0
        turns = min(K, 2 * int(round(e)) + 1)
        B = _bumps(cells)
        per_state = 26 * _I64         # run chain: succ, end, bindex, prefix sums (x7), pi ...
        per_entry = 3 * _I64 + 2 * (_I32 + _F64) + _I64   # bump rows: parts, COO, CSR, Cc
        return MemoryEstimate("the coverage chain", N * per_state + B * turns * per_entry,
                              0.0, N * _F64 * (1 + len(angles)))
    if model == "sampled":
        grid = int(getattr(settings, "grid", 3))
        nt = int(getattr(settings, "theta_samples", 2))
        samples = float(N) * grid * grid * nt
        return MemoryEstimate("the sampled coverage model", samples * _SAMPLED_PER_SAMPLE,
                              P * grid * grid * _GEOM_NATIVE)
    if model == "event":
        bin_length = float(getattr(settings, "bin_length", 0.03))
        samples = int(getattr(settings, "samples", 2))
        ring = cells.env.cspace.boundary
        rings = max(1, len(getattr(ring, "geoms", [ring])))
        bins = math.ceil(ring.length / bin_length) + rings
        flights = float(bins) * K * samples
        return MemoryEstimate("the event coverage model",
                              flights * _EVENT_PER_FLIGHT + bins * _EVENT_PER_BIN)
    raise UserError(f"unknown coverage model {model!r}; use step, sampled or event.")


def estimate(cells, angles=(), *, task: str = "plan", eps_deg: float = 0.0,
             model: str = "step", settings=None, searches: int = _SEARCH_CACHE
             ) -> MemoryEstimate:
    """Peak memory of a task on ``cells`` (a :class:`planners.cells.CellSpace`).

    ``task`` is ``"cells"`` (the step table), ``"plan"`` (step table, roadmap and up to
    ``searches`` cached single-source searches), ``"allpairs"`` or ``"coverage"`` (step
    table and the ``model``'s chain for the largest of ``angles``).
    """
    if task not in TASKS:
        raise ValueError(f"task must be one of {TASKS}, got {task!r}.")
    N, m = cells.N, max(1, len(angles))
    stages = [] if "forward" in vars(cells) else [step_table_bytes(N)]
    if task in ("plan", "allpairs"):
        stages.append(roadmap_bytes(N, m, vars(cells).get("forward")))
        stages.append(all_pairs_bytes(N, m) if task == "allpairs"
                      else search_bytes(N, m, searches))
    elif task == "coverage":
        stages.append(chain_bytes(cells, angles, eps_deg, model, settings))
    kept, peak = 0.0, MemoryEstimate("nothing", 0.0)
    for st in stages:
        if kept + st.total > peak.total:
            peak = MemoryEstimate(st.what, kept + st.traced, st.native)
        kept += st.keep
    return peak


def check_memory(cells, angles=(), *, task: str = "plan", eps_deg: float = 0.0,
                 model: str = "step", settings=None, searches: int = _SEARCH_CACHE,
                 max_memory=DEFAULT_MAX_MEMORY) -> MemoryEstimate:
    """Raise :class:`envs.UserError` (one sentence) when :func:`estimate` exceeds
    ``max_memory`` (bytes, or a size such as ``"2G"``; None: no limit); else return it.
    """
    est = estimate(cells, angles, task=task, eps_deg=eps_deg, model=model,
                   settings=settings, searches=searches)
    _refuse(est, max_memory, f"{_TASK_WORDS[task]} in {cells.env.name} with "
            f"N = {cells.N} configurations")
    return est


def max_grid_cells(max_memory=DEFAULT_MAX_MEMORY) -> int:
    """The largest grid (rows x columns) whose validation fits in ``max_memory``: what to
    pass as ``envs.load(..., max_grid_cells=)``, which refuses larger grids before building
    them.
    """
    return max(1, int(parse_memory(max_memory) // grid_bytes(1, 1).total))


def available_memory() -> int | None:
    """Bytes of physical memory available now (Linux ``MemAvailable``, else free pages), or
    None where the platform does not say.
    """
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return None


def memory_warning(est: MemoryEstimate, available: int | None = None) -> str | None:
    """One sentence when ``est`` (within the limit, or :func:`check_memory` would have
    refused it) exceeds the memory available now (default :func:`available_memory`), else
    None: the job may swap or be killed.
    """
    available = available_memory() if available is None else available
    if available is None or est.total <= available:
        return None
    return (f"{est.what} needs about {format_bytes(est.total)}, more than the "
            f"{format_bytes(available)} of memory free now: expect swapping, or use fewer "
            "orientations or a larger cell size.")


_TASK_WORDS = {"cells": "the step table", "plan": "planning", "allpairs": "all pairs",
               "coverage": "coverage"}


def _refuse(est: MemoryEstimate, max_memory, what: str) -> None:
    if max_memory is None:
        return
    limit = parse_memory(max_memory)
    if not est.total <= limit:
        raise UserError(f"{what} needs about {format_bytes(est.total)} "
                        f"({est.what}), more than the {format_bytes(limit)} memory limit; "
                        "use fewer orientations, a larger cell size or a larger "
                        "--max-memory (max_memory in Python).")


def _bumps(cells) -> int:
    fwd = vars(cells).get("forward")
    return cells.N if fwd is None else int((fwd < 0).sum())


def _edges(N: int, m: int, forward=None) -> float:
    if forward is None:                   # before the step table: every z steps or bumps
        return float(N) * max(2 * m, m * m + m)
    B = int((forward < 0).sum())
    return 2.0 * m * (N - B) + (m * m + m) * B
