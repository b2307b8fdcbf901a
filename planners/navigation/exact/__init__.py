"""The exact navigation planner (docs/model.md §13): plans over exact bump poses.

One public front, :class:`ExactNavigator` (:mod:`.planner`), with three private helpers: the
many-start search of all pairs (``_batch``), the scalar casts with walls culled per heading
(``_cast``) and the flight chords through cells (``_chords``, public as :func:`chords`: the
feedback planner's goal arrivals use them too).
"""

from __future__ import annotations

from ._chords import chords
from .planner import ExactAllPairs, ExactNavigator, ExactSearch

__all__ = ["ExactAllPairs", "ExactNavigator", "ExactSearch", "chords"]
