"""Where a sweep's trials run: in this process, on a local process pool or on Dask.

Every executor has the same small interface (a context manager with ``map_unordered(fn,
args)`` yielding results as they complete, and ``describe()`` for ``config.json``), so
:class:`bouncesim.runs.sweep.Sweep` gives the same table on each.
:func:`add_executor_args` / :func:`make_executor` give every experiment the same flags:
``--workers N`` (1 = serial), ``--dask-local N``, ``--dask tcp://HOST:PORT``.
"""

from __future__ import annotations

import argparse
import os
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures import as_completed as futures_as_completed

from envs import UserError

__all__ = ["SerialExecutor", "PoolExecutor", "DaskExecutor", "add_executor_args",
           "make_executor"]


def _exit_with_parent(parent: int) -> None:
    """Worker initializer: end this worker when the process that started it is gone (so a
    killed sweep leaves no orphans computing chunks nobody will read).
    """

    def watch() -> None:
        while True:
            time.sleep(0.5)
            if os.getppid() != parent:
                os._exit(1)

    threading.Thread(target=watch, name="exit-with-parent", daemon=True).start()


def _results_as_completed(futures: list, as_completed: Callable) -> Iterator:
    """Results of ``futures`` as they complete; the rest are cancelled when the consumer
    stops early (an error, or a closed generator).
    """
    try:
        for fut in as_completed(futures):
            yield fut.result()
    finally:
        for fut in futures:
            fut.cancel()


class SerialExecutor:
    """Run chunks one after the other in this process (debugging, ``--workers 1``)."""

    workers = 1
    name = "serial"

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def map_unordered(self, fn: Callable, args: Sequence[tuple]) -> Iterator:
        """Call ``fn(*a)`` for each ``a`` in turn, yielding the results in order."""
        for a in args:
            yield fn(*a)

    def describe(self) -> dict:
        """Kind and worker count, for ``config.json``."""
        return {"kind": self.name, "workers": 1}


class PoolExecutor:
    """A local ``concurrent.futures.ProcessPoolExecutor``.

    Parameters
    ----------
    workers : int, optional   worker processes (default: every core, ``os.cpu_count()``)
    """

    name = "process-pool"

    def __init__(self, workers: int | None = None) -> None:
        self.workers = int(workers or os.cpu_count() or 1)
        self._pool = None

    def __enter__(self):
        self._pool = ProcessPoolExecutor(max_workers=self.workers,
                                         initializer=_exit_with_parent,
                                         initargs=(os.getpid(),))
        return self

    def __exit__(self, *exc):
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None
        return False

    def map_unordered(self, fn: Callable, args: Sequence[tuple]) -> Iterator:
        """Submit ``fn(*a)`` for every ``a``; yield results as they complete."""
        return _results_as_completed([self._pool.submit(fn, *a) for a in args],
                                     futures_as_completed)

    def describe(self) -> dict:
        """Kind and worker count, for ``config.json``."""
        return {"kind": self.name, "workers": self.workers}


PROBE_SECONDS = 10.0     # a scheduler address must answer within this time


def probe_scheduler(address: str, seconds: float = PROBE_SECONDS) -> None:
    """Check that a Dask scheduler answers at ``address`` before a Client connects to it:
    open a comm, ask its identity and expect a scheduler's, all within ``seconds``. Anything
    else (nothing listening, a server that never answers, or one that answers in another
    protocol, whose bytes dask would read as a frame of exabytes) is one sentence.
    """
    import asyncio

    from distributed.comm import connect

    async def ask() -> dict:
        comm = await connect(address, timeout=seconds)
        try:
            await comm.write({"op": "identity"})
            return await comm.read()
        finally:
            comm.abort()

    try:
        reply = asyncio.run(asyncio.wait_for(ask(), seconds))
    except (asyncio.TimeoutError, TimeoutError):
        raise UserError(f"nothing answered as a Dask scheduler at {address} within "
                        f"{seconds:g} s.") from None
    except Exception as exc:                     # any protocol failure: garbage, refusal, ...
        raise UserError(f"{address} is not a Dask scheduler that can be reached "
                        f"({type(exc).__name__}).") from None
    if not (isinstance(reply, dict) and reply.get("type") == "Scheduler"):
        raise UserError(f"{address} answers, but not as a Dask scheduler.")


class DaskExecutor:
    """Dask: a new ``LocalCluster`` of single-threaded worker processes, or a scheduler.

    Parameters
    ----------
    local_workers : int, optional   start a LocalCluster with this many worker processes
    address : str, optional         connect to an existing scheduler (``tcp://HOST:PORT``)
    """

    name = "dask"

    def __init__(self, local_workers: int | None = None, address: str | None = None) -> None:
        if (local_workers is None) == (address is None):
            raise UserError("give exactly one of a local worker count and a scheduler address.")
        self.local_workers = local_workers
        self.address = address
        self._client = self._cluster = None
        self.workers = local_workers or 0

    def __enter__(self):
        try:
            from distributed import Client, LocalCluster
        except ImportError:
            raise UserError("Dask is not installed; install it with "
                            "pip install 'bouncesim[dist]'.") from None
        if self.address is None:
            self._cluster = LocalCluster(n_workers=int(self.local_workers),
                                         threads_per_worker=1, processes=True,
                                         dashboard_address=":0")
            self._client = Client(self._cluster)
        else:
            probe_scheduler(self.address)
            try:
                self._client = Client(self.address, timeout=PROBE_SECONDS)
            except OSError as exc:
                raise UserError(f"cannot reach the Dask scheduler at {self.address}: "
                                f"{exc}.") from None
            self.workers = len(self._client.scheduler_info().get("workers", {}))
        return self

    def __exit__(self, *exc):
        if self._client is not None:
            self._client.close()
        if self._cluster is not None:
            self._cluster.close()
        self._client = self._cluster = None
        return False

    def map_unordered(self, fn: Callable, args: Sequence[tuple]) -> Iterator:
        """Submit ``fn(*a)`` for every ``a`` to the cluster; yield results as they complete."""
        from distributed import as_completed
        return _results_as_completed(
            [self._client.submit(fn, *a, pure=False) for a in args], as_completed)

    def describe(self) -> dict:
        """Kind, worker count and cluster address, for ``config.json``."""
        return {"kind": self.name, "workers": self.workers,
                "cluster": "LocalCluster" if self.address is None else self.address}


def add_executor_args(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """Add ``--workers``, ``--dask-local`` and ``--dask`` (mutually exclusive)."""
    g = parser.add_argument_group("execution (the same seed gives the same table on each)")
    ex = g.add_mutually_exclusive_group()
    ex.add_argument("--workers", type=int, default=None, metavar="N",
                    help="local worker processes (default: every core; 1 runs serially "
                    "in this process)")
    ex.add_argument("--dask-local", type=int, default=None, metavar="N",
                    help="start a dask.distributed LocalCluster with N single-threaded "
                    "worker processes")
    ex.add_argument("--dask", default=None, metavar="ADDRESS",
                    help="use an existing Dask scheduler, e.g. tcp://HOST:8786")
    g.add_argument("--no-progress", action="store_true", help="no progress bar")
    return parser


def make_executor(args: argparse.Namespace):
    """The executor that :func:`add_executor_args` flags ask for."""
    if getattr(args, "dask", None):
        return DaskExecutor(address=args.dask)
    if getattr(args, "dask_local", None) is not None:
        if args.dask_local < 1:
            raise UserError(f"--dask-local needs at least one worker, got {args.dask_local}.")
        return DaskExecutor(local_workers=args.dask_local)
    workers = getattr(args, "workers", None)
    if workers is not None and workers < 1:
        raise UserError(f"--workers needs at least one worker, got {workers}.")
    if workers == 1:
        return SerialExecutor()
    return PoolExecutor(workers)
