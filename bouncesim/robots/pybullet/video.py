"""Top-down video of a PyBullet world: frames from PyBullet's tiny renderer, written by
imageio (``.gif``, or ``.mp4`` and other containers with imageio-ffmpeg).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from envs import UserError

__all__ = ["check_record_format", "render_top_down", "write_video"]


def check_record_format(path: Path) -> None:
    """Refuse, in one sentence, a video file name that cannot be written."""
    ext = path.suffix.lower()
    if ext == ".gif":
        return
    if ext in (".mp4", ".avi", ".mkv", ".mov"):
        try:
            import imageio_ffmpeg  # noqa: F401
        except ImportError:
            raise UserError(f"recording {ext} video needs imageio-ffmpeg "
                            f"(pip install imageio-ffmpeg); record to a .gif instead.") \
                from None
        return
    raise UserError(f"cannot record to {path.name!r}: use a .gif or .mp4 file name.")


def render_top_down(p, kw: dict, bounds, width: int, wall_height: float) -> np.ndarray:
    """One RGB uint8 frame, ``width`` pixels wide, looking straight down on ``bounds``
    (x0, y0, x1, y1) [m] with a 0.15 m margin; ``p`` is the pybullet module and ``kw`` the
    client's keyword arguments.
    """
    x0, y0, x1, y1 = bounds
    m = 0.15
    w, h = (x1 - x0) + 2 * m, (y1 - y0) + 2 * m
    W = width
    H = max(16, int(round(W * h / w)) // 2 * 2)
    fov = 20.0
    dist = (h / 2) / math.tan(math.radians(fov / 2)) + wall_height
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    view = p.computeViewMatrix([cx, cy, dist], [cx, cy, 0], [0, 1, 0])
    proj = p.computeProjectionMatrixFOV(fov, W / H, dist / 4, dist * 2)
    img = p.getCameraImage(W, H, view, proj, renderer=p.ER_TINY_RENDERER, shadow=0,
                           flags=p.ER_NO_SEGMENTATION_MASK, **kw)
    return np.reshape(np.asarray(img[2], dtype=np.uint8), (H, W, 4))[:, :, :3].copy()


def write_video(path: Path, frames: list, period: float) -> None:
    """Write ``frames`` taken every ``period`` [s] of simulated time to ``path``."""
    import imageio.v3 as iio
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.suffix.lower() == ".gif":
        iio.imwrite(path, np.stack(frames), duration=1000 * period, loop=0)
    else:
        iio.imwrite(path, np.stack(frames), fps=1 / period, plugin="FFMPEG")
