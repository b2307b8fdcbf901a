"""Options shared by the command line and the experiments."""

from __future__ import annotations

from envs import UserError

__all__ = ["parse_angles"]


def parse_angles(text: str) -> list[float]:
    """Bouncing angles [deg] from text: '45,90,135' -> [45.0, 90.0, 135.0]; a trailing ° is
    allowed, duplicates and junk are one-sentence errors.

    >>> parse_angles("45, 90°,135")
    [45.0, 90.0, 135.0]
    """
    out = []
    for tok in str(text).replace(" ", "").split(","):
        if not tok:
            continue
        try:
            out.append(float(tok.rstrip("°")))
        except ValueError:
            raise UserError(f"--angles takes numbers of degrees separated by commas, "
                            f"got {tok!r}.") from None
    if not out:
        raise UserError("--angles needs at least one bouncing angle.")
    if len(set(out)) != len(out):
        raise UserError(f"--angles lists an angle twice ({text}).")
    return out
