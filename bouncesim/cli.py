"""The ``bouncesim`` command line: one sub-command per module in :mod:`bouncesim.commands`.

Every error a user can cause is printed as one sentence with exit status 2; a planning query
with no path exits with 3; a robot run that fails exits with 4. Output paths are checked
before any work (:func:`bouncesim.commands.common.check_outputs`); warnings and progress go to
stderr, so ``--json`` output on stdout stays machine-readable.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys

__all__ = ["build_parser", "main", "version_text"]

# Sub-command modules, in the order --help lists them. Each defines
# ``register(subparsers)``, which adds a parser whose ``func(args)`` returns the exit status.
COMMAND_MODULES = [
    "bouncesim.commands.info",
    "bouncesim.commands.plan",
    "bouncesim.commands.allpairs",
    "bouncesim.commands.coverage",
    "bouncesim.commands.run_plan",
    "bouncesim.commands.show",
    "bouncesim.commands.validate",
    "bouncesim.commands.emulator",
    "bouncesim.commands.import_map",
]

EPILOG = """\
ENV is a catalogue name (lab, fig1, complex, studio) or a path to a JSON/YAML env file.
Angles are in degrees and must be multiples of 360/K (K = orientations).

examples:
  bouncesim info lab --json
  bouncesim plan lab --angles 45,90,135 --start 8 --goal 0
  bouncesim plan lab --angles 90,135 --start 2.89,0.17,0 --goal 0.17,0.17,0 --json
  bouncesim allpairs fig1 --angles 45,90,135 --out results/allpairs_fig1

Output paths (--out, --trace, --record) are checked before any work. Warnings about the map
(walls off the cell grid, cells smaller than the robot, passages no wider than it) go to
stderr as "bouncesim: warning: ...", as do run-plan's progress lines; stdout keeps the
results. Exit status: 0 done, 2 a user error (one sentence), 3 no plan, 4 a robot run that
failed (with rotation noise an expected outcome, not a bug). More: docs/readme_cli.md.
"""


def version_text() -> str:
    """``bouncesim <version>`` (from the installed metadata) plus the git revision when the
    package runs from a git checkout.
    """
    from importlib import metadata

    from bouncesim.runs.metadata import git_revision
    try:
        text = f"bouncesim {metadata.version('bouncesim')}"
    except metadata.PackageNotFoundError:
        text = "bouncesim (version unknown: not installed)"
    rev = git_revision()
    return text + (f" (git {rev[:12]}{'-dirty' if rev.endswith('-dirty') else ''})"
                   if rev else "")


class _Version(argparse.Action):
    """--version, computed only when asked (the git revision costs a subprocess)."""

    def __init__(self, option_strings, dest=argparse.SUPPRESS, **kw):
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS, **kw)

    def __call__(self, parser, namespace, values, option_string=None):
        print(version_text())
        parser.exit()


def build_parser() -> argparse.ArgumentParser:
    """The ``bouncesim`` argument parser with every built command registered."""
    parser = argparse.ArgumentParser(
        prog="bouncesim",
        description="Plan, analyse and simulate minimalist bump-and-clock robots.",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", action=_Version,
                        help="print the package version (and git revision) and exit")
    parser.add_argument("--config", metavar="RUN.toml",
                        help="first argument only: take the command and its options from a "
                        "TOML file (command = \"coverage\", env = \"lab\", angles = [30, 75], "
                        "no_plots = true, ...); flags after it override the file "
                        "(docs/readme_cli.md)")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_MODULES:
        importlib.import_module(name).register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the ``bouncesim`` command line; returns the exit status (2: a user error)."""
    # the commands write figure files only: without a user choice, no GUI backend
    os.environ.setdefault("MPLBACKEND", "Agg")
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv == ["--version"]:       # before the commands' imports (numpy, scipy, shapely)
        print(version_text())
        return 0
    from bouncesim.commands.common import (
        check_outputs,
        discard_warnings,
        flush_warnings,
        remove_created,
    )
    from bouncesim.commands.config_file import apply_config, split_config
    from bouncesim.robots.base import RobotError
    from envs import UserError
    parser = build_parser()
    try:
        config_path, rest = split_config(argv)
        config = None
        if config_path is not None:             # the file's values become the defaults
            commands = next(a.choices for a in parser._actions
                            if isinstance(a, argparse._SubParsersAction))
            rest, config = apply_config(config_path, rest, commands)
    except UserError as exc:
        print(f"bouncesim: error: {exc}", file=sys.stderr)
        return 2
    args = parser.parse_args(rest)
    args.argv = argv                            # for provenance records
    args.config_file = config
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    created: list = []                          # output folders made by the check
    code = 1
    discard_warnings()
    try:
        check_outputs(args, created)            # every output path, before any work
        code = int(args.func(args) or 0)
        flush_warnings()                        # those the command did not print yet
    except UserError as exc:
        print(f"bouncesim: error: {exc}", file=sys.stderr)
        code = 2
    except RobotError as exc:                   # e.g. no robot answering on the port
        print(f"bouncesim: robot error: {exc}", file=sys.stderr)
        code = 4
    except KeyboardInterrupt:
        print("bouncesim: interrupted.", file=sys.stderr)
        code = 130
    except BrokenPipeError:                     # the reader left (e.g. `| head`): the work
        # is done and its files stay; stdout goes nowhere so that Python's exit is quiet
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        created.clear()
        code = 141                              # as a shell reports SIGPIPE
    finally:
        discard_warnings()                      # an error is one line: no warning before it
        if code != 0:
            remove_created(created)             # no empty folder left by a failed command
    return code


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
