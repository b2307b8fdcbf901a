"""Run traces: what happened when, and where the robot was (docs/model.md §8, §21).

A :class:`Trace` is an append-only list of rows ``(t, x, y, heading, event, detail)``:
time [s] on the robot's clock, the true pose (x [m], y [m], heading [deg]; NaN on hardware,
where there is none) and an event name with a free-text detail.

Events written by the executors: ``start``, ``bump``, ``back_off``, ``turn``, ``step``
(a forward step of a coverage run), ``deviation``, ``no_bump``, ``stop``, ``error``, and
after the stop of a run with a goal ``outcome`` ("success: ..." or "failure: ...", the
run's reason), so that a trace file says how its run ended.

Examples
--------
>>> tr = Trace()
>>> tr.add(0.0, (0.17, 0.17, 0.0), "start")
>>> tr.add(1.7, (0.51, 0.17, 0.0), "bump", "left+right")
>>> len(tr), tr.events("bump")[0].detail
(2, 'left+right')
>>> tr.to_frame().columns.tolist()
['t', 'x', 'y', 'heading', 'event', 'detail']
"""

from __future__ import annotations

import csv
import math
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import pandas as pd

__all__ = ["Trace", "TraceRow", "EVENTS"]

EVENTS = ("start", "bump", "back_off", "turn", "step", "deviation", "no_bump", "stop",
          "error", "outcome")
_NAN = float("nan")


@dataclass(frozen=True)
class TraceRow:
    """One trace row: time [s], pose (x [m], y [m], heading [deg]; NaN when unknown), event."""

    t: float
    x: float
    y: float
    heading: float
    event: str
    detail: str = ""


class Trace:
    """Append-only event log of a run (see module docstring)."""

    COLUMNS = ("t", "x", "y", "heading", "event", "detail")

    def __init__(self, rows: Iterable[TraceRow] = ()) -> None:
        self._rows: list[TraceRow] = list(rows)

    def add(self, t: float, pose: tuple[float, float, float] | None, event: str,
            detail: str = "") -> None:
        """Append a row; ``pose`` is (x, y, heading) or None (hardware)."""
        if event not in EVENTS:
            raise ValueError(f"unknown trace event {event!r}; use one of {', '.join(EVENTS)}.")
        x, y, h = pose if pose is not None else (_NAN, _NAN, _NAN)
        self._rows.append(TraceRow(float(t), float(x), float(y), float(h), event, str(detail)))

    @property
    def rows(self) -> tuple[TraceRow, ...]:
        """All rows, oldest first."""
        return tuple(self._rows)

    def __len__(self) -> int:
        return len(self._rows)

    def __iter__(self):
        return iter(self._rows)

    def __getitem__(self, i):
        return self._rows[i]

    def events(self, kind: str) -> list[TraceRow]:
        """All rows of one event kind."""
        return [r for r in self._rows if r.event == kind]

    def count(self, kind: str) -> int:
        """Number of rows of one event kind."""
        return sum(1 for r in self._rows if r.event == kind)

    def to_frame(self) -> pd.DataFrame:
        """A pandas DataFrame with columns t, x, y, heading, event, detail."""
        import pandas as pd
        return pd.DataFrame([tuple(getattr(r, c) for c in self.COLUMNS) for r in self._rows],
                            columns=list(self.COLUMNS))

    def to_csv(self, path: str | Path) -> Path:
        """Write the trace as CSV (one row per event; empty cells where the pose is unknown)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        with open(path, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(self.COLUMNS)
            for r in self._rows:
                w.writerow([_fmt(r.t), _fmt(r.x), _fmt(r.y), _fmt(r.heading), r.event,
                            r.detail])
        return path

    def __repr__(self) -> str:
        return f"Trace({len(self)} rows)"


def _fmt(v: float) -> str:
    return "" if math.isnan(v) else f"{v:.6f}"
