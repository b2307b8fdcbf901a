"""The MuJoCo Create 2: a wheeled rigid body in a MuJoCo world built from an environment.

:class:`MuJoCoRobot` implements the :class:`~bouncesim.robots.base.Robot` interface with the
MuJoCo physics engine (DeepMind; a different team, contact model and solver from PyBullet's
Bullet): the body of :mod:`.world` (a 0.17 m disk on two driven wheels, frictionless caster
and skid, walls extruded from the environment's polygons), a bumper read from the engine's
contacts between the body and the walls, wheel encoders from the wheel joint angles and a
simulated clock.

Why wheels, not a planar body moved by setting its velocity: a body whose velocity is set
obeys whatever slide rule the setter encodes (an isotropic velocity servo slides along a
frictionless wall at exactly v·cos α), so it could only repeat the model's assumption. With
wheels on a floor the engine itself decides how the robot meets a wall: the wheels push, slip
sideways against their floor friction, and the wall's reaction turns the body or not. That
is what a second engine is for (docs/readme_physics_mujoco.md compares the two).

Each robot owns its own ``MjModel`` / ``MjData``; MuJoCo is deterministic for a given model,
so the only randomness is the rotation noise drawn from the robot's seeded ``rng``.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import shapely

from envs import Environment, UserError
from envs.contact import at_speed, switches
from envs.motion import MUJOCO_CONTACTS, ContactParams
from planners.measures import wrap180

from ..base import CREATE2, Robot, RobotSpec
from ..noise import NoiseModel, noise_and_rng
from ..stepped import SETTLE_STEPS, SteppedWheels
from .world import CONTACT_MARGIN, BodyParams, world_xml

__all__ = ["MuJoCoRobot", "DECLARED_TURNS", "DECLARED_TURNS_AT", "DECLARED_REST_TURNS",
           "declared_turns_at",
           "DEFAULT_TIME_STEP", "DEFAULT_TURN_SPEED",
           "import_mujoco", "SETTLE_STEPS", "Bodies"]

DEFAULT_TIME_STEP = 1 / 200
"""Physics step [s]: 5 ms, as in PyBullet (the 15 ms sensor period is 3 steps)."""
DEFAULT_TURN_SPEED = 0.1
"""Wheel speed while turning in place [m/s], as in PyBullet."""

DECLARED_TURNS = "gauss:0.45,offset=-1,factor=0.9979"
"""The default body's own turn errors after a bump driven at 0.3 m/s (``validate``'s speed),
as it declares them to a feedback filter (:func:`bouncesim.runs.feedback.body_turns`) and
to the coverage chain (docs/model.md §11b), measured by ``python -m experiments.body_turns
--bodies mujoco --angles 30,45,75,90,135,315 --trials 900 --factor --rest`` (seed 0, lab):
its turns by clock lag by 1.00° and by 0.21 % of the spin, in the sense it spins (30°:
−1.16°, 45°: −1.07°, 75°: −1.09°, 90°: −1.29°, 135°: −1.27°; 315°, a 45° clockwise spin
the shorter way: +1.04°), with a scatter of 0.45° (the fit's residuals and the flights'
rotations in quadrature). Before the factor was fitted it declared the mean over 45°, 90°
and 135°, ``gauss:0.6,offset=-1.26`` (150 trials); before bumps spun the shorter way it
declared ``gauss:0.45,offset=-1.04,factor=0.9982`` from 315° spun counter-clockwise
(−1.59°). Its turns after a bump from rest are :data:`DECLARED_REST_TURNS`; after a bump at
0.2 m/s it turns less short (:data:`DECLARED_TURNS_AT`)."""

DECLARED_REST_TURNS = "gauss:0.19,offset=-0.28,factor=0.9979"
"""The default body's turn errors after a bump from rest: a flight of length zero, when the
turn before left it facing its wall (docs/model.md §11b), measured by the same command (its
"rest" trials, the factor fixed to :data:`DECLARED_TURNS`'): 0.72° less of a lag than after
a flight (30°: −0.36°, 45°: −0.29°, 75°: −0.44°, 90°: −0.66°, 315° spun 45° clockwise:
+0.31°). The event model's zero-length flights take it (``validate --backend mujoco``)."""

DECLARED_TURNS_AT = {
    0.3: DECLARED_TURNS,
    0.2: "gauss:0.55,offset=-0.77,bias=0.5",
}
"""The default body's turn errors by the speed [m/s] of the drive into the bump before the
turn (:meth:`MuJoCoRobot.turn_errors_at`): ``python -m experiments.body_turns --bodies mujoco
--trials 150 --speed V`` (seed 0, lab). At 0.2 m/s (navigation's speed) its turns end 0.77°
short (45°: −0.60°, 90°: −0.85°, 135°: −0.82°), not 1.26°: told the 0.3 m/s offset, a
feedback filter's heading drifted by 0.5° per turn where the flights do not measure it
(docs/readme_feedback.md, "MuJoCo"). ``bias=0.5``: the offset lies up to 0.27° from the
mean between angles and rooms (studio: −0.50° in a navigation run), so a filter learns it
within ±0.5° (the coverage chain takes the offset, docs/model.md §11b)."""


def declared_turns_at(speed: float | None) -> str | None:
    """The default body's declared turn errors after a bump driven at ``speed`` [m/s]
    (:data:`DECLARED_TURNS_AT`, within 0.01 m/s); None at a speed not measured.
    """
    return at_speed(DECLARED_TURNS_AT, speed)


def import_mujoco():
    """The mujoco module; one sentence naming the extra to install when it is missing."""
    try:
        import mujoco
    except ImportError:
        raise UserError("the MuJoCo world needs mujoco: pip install 'bouncesim[mujoco]'.") \
            from None
    return mujoco


class Bodies:
    """Index tables of the robots of one compiled MuJoCo world (shared with the batch).

    Attributes (arrays indexed by robot)
    ------------------------------------
    qadr : int array        qpos address of each free joint (x, y, z, qw, qx, qy, qz)
    dadr : int array        qvel address of each free joint
    wheel_q : (n, 2) int    qpos addresses of the (left, right) wheel joints
    wheel_d : (n, 2) int    qvel addresses of the wheel joints
    act : (n, 2) int        actuator ids (left, right)
    body_geom : int array   geom id of each robot's body cylinder
    robot_of_geom : dict    body geom id -> robot index
    walls : frozenset       geom ids of the walls
    """

    def __init__(self, mj, model, n: int) -> None:
        def jid(name):
            return mj.mj_name2id(model, mj.mjtObj.mjOBJ_JOINT, name)

        def gid(name):
            return mj.mj_name2id(model, mj.mjtObj.mjOBJ_GEOM, name)

        def aid(name):
            return mj.mj_name2id(model, mj.mjtObj.mjOBJ_ACTUATOR, name)
        free = [jid(f"r{i}_free") for i in range(n)]
        self.qadr = np.array([model.jnt_qposadr[j] for j in free])
        self.dadr = np.array([model.jnt_dofadr[j] for j in free])
        wheels = [[jid(f"r{i}_left"), jid(f"r{i}_right")] for i in range(n)]
        self.wheel_q = np.array([[model.jnt_qposadr[j] for j in w] for w in wheels])
        self.wheel_d = np.array([[model.jnt_dofadr[j] for j in w] for w in wheels])
        self.act = np.array([[aid(f"r{i}_left"), aid(f"r{i}_right")] for i in range(n)])
        self.body_geom = np.array([gid(f"r{i}_body") for i in range(n)])
        self.robot_of_geom = {int(g): i for i, g in enumerate(self.body_geom)}
        names = [mj.mj_id2name(model, mj.mjtObj.mjOBJ_GEOM, g) or "" for g in range(model.ngeom)]
        self.walls = frozenset(g for g, nm in enumerate(names) if nm.startswith("wall"))


def pose_of(data, qadr: int) -> tuple[float, float, float]:
    """(x [m], y [m], heading [deg] in (−180, 180]) of the free body at qpos address qadr."""
    q = data.qpos
    w, qx, qy, qz = q[qadr + 3], q[qadr + 4], q[qadr + 5], q[qadr + 6]
    yaw = math.atan2(2 * (w * qz + qx * qy), 1 - 2 * (qy * qy + qz * qz))
    return float(q[qadr]), float(q[qadr + 1]), math.degrees(yaw)


def wall_bearings(data, bodies: Bodies, tolerance: float = CONTACT_MARGIN) -> dict:
    """{robot index: [bearing [deg] from its heading of each body–wall contact closer than
    ``tolerance`` [m]]} from the engine's contact list.
    """
    out: dict = {}
    con = data.contact
    if data.ncon == 0:
        return out
    geom, dist, pos = con.geom, con.dist, con.pos
    rog, walls = bodies.robot_of_geom, bodies.walls
    for k in range(data.ncon):
        g1, g2 = int(geom[k, 0]), int(geom[k, 1])
        if g1 in walls:
            g1, g2 = g2, g1
        i = rog.get(g1)
        if i is None or g2 not in walls or dist[k] > tolerance:
            continue
        x, y, yaw = pose_of(data, bodies.qadr[i])
        b = wrap180(math.degrees(math.atan2(pos[k, 1] - y, pos[k, 0] - x)) - yaw)
        out.setdefault(i, []).append(b)
    return out


def bumper_of(bearings, arc_deg: float) -> tuple[bool, bool]:
    """(left, right) switches closed by contacts at ``bearings`` [deg] within ± ``arc_deg``."""
    return switches([b for b in bearings if abs(b) <= arc_deg])


class MuJoCoRobot(SteppedWheels, Robot):
    """An iRobot Create 2 in a MuJoCo world built from an environment.

    Parameters
    ----------
    env : Environment or str
        The environment (or a catalogue name / env file path).
    noise : NoiseModel, optional
        Rotation noise (``sample(rng, commanded_deg) -> actual_deg``); None: exact turns.
    rng : numpy.random.Generator or int, optional
        Random source of the noise (required when the noise is not exact).
    time_step : float
        Physics step [s] (default 5 ms; waits are rounded to whole steps without drift).
    turn_speed : float
        Wheel speed while turning in place [m/s].
    wheel_torque : float
        Torque limit of each wheel's velocity actuator [N m].
    wheel_gain : float
        Velocity gain of the wheel actuators [N m s/rad].
    bumper_arc_deg : float
        Contacts within ± this angle of the heading close the bumper (default 80°, as the
        PyBullet body: a wall the robot runs along, touching at ±90°, does not press it).
    clearance : float
        The collision body is this much [m] smaller in radius than ``spec.radius`` (2 mm, as
        in PyBullet: exact tangency with a wall is fragile in a physics engine).
    solver_iterations : int
        MuJoCo's constraint solver iterations.
    cone : {"elliptic", "pyramidal"}
        MuJoCo's friction cone of the wheel–floor contacts: Coulomb's isotropic cone
        (default) or MuJoCo's default four-sided pyramid, under which a wheel slips sideways
        more easily along some directions than others (a pushed robot turns into a wall
        about four times faster with it).
    spec : RobotSpec, optional
        Body and drive figures (default the Create 2 with the environment's robot radius).
    start : (x, y, heading_deg), optional
        Initial pose; default the centre of the first free cell facing east.

    Examples
    --------
    >>> with MuJoCoRobot("lab") as bot:
    ...     bot.place(0.51, 0.51, 0.0)
    ...     ev = bot.drive_until_bump(0.2, timeout=30.0)
    ...     round(bot.true_pose()[0], 2), ev.bumped
    (2.21, True)
    """

    contact = None
    """No speed-free contact rule: the MuJoCo body's turn-in slides depend on its drive speed
    (:meth:`contact_at`)."""

    turn_errors = None
    """The body's own turn errors, a noise spec (:func:`bouncesim.runs.feedback.body_turns`):
    at the default ``time_step``, ``turn_speed``, ``wheel_torque`` and ``wheel_gain``,
    :data:`DECLARED_TURNS`; None (nothing declared) with any other setting, which turns
    differently."""

    def contact_at(self, speed: float | None) -> ContactParams | None:
        """The contact rule (docs/model.md §9) this body declares at drive ``speed`` [m/s]:
        its turn-in rule fitted at that speed (``envs.motion.MUJOCO_CONTACTS``, 0.2 and
        0.3 m/s, within 0.01 m/s) at the default settings (:attr:`turn_errors`' condition);
        else None, nothing declared.
        """
        return None if self.turn_errors is None else at_speed(MUJOCO_CONTACTS, speed)

    def turn_errors_at(self, speed: float | None) -> str | None:
        """The turn errors (a noise spec) this body declares after a bump driven at ``speed``
        [m/s] (:data:`DECLARED_TURNS_AT`, within 0.01 m/s) at the default settings
        (:attr:`turn_errors`' condition); else None, nothing declared.
        """
        return None if self.turn_errors is None else declared_turns_at(speed)

    def __init__(self, env: Environment | str, noise: NoiseModel | None = None,
                 rng: np.random.Generator | int | None = None, *,
                 time_step: float = DEFAULT_TIME_STEP,
                 turn_speed: float = DEFAULT_TURN_SPEED, wheel_torque: float = 2.0,
                 wheel_gain: float = 2.0, bumper_arc_deg: float = 80.0,
                 clearance: float = 0.002, solver_iterations: int = 50,
                 cone: str = "elliptic", spec: RobotSpec | None = None,
                 start: tuple[float, float, float] | None = None) -> None:
        self._closed = True
        if isinstance(env, (str, Path)):
            import envs
            env = envs.load(env)
        self.env = env
        spec = spec if spec is not None else replace(CREATE2, radius=env.robot_radius)
        self.spec = spec
        if not (time_step > 0 and math.isfinite(time_step)):
            raise UserError(f"time_step must be a positive number of seconds, got {time_step}.")
        if not 0 < turn_speed <= spec.max_wheel_speed:
            raise UserError(f"turn_speed must be in (0, {spec.max_wheel_speed}] m/s, "
                            f"got {turn_speed}.")
        if not 0 <= clearance < spec.radius / 2:
            raise UserError(f"clearance must be in [0, {spec.radius / 2}) m, got {clearance}.")
        if not (wheel_torque > 0 and wheel_gain > 0):
            raise UserError("wheel_torque and wheel_gain must be positive.")
        if cone not in ("elliptic", "pyramidal"):
            raise UserError(f"cone must be 'elliptic' or 'pyramidal', got {cone!r}.")
        self.cone = cone
        if (time_step, turn_speed, wheel_torque, wheel_gain) == \
                (DEFAULT_TIME_STEP, DEFAULT_TURN_SPEED, 2.0, 2.0):
            self.turn_errors = DECLARED_TURNS
        self.solver_iterations = int(solver_iterations)
        self.noise, self.rng = noise_and_rng(noise, rng)
        self.time_step = float(time_step)
        self.turn_speed = float(turn_speed)
        self.bumper_arc_deg = float(bumper_arc_deg)
        self.body_radius = spec.radius - float(clearance)
        self.params = BodyParams(body_radius=self.body_radius, wheel_torque=float(wheel_torque),
                                 wheel_gain=float(wheel_gain))
        mj = self._mj = import_mujoco()
        self.model = mj.MjModel.from_xml_string(world_xml(
            env, 1, spec=spec, params=self.params, time_step=self.time_step,
            solver_iterations=self.solver_iterations, cone=cone))
        self.data = mj.MjData(self.model)
        self.bodies = Bodies(mj, self.model, 1)
        self._wheel_r = spec.wheel_diameter / 2
        self._steps = 0
        self._t_goal = 0.0
        self._closed = False
        if start is None:
            grid = env.grid_centres_free()
            j, i = np.argwhere(grid)[0]
            x0, y0 = env.origin
            h = env.cell_size
            start = (x0 + (i + 0.5) * h, y0 + (j + 0.5) * h, 0.0)
        self.place(*start)

    # ------------------------------------------------------------------ internals
    def _set_wheels(self, v_left: float, v_right: float) -> None:
        R = self._wheel_r
        self.data.ctrl[self.bodies.act[0]] = (v_left / R, v_right / R)

    def _step(self, n: int) -> None:
        self._mj.mj_step(self.model, self.data, nstep=int(n))
        self._steps += int(n)

    # ------------------------------------------------------------------ Robot interface
    def bumper(self) -> tuple[bool, bool]:
        """(left, right) bumper switches from the engine's body–wall contacts.

        A contact closer than 1 mm on the front arc (± ``bumper_arc_deg`` of the heading)
        closes the switch on its side; within ±10° of straight ahead both close
        (:func:`envs.contact.switches`).
        """
        self._check_open()
        return bumper_of(self.wall_contacts_bearings(), self.bumper_arc_deg)

    def wall_contacts_bearings(self) -> list[float]:
        """Bearings [deg] from the heading of the body's wall contacts closer than 1 mm."""
        return wall_bearings(self.data, self.bodies).get(0, [])

    def wall_contacts(self) -> list[tuple[float, float]]:
        """(bearing [deg], distance [m]) of every body–wall contact closer than 1 mm,
        whatever the bumper arc (simulation only, for calibration; the distance is the
        engine's, negative when overlapping).
        """
        self._check_open()
        d = self.data
        x, y, yaw = self.true_pose()
        out = []
        g = int(self.bodies.body_geom[0])
        for k in range(d.ncon):
            c = d.contact[k]
            other = c.geom2 if c.geom1 == g else c.geom1 if c.geom2 == g else None
            if other is None or other not in self.bodies.walls or c.dist > CONTACT_MARGIN:
                continue
            b = wrap180(math.degrees(math.atan2(c.pos[1] - y, c.pos[0] - x)) - yaw)
            out.append((b, float(c.dist)))
        return out

    def encoders(self) -> tuple[int, int]:
        """(left, right) cumulative encoder counts from the wheel joint angles."""
        self._check_open()
        k = self.spec.counts_per_rev / (2 * math.pi)
        a_l, a_r = self.data.qpos[self.bodies.wheel_q[0]]
        return int(a_l * k), int(a_r * k)

    def turn(self, angle_deg: float) -> None:
        """Turn in place CCW by ``angle_deg`` [deg] plus the rotation noise (blocking), by
        clock: wheels at ±turn_speed for φ / ω (ω = 2 v / wheel_base), then stop and settle.
        """
        self._check_open()
        actual = float(self.noise.sample(self.rng, float(angle_deg)))
        if actual != 0:
            self._turn_by_clock(actual)

    # ------------------------------------------------------------------ simulation only
    def place(self, x: float, y: float, heading_deg: float) -> None:
        """Put the robot at (x [m], y [m]) facing ``heading_deg`` [deg], at rest, stopped.

        Raises :class:`~envs.UserError` when the body would overlap a wall there.
        """
        self._check_open()
        pt = shapely.points(float(x), float(y))
        if not (self.env.free_space.covers(pt)
                and shapely.distance(pt, self.env.walls) >= self.body_radius - 1e-6):
            raise UserError(f"cannot place the robot at ({x:g}, {y:g}): its body would "
                            f"overlap a wall.")
        place_body(self._mj, self.model, self.data, self.bodies, 0, x, y, heading_deg,
                   self._wheel_r)
        self._set_wheels(0.0, 0.0)

    def true_pose(self) -> tuple[float, float, float]:
        """(x [m], y [m], heading [deg] in (−180, 180]) of the body centre."""
        self._check_open()
        return pose_of(self.data, self.bodies.qadr[0])

    def close(self) -> None:
        """Stop and release the world (idempotent)."""
        if not self._closed:
            self.stop()
            self._closed = True

    def __repr__(self) -> str:
        return f"MuJoCoRobot(env={self.env.name!r}, time_step={self.time_step:g})"


def place_body(mj, model, data, bodies: Bodies, i: int, x: float, y: float,
               heading_deg: float, wheel_r: float) -> None:
    """Put robot ``i`` at a pose at rest (wheel angles kept), and recompute the contacts."""
    a, d = bodies.qadr[i], bodies.dadr[i]
    h = math.radians(heading_deg) / 2
    data.qpos[a:a + 7] = (x, y, wheel_r, math.cos(h), 0.0, 0.0, math.sin(h))
    data.qvel[d:d + 6] = 0.0
    data.qvel[bodies.wheel_d[i]] = 0.0
    data.qacc_warmstart[d:d + 6] = 0.0
    mj.mj_forward(model, data)
