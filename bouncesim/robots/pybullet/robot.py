"""The PyBullet Create 2: a wheeled rigid body in a walled world built from an environment.

:class:`PyBulletRobot` implements the :class:`~bouncesim.robots.base.Robot` interface with a
physics simulation: a 0.17 m disk body on two driven wheels (velocity-controlled revolute
joints with friction against the floor), a frictionless front caster and rear skid, walls
extruded from the environment's polygons, a bumper read from the contact points on the front
half of the body, wheel encoders read from the wheel joint angles and a simulated clock.

Each robot owns its own PyBullet client (``DIRECT`` by default, never the global default
client), so several robots/worlds coexist in one process. PyBullet in ``DIRECT`` mode is
deterministic; the only randomness is the rotation noise, drawn from the robot's seeded
``rng``: the same seed gives the same trajectory.

Geometry (world frame of docs/model.md §1: x east, y north, headings CCW from east): the
boundary and the obstacles are extruded from the convex pieces of
:mod:`bouncesim.robots.wall_pieces`; walls are 0.2 m high, the robot body 0.09 m.
"""

from __future__ import annotations

import contextlib
import math
import os
import sys
import time as _time
from dataclasses import replace
from pathlib import Path

import numpy as np
import shapely
from shapely.geometry import Polygon
from shapely.geometry.polygon import orient

from envs import Environment, UserError
from envs.motion import PYBULLET_CONTACT

from ..base import CREATE2, Robot, RobotSpec
from ..noise import NoiseModel, noise_and_rng
from ..stepped import SETTLE_STEPS, SteppedWheels
from ..wall_pieces import WALL_THICKNESS, convex_pieces, wall_pieces
from .bumper import CONTACT_TOLERANCE, normal_bearing, read_bumper
from .video import Recorder, check_record_format

__all__ = ["PyBulletRobot", "DEFAULT_SPEED", "DEFAULT_TURN_SPEED", "DEFAULT_TIME_STEP",
           "import_pybullet", "DEFAULT_CFM"]

DEFAULT_SPEED = 0.2
"""Default forward speed [m/s]: 3 mm of travel per 15 ms bumper poll, so a bump is caught
and the robot stopped within a few millimetres of first contact (well inside 1 cm)."""

DEFAULT_TURN_SPEED = 0.1
"""Default wheel speed while turning in place [m/s] (ω = 2 v / 0.235 m ≈ 48.8 °/s)."""

DEFAULT_TIME_STEP = 1 / 200
"""Physics step [s]: 5 ms, so the 15 ms sensor period is exactly 3 steps."""

DEFAULT_CFM = 1e-7
"""Bullet's global constraint force mixing of the body's world (``PyBulletRobot(cfm=)``): a
regularisation of the contact problem that makes a glancing slide's solution unique, the
same on every wall (Bullet's default 0 made it depend on the wall's direction in the world;
docs/model.md Appendix B)."""

_WALL_HEIGHT = 0.2          # [m]
_BODY_HEIGHT = 0.09         # [m]
_BODY_CLEARANCE = 0.01      # floor to the underside of the body [m]
_WHEEL_MASS = 0.1           # each [kg]
_CASTER_RADIUS = 0.01       # [m]
_CASTER_OFFSET = 0.13       # caster/skid distance ahead of / behind the axle [m]
_CASTER_GAP = 0.001         # casters hang this far above the floor at rest [m]
_MESH_MARGIN = 1e-4         # collision margin of the wall prisms [m]


# ---------------------------------------------------------------------------- the robot
@contextlib.contextmanager
def _quiet_stdout():
    """Silence C-level writes to the process's stdout (file descriptor 1) meanwhile."""
    try:
        sys.stdout.flush()
        saved = os.dup(1)
    except (AttributeError, OSError, ValueError):
        yield
        return
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 1)
        yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)


def import_pybullet():
    """The pybullet module; one sentence naming the extra to install when it is missing."""
    try:
        import pybullet
    except ImportError:
        raise UserError("the PyBullet world needs pybullet: pip install 'bouncesim[sim]'.") \
            from None
    return pybullet


class PyBulletRobot(SteppedWheels, Robot):
    """An iRobot Create 2 in a PyBullet world built from an environment.

    Parameters
    ----------
    env : Environment or str
        The environment (or a catalogue name / env file path).
    noise : NoiseModel, optional
        Rotation noise: anything with ``sample(rng, commanded_deg) -> actual_deg`` (the models
        of :mod:`bouncesim.robots.noise`). None: turns are commanded exactly.
    rng : numpy.random.Generator or int, optional
        Random source for the noise (an int is a seed). Required when the noise is not exact
        (:func:`bouncesim.robots.noise.noise_and_rng`, the contract of every simulated body).
    gui : bool
        Open the PyBullet GUI (needs a display) and pace the simulation to real time.
    record : str or Path, optional
        Write a top-down video of the run at :meth:`close` (``.gif``; ``.mp4`` needs
        imageio-ffmpeg). Frames every ``record_period`` [s] of simulated time.
    turn : {"clock", "encoders"}
        Turn by clock (wheels at ±turn_speed for φ / ω, ω = 2 v / wheel_base) or by the
        simulated wheel encoders (turn until the encoder heading change reaches φ).
    back_off : float
        Drive back this far [m] before each turn (the Create 2 advice is about 0.01 m, so the
        bumper does not drag on the wall). Default 0.
    time_step : float
        Physics step [s]. Waits are rounded to whole steps; 1/200 s makes the 15 ms sensor
        period exactly 3 steps.
    turn_speed : float
        Wheel speed while turning [m/s].
    solver : {"dantzig", "si"}
        Constraint solver. "dantzig" (default): Bullet's exact MLCP solver for the small
        contact problem of one robot; a robot pushing along a wall keeps its heading and turns
        come out within ~0.2°, but how fast a glancing slide turns into the wall depends on
        the wall's direction in the world (docs/model.md Appendix B). "si": PyBullet's
        default sequential-impulse solver (with 10 iterations it turns a robot that scrapes a
        wall on its left into that wall, a few degrees per second; with 50 its slides turn in
        and bump at about 10.4°, alike on every wall and either side).
    solver_iterations : int
        Iterations of the sequential-impulse solver (PyBullet's default is 50), also used by
        the Dantzig solver's fallback.
    wheel_torque : float
        Maximum wheel motor torque [N m] of the velocity controllers.
    bumper_arc_deg : float
        Contacts within ± this angle of the heading close the bumper. The Create 2's bumper
        spans the front half (±90°); the default 79.5° leaves out contacts with a wall the
        robot runs parallel to (after a 90° turn at a wall), which do not press a real bumper,
        and puts the incidence below which a wall is slid along (90° − arc = 10.5°) half-way
        between whole degrees: with 80° the headings of a 1° grid met walls at exactly the
        threshold, where a quarter-degree turn error decided (docs/model.md Appendix B).
    spec : RobotSpec, optional
        Body and drive figures (default the Create 2 with the environment's robot radius).
    record_period : float
        Simulated time between video frames [s].
    record_width : int
        Video frame width [px]; the height follows the environment's aspect ratio.
    clearance : float
        The collision body is this much [m] smaller in radius than ``spec.radius``. The cell
        model lets the disk pass walls and corners at exactly zero distance (cell centres
        next to a wall are exactly r from it); in a physics engine exact tangency is fragile
        (a 0.1 mm drift turns a passing corner into a glancing collision), so the body keeps
        a 2 mm margin by default.
    contact_threshold : float, optional
        Speed setting [m]: Bullet's contact breaking threshold (default 0.02 m) and no
        speculative contacts in the solver (robot links' contact processing threshold 0).
        None (default) keeps Bullet's defaults. :class:`.batch.PyBulletBatch` uses 0.002.
    cfm : float
        Bullet's global constraint force mixing (``globalCFM``): cfm / time step is added to
        the diagonal of the contact problem, a regularisation far below anything the body
        feels (1e-7 / 5 ms = 2e-5 against the 0.2–0.5 of a 4 kg body's inverse mass). With
        Bullet's default 0, the Dantzig solver's problem of a body that
        pushes along a frictionless wall is degenerate, and the solution it picks turned the
        body into walls along y 3–10 times faster than into walls along x (docs/model.md
        Appendix B); with any cfm from 1e-9 to 1e-4 every wall gives the same slide, the
        heading kept. Turns, bump gaps and speed do not change (``bench_pybullet``).
    start : (x, y, heading_deg), optional
        Initial pose; default the centre of the first free cell (p = 0) facing east.

    Notes
    -----
    Encoders are cumulative signed counts (508.8 per wheel revolution, truncated toward zero)
    without the Create 2's 16-bit wrap-around, which a simulated run never needs.
    Wheel speeds are not quantised to the Create 2's 28.5 mm/s steps.

    Examples
    --------
    >>> with PyBulletRobot("lab") as bot:                            # doctest: +SKIP
    ...     bot.place(0.17, 0.17, 0.0)
    ...     ev = bot.drive_until_bump(0.2, timeout=30.0)
    ...     bot.turn(90)
    """

    contact = PYBULLET_CONTACT
    """The contact rule this body follows (docs/model.md §9: the one fitted to it)."""


    def __init__(self, env: Environment | str, noise: NoiseModel | None = None,
                 rng: np.random.Generator | int | None = None, *,
                 gui: bool = False, record: str | Path | None = None,
                 turn: str = "clock", back_off: float = 0.0,
                 time_step: float = DEFAULT_TIME_STEP,
                 turn_speed: float = DEFAULT_TURN_SPEED, solver: str = "dantzig",
                 solver_iterations: int = 10,
                 wheel_torque: float = 2.0, bumper_arc_deg: float = 79.5,
                 spec: RobotSpec | None = None, record_period: float = 0.1,
                 record_width: int = 640, clearance: float = 0.002,
                 contact_threshold: float | None = None, cfm: float = DEFAULT_CFM,
                 start: tuple[float, float, float] | None = None) -> None:
        self._cid = None
        if isinstance(env, (str, Path)):
            import envs
            env = envs.load(env)
        self.env = env
        spec = spec if spec is not None else replace(CREATE2, radius=env.robot_radius)
        self.spec = spec
        if solver not in ("dantzig", "si"):
            raise UserError(f"solver must be 'dantzig' or 'si', got {solver!r}.")
        self.solver = solver
        if turn not in ("clock", "encoders"):
            raise UserError(f"turn must be 'clock' or 'encoders', got {turn!r}.")
        if not (time_step > 0 and math.isfinite(time_step)):
            raise UserError(f"time_step must be a positive number of seconds, got {time_step}.")
        if not 0 < turn_speed <= spec.max_wheel_speed:
            raise UserError(f"turn_speed must be in (0, {spec.max_wheel_speed}] m/s, "
                            f"got {turn_speed}.")
        if not 0 <= back_off < env.cell_size:
            raise UserError(f"back_off must be between 0 and one cell ({env.cell_size} m), "
                            f"got {back_off}.")
        self.noise, self.rng = noise_and_rng(noise, rng)
        self.turn_mode = turn
        self.back_off = float(back_off)
        self.time_step = float(time_step)
        self.turn_speed = float(turn_speed)
        self.wheel_torque = float(wheel_torque)
        self.bumper_arc_deg = float(bumper_arc_deg)
        self.gui = bool(gui)
        if not 0 <= clearance < spec.radius / 2:
            raise UserError(f"clearance must be in [0, {spec.radius / 2}) m, got {clearance}.")
        self.body_radius = spec.radius - float(clearance)
        self.contact_threshold = None if contact_threshold is None else float(contact_threshold)
        if not (math.isfinite(cfm) and cfm >= 0):
            raise UserError(f"cfm must be a non-negative number, got {cfm}.")
        self.cfm = float(cfm)
        self._record = Path(record) if record is not None else None
        self._record_every = max(1, round(record_period / self.time_step))
        self.recorder: Recorder | None = None
        if self._record is not None:
            check_record_format(self._record)
            self.recorder = Recorder(self._record, self._record_every * self.time_step,
                                     int(record_width), self.env.bounds, _WALL_HEIGHT)

        p = self._p = import_pybullet()
        if self.gui:
            # Without a display PyBullet's GUI ends the whole process: check first.
            if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY")
                                                         or os.environ.get("WAYLAND_DISPLAY")):
                raise UserError("the PyBullet GUI needs a display (DISPLAY is not set): "
                                "run without the GUI (no --gui; gui=False in Python), or "
                                "record a video instead (--record; record=).")
            cid = p.connect(p.GUI)
            if cid < 0:
                raise UserError("cannot open the PyBullet GUI (only one per process, and it "
                                "needs a display): drop --gui (gui=False in Python).")
        else:
            cid = p.connect(p.DIRECT)
        self._cid = cid
        self._kw = {"physicsClientId": cid}
        self._closed = False
        self._steps = 0
        self._t_goal = 0.0
        self._wall_t0 = _time.perf_counter()
        self._speeds = (0.0, 0.0)
        self._wheel_r = spec.wheel_diameter / 2
        self._visual = self.gui or self._record is not None
        try:
            self._build(solver_iterations)
            if start is None:
                start = self._default_start()
            self.place(*start)
        except BaseException:
            self._disconnect()
            raise

    # ------------------------------------------------------------------ construction
    def _default_start(self) -> tuple[float, float, float]:
        grid = self.env.grid_centres_free()
        j, i = np.argwhere(grid)[0]
        x0, y0 = self.env.origin
        h = self.env.cell_size
        return x0 + (i + 0.5) * h, y0 + (j + 0.5) * h, 0.0

    def _build(self, solver_iterations: int) -> None:
        p, kw = self._p, self._kw
        p.resetSimulation(**kw)
        p.setGravity(0, 0, -9.81, **kw)
        p.setPhysicsEngineParameter(fixedTimeStep=self.time_step,
                                    numSolverIterations=int(solver_iterations),
                                    deterministicOverlappingPairs=1, globalCFM=self.cfm,
                                    **kw)
        if self.contact_threshold is not None:
            p.setPhysicsEngineParameter(contactBreakingThreshold=self.contact_threshold, **kw)
        if self.solver == "dantzig":
            with _quiet_stdout():   # Bullet announces the switch on stdout
                p.setPhysicsEngineParameter(
                    constraintSolverType=p.CONSTRAINT_SOLVER_LCP_DANTZIG, **kw)
        if self.gui:
            p.configureDebugVisualizer(p.COV_ENABLE_GUI, 0, **kw)
        # floor (drawn: a slab whose top is 1 mm above the plane; coplanar faces speckle)
        plane = p.createCollisionShape(p.GEOM_PLANE, **kw)
        self._floor = p.createMultiBody(0, plane, **kw)
        p.changeDynamics(self._floor, -1, lateralFriction=1.0, **kw)
        x0, y0, x1, y1 = self.env.bounds
        if self._visual:
            m = WALL_THICKNESS
            vis = p.createVisualShape(p.GEOM_BOX, halfExtents=[(x1 - x0) / 2 + m,
                                                               (y1 - y0) / 2 + m, 0.0005],
                                      rgbaColor=[0.93, 0.93, 0.88, 1], **kw)
            p.createMultiBody(0, -1, vis, basePosition=[(x0 + x1) / 2, (y0 + y1) / 2, 0.0005],
                              **kw)
        # walls: the boundary slabs and the obstacles' convex pieces, extruded
        self._walls: list[int] = []
        self._wall_slabs = wall_pieces(self.env.boundary, WALL_THICKNESS)
        for slab in self._wall_slabs:
            self._add_prism(slab, [0.35, 0.35, 0.38, 1])
        self._pieces = [pc for ob in self.env.obstacles for pc in convex_pieces(ob)]
        for pc in self._pieces:
            self._add_prism(pc, [0.62, 0.40, 0.22, 1])
        self._wall_set = frozenset(self._walls)
        for w in self._walls:
            p.changeDynamics(w, -1, lateralFriction=0.0, **kw)
        self._build_robot()

    def _add_prism(self, piece: Polygon, rgba) -> None:
        """A static body: the convex polygon extruded from the floor to the wall height."""
        p, kw = self._p, self._kw
        ring = np.asarray(orient(piece, 1.0).exterior.coords)[:-1]
        cx, cy = ring.mean(axis=0)
        local = ring - [cx, cy]
        verts = [[float(x), float(y), z] for z in (0.0, _WALL_HEIGHT) for x, y in local]
        col = p.createCollisionShape(p.GEOM_MESH, vertices=verts, **kw)
        vis = -1
        if self._visual:
            k = len(local)
            idx = []
            for i in range(1, k - 1):                      # bottom and top fans
                idx += [0, i + 1, i, k, k + i, k + i + 1]
            for i in range(k):                             # sides
                j = (i + 1) % k
                idx += [i, j, k + j, i, k + j, k + i]
            vis = p.createVisualShape(p.GEOM_MESH, vertices=verts, indices=idx,
                                      rgbaColor=rgba, **kw)
        body = p.createMultiBody(0, col, vis, basePosition=[cx, cy, 0.0], **kw)
        # A convex hull is padded by its collision margin (about 1 mm by default), which
        # would stop the robot that far short of the wall: keep 0.1 mm.
        p.changeDynamics(body, -1, collisionMargin=_MESH_MARGIN, **kw)
        self._walls.append(body)

    def _build_robot(self) -> None:
        self._robot = self._create_body()
        self._set_wheels(0.0, 0.0)

    def _create_body(self) -> int:
        """Add one Create 2 body (disk, casters, two wheel joints) to the world; its id."""
        p, kw, s = self._p, self._kw, self.spec
        R = self._wheel_r
        # The base frame sits at axle height on the axle midpoint = the disk centre.
        body_z = _BODY_CLEARANCE + _BODY_HEIGHT / 2 - R
        caster_z = _CASTER_RADIUS + _CASTER_GAP - R
        body = p.createCollisionShapeArray(
            [p.GEOM_CYLINDER, p.GEOM_SPHERE, p.GEOM_SPHERE],
            radii=[self.body_radius, _CASTER_RADIUS, _CASTER_RADIUS], lengths=[_BODY_HEIGHT, 0, 0],
            collisionFramePositions=[[0, 0, body_z], [_CASTER_OFFSET, 0, caster_z],
                                     [-_CASTER_OFFSET, 0, caster_z]], **kw)
        wheel = p.createCollisionShape(p.GEOM_SPHERE, radius=R, **kw)
        vis = -1
        if self._visual:
            vis = p.createVisualShapeArray(
                [p.GEOM_CYLINDER, p.GEOM_BOX], radii=[self.body_radius, 0],
                lengths=[_BODY_HEIGHT, 0],
                halfExtents=[[0, 0, 0], [0.035, 0.025, 0.005]],
                rgbaColors=[[0.25, 0.45, 0.85, 1], [1.0, 0.85, 0.1, 1]],
                visualFramePositions=[[0, 0, body_z],
                                      [s.radius - 0.05, 0, body_z + _BODY_HEIGHT / 2 + 0.006]],
                **kw)
        base_mass = s.mass - 2 * _WHEEL_MASS
        half_base = s.wheel_base / 2
        robot = p.createMultiBody(
            base_mass, body, vis, basePosition=[0, 0, R],
            linkMasses=[_WHEEL_MASS, _WHEEL_MASS], linkCollisionShapeIndices=[wheel, wheel],
            linkVisualShapeIndices=[-1, -1],
            linkPositions=[[0, half_base, 0], [0, -half_base, 0]],   # left (+y), right
            linkOrientations=[[0, 0, 0, 1]] * 2, linkInertialFramePositions=[[0, 0, 0]] * 2,
            linkInertialFrameOrientations=[[0, 0, 0, 1]] * 2, linkParentIndices=[0, 0],
            linkJointTypes=[p.JOINT_REVOLUTE] * 2, linkJointAxis=[[0, 1, 0]] * 2, **kw)
        # Centre of mass over the axle: all weight on the drive wheels, casters nearly idle.
        ixx = base_mass * (3 * self.body_radius ** 2 + _BODY_HEIGHT ** 2) / 12
        izz = base_mass * self.body_radius ** 2 / 2
        p.changeDynamics(robot, -1, lateralFriction=0.0, rollingFriction=0.0,
                         spinningFriction=0.0, localInertiaDiagonal=[ixx, ixx, izz], **kw)
        for j in (0, 1):
            # (no damping arguments here: PyBullet applies those, and with them this
            # call's friction, to the base)
            p.changeDynamics(robot, j, lateralFriction=1.0, rollingFriction=0.0,
                             spinningFriction=0.0, **kw)
        if self.contact_threshold is not None:
            for j in (-1, 0, 1):
                p.changeDynamics(robot, j, contactProcessingThreshold=0.0, **kw)
        return robot

    # ------------------------------------------------------------------ internals
    def _set_wheels(self, v_left: float, v_right: float) -> None:
        R = self._wheel_r
        self._p.setJointMotorControlArray(
            self._robot, [0, 1], self._p.VELOCITY_CONTROL,
            targetVelocities=[v_left / R, v_right / R],
            forces=[self.wheel_torque, self.wheel_torque], **self._kw)
        self._speeds = (v_left, v_right)

    def _step(self, n: int) -> None:
        p, kw = self._p, self._kw
        step = p.stepSimulation
        if not self._visual:
            for _ in range(n):
                step(**kw)
            self._steps += n
            return
        for _ in range(n):
            step(**kw)
            self._steps += 1
            if self.recorder is not None and self._steps % self._record_every == 0:
                self.recorder.capture(p, kw, self.clock(), self.true_pose())
        if self.gui:   # pace to real time
            ahead = self._steps * self.time_step - (_time.perf_counter() - self._wall_t0)
            if ahead > 0:
                _time.sleep(ahead)

    def _wheel_angles(self) -> tuple[float, float]:
        st = self._p.getJointStates(self._robot, [0, 1], **self._kw)
        return st[0][0], st[1][0]

    def _encoder_heading(self, enc: tuple[int, int]) -> float:
        """Heading [rad] from encoder counts (CREATE2_OI: Δθ = (Δs_r − Δs_l) / b)."""
        mpc = self.spec.metres_per_count
        return (enc[1] - enc[0]) * mpc / self.spec.wheel_base

    # ------------------------------------------------------------------ Robot interface
    def bumper(self) -> tuple[bool, bool]:
        """(left, right) bumper switches from the body's contacts with walls.

        A wall contact that touches the body (within ``BUMPER_REACH``) on the front arc
        (± ``bumper_arc_deg`` of the heading) closes the switch on its side; within ±10° of
        straight ahead both close.
        """
        self._check_open()
        return read_bumper(self._p, self._robot, self._wall_set, self.bumper_arc_deg, self._kw)

    def encoders(self) -> tuple[int, int]:
        """(left, right) cumulative encoder counts (no 16-bit wrap in simulation)."""
        self._check_open()
        k = self.spec.counts_per_rev / (2 * math.pi)
        a_l, a_r = self._wheel_angles()
        return int(a_l * k), int(a_r * k)

    def turn(self, angle_deg: float) -> None:
        """Turn in place CCW by ``angle_deg`` [deg] plus the rotation noise (blocking).

        The noise model maps the commanded angle to the executed one; a negative executed
        angle turns clockwise. With ``back_off`` > 0 the robot first backs off that far.
        """
        self._check_open()
        cmd = float(angle_deg)
        actual = float(self.noise.sample(self.rng, cmd))
        if self.back_off > 0:
            v = self.turn_speed
            self.drive(-v)
            self.wait(round(self.back_off / v / self.time_step) * self.time_step)
            self.stop()
        if actual == 0:
            return
        if self.turn_mode == "clock":
            self._turn_by_clock(actual)
        else:
            self._turn_by_encoders(actual)

    def _turn_by_encoders(self, angle_deg: float) -> None:
        """Turn until the encoder heading change reaches the target, polling every sensor
        period; the wheel speed ramps down near the target (never below 0.03 m/s, about the
        Create 2's speed resolution) and the turn stops at the poll nearest the target.
        """
        target = math.radians(angle_deg)
        sign = 1.0 if target > 0 else -1.0
        remaining_total = abs(target)
        period = self.spec.sensor_period
        b = self.spec.wheel_base
        e0 = self.encoders()
        limit = 2.0 * remaining_total / (2 * 0.03 / b) + 5.0   # generous time-out [s]
        t0 = self.clock()
        while True:
            e = self.encoders()
            done = sign * self._encoder_heading((e[0] - e0[0], e[1] - e0[1]))
            remaining = remaining_total - done
            # speed that would cover the rest in about two periods, clipped
            v = min(self.turn_speed, max(0.03, remaining * b / 2 / (2 * period)))
            step = 2 * v / b * period
            if remaining <= step / 2 or self.clock() - t0 > limit:
                break
            self._set_wheels(-sign * v, sign * v)
            self.wait(period)
        self.stop()
        self.wait(SETTLE_STEPS * self.time_step)

    # ------------------------------------------------------------------ simulation only
    def place(self, x: float, y: float, heading_deg: float) -> None:
        """Put the robot at (x [m], y [m]) facing ``heading_deg`` [deg], at rest, stopped.

        Raises :class:`~envs.UserError` when the body would overlap a wall there.
        """
        self._check_open()
        p, kw = self._p, self._kw
        pt = shapely.points(float(x), float(y))
        if not (self.env.free_space.covers(pt)
                and shapely.distance(pt, self.env.walls) >= self.body_radius - 1e-6):
            raise UserError(f"cannot place the robot at ({x:g}, {y:g}): its body would "
                            f"overlap a wall.")
        orn = p.getQuaternionFromEuler([0, 0, math.radians(heading_deg)])
        p.resetBasePositionAndOrientation(self._robot, [x, y, self._wheel_r], orn, **kw)
        p.resetBaseVelocity(self._robot, [0, 0, 0], [0, 0, 0], **kw)
        a_l, a_r = self._wheel_angles()
        p.resetJointState(self._robot, 0, a_l, 0.0, **kw)
        p.resetJointState(self._robot, 1, a_r, 0.0, **kw)
        self._set_wheels(0.0, 0.0)
        p.performCollisionDetection(**kw)

    def wall_contacts(self) -> list[tuple[float, float]]:
        """(bearing [deg] from the heading, distance [m]) of every body–wall contact point
        closer than 1 mm, whatever the bumper arc (simulation only, for calibration).
        """
        self._check_open()
        p, kw = self._p, self._kw
        yaw = self.true_pose()[2]
        return [(normal_bearing(c[7], yaw), c[8])
                for c in p.getContactPoints(bodyA=self._robot, linkIndexA=-1, **kw)
                if c[2] in self._wall_set and c[8] <= CONTACT_TOLERANCE]

    def true_pose(self) -> tuple[float, float, float]:
        """(x [m], y [m], heading [deg] in (−180, 180]) of the body centre."""
        self._check_open()
        p, kw = self._p, self._kw
        (x, y, _), orn = p.getBasePositionAndOrientation(self._robot, **kw)
        return x, y, math.degrees(p.getEulerFromQuaternion(orn)[2])

    @property
    def frames(self) -> list[np.ndarray]:
        """Video frames recorded so far (RGB uint8 arrays, without the overlay)."""
        return self.recorder.frames if self.recorder is not None else []

    def close(self) -> None:
        """Stop, write the recording (if any) and disconnect (idempotent)."""
        if self._closed or self._cid is None:
            return
        try:
            self.stop()
            if self.recorder is not None:
                self.recorder.write()
        finally:
            self._disconnect()

    def _disconnect(self) -> None:
        if self._cid is not None and not getattr(self, "_closed", True):
            try:
                self._p.disconnect(**self._kw)
            except Exception:  # noqa: BLE001 - already gone
                pass
        self._closed = True

    def __del__(self) -> None:
        try:
            self._disconnect()
        except Exception:  # noqa: BLE001
            pass

    def __repr__(self) -> str:
        return (f"PyBulletRobot(env={self.env.name!r}, turn={self.turn_mode!r}, "
                f"time_step={self.time_step:g}, back_off={self.back_off})")
