"""Seeded, resumable parameter sweeps on a local process pool or a Dask cluster.

A sweep runs ``trial_fn(params, rng) -> dict`` once for every entry of a list of trial
parameter dicts (usually a :func:`grid`: environment x plan x noise x seed x backend ...).

- **Seeds.** Trial ``i`` gets ``numpy.random.SeedSequence(root_seed, spawn_key=(i,))``, the
  same child that ``SeedSequence(root_seed).spawn(n)[i]`` gives: it depends only on the root
  seed and the trial's index in the list, never on which worker runs it or when. So the
  serial runner, the process pool and Dask give identical tables, and so does a resumed run.
- **Journal.** Every finished trial is appended to ``<name>.jsonl`` in the output folder as
  one JSON line, then flushed and fsynced. A run that is killed (even SIGKILL mid-write) and
  started again with the same arguments reads the journal, drops a torn last line, skips the
  trials already done and runs the rest: no row is lost or duplicated. At the end the tidy
  table ``<name>.csv`` (one row per trial, sorted by trial index; optionally Parquet) is
  written atomically.
- **Config.** ``config.json`` holds the sweep's identity (root seed, trial function, number of
  trials, a SHA-256 of the trial list and the caller's config dict) plus the caller's
  ``provenance`` (the command line, seed and map hash; not compared on resume), package
  versions, the git revision and one entry per session. A re-run whose identity differs is
  refused with one sentence (:class:`envs.UserError`) instead of mixing two sweeps in one
  table.
- **Executors** (:mod:`bouncesim.runs.executors`). :class:`SerialExecutor` (in-process, for
  debugging), :class:`PoolExecutor` (``concurrent.futures.ProcessPoolExecutor``, all cores by
  default) and :class:`DaskExecutor` (a new ``dask.distributed.LocalCluster`` or an existing
  scheduler).
  :func:`add_executor_args` / :func:`make_executor` give every experiment the same flags:
  ``--workers N`` (1 = serial), ``--dask-local N``, ``--dask tcp://HOST:PORT``.
- **Progress.** A tqdm bar (done, total, ETA) on stderr.

``trial_fn`` must be a module-level function (it is pickled to the workers) and a pure
function of its parameters and its generator. Parameter values and results must be
JSON-serialisable scalars (str, int, float, bool, None).

Examples
--------
>>> import tempfile
>>> trials = grid(mu=[0.0, 1.0], n=[3])
>>> with tempfile.TemporaryDirectory() as d:
...     table = run_sweep(demo_trial, trials, root_seed=1, out_dir=d, progress=False)
>>> list(table.columns[:4]), len(table)
(['trial', 'mu', 'n', 'mean'], 2)
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import os
import sys
import time
import traceback
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pandas as pd

from envs import UserError

from .executors import PoolExecutor, SerialExecutor
from .metadata import atomic_write_text, config_record

__all__ = ["grid", "trial_seed", "Sweep", "SweepResult", "run_sweep", "read_journal",
           "demo_trial", "TrialError"]


class TrialError(RuntimeError):
    """A trial function raised; the message names the trial and carries the traceback."""


# ============================================================================ trials and seeds
def grid(**axes: Iterable) -> list[dict]:
    """The Cartesian product of named parameter axes, as a list of dicts.

    The order is deterministic: the first axis varies slowest (``itertools.product``).

    >>> grid(a=[1, 2], b=["x", "y"])
    [{'a': 1, 'b': 'x'}, {'a': 1, 'b': 'y'}, {'a': 2, 'b': 'x'}, {'a': 2, 'b': 'y'}]
    """
    names = list(axes)
    values = [list(v) for v in axes.values()]
    return [dict(zip(names, combo)) for combo in itertools.product(*values)]


def trial_seed(root_seed: int, index: int) -> np.random.SeedSequence:
    """The SeedSequence of trial ``index``: ``SeedSequence(root_seed).spawn(n)[index]``.

    >>> a = trial_seed(7, 3).generate_state(2)
    >>> b = np.random.SeedSequence(7).spawn(5)[3].generate_state(2)
    >>> bool((a == b).all())
    True
    """
    return np.random.SeedSequence(int(root_seed), spawn_key=(int(index),))


def _jsonable(value):
    """A JSON-safe scalar (numpy scalars become Python ones)."""
    if isinstance(value, np.generic):
        return value.item()
    return value


def _normalise(d: dict, what: str) -> dict:
    out = {}
    for k, v in d.items():
        v = _jsonable(v)
        if not (v is None or isinstance(v, (str, int, float, bool))):
            raise UserError(f"{what} {k!r} must be a str, int, float, bool or None, "
                            f"got {type(v).__name__}.")
        out[str(k)] = v
    return out


def demo_trial(params: dict, rng: np.random.Generator) -> dict:
    """A cheap trial for tests and examples: the mean of ``n`` draws of N(mu, 1).

    ``params`` may hold ``sleep`` [s] to make the trial slow (for interruption tests).
    """
    if params.get("sleep"):
        time.sleep(float(params["sleep"]))
    x = rng.normal(float(params.get("mu", 0.0)), 1.0, size=int(params.get("n", 10)))
    return {"mean": float(x.mean()), "first": float(x[0]), "above": int((x > 0).sum())}


def _importable(fn: Callable) -> Callable:
    """The same function under its importable module name when it was defined in a module run
    as ``python -m package.module`` (``__main__``), so that workers and a remote scheduler
    import it by name and the sweep's identity does not depend on how the module was run.
    """
    if getattr(fn, "__module__", None) != "__main__":
        return fn
    spec = getattr(sys.modules.get("__main__"), "__spec__", None)
    if spec is None or not spec.name or spec.name == "__main__":
        return fn
    import importlib
    try:
        twin = getattr(importlib.import_module(spec.name), fn.__qualname__, None)
    except ImportError:
        return fn
    return twin if callable(twin) else fn


# ============================================================================ workers
def _run_chunk(trial_fn: Callable, root_seed: int, items: list[tuple[int, dict]]
               ) -> list[dict]:
    """Run trials (index, params) in a worker; return their rows."""
    rows = []
    for index, params in items:
        rng = np.random.default_rng(trial_seed(root_seed, index))
        try:
            result = trial_fn(dict(params), rng)
        except Exception as exc:
            raise TrialError(f"trial {index} {params} raised {type(exc).__name__}: {exc}\n"
                             + traceback.format_exc()) from None
        if not isinstance(result, dict):
            raise TrialError(f"trial {index}: the trial function returned "
                             f"{type(result).__name__}, not a dict.")
        clash = set(result) & (set(params) | {"trial"})
        if clash:
            raise TrialError(f"trial {index}: result keys {sorted(clash)} repeat parameter "
                             f"names.")
        rows.append({"trial": index, **params, **_normalise(result, "result")})
    return rows


# ============================================================================ journal
def read_journal(path: Path, repair: bool = True) -> dict[int, dict]:
    """Rows already in a journal, by trial index.

    A last line without its newline (a write cut short) is dropped and, with ``repair``,
    cut off the file. A broken line anywhere else is an error; a repeated trial keeps its
    first row.
    """
    path = Path(path)
    if not path.exists():
        return {}
    data = path.read_bytes()
    rows: dict[int, dict] = {}
    good_end = 0
    pos = 0
    while pos < len(data):
        nl = data.find(b"\n", pos)
        if nl < 0:                                   # torn last line
            break
        line = data[pos:nl]
        if line.strip():
            try:
                row = json.loads(line)
                index = int(row["trial"])
            except (ValueError, KeyError, TypeError):
                raise UserError(f"{path} has a broken line at byte {pos}; the journal is "
                                f"damaged beyond a torn last line.") from None
            rows.setdefault(index, row)
        pos = good_end = nl + 1
    if repair and good_end < len(data):
        with open(path, "r+b") as f:
            f.truncate(good_end)
            f.flush()
            os.fsync(f.fileno())
    return rows


class _Journal:
    def __init__(self, path: Path) -> None:
        self._f = open(path, "ab", buffering=0)

    def append(self, rows: list[dict]) -> None:
        if not rows:
            return
        blob = b"".join(json.dumps(r, allow_nan=True).encode() + b"\n" for r in rows)
        self._f.write(blob)
        os.fsync(self._f.fileno())

    def close(self) -> None:
        self._f.close()


# ============================================================================ the sweep
@dataclass(frozen=True)
class SweepResult:
    """What :meth:`Sweep.run` did.

    Attributes
    ----------
    table : pandas.DataFrame   one row per trial, sorted by trial index
    csv : Path                 the tidy table
    n_trials : int
    n_resumed : int            trials found done in the journal
    n_run : int                trials run in this session
    wall_s : float             this session's wall time [s]
    executor : dict            what ran the trials
    """

    table: pd.DataFrame
    csv: Path
    n_trials: int
    n_resumed: int
    n_run: int
    wall_s: float
    executor: dict


class Sweep:
    """A seeded, resumable sweep (see the module docstring).

    Parameters
    ----------
    trial_fn : callable ``(params: dict, rng: numpy.random.Generator) -> dict``
        Module-level, pure. Result keys must not repeat parameter names or ``trial``.
    trials : sequence of dict
        The parameters of every trial (e.g. from :func:`grid`); the index in this list is the
        trial's identity and selects its seed.
    root_seed : int
    out_dir : path            folder for config.json, the journal and the table
    config : dict, optional   the caller's parameters, stored in config.json and compared on
                              resume (must be JSON-serialisable)
    name : str                base name of the journal and the table (``runs``)
    parquet : bool            also write ``<name>.parquet`` (needs pyarrow or fastparquet)
    chunk : int, optional     trials per task (default: about 32 tasks per worker, at most 16
                              trials each; 1 on the serial executor)
    provenance : dict, optional  how the run was asked for (``runs.metadata.provenance``: the
                              command line, the environment's hash, the seed), stored in
                              config.json when the sweep starts but not compared on resume;
                              each session records its own ``command``
    """

    def __init__(self, trial_fn: Callable, trials: Sequence[dict], root_seed: int,
                 out_dir, config: dict | None = None, *, name: str = "runs",
                 parquet: bool = False, chunk: int | None = None,
                 provenance: dict | None = None) -> None:
        if not callable(trial_fn):
            raise UserError("the trial function is not callable.")
        qual = getattr(trial_fn, "__qualname__", "")
        if "<locals>" in qual or "<lambda>" in qual:
            raise UserError(f"the trial function {qual} must be defined at module level so "
                            f"that it can be sent to worker processes.")
        self.trial_fn = _importable(trial_fn)
        self.trials = [_normalise(t, "parameter") for t in trials]
        if any("trial" in t for t in self.trials):
            raise UserError("'trial' is reserved for the trial index; rename that parameter.")
        self.root_seed = int(root_seed)
        self.out_dir = Path(out_dir)
        self.config = json.loads(json.dumps(config or {}, default=str))
        self.provenance = json.loads(json.dumps(provenance or {}, default=str))
        self.name = name
        self.parquet = parquet
        self.chunk = chunk

    # ------------------------------------------------------------------ identity
    @property
    def identity(self) -> dict:
        """What makes a sweep the same sweep (trial function, seed, trials' hash): a re-run must
        match.
        """
        blob = json.dumps(self.trials, sort_keys=True).encode()
        fn = self.trial_fn
        return {"trial_fn": f"{fn.__module__}.{fn.__qualname__}", "root_seed": self.root_seed,
                "n_trials": len(self.trials), "trials_sha256": hashlib.sha256(blob).hexdigest(),
                "seeding": "trial i uses numpy SeedSequence(root_seed, spawn_key=(i,)) = "
                           "SeedSequence(root_seed).spawn(n)[i]",
                "config": self.config}

    @property
    def journal_path(self) -> Path:
        """The append-only journal of finished trials (JSON lines)."""
        return self.out_dir / f"{self.name}.jsonl"

    @property
    def csv_path(self) -> Path:
        """The tidy CSV of all trials, written when the sweep completes."""
        return self.out_dir / f"{self.name}.csv"

    @property
    def config_path(self) -> Path:
        """The sweep's ``config.json``."""
        return self.out_dir / "config.json"

    def check_folder(self) -> dict | None:
        """Check, without writing, that the output folder is empty of sweeps or holds this
        one (so a caller can refuse before any expensive work): its stored ``config.json``,
        or None when it has none yet. One sentence when it cannot be resumed.
        """
        ident = self.identity
        if self.config_path.exists():
            try:
                stored = json.loads(self.config_path.read_text())
            except ValueError:
                raise UserError(f"{self.config_path} is not valid JSON; remove the folder "
                                f"or use another output folder.") from None
            old = stored.get("sweep")
            if old != ident:
                diff = sorted(k for k in set(ident) | set(old or {})
                              if (old or {}).get(k) != ident.get(k))
                raise UserError(f"{self.out_dir} holds a different sweep (it differs in "
                                f"{', '.join(diff)}); use another output folder or delete "
                                f"this one to start again.")
            return stored
        if self.journal_path.exists() and self.journal_path.stat().st_size > 0:
            raise UserError(f"{self.journal_path} exists without its config.json, so it cannot "
                            f"be checked; use another output folder or delete it.")
        return None

    def _load_or_create_config(self) -> dict:
        stored = self.check_folder()
        if stored is not None:
            return stored
        stored = config_record({**self.provenance, **self.config, "sweep": self.identity,
                                "sessions": []})
        atomic_write_text(self.config_path, json.dumps(stored, indent=2, default=str) + "\n")
        return stored

    # ------------------------------------------------------------------ run
    def run(self, executor=None, progress: bool = True) -> SweepResult:
        """Run every trial not yet in the journal; write the table; return it."""
        self.out_dir.mkdir(parents=True, exist_ok=True)
        stored = self._load_or_create_config()
        done = read_journal(self.journal_path, repair=True)
        n = len(self.trials)
        bad = [i for i in done if not 0 <= i < n or
               any(done[i].get(k) != v for k, v in self.trials[i].items())]
        if bad:
            raise UserError(f"{self.journal_path} has rows that do not match this sweep's "
                            f"trials (e.g. trial {bad[0]}); use another output folder.")
        todo = [i for i in range(n) if i not in done]
        executor = executor if executor is not None else PoolExecutor()
        n_resumed = len(done)
        t0 = time.perf_counter()
        started = datetime.now(UTC).isoformat(timespec="seconds")
        if todo:
            with executor as ex:
                workers = max(1, int(getattr(ex, "workers", 1) or 1))
                chunk = self.chunk or max(1, min(16, math.ceil(len(todo) / (32 * workers))))
                if isinstance(ex, SerialExecutor):
                    chunk = self.chunk or 1
                tasks = [(self.trial_fn, self.root_seed,
                          [(i, self.trials[i]) for i in todo[s:s + chunk]])
                         for s in range(0, len(todo), chunk)]
                journal = _Journal(self.journal_path)
                bar = _progress(n, n_resumed, self.name, progress)
                try:
                    for rows in ex.map_unordered(_run_chunk, tasks):
                        journal.append(rows)
                        for r in rows:
                            done[r["trial"]] = json.loads(json.dumps(r))
                        bar.update(len(rows))
                finally:
                    bar.close()
                    journal.close()
        wall = time.perf_counter() - t0
        table = pd.DataFrame([done[i] for i in range(n)])
        if len(table):
            cols = ["trial", *self.trials[0].keys()]
            table = table[cols + [c for c in table.columns if c not in cols]]
        atomic_write_text(self.csv_path, table.to_csv(index=False))
        if self.parquet:
            table.to_parquet(self.out_dir / f"{self.name}.parquet", index=False)
        desc = executor.describe() if todo else {"kind": "none (all trials were done)"}
        stored.setdefault("sessions", []).append(
            {"started": started, **({"command": self.provenance["command"]}
                                    if "command" in self.provenance else {}),
             "wall_s": round(wall, 3), "trials_run": len(todo),
             "trials_resumed": n_resumed, "executor": desc})
        atomic_write_text(self.config_path, json.dumps(stored, indent=2, default=str) + "\n")
        return SweepResult(table=table, csv=self.csv_path, n_trials=n, n_resumed=n_resumed,
                           n_run=len(todo), wall_s=wall, executor=desc)


def _progress(total: int, initial: int, name: str, enabled: bool):
    from tqdm import tqdm
    return tqdm(total=total, initial=initial, desc=name, unit="trial", disable=not enabled,
                smoothing=0.05, file=sys.stderr)


def run_sweep(trial_fn: Callable, trials: Sequence[dict], root_seed: int, out_dir,
              config: dict | None = None, executor=None, *, progress: bool = True,
              name: str = "runs", parquet: bool = False, chunk: int | None = None,
              provenance: dict | None = None) -> pd.DataFrame:
    """Run (or resume) a sweep and return its table; see :class:`Sweep`.

    ``executor`` defaults to a process pool on every core; pass :class:`SerialExecutor` to
    debug in-process, or ``make_executor(args)`` after :func:`add_executor_args`.
    """
    sweep = Sweep(trial_fn, trials, root_seed, out_dir, config, name=name, parquet=parquet,
                  chunk=chunk, provenance=provenance)
    return sweep.run(executor, progress=progress).table
