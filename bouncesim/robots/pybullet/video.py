"""Top-down video of a PyBullet world: frames from PyBullet's tiny renderer with an overlay
(the path so far, the goal, the clock and the plan segment), written by imageio (``.gif``, or
``.mp4`` and other containers with imageio-ffmpeg).

A :class:`Recorder` keeps every frame with its time [s] and the robot's pose; the overlay is
drawn when the video is written, so the run's plan and goal (known to the caller, not to the
robot) can be added afterwards with :meth:`Recorder.annotate_plan`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from envs import UserError

__all__ = ["Camera", "Recorder", "check_record_format", "gif_frames", "plan_segments",
           "render_top_down", "write_video"]

_MARGIN = 0.15           # [m] around the room's bounding box
_FOV = 20.0              # [deg] vertical field of view
_GOAL_RGB, _PATH_RGB, _TEXT_RGB, _PAPER_RGB = (44, 160, 44), (255, 127, 14), (0, 0, 0), \
    (255, 255, 255)      # the overlay's colours: kept exactly in a GIF's palette


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


@dataclass(frozen=True)
class Camera:
    """The top-down pinhole camera over ``bounds`` (x0, y0, x1, y1) [m]: image ``width`` x
    ``height`` [px], at ``dist`` [m] above the floor, centred on (cx, cy) [m].
    """

    width: int
    height: int
    dist: float
    cx: float
    cy: float

    @classmethod
    def over(cls, bounds, width: int, wall_height: float) -> Camera:
        """The camera that frames ``bounds`` with a 0.15 m margin, ``width`` pixels wide."""
        x0, y0, x1, y1 = bounds
        w, h = (x1 - x0) + 2 * _MARGIN, (y1 - y0) + 2 * _MARGIN
        H = max(16, int(round(width * h / w)) // 2 * 2)
        dist = (h / 2) / math.tan(math.radians(_FOV / 2)) + wall_height
        return cls(int(width), H, dist, (x0 + x1) / 2, (y0 + y1) / 2)

    @property
    def pixels_per_metre(self) -> float:
        """Scale on the floor (z = 0) [px/m]."""
        return self.height / (2 * self.dist * math.tan(math.radians(_FOV / 2)))

    def to_pixels(self, x, y) -> tuple[np.ndarray, np.ndarray]:
        """Floor point(s) (x [m], y [m]) to image (column, row) [px], row 0 at the top."""
        s = self.pixels_per_metre
        return (self.width / 2 + (np.asarray(x) - self.cx) * s,
                self.height / 2 - (np.asarray(y) - self.cy) * s)


def render_top_down(p, kw: dict, bounds, width: int, wall_height: float) -> np.ndarray:
    """One RGB uint8 frame, ``width`` pixels wide, looking straight down on ``bounds``
    (x0, y0, x1, y1) [m] with a 0.15 m margin; ``p`` is the pybullet module and ``kw`` the
    client's keyword arguments.
    """
    cam = Camera.over(bounds, width, wall_height)
    W, H = cam.width, cam.height
    view = p.computeViewMatrix([cam.cx, cam.cy, cam.dist], [cam.cx, cam.cy, 0], [0, 1, 0])
    proj = p.computeProjectionMatrixFOV(_FOV, W / H, cam.dist / 4, cam.dist * 2)
    img = p.getCameraImage(W, H, view, proj, renderer=p.ER_TINY_RENDERER, shadow=0,
                           flags=p.ER_NO_SEGMENTATION_MASK, **kw)
    return np.reshape(np.asarray(img[2], dtype=np.uint8), (H, W, 4))[:, :, :3].copy()


def plan_segments(plan, trace) -> list[tuple[float, str]]:
    """(start time [s] on the trace's clock, label) of each plan segment that ran: segment
    i + 1 starts at the i-th ``turn`` of the trace (docs/model.md §21: drive the zeros, bump,
    turn by the angle).
    """
    segs = plan.segments()
    n = len(segs)
    turns = [r.t for r in trace if r.event == "turn"]
    starts = [0.0] + turns
    out = []
    for i, (zeros, angle) in enumerate(segs[:len(starts)]):
        label = ("0" * zeros + (f" {angle:g}°" if angle is not None else "")).strip()
        out.append((starts[i], f"segment {i + 1}/{n}: {label}"))
    return out


class Recorder:
    """Frames of a run with their time [s] and the robot's pose, written with an overlay.

    Parameters
    ----------
    path : Path
        ``.gif`` (or ``.mp4`` etc. with imageio-ffmpeg).
    period : float
        Simulated time between frames [s].
    width : int
        Frame width [px]; a caption strip (clock, plan segment) is added below the map.
    bounds : (x0, y0, x1, y1)
        The room's bounding box [m].
    wall_height : float
        [m], for the camera distance.
    """

    def __init__(self, path: Path, period: float, width: int, bounds, wall_height: float):
        self.path = Path(path)
        self.period = float(period)
        self.camera = Camera.over(bounds, width, wall_height)
        self._bounds, self._wall_height = bounds, wall_height
        self.frames: list[np.ndarray] = []
        self.times: list[float] = []
        self.poses: list[tuple[float, float, float]] = []
        self.title = ""
        self.goal: tuple | None = None
        self.segments: list[tuple[float, str]] = []
        self.t0 = 0.0

    def capture(self, p, kw: dict, t: float, pose) -> None:
        """Render and keep one frame at time ``t`` [s] with the robot at ``pose``."""
        self.frames.append(render_top_down(p, kw, self._bounds, self.camera.width,
                                           self._wall_height))
        self.times.append(float(t))
        self.poses.append(tuple(float(v) for v in pose))

    def annotate_plan(self, plan, trace, goal=None, t0: float = 0.0, title: str = "") -> None:
        """Add a plan's segments (timed from ``trace``, whose t = 0 is the recorder's ``t0``
        [s]), the goal pose (x [m], y [m], heading [deg]) and a title to the overlay.
        """
        self.t0 = float(t0)
        self.segments = [(t0 + t, label) for t, label in plan_segments(plan, trace)]
        self.goal = tuple(goal) if goal is not None else None
        self.title = str(title)

    def caption(self, i: int) -> str:
        """The overlay text of frame ``i``: the run's clock [s], then the plan segment (if
        annotated).
        """
        t = self.times[i]
        text = f"t = {t - self.t0:.1f} s"
        current = [label for start, label in self.segments if start <= t + 1e-9]
        if current:
            text += "   " + current[-1]
        return text

    def overlaid(self, i: int) -> np.ndarray:
        """Frame ``i`` with the overlay: path so far, goal, and a caption strip below."""
        from PIL import Image, ImageDraw
        cam = self.camera
        W, H = cam.width, cam.height
        size = max(8, W // 36)
        font = _font(size)
        lines = [s for s in (self.title, self.caption(i)) if s]
        strip = int(len(lines) * size * 1.35 + size * 0.6) // 2 * 2 + 2   # even: for mp4
        img = Image.new("RGB", (W, H + strip), _PAPER_RGB)
        img.paste(Image.fromarray(self.frames[i]), (0, 0))
        draw = ImageDraw.Draw(img)
        lw = max(1, W // 240)
        if self.goal is not None:
            gx, gy = (float(v) for v in cam.to_pixels(self.goal[0], self.goal[1]))
            r = max(3, W // 50)
            draw.ellipse([gx - r, gy - r, gx + r, gy + r], outline=_GOAL_RGB, width=lw + 1)
            if len(self.goal) > 2:
                a = math.radians(self.goal[2])
                draw.line([gx, gy, gx + 2.5 * r * math.cos(a), gy - 2.5 * r * math.sin(a)],
                          fill=_GOAL_RGB, width=lw + 1)
        xs, ys = cam.to_pixels([q[0] for q in self.poses[:i + 1]],
                               [q[1] for q in self.poses[:i + 1]])
        if i > 0:
            draw.line(list(zip(xs.tolist(), ys.tolist())), fill=_PATH_RGB, width=lw)
        y = H + int(size * 0.3)
        for s in lines:
            draw.text((int(size * 0.5), y), s, fill=_TEXT_RGB, font=font)
            y += int(size * 1.35)
        return np.asarray(img)

    def write(self) -> Path | None:
        """Write the video with the overlay (nothing when no frame was taken)."""
        if not self.frames:
            return None
        write_video(self.path, [self.overlaid(i) for i in range(len(self.frames))],
                    self.period)
        return self.path


def _font(size: int):
    from PIL import ImageFont
    try:
        from matplotlib import font_manager
        return ImageFont.truetype(font_manager.findfont("DejaVu Sans"), size)
    except (ImportError, OSError, ValueError):
        return ImageFont.load_default(size=size)


def write_video(path: Path, frames: list, period: float) -> None:
    """Write ``frames`` taken every ``period`` [s] of simulated time to ``path``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.suffix.lower() == ".gif":
        first, *rest = gif_frames(frames)
        first.save(path, save_all=True, append_images=rest, duration=round(1000 * period),
                   loop=0)
    else:
        import imageio.v3 as iio
        iio.imwrite(path, np.stack(frames), fps=1 / period, plugin="FFMPEG")


def gif_frames(frames: list) -> list:
    """RGB frames as palette images for a GIF: one palette for every frame (a
    maximum-coverage cut of the first, middle and last frames' colours, plus the overlay's
    colours exactly), each pixel mapped to its nearest palette colour without dithering
    (dithering scatters dots over flat areas such as the floor, changing from frame to frame).
    """
    from PIL import Image
    frames = [np.asarray(f, dtype=np.uint8) for f in frames]
    sample = np.concatenate([frames[0], frames[len(frames) // 2], frames[-1]], axis=0)
    exact = [_GOAL_RGB, _PATH_RGB, _TEXT_RGB, _PAPER_RGB]
    cut = Image.fromarray(sample).quantize(256 - len(exact), method=Image.Quantize.MAXCOVERAGE)
    colours = cut.getpalette()[:3 * (256 - len(exact))]
    palette = Image.new("P", (1, 1))
    palette.putpalette(colours + [c for rgb in exact for c in rgb])
    return [Image.fromarray(f).quantize(palette=palette, dither=Image.Dither.NONE)
            for f in frames]

