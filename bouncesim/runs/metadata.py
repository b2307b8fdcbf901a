"""Run metadata: what produced a result (the one home of package versions and the git
revision written to every ``config.json``, by sweeps and experiments alike).
"""

from __future__ import annotations

import hashlib
import json
import platform
import shlex
import subprocess
import sys
from datetime import UTC, datetime
from importlib import metadata
from pathlib import Path

__all__ = ["PACKAGES", "env_sha256", "git_revision", "provenance", "run_metadata", "versions"]

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


def provenance(argv, env=None, seed=None) -> dict:
    """What a CLI output folder's ``config.json`` holds: the command line (``command``, and
    ``argv`` as a list), the environment's name and :func:`env_sha256`, the seed (None for a
    command without randomness), :func:`run_metadata` and the time it was written (UTC).
    """
    argv = [str(a) for a in argv]
    out = {"command": shlex.join(["bouncesim", *argv]), "argv": argv, "seed": seed}
    if env is not None:
        out.update({"env": env.name, "env_sha256": env_sha256(env)})
    out.update(run_metadata())
    out["created"] = datetime.now(UTC).isoformat(timespec="seconds")
    return out
