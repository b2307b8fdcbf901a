"""Options shared by the command line and the experiments."""

from __future__ import annotations

from dataclasses import fields, replace

from envs import UserError

__all__ = ["parse_angles", "with_options"]


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


def with_options(base, options, flag: str, whose: str = ""):
    """A copy of the dataclass record ``base`` with ``KEY=VALUE`` strings applied (``-`` in a
    key reads as ``_``). A value takes its field's type from the default: true/false (or 1/0)
    for a bool, a number for an int or a float, the text for a str; other fields cannot be
    set this way. Errors are one sentence naming ``flag`` (and ``whose`` settings they are).

    >>> from dataclasses import dataclass
    >>> @dataclass(frozen=True)
    ... class S:
    ...     n: int = 1
    ...     x: float = 0.5
    ...     on: bool = False
    >>> with_options(S(), ["n=3", "x=1", "on=true"], "--opt")
    S(n=3, x=1.0, on=True)
    """
    known = [f.name for f in fields(base)]
    values = {}
    for opt in options:
        key, sep, text = str(opt).partition("=")
        key, text = key.strip().replace("-", "_"), text.strip()
        if not sep or key not in known:
            raise UserError(f"{flag} {opt!r} is not KEY=VALUE with KEY one of "
                            f"{', '.join(known)}{whose}.")
        default = getattr(base, key)
        if isinstance(default, bool):
            if text.lower() not in ("true", "false", "1", "0"):
                raise UserError(f"{flag} {key} needs true or false, got {text!r}.")
            values[key] = text.lower() in ("true", "1")
        elif isinstance(default, str):
            values[key] = text
        elif isinstance(default, (int, float)):
            try:
                values[key] = type(default)(text)
            except ValueError:
                raise UserError(f"{flag} {key} needs a {type(default).__name__}, got "
                                f"{text!r}.") from None
        else:
            raise UserError(f"{flag} {key} cannot be set from text.")
    return replace(base, **values)
