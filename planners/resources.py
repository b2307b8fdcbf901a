"""Pre-flight memory estimates: refuse a job in one sentence before it allocates.

Every estimate is read off the arrays the code allocates (the byte counts name them), at the
moment of each stage's peak, plus the native memory that Python's allocator does not see (one
GEOS geometry per point or segment checked, scipy's Dijkstra heap). A pipeline's peak is the
largest stage peak plus what the earlier stages keep (the step table, the roadmap's CSR
matrix): :func:`pipeline`.

This module holds the shared stages and the machinery; each planner and coverage model owns
its estimate (``memory_estimate`` on the class: :class:`planners.navigation.Navigator`,
:class:`~planners.navigation.ExactNavigator`, :class:`~planners.navigation.ReliableNavigator`,
:class:`~planners.navigation.FeedbackPlanner`, and the coverage models of
:data:`planners.coverage.MODELS`).

- the grid (environment validation and ``CellSpace.index_grid``): rows x columns points;
- the step table (``CellSpace.forward``): N = K * P configurations.

Not included: the fill-in of scipy's sparse LU factorisation when a coverage chain's closed
class is solved directly (it depends on the chain's structure, not on its size alone).

Examples
--------
>>> parse_memory("500M"), parse_memory("2G"), parse_memory("1.5GiB"), parse_memory("4096")
(524288000, 2147483648, 1610612736, 4096)
>>> import envs
>>> from planners.cells import CellSpace
>>> cs = CellSpace(envs.load("complex", orientations=100000))
>>> check_memory(cs, max_memory="1G")  # doctest: +ELLIPSIS
Traceback (most recent call last):
...
envs.errors.UserError: the step table in complex with N = 18300000 configurations needs about ...
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass

from envs import UserError

__all__ = ["BOOL", "DEFAULT_MAX_MEMORY", "F64", "GEOM_NATIVE", "GEOM_PY", "HEAP_NATIVE", "I32",
           "I64", "MemoryEstimate", "available_memory", "check", "check_memory", "format_bytes",
           "grid_bytes", "max_grid_cells", "memory_warning", "parse_memory", "pipeline",
           "step_table_bytes"]

DEFAULT_MAX_MEMORY = 4 * 2**30          # 4 GiB

# Bytes per element of the arrays named in the estimates (here and on the classes).
I64 = F64 = 8
I32 = 4
BOOL = 1
GEOM_PY = 64            # a shapely geometry: 8 in the object array + a 56-byte Python object
GEOM_NATIVE = 230       # its GEOS point or 2-point line string (measured RSS, shapely 2)
HEAP_NATIVE = 48        # scipy's Dijkstra: one Fibonacci-heap node per graph node

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
    per = (2 * I64              # np.mgrid rows and columns
           + 2 * 2 * F64        # x and y with their temporaries
           + 2 * F64            # the stacked points
           + GEOM_PY            # shapely.points
           + F64 + 2 * BOOL    # covers, distance, the result
           + I64 + BOOL)       # index_grid and its free mask
    return MemoryEstimate("the cell grid", n * per, n * GEOM_NATIVE, n * I64)


def step_table_bytes(N: int) -> MemoryEstimate:
    """``CellSpace.forward`` at N configurations, peak inside ``segments_free``."""
    per = (3 * 2 * F64          # centres c, headings uu, ends d (N x 2 each)
           + I64 + BOOL        # destination cells, the ok mask
           + 2 * 2 * F64        # c[ok], d[ok]
           + GEOM_PY)           # one shapely point (then one line string) per move
    return MemoryEstimate("the step table", N * per, N * GEOM_NATIVE, N * I64)


def pipeline(cells, *stages: MemoryEstimate) -> MemoryEstimate:
    """Peak memory of a job on ``cells`` (a :class:`planners.cells.CellSpace`): the step
    table (unless already built), then ``stages`` in order, each running while what the
    earlier ones keep is kept (the planners' and coverage models' ``memory_estimate``).
    """
    stages = ([] if "forward" in vars(cells) else [step_table_bytes(cells.N)]) + list(stages)
    kept, peak = 0.0, MemoryEstimate("nothing", 0.0)
    for st in stages:
        if kept + st.total > peak.total:
            peak = MemoryEstimate(st.what, kept + st.traced, st.native)
        kept += st.keep
    return peak


def check_memory(cells, est: MemoryEstimate | None = None, *, what: str = "the step table",
                 max_memory=DEFAULT_MAX_MEMORY) -> MemoryEstimate:
    """``est`` (default: the step table's :func:`pipeline`) checked against ``max_memory``
    (bytes, or a size such as ``"2G"``; None: no limit): :class:`envs.UserError` in one
    sentence naming ``what``, the map and N when it exceeds it.
    """
    est = pipeline(cells) if est is None else est
    return check(est, max_memory, f"{what} in {cells.env.name} with N = {cells.N} "
                 "configurations")


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


def check(est: MemoryEstimate, max_memory, what: str) -> MemoryEstimate:
    """Raise :class:`envs.UserError` (one sentence naming ``what``) when ``est`` exceeds
    ``max_memory`` (bytes, or a size such as ``"2G"``; None: no limit); else return it.
    """
    if max_memory is None:
        return est
    limit = parse_memory(max_memory)
    if not est.total <= limit:
        raise UserError(f"{what} needs about {format_bytes(est.total)} "
                        f"({est.what}), more than the {format_bytes(limit)} memory limit; "
                        "use fewer orientations, a larger cell size or a larger "
                        "--max-memory (max_memory in Python).")
    return est
