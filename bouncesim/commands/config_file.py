"""``bouncesim --config RUN.toml [FLAGS]``: a command's options from a TOML file, so that a
study can be re-run from one file; flags on the command line override the file.

The file names the command and gives its options by their long names (``-`` or ``_``)::

    command = "coverage"
    env = "lab"                      # the positional argument(s), by name
    angles = [30, 75, 315]           # a list is written comma-separated ...
    eps = 5
    r = 0.8
    model = "event"
    model_option = ["bin_length=0.05"]   # ... or repeated, for a repeatable option
    no_plots = true                  # a switch: true sets it, false leaves it off
    out = "results/lab_event"

Every value goes through the option's own parsing and checks (type and choices), as if it had
been typed. ``config.json`` of the run records the file's path and its values.
"""

from __future__ import annotations

import argparse
import tomllib
from pathlib import Path

from envs import UserError

__all__ = ["apply_config", "split_config"]


def split_config(argv: list[str]) -> tuple[str | None, list[str]]:
    """(the path of a leading ``--config FILE`` / ``--config=FILE``, the rest of argv)."""
    if argv[:1] == ["--config"]:
        if len(argv) < 2:
            raise UserError("--config needs a TOML file name.")
        return argv[1], argv[2:]
    if argv and argv[0].startswith("--config="):
        return argv[0].split("=", 1)[1], argv[1:]
    return None, argv


def _read(path: str) -> dict:
    p = Path(path)
    if not p.is_file():
        raise UserError(f"--config {path} is not a file.")
    try:
        return tomllib.loads(p.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise UserError(f"--config {path} is not valid TOML ({str(exc).rstrip('.')}).") \
            from None


def _text(key: str, value) -> str:
    if isinstance(value, bool) or isinstance(value, (dict, list)):
        raise UserError(f"config key {key!r} takes a single value, got {value!r}.")
    return str(value)


def apply_config(path: str, rest: list[str], commands: dict) -> tuple[list[str], dict]:
    """The argv to parse (the file's command, then ``rest``) after setting the file's values
    as that command's defaults on its parser (``commands``: name -> sub-parser); and the
    record of the file for ``config.json``. One sentence for an unknown command or key.
    """
    values = _read(path)
    command = values.pop("command", None)
    if rest and rest[0] in commands:
        if command is not None and rest[0] != command:
            raise UserError(f"--config {path} is for {command}, not {rest[0]}.")
        command, rest = rest[0], rest[1:]
    if command not in commands:
        raise UserError(f"--config {path} needs command = one of {', '.join(commands)} "
                        f"(got {command!r}).")
    parser = commands[command]
    by_name = {a.dest: a for a in parser._actions if a.dest not in ("help",)}
    defaults = {}
    for key, value in values.items():
        action = by_name.get(key.replace("-", "_"))
        if action is None or not (action.option_strings or action.nargs in (None, "?")):
            known = ", ".join(sorted(d for d, a in by_name.items()
                                     if not d.startswith("_")))
            raise UserError(f"--config {path}: {command} has no option {key!r} (it has "
                            f"{known}).")
        defaults[action.dest] = _default(action, key, value)
        action.required = False
        if not action.option_strings:       # a positional given by the file: optional now
            action.nargs = "?"
    parser.set_defaults(**defaults)
    return [command, *rest], {"path": str(path), "values": {"command": command, **values}}


def _default(action: argparse.Action, key: str, value):
    """A file value as the parser's default, parsed and checked as typed input would be."""
    if isinstance(action, (argparse._StoreTrueAction, argparse._StoreFalseAction)):
        if not isinstance(value, bool):
            raise UserError(f"config key {key!r} is a switch: write true or false.")
        return value if isinstance(action, argparse._StoreTrueAction) else not value
    if isinstance(action, argparse._AppendAction):
        items = value if isinstance(value, list) else [value]
        return [_convert(action, key, _text(key, v)) for v in items]
    if isinstance(value, list):
        value = ",".join(_text(key, v) for v in value)
    return _convert(action, key, _text(key, value))


def _convert(action: argparse.Action, key: str, text: str):
    try:
        out = action.type(text) if callable(action.type) else text
    except argparse.ArgumentTypeError as exc:       # the option's own sentence
        raise UserError(f"config key {key!r}: {str(exc).rstrip('.')}.") from None
    except (TypeError, ValueError):
        kind = {"int": "an integer", "float": "a number"}.get(
            getattr(action.type, "__name__", ""), "a valid value")
        raise UserError(f"config key {key!r} must be {kind}, got {text!r}.") from None
    if action.choices is not None and out not in action.choices:
        raise UserError(f"config key {key!r} must be one of "
                        f"{', '.join(map(str, action.choices))}, got {text!r}.")
    return out
