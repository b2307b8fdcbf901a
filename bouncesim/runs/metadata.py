"""Run metadata: what produced a result. The one home of package versions, the git revision
and the ``config.json`` writer used by the CLI, the sweeps and the experiments alike.
"""

from __future__ import annotations

import hashlib
import json
import os
import platform
import shlex
import subprocess
import sys
from datetime import UTC, datetime
from importlib import metadata
from pathlib import Path

__all__ = ["PACKAGES", "atomic_write_text", "config_record", "env_sha256", "git_revision",
           "provenance", "run_metadata", "versions", "write_config"]

PACKAGES = ("numpy", "scipy", "shapely", "networkx", "pandas", "matplotlib", "pybullet",
            "dask", "distributed", "bouncesim")
"""The packages whose versions :func:`versions` reports (None when not installed)."""

_ROOT = Path(__file__).resolve().parents[2]     # the repository (bouncesim/runs/ -> root)


def versions() -> dict[str, str | None]:
    """Python, platform and the version of every package in :data:`PACKAGES`."""
    out: dict[str, str | None] = {"python": sys.version.split()[0],
                                  "platform": platform.platform()}
    for name in PACKAGES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = None
    return out


def git_revision() -> str | None:
    """The current git commit (with '-dirty' when tracked files have changes), or None."""
    try:
        rev = subprocess.run(["git", "rev-parse", "HEAD"], cwd=_ROOT, capture_output=True,
                             text=True, timeout=10)
        if rev.returncode != 0:
            return None
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"],
                               cwd=_ROOT, capture_output=True, text=True, timeout=10)
        return rev.stdout.strip() + ("-dirty" if dirty.stdout.strip() else "")
    except (OSError, subprocess.SubprocessError):
        return None


def run_metadata() -> dict:
    """``{"versions": versions(), "git_revision": git_revision()}``."""
    return {"versions": versions(), "git_revision": git_revision()}


def env_sha256(env) -> str:
    """SHA-256 of an environment's env-file form (``Environment.to_dict`` as JSON with sorted
    keys): the same room gives the same hash whichever file or name it was loaded from.
    """
    blob = json.dumps(env.to_dict(), sort_keys=True, separators=(",", ":")).encode()
    return hashlib.sha256(blob).hexdigest()


def provenance(argv, env=None, seed=None, program: str = "bouncesim") -> dict:
    """The fields that say how a result was asked for: the command line (``command``, and
    ``argv`` as a list), the seed (None for a run without randomness) and, with ``env``, the
    environment's name and :func:`env_sha256`. ``program`` is what ``argv`` follows
    ("bouncesim", or "python -m experiments.nav_exact").
    """
    argv = [str(a) for a in argv]
    out = {"command": " ".join([program, shlex.join(argv)]).strip(), "argv": argv,
           "seed": seed}
    if env is not None:
        out.update({"env": env.name, "env_sha256": env_sha256(env)})
    return out


def config_record(fields: dict) -> dict:
    """``fields`` plus :func:`run_metadata` and the time it was made (UTC), unless
    ``fields`` already has them (a resumed sweep keeps its first ones).
    """
    out = dict(fields)
    for key, value in run_metadata().items():
        out.setdefault(key, value)
    out.setdefault("created", datetime.now(UTC).isoformat(timespec="seconds"))
    return out


def atomic_write_text(path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file and a rename: a reader (or a run
    stopped half-way) sees the old file or the new one, never a part.
    """
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "w") as f:
        f.write(text)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


def write_config(path, fields: dict) -> Path:
    """Write :func:`config_record` of ``fields`` as JSON to ``path`` (a folder, which gets
    ``config.json``, or a ``.json`` file); returns the file written. Every ``config.json``
    the CLI, the sweeps and the experiments write goes through here.
    """
    path = Path(path)
    if path.suffix != ".json":
        path.mkdir(parents=True, exist_ok=True)
        path = path / "config.json"
    atomic_write_text(path, json.dumps(config_record(fields), indent=2, default=str) + "\n")
    return path
