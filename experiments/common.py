"""Shared plumbing for experiments: argument parsing, output folders and config.json."""

from __future__ import annotations

import argparse
import sys
from dataclasses import asdict, dataclass, fields
from pathlib import Path

from bouncesim.runs.metadata import provenance
from bouncesim.runs.metadata import write_config as save_config
from envs import UserError
from planners.coverage import MODELS, check_model

__all__ = ["EXECUTION_FIELDS", "add_models_arg", "experiment_parser", "name_list", "output_dir",
           "invocation", "recorded", "run_main", "write_config"]



@dataclass(frozen=True)
class SweepOptions:
    """How a sweep experiment runs, not what it computes: the base of their ``Config``s.

    Attributes
    ----------
    workers, dask_local, dask : the executor (see ``add_executor_args``)
    progress : bool           show a progress bar
    """

    workers: int | None = None
    dask_local: int | None = None
    dask: str | None = None
    progress: bool = True


EXECUTION_FIELDS = ("out",) + tuple(f.name for f in fields(SweepOptions))
"""Config fields that say where and how a sweep runs, not what it computes."""


_INVOCATION: dict = {}
"""The program and arguments of the last experiment command line parsed (for config.json)."""


class _ExperimentParser(argparse.ArgumentParser):
    """An ArgumentParser that remembers the command line it parsed, for config.json."""

    def parse_args(self, args=None, namespace=None):
        _INVOCATION.update(program=self.prog,
                           argv=list(sys.argv[1:] if args is None else args))
        return super().parse_args(args, namespace)


def experiment_parser(name: str, description: str, default_seed: int = 0
                      ) -> argparse.ArgumentParser:
    """An ArgumentParser with the common --quick, --seed and --out flags."""
    p = _ExperimentParser(prog=f"python -m experiments.{name}", description=description)
    p.add_argument("--quick", action="store_true",
                   help="small budget (what CI runs); the full run is the default")
    p.add_argument("--seed", type=int, default=default_seed, help="root random seed")
    p.add_argument("--out", type=Path, default=Path("results") / name,
                   help=f"output folder (default results/{name}/)")
    return p


def name_list(text: str) -> tuple[str, ...]:
    """Comma-separated names (maps, environments) as a tuple, blanks dropped."""
    return tuple(n.strip() for n in str(text).split(",") if n.strip())


def run_main(name: str, make_config, run, compare: Path | None = None) -> int:
    """An experiment's ``main`` after parsing: ``run(make_config())``, then with ``compare``
    (``--compare DIR``, :func:`experiments.compare.add_compare_arg`) the comparison of its
    tables with DIR's (exit status 1 when they differ); a :class:`UserError` becomes
    ``<name>: error: <sentence>`` on stderr and exit status 2.
    """
    from .compare import report
    try:
        config = make_config()
        run(config)
        return 0 if compare is None else report(compare, config.out)
    except UserError as exc:
        print(f"{name}: error: {exc}", file=sys.stderr)
        return 2


def _model_list(text: str) -> list[str]:
    try:
        return [check_model(m) for m in name_list(text) or [""]]
    except UserError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def add_models_arg(p: argparse.ArgumentParser, default: str, what: str) -> None:
    """``--models``: comma-separated names from the coverage-model registry (a list)."""
    p.add_argument("--models", type=_model_list, default=default, metavar="M1,M2,...",
                   help=f"comma-separated coverage models ({', '.join(MODELS)}): {what} "
                   f"(default {default})")


def recorded(config) -> dict:
    """A frozen experiment Config as the dict a sweep stores and compares on resume.

    ``dataclasses.asdict`` without :data:`EXECUTION_FIELDS`: the output folder, the executor
    and the progress bar may change between a run and its resumption.
    """
    return {k: v for k, v in asdict(config).items() if k not in EXECUTION_FIELDS}


def output_dir(path: Path) -> Path:
    """Create ``path`` (and parents) if needed; returns it."""
    path = Path(path)
    path.mkdir(parents=True, exist_ok=True)
    return path


def invocation(seed=None) -> dict:
    """The command line that ran this experiment and its seed
    (``bouncesim.runs.metadata.provenance``): config.json's first fields, and a sweep's
    ``provenance``.
    """
    return provenance(_INVOCATION.get("argv", sys.argv[1:]), seed=seed,
                      program=_INVOCATION.get("program", "python -m experiments"))


def write_config(out_dir: Path, config: dict) -> Path:
    """Write ``config.json``: the given parameters, the command line that ran the experiment,
    package versions, git revision and time (``bouncesim.runs.metadata.write_config``).
    """
    return save_config(output_dir(out_dir), {**invocation(config.get("seed")), **config})
