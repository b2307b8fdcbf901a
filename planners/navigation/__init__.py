"""Navigation: plans from a start pose to a goal pose (docs/model.md §6, §15, §21, §22)."""

from __future__ import annotations

from .step import AllPairs, Navigator, Route

__all__ = ["AllPairs", "Navigator", "Route"]
