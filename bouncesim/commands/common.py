"""Argument helpers shared by the sub-commands: ENV and its overrides, output paths
(declared with :func:`add_output`, all checked by :func:`check_outputs` before a command
starts), warnings and progress lines (both on stderr).

Warnings (:func:`warn`: the map's diagnostics when ENV is loaded, memory notes) wait until
the inputs are valid: a command prints them with :func:`flush_warnings` just before its long
work, and ``bouncesim.cli.main`` prints any left at the end. A command that fails with a
user error prints its one error line only.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

import envs
from bouncesim.runs.metadata import provenance
from bouncesim.runs.metadata import write_config as save_config
from bouncesim.runs.options import parse_angles
from envs import UserError
from envs.contact import at_speed
from envs.diagnostics import diagnose
from envs.motion import MUJOCO_CONTACT, MUJOCO_CONTACTS, PYBULLET_CONTACT, ContactParams
from planners.cells import CellSpace
from planners.coverage import MODELS
from planners.resources import (
    MemoryEstimate,
    check_memory,
    max_grid_cells,
    memory_warning,
    parse_memory,
)

__all__ = ["CONTACT_RULES", "FIGURE_FORMATS", "add_angle_noise_args", "add_contact_arg",
           "add_env_args", "add_figures_arg", "add_output", "check_fits", "check_outputs",
           "cli_provenance", "contact_name", "contact_rule", "discard_warnings", "flush_warnings",
           "load_env", "make_cells", "make_rng", "max_memory", "parse_angles",
           "print_json", "progress", "remove_created", "report_written", "warn",
           "writable_path", "write_config"]

_PENDING: list[str] = []            # warnings not printed yet (see the module docstring)


def add_env_args(p: argparse.ArgumentParser) -> None:
    """ENV plus the --cell-size / --orientations overrides."""
    p.add_argument("env", metavar="ENV",
                   help="catalogue name (%s) or path to an env file" % ", ".join(envs.names()))
    p.add_argument("--cell-size", type=float, default=None, metavar="M",
                   help="override the file's cell size [m]")
    p.add_argument("--orientations", type=int, default=None, metavar="K",
                   help="override the file's number of orientations")
    p.add_argument("--max-memory", default="4G", metavar="SIZE",
                   help="refuse, before allocating, a job whose estimated peak memory "
                   "exceeds SIZE (e.g. 500M, 2G; default 4G)")


def add_angle_noise_args(p: argparse.ArgumentParser) -> None:
    """--angles, and the rotation noise --eps / --r of docs/model.md §11 (coverage, validate)."""
    p.add_argument("--angles", required=True, metavar="A1,A2,...",
                   help="bouncing angles [deg], multiples of 360/K")
    p.add_argument("--eps", type=float, default=0.0, metavar="DEG",
                   help="rotation error range eps [deg], a multiple of 360/K (default 0)")
    p.add_argument("--r", type=float, default=1.0, metavar="R",
                   help="reliability: probability of turning by exactly the angle, in [0, 1] "
                   "(default 1)")


CONTACT_RULES = {"off": None, "pybullet": PYBULLET_CONTACT, "mujoco": MUJOCO_CONTACT}
"""The contact rules of ``--contact`` (docs/model.md §9)."""


def add_contact_arg(p: argparse.ArgumentParser, auto: bool = False, what: str = "",
                    auto_text: str = "the rule of --backend pybullet or mujoco, else off"
                    ) -> None:
    """--contact: the executing robot's contact rule (docs/model.md §9) for a model or a
    planner; with ``auto`` also the choice "auto" (``auto_text`` says what it means) as
    default.
    """
    choices = ("auto", *CONTACT_RULES) if auto else tuple(CONTACT_RULES)
    p.add_argument("--contact", choices=choices, default=choices[0],
                   help=f"contact rule{what} (docs/model.md section 9): off = every front "
                   "contact bumps, pybullet = PyBullet's fitted bumper arc: glancing contacts "
                   "slide on, mujoco = MuJoCo's at --speed: glancing contacts slide while "
                   "turning into the wall, then bump" + (
                       f"; auto (default) = {auto_text}" if auto else " (default off)"))


def contact_rule(args: argparse.Namespace) -> ContactParams | None:
    """The contact rule of ``--contact`` (docs/model.md §9), or None for none. "auto" follows
    ``--backend``; a rule is refused in one sentence for a ``--model`` other than event
    (a command without ``--model``, such as ``plan``, passes it to its planner).
    """
    choice = getattr(args, "contact", "off")
    if choice == "auto":
        backend = getattr(args, "backend", None)
        choice = backend if backend in CONTACT_RULES else "off"
    if choice == "off":
        return None
    model = getattr(args, "model", None)
    if model is not None and not MODELS[model].contact_rule:
        if args.contact == "auto":
            return None
        users = ", ".join(n for n, c in MODELS.items() if c.contact_rule)
        raise UserError(f"the contact rule is part of the {users} model only, not the "
                        f"{model} model.")
    speed = getattr(args, "speed", None)
    if choice == "mujoco" and speed is not None:      # MuJoCo's rule depends on the speed
        rule = at_speed(MUJOCO_CONTACTS, speed)
        if rule is not None:
            return rule
        near = min(MUJOCO_CONTACTS, key=lambda v: abs(v - float(speed)))
        warn(f"MuJoCo's contact rule is fitted at {', '.join(map(str, MUJOCO_CONTACTS))} m/s "
             f"only; at --speed {speed:g} the {near:g} m/s rule is used.")
        return MUJOCO_CONTACTS[near]
    return CONTACT_RULES[choice]


def contact_name(contact: ContactParams | None) -> str:
    """The ``--contact`` name of a rule ("off", "pybullet", "mujoco" for MuJoCo's at any
    fitted speed), else its text.
    """
    for name, rule in CONTACT_RULES.items():
        if rule == contact:
            return name
    if contact in MUJOCO_CONTACTS.values():
        return "mujoco"
    return contact.text


def max_memory(args: argparse.Namespace) -> int:
    """--max-memory in bytes."""
    return parse_memory(args.max_memory)


def load_env(args: argparse.Namespace, warnings: bool = True) -> envs.Environment:
    """ENV with the overrides; a grid too large for --max-memory is refused before it is
    built. With ``warnings``, the map's diagnostics (:func:`envs.diagnostics.diagnose`) are
    queued with :func:`warn`.
    """
    env = envs.load(args.env, cell_size=args.cell_size, orientations=args.orientations,
                    max_grid_cells=max_grid_cells(max_memory(args)))
    if warnings:
        for w in diagnose(env):
            warn(w.message)
    return env


def warn(message: str) -> None:
    """Queue ``bouncesim: warning: <message>`` for stderr (stdout stays machine-readable);
    a message already queued is not repeated.
    """
    line = f"bouncesim: warning: {message}"
    if line not in _PENDING:
        _PENDING.append(line)


def flush_warnings() -> None:
    """Print the queued warnings on stderr, once: call it just before the long work."""
    while _PENDING:
        print(_PENDING.pop(0), file=sys.stderr, flush=True)


def discard_warnings() -> None:
    """Forget the queued warnings (a command failed before its work started)."""
    _PENDING.clear()


def progress(args: argparse.Namespace):
    """A printer of progress lines on stderr, or None with ``--quiet``."""
    if getattr(args, "quiet", False):
        return None
    return lambda line: print(line, file=sys.stderr, flush=True)


def add_output(p: argparse.ArgumentParser, *flags: str, folder: bool = False,
               as_path: bool = True, suffixes: tuple = (), **kw) -> argparse.Action:
    """Add an output option (a file, or with ``folder`` a folder) that
    :func:`check_outputs` checks before the command starts; its value is a Path
    (``as_path``) or the string as given. With ``suffixes`` (e.g. ``(".png", ".svg")``) the
    file name must end in one of them.
    """
    action = p.add_argument(*flags, **kw)
    outputs = p.get_default("_outputs") or ()
    p.set_defaults(_outputs=(*outputs, (action.dest, flags[0], folder, as_path, suffixes)))
    return action


def check_outputs(args: argparse.Namespace, created: list | None = None) -> list[Path]:
    """Check every output option of the command (:func:`add_output`) before any work:
    :class:`UserError` in one sentence for the first that cannot be written. Returns (and
    appends to ``created``) the folders it had to create, deepest first.
    """
    created = [] if created is None else created
    for dest, flag, folder, as_path, suffixes in getattr(args, "_outputs", ()):
        value = getattr(args, dest, None)
        if value is None:
            continue
        if not str(value).strip():
            raise UserError(f"{flag} needs a {'folder' if folder else 'file'} name.")
        path = Path(value)
        if suffixes and path.suffix.lower() not in suffixes:
            listed = (f"{', '.join(suffixes[:-1])} or {suffixes[-1]}" if len(suffixes) > 1
                      else suffixes[0])
            raise UserError(f"{flag} must end in {listed}, "
                            f"got {path.name!r}.")
        base = path if folder else path.parent
        missing = [q for q in (base, *base.parents) if not q.exists()]
        try:
            writable_path(path, flag, folder=folder)
        finally:
            made = [q for q in missing if q.is_dir()]
            created.extend(made)
        parents = [q for q in made if q != path]       # not the asked-for --out folder itself
        if parents:         # said, not silent (queued: an error after it stays one line)
            warn(f"created the folder {parents[-1]} for {flag} {value}.")
        if as_path:
            setattr(args, dest, path)
    return created


def remove_created(created) -> None:
    """Remove the folders :func:`check_outputs` created that are still empty."""
    for q in created:
        try:
            q.rmdir()
        except OSError:
            pass


def make_cells(args: argparse.Namespace, env: envs.Environment) -> CellSpace:
    """The cell space of ENV, refusing a step table above --max-memory."""
    return CellSpace(env, max_memory=max_memory(args))


FIGURE_FORMATS = (".png", ".svg", ".pdf")
"""The figure files the commands write: a raster (PNG) or vector (SVG, PDF) by the suffix."""


def add_figures_arg(p: argparse.ArgumentParser) -> None:
    """``--figures png|svg|pdf``: the format of the figures a command writes into --out."""
    p.add_argument("--figures", choices=[f.lstrip(".") for f in FIGURE_FORMATS], default="png",
                   help="format of the figures written into --out (default png; svg and pdf "
                   "are vector graphics for papers)")


def check_fits(args: argparse.Namespace, cells: CellSpace, est: MemoryEstimate,
               what: str = "planning") -> MemoryEstimate:
    """A planner's or model's memory estimate ``est`` (its ``memory_estimate``) checked at
    --max-memory (refused above it, in one sentence), and a warning when it exceeds the
    memory free now; returns it.
    """
    est = check_memory(cells, est, what=what, max_memory=max_memory(args))
    note = memory_warning(est)
    if note:
        warn(note)
    return est


def make_rng(seed) -> np.random.Generator:
    """The random generator of --seed (a non-negative integer)."""
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise UserError(f"--seed must be a non-negative integer, got {seed}.")
    return np.random.default_rng(seed)


def cli_provenance(args, env=None) -> dict:
    """:func:`bouncesim.runs.metadata.provenance` of a CLI run: its command line, seed and
    environment, and with ``--config`` the file's path and values (``config_file``).
    """
    out = provenance(getattr(args, "argv", sys.argv[1:]), env, getattr(args, "seed", None))
    if getattr(args, "config_file", None) is not None:      # --config FILE: its values
        out["config_file"] = args.config_file
    return out


def write_config(out: Path, args, env=None) -> Path:
    """Write ``out/config.json``: the provenance of a CLI output folder (the command line,
    the environment and its hash, the seed, package versions and the git revision); returns
    its path. ``out`` may also be a ``.json`` file (the provenance beside a single output).
    """
    return save_config(out, cli_provenance(args, env))


def writable_path(path, what: str = "--out", folder: bool = False) -> Path:
    """Check that an output file (or, with ``folder``, a folder, created here) can be
    written, before any long work; :class:`UserError` in one sentence otherwise.
    """
    if not str(path).strip():           # Path("") would be the current folder
        raise UserError(f"{what} needs a {'folder' if folder else 'file'} name.")
    p = Path(path)
    if folder and p.exists() and not p.is_dir():
        raise UserError(f"{what} {p} is a file, not a folder.")
    try:
        if folder:
            p.mkdir(parents=True, exist_ok=True)
            probe_dir = p
        else:
            if p.is_dir():
                raise UserError(f"{what} {p} is a folder, not a file.")
            p.parent.mkdir(parents=True, exist_ok=True)
            probe_dir = p.parent
            if p.exists():
                open(p, "a").close()
        with tempfile.TemporaryFile(dir=probe_dir):
            pass
    except UserError:
        raise
    except (OSError, ValueError) as exc:
        reason = getattr(exc, "strerror", None) or str(exc)
        raise UserError(f"cannot write {what} {p} ({reason.rstrip('.')}).") from None
    return p


def report_written(paths, args) -> None:
    """One ``wrote PATH`` line per file written, on stdout, or on stderr under ``--json``
    (whose stdout is data).
    """
    stream = sys.stderr if getattr(args, "json", False) else sys.stdout
    for path in paths:
        print(f"wrote {path}", file=stream)


def print_json(obj, file=None) -> None:
    """Print ``obj`` as one line of JSON (non-ASCII kept, e.g. ``°``)."""
    print(json.dumps(obj, separators=(", ", ": "), ensure_ascii=False),
          file=file or sys.stdout)
