"""Registry helpers shared by both wings (:data:`planners.navigation.PLANNERS`,
:data:`planners.coverage.MODELS`): a name checked once, with "did you mean".

>>> check_name("planner", "exat", ("step", "exact"))
Traceback (most recent call last):
...
envs.errors.UserError: unknown planner 'exat'; did you mean 'exact'? (planners: step, exact)
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable

from envs import UserError

__all__ = ["check_name"]


def check_name(kind: str, name, names: Iterable[str]) -> str:
    """``name`` when it is one of ``names``; else a one-sentence :class:`UserError` that
    suggests the closest name.
    """
    names = tuple(names)
    if isinstance(name, str) and name in names:
        return name
    close = difflib.get_close_matches(str(name), names, n=1, cutoff=0.5)
    hint = f"; did you mean {close[0]!r}?" if close else ""
    raise UserError(f"unknown {kind} {name!r}{hint} ({kind}s: {', '.join(names)})")
