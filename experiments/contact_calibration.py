"""Contact calibration: a physics Create 2 driven into a straight wall at incidences 0.5°–90°.

``--backend pybullet`` (default) calibrates the PyBullet body, ``--backend mujoco`` the MuJoCo
one (:class:`bouncesim.robots.mujoco.MuJoCoRobot`, the same ±80° bumper arc, built by another
engine); the PyBullet figures below are the ones stored in ``envs.motion.PYBULLET_CONTACT``.

A disk that meets a wall at incidence α (the angle between its heading and the wall) touches
it at a bearing of α − 90° from its heading. The PyBullet bumper reads contacts within ±80° of
the heading (:class:`bouncesim.robots.pybullet.PyBulletRobot`, ``bumper_arc_deg``), so below
about 10° the body slides along the wall instead of bumping. This experiment measures that
and fits the two numbers a contact rule needs (:class:`envs.motion.ContactParams`):

- ``beta_deg``: the incidence where the bump probability crosses 1/2 (linear interpolation of
  the bump rate between neighbouring incidences);
- ``slide_friction``: μ of the slide rule v_t = v · max(cos α − μ sin α, 0), the speed along
  the wall while sliding (least squares over the sliding trials; μ = 0 is a frictionless
  slide that keeps the along-wall component of the drive).

Each trial places the robot in a 6 m × 1.5 m room (longer for a ``--slide-budget`` above
4.5 m) facing the bottom wall at incidence α, its
body edge a random gap g ~ U(0.5, 5) mm from the wall (so the contact falls at a random phase
of the 15 ms bumper poll), drives at ``speed`` and polls every 15 ms: the first wall contact,
its bearing, then either a bump (the bumper closes) or a slide of ``slide_budget`` along the
wall without one. Recorded: bump, bearing, the slide length (along-wall travel from the first
contact to the bump or the end), the speed factor v_t / v and the heading change.

Outputs (under ``--out``, default results/contact_calibration/, or
results/contact_calibration_mujoco/ for MuJoCo): ``trials.csv`` (one row per
trial), ``fit.csv`` (bump rate and means per incidence), ``config.json`` (parameters, the
fitted ``beta_deg`` and ``slide_friction``, versions, git revision) and ``contact.png`` (bump
rate, slide length, heading change and speed factor against incidence, from the CSV alone).

``--quick``: 12 incidences, 2 trials each. ``--incidences A,B,...`` chooses them,
``--slide-budget M`` lets slides run M metres (PyBullet's slides from 9° bump only after
5.7 m), ``--wall south|east|north|west`` calibrates on another wall of a square room
(docs/model.md Appendix B: PyBullet's slides turn into walls at rates that depend on their
direction in the world).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import pandas as pd

import envs
from envs.motion import MUJOCO_CONTACT, PYBULLET_CONTACT
from experiments.common import experiment_parser, name_list, output_dir, write_config

__all__ = ["BACKENDS", "INCIDENCES", "QUICK_INCIDENCES", "WALLS", "Config", "OnWall",
           "draw_figure", "fit", "main", "make_body", "run",
           "trial", "wall_room"]

NAME = "contact_calibration"
INCIDENCES = (0.5, 1, 2, 3, 5, 7, 8, 9, 9.5, 9.75, 9.9, 10, 10.1, 10.25, 10.5, 11, 12, 15,
              20, 30, 45, 60, 75, 90)
QUICK_INCIDENCES = (0.5, 1, 3, 9, 9.75, 10.25, 11, 15, 30, 45, 60, 90)
BACKENDS = ("pybullet", "mujoco")
MUJOCO_SLIDES = ((1.0, 0.45), (3.0, 1.21), (10.0, 1.46))
"""(incidence [deg], slide [m]) of the separate MuJoCo check quoted in the issue."""


SI_ITERATIONS = 50
"""Iterations of PyBullet's sequential-impulse solver with ``--solver si`` (its default)."""


def wall_room(length: float = 6.0) -> envs.Environment:
    """An empty room ``length`` [m] × 1.5 m; the bottom wall (y = 0) is the calibration wall."""
    L = float(length)
    return envs.Environment.from_dict({"name": "wall", "boundary": [[0, 0], [L, 0], [L, 1.5],
                                                                    [0, 1.5]],
                                       "robot_radius": 0.17})


WALLS = {"south": 0.0, "east": 90.0, "north": 180.0, "west": 270.0}
"""The calibration wall, by the angle [deg] a square room is turned to bring the south wall
there: a slide runs counter-clockwise round the room, the wall on the body's right."""


class OnWall:
    """A body in a square room of side ``side`` [m], seen in the frame of one of its walls:
    that wall is y = 0 and the slide runs along +x, so :func:`trial` runs unchanged on every
    wall (the bumper and the contact bearings do not depend on the frame).
    """

    def __init__(self, bot, wall: str, side: float) -> None:
        self.bot, self.c = bot, float(side) / 2
        self.phi = WALLS[wall]
        a = math.radians(self.phi)
        self._cs = (math.cos(a), math.sin(a))

    def __getattr__(self, name):
        return getattr(self.bot, name)

    def __enter__(self):
        self.bot.__enter__()
        return self

    def __exit__(self, *exc):
        return self.bot.__exit__(*exc)

    def _turn(self, x: float, y: float, sign: float) -> tuple[float, float]:
        """(x, y) turned about the room centre by +φ (``sign`` 1) or −φ (−1)."""
        (co, si), c = self._cs, self.c
        dx, dy = x - c, y - c
        return c + co * dx - sign * si * dy, c + sign * si * dx + co * dy

    def place(self, x: float, y: float, heading_deg: float) -> None:
        """Place the body at the wall-frame pose (x [m], y [m], heading [deg])."""
        self.bot.place(*self._turn(x, y, 1.0), heading_deg + self.phi)

    def true_pose(self) -> tuple[float, float, float]:
        """The body's pose in the wall's frame (x [m], y [m], heading [deg] in [−180, 180))."""
        X, Y, H = self.bot.true_pose()
        return (*self._turn(X, Y, -1.0), (H - self.phi + 180.0) % 360.0 - 180.0)


def make_body(backend: str, bumper_arc_deg: float | None = None, slide_budget: float = 3.0,
              wall: str = "south", solver: str | None = None, cfm: float | None = None):
    """The calibrated body: a PyBullet or a MuJoCo Create 2 in a :func:`wall_room` long
    enough for a ``slide_budget`` [m] slide from x = 0.5 m, or for another ``wall`` than
    the south one, in a square room of that side seen from that wall (:class:`OnWall`).
    ``solver`` (PyBullet only): "dantzig" (its default) or "si", the sequential-impulse
    solver at PyBullet's default 50 iterations; ``cfm`` (PyBullet only): the world's
    constraint force mixing (None: the body's default; 0: Bullet's, whose Dantzig slides
    depend on the wall's direction).
    """
    side = max(6.0, slide_budget + 1.5)
    room = wall_room(side) if wall == "south" else envs.Environment.from_dict(
        {"name": "square", "boundary": [[0, 0], [side, 0], [side, side], [0, side]],
         "robot_radius": 0.17})
    arc = {} if bumper_arc_deg is None else {"bumper_arc_deg": float(bumper_arc_deg)}
    if backend == "mujoco":
        from bouncesim.robots.mujoco import MuJoCoRobot
        bot = MuJoCoRobot(room, **arc)
    else:
        from bouncesim.robots.pybullet import PyBulletRobot
        kw = {} if solver in (None, "dantzig") else {"solver": solver,
                                                     "solver_iterations": SI_ITERATIONS}
        if cfm is not None:
            kw["cfm"] = float(cfm)
        bot = PyBulletRobot(room, **arc, **kw)
    return bot if wall == "south" else OnWall(bot, wall, side)


def trial(bot, incidence: float, gap: float, speed: float,
          slide_budget: float) -> dict:
    """One approach of ``bot`` (a PyBullet or MuJoCo Create 2 with ``wall_contacts``) to the
    bottom wall at ``incidence`` [deg] from ``gap`` [m]; the record.
    """
    x0 = 0.5
    bot.place(x0, bot.body_radius + gap, -float(incidence))
    period = bot.spec.sensor_period
    approach = gap / math.sin(math.radians(incidence))
    limit = (approach + slide_budget) / speed + 2.0
    t0 = bot.clock()
    contact = None                    # (t, x, heading, bearing) at the first contact
    bumped = False
    bot.drive(speed)
    while bot.clock() - t0 < limit:
        bot.wait(period)
        x, _, yaw = bot.true_pose()
        if contact is None:
            cs = bot.wall_contacts()
            if cs:
                contact = (bot.clock(), x, yaw, float(np.mean([b for b, _ in cs])))
        if any(bot.bumper()):
            bumped = True
            break
        if contact is not None and x - contact[1] >= slide_budget:
            break
    bot.stop()
    x, _, yaw = bot.true_pose()
    row = {"incidence_deg": float(incidence), "gap_m": gap, "bump": int(bumped),
           "contact": int(contact is not None)}
    if contact is None:
        return {**row, "bearing_deg": math.nan, "slide_m": math.nan, "slide_s": math.nan,
                "speed_factor": math.nan, "heading_change_deg": math.nan}
    t_c, x_c, yaw_c, bearing = contact
    slide, dt = x - x_c, bot.clock() - t_c
    return {**row, "bearing_deg": bearing, "slide_m": slide, "slide_s": dt,
            "speed_factor": slide / (speed * dt) if dt > 0 else math.nan,
            "heading_change_deg": (yaw - yaw_c + 180.0) % 360.0 - 180.0}


def fit(trials: pd.DataFrame) -> dict:
    """β [deg] (bump rate crosses 1/2) and μ of the slide rule from the trials table."""
    rate = trials.groupby("incidence_deg")["bump"].mean().sort_index()
    a, r = rate.index.to_numpy(float), rate.to_numpy(float)
    beta = math.nan
    for i in range(len(a) - 1):
        if r[i] < 0.5 <= r[i + 1]:
            beta = float(a[i] + (0.5 - r[i]) * (a[i + 1] - a[i]) / (r[i + 1] - r[i]))
            break
    slides = trials[(trials.bump == 0) & (trials.contact == 1)]
    s = np.sin(np.radians(slides.incidence_deg.to_numpy(float)))
    c = np.cos(np.radians(slides.incidence_deg.to_numpy(float)))
    k = slides.speed_factor.to_numpy(float)
    mu = float(((c - k) * s).sum() / (s * s).sum()) if len(s) and (s * s).sum() > 0 else math.nan
    drift = (slides.heading_change_deg / slides.slide_m).to_numpy(float)
    return {"beta_deg": beta, "slide_friction": mu,
            "slide_heading_drift_deg_per_m": float(np.mean(drift)) if len(drift) else math.nan,
            "slide_speed_factor_rms_error": (float(np.sqrt(np.mean((k - (c - mu * s)) ** 2)))
                                             if len(k) else math.nan),
            "bumps_all_above_deg": float(a[r < 1].max()) if (r < 1).any() else math.nan,
            "no_bump_below_deg": float(a[r > 0].min()) if (r > 0).any() else math.nan,
            **fit_turn_in(trials)}


def fit_turn_in(trials: pd.DataFrame) -> dict:
    """The turn-in table of ``ContactParams.turn_in`` (docs/model.md §9): the incidences
    below the bumper arc where every trial slid, turned into the wall and then bumped, each
    with its mean slide [m]; ``turn_in_beta_deg`` the incidence they bumped at (the median
    of start + turn). Empty when no incidence does (PyBullet within its 3 m budget, but for
    a few near β whose 0.1°/m drift ends a slide).
    """
    g = trials[trials.contact == 1].groupby("incidence_deg")
    rows = [(float(a), float(t.slide_m.mean()), t) for a, t in g
            if (t.bump == 1).all() and (t.slide_m > 0).all()
            and (t.heading_change_deg < 0).all()]
    if not rows:
        return {"turn_in_beta_deg": math.nan, "turn_in": []}
    ends = np.concatenate([a - t.heading_change_deg.to_numpy(float) for a, _, t in rows])
    return {"turn_in_beta_deg": float(np.median(ends)),
            "turn_in": [[a, round(ell, 4)] for a, ell, _ in rows]}


def draw_figure(out: Path) -> Path:
    """contact.png from trials.csv and config.json alone."""
    import json

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from bouncesim.plots import save_figure

    out = Path(out)
    t = pd.read_csv(out / "trials.csv")
    cfg = json.loads((out / "config.json").read_text())
    beta, mu = cfg["fit"]["beta_deg"], cfg["fit"]["slide_friction"]
    g = t.groupby("incidence_deg")
    fig, ax = plt.subplots(2, 2, figsize=(11, 7.5))
    a = ax[0, 0]
    engine = {"pybullet": "PyBullet", "mujoco": "MuJoCo"}[cfg.get("backend", "pybullet")]
    a.plot(g.bump.mean().index, g.bump.mean(), "o-", label=f"{engine} bump rate")
    a.axvline(beta, color="C3", ls="--", label=f"fitted β = {beta:.2f}°")
    a.axvline(90 - cfg["bumper_arc_deg"], color="0.5", ls=":",
              label=f"geometry: 90° − arc = {90 - cfg['bumper_arc_deg']:g}°")
    a.set(xscale="log", xlabel="incidence α [deg]", ylabel="P(bump)",
          title="bump or slide (contact bearing α − 90°)")
    a.legend(fontsize=8)
    a = ax[0, 1]
    sl = t[t.contact == 1]
    for bump, m, lab in ((0, "o", "slide (no bump)"), (1, "x", "bump")):
        s = sl[sl.bump == bump]
        a.plot(s.incidence_deg, s.slide_m, m, ms=5, alpha=0.7, label=lab)
    mj = np.array(MUJOCO_SLIDES)
    a.plot(mj[:, 0], mj[:, 1], "s", color="k", mfc="none", label="MuJoCo check (issue)")
    a.axhline(cfg["slide_budget"], color="0.6", ls=":", label="slide budget (censored)")
    a.set(xscale="log", xlabel="incidence α [deg]", ylabel="along-wall travel after contact [m]",
          title="slide length")
    a.legend(fontsize=8)
    a = ax[1, 0]
    a.plot(sl.incidence_deg, sl.heading_change_deg, "o", ms=4)
    a.set(xscale="log", xlabel="incidence α [deg]", ylabel="heading change [deg]",
          title="heading change from first contact to bump / end")
    a = ax[1, 1]
    s = sl[sl.bump == 0]
    xs = np.linspace(0, max(15.0, float(s.incidence_deg.max()) if len(s) else 15.0), 100)
    a.plot(s.incidence_deg, s.speed_factor, "o", ms=5, label="measured v_t / v (slides)")
    a.plot(xs, np.cos(np.radians(xs)) - mu * np.sin(np.radians(xs)), "-",
           label=f"fit cos α − μ sin α, μ = {mu:.3f}")
    a.plot(xs, np.cos(np.radians(xs)), ":", color="0.5", label="frictionless: cos α")
    a.set(xlabel="incidence α [deg]", ylabel="speed factor", title="slide rule")
    a.legend(fontsize=8)
    fig.suptitle(f"{engine} Create 2 against a straight wall at {cfg['speed']} m/s "
                 f"({len(t)} trials)")
    fig.tight_layout()
    return save_figure(fig, out / "contact.png", dpi=100)


@dataclass(frozen=True)
class Config:
    """Parameters of one contact_calibration run (``config.json``).

    Attributes
    ----------
    incidences : tuple of float   incidences α [deg]
    repeats : int                 trials per incidence (random gaps)
    speed : float                 drive speed [m/s]
    slide_budget : float          along-wall travel [m] after which a slide ends unbumped
    bumper_arc_deg : float        the bumper arc [deg] (None: the body's own default)
    backend : str                 the physics engine: "pybullet" or "mujoco"
    wall : str                    the calibration wall (:data:`WALLS`; south: the long room)
    solver : str                  PyBullet's constraint solver: "dantzig" (the body's
                                  default) or "si" (:func:`make_body`)
    cfm : float or None           PyBullet's constraint force mixing (None: the body's
                                  default; 0: Bullet's own, :func:`make_body`)
    quick : bool
    seed : int
    out : Path
    """

    incidences: tuple = INCIDENCES
    repeats: int = 6
    speed: float = 0.3
    slide_budget: float = 3.0
    bumper_arc_deg: float | None = None
    backend: str = "pybullet"
    wall: str = "south"
    solver: str = "dantzig"
    cfm: float | None = None
    quick: bool = False
    seed: int = 0
    out: Path = Path("results") / NAME


def run(config: Config) -> Path:
    """Run every trial, fit, write the CSVs, config.json and the figure; the output folder."""
    out = output_dir(config.out)
    rng = np.random.default_rng(config.seed)
    rows = []
    with make_body(config.backend, config.bumper_arc_deg, config.slide_budget,
                   config.wall, config.solver, config.cfm) as bot:
        arc = float(bot.bumper_arc_deg)
        for inc in config.incidences:
            for rep in range(config.repeats):
                gap = float(rng.uniform(0.0005, 0.005))
                rows.append({"repeat": rep, **trial(bot, inc, gap, config.speed,
                                                    config.slide_budget)})
    trials = pd.DataFrame(rows)
    trials.to_csv(out / "trials.csv", index=False, float_format="%.6g")
    summary = trials.groupby("incidence_deg").agg(
        bump_rate=("bump", "mean"), bearing_deg=("bearing_deg", "mean"),
        slide_m=("slide_m", "mean"), speed_factor=("speed_factor", "mean"),
        heading_change_deg=("heading_change_deg", "mean")).reset_index()
    summary.to_csv(out / "fit.csv", index=False, float_format="%.6g")
    result = fit(trials)
    cfg = asdict(config)
    cfg.update(experiment=NAME, out=str(config.out), fit=result, bumper_arc_deg=arc,
               defaults_in_code=asdict({"pybullet": PYBULLET_CONTACT,
                                        "mujoco": MUJOCO_CONTACT}[config.backend]),
               create2_facts="one spring-loaded front bumper over the front half (±90°), "
               "read by two switches at 11 and 1 o'clock; trip angle not published")
    write_config(out, cfg)
    draw_figure(out)
    with pd.option_context("display.width", 140):
        print(summary.to_string(index=False, float_format=lambda v: f"{v:.3f}"))
    print("fit:", {k: v if isinstance(v, list) else round(v, 4) for k, v in result.items()})
    print(f"wrote {out}")
    return out


def main(argv=None) -> int:
    """Parse the command line into a :class:`Config` and :func:`run` it (exit status)."""
    p = experiment_parser(NAME, __doc__.split("\n\n")[0])
    p.add_argument("--repeats", type=int, default=None, help="trials per incidence (default 6; "
                   "quick 2)")
    p.add_argument("--speed", type=float, default=0.3, help="drive speed [m/s] (default 0.3)")
    p.add_argument("--backend", choices=BACKENDS, default="pybullet",
                   help="the physics engine of the body (default pybullet)")
    p.add_argument("--slide-budget", type=float, default=3.0, metavar="M",
                   help="along-wall travel [m] after which a slide ends unbumped; the room "
                   "is made long enough (default 3)")
    p.add_argument("--wall", choices=tuple(WALLS), default="south",
                   help="the calibration wall: south (default) in a 1.5 m wide room; the "
                   "others in a square room, the slide counter-clockwise round it (an engine "
                   "whose slides depend on their direction in the world shows it here)")
    p.add_argument("--solver", choices=("dantzig", "si"), default="dantzig",
                   help="PyBullet's constraint solver: dantzig (the body's default) or si "
                   f"(sequential impulse, {SI_ITERATIONS} iterations: slides that do not "
                   "depend on their direction in the world, docs/model.md Appendix B)")
    p.add_argument("--cfm", type=float, default=None, metavar="C",
                   help="PyBullet's constraint force mixing (default: the body's, 1e-7; 0 is "
                   "Bullet's own, whose Dantzig slides turn into walls along y faster than "
                   "into walls along x, docs/model.md Appendix B)")
    p.add_argument("--incidences", type=name_list, default=None, metavar="A,B,...",
                   help="incidences [deg] to try (default: 24 from 0.5 to 90, quick 12)")
    args = p.parse_args(argv)
    try:
        incs = tuple(float(a) for a in args.incidences) if args.incidences else None
    except ValueError:
        p.error(f"--incidences needs numbers in degrees, got {','.join(args.incidences)!r}")
    if incs is not None and not all(0 < a <= 90 for a in incs):
        p.error("--incidences must lie in (0, 90] degrees.")
    if not args.slide_budget > 0:
        p.error(f"--slide-budget must be positive, got {args.slide_budget}")
    if args.solver != "dantzig" and args.backend != "pybullet":
        p.error("--solver chooses PyBullet's constraint solver: give --backend pybullet.")
    if args.cfm is not None and (args.backend != "pybullet" or not args.cfm >= 0):
        p.error("--cfm is PyBullet's constraint force mixing, a number >= 0: give --backend "
                "pybullet.")
    q = args.quick
    if args.backend != "pybullet" and args.out == Path("results") / NAME:
        args.out = Path("results") / f"{NAME}_{args.backend}"
    config = Config(incidences=incs or (QUICK_INCIDENCES if q else INCIDENCES),
                    repeats=args.repeats or (2 if q else 6), speed=args.speed,
                    slide_budget=args.slide_budget, wall=args.wall, solver=args.solver,
                    cfm=args.cfm, backend=args.backend, quick=q,
                    seed=args.seed, out=args.out)
    run(config)
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
