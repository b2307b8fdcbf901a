"""The kinematic twin: exact continuous geometry, simulated time (docs/model.md §8, §21).

The robot is a disk of radius r moving inside the C-space (E eroded by r). Everything about
how it moves, stops and is counted comes from the motion layer :mod:`envs.motion`, which
the coverage models share: the exact capsule ray casts (:class:`WallCaster`,
:class:`LocalCaster`), the contact constants, the step rule and point → cell.

Two bodies use it:

- :class:`KinematicRobot`, a :class:`bouncesim.robots.base.Robot` for the executors: ``wait(dt)``
  advances the pose under the current wheel command, ``drive_until_bump`` jumps straight to
  the contact (or the timeout), ``turn`` is exact plus a seeded noise sample.
- :class:`KinematicBatch`, thousands of independent robots stepped at once under the
  docs/model.md §8 step semantics, for Monte-Carlo coverage.

Contact conventions (shared by both)
------------------------------------
- A drive stops ``CONTACT_GAP`` = 1e-9 m (along the ray) before the computed contact, so the
  disk does not penetrate a wall (at a glancing incidence the gap to the wall is smaller than
  1e-9 m; rounding is then of order 1e-16 m).
- Motion parallel to a wall the disk touches is not a contact (a robot in a cell next to a wall
  sits at exactly distance r from it): a side is hit only when the motion approaches its line
  (rate > 1e-12 per metre), a wall corner only when the ray passes closer than r − 1e-7 m
  (100 times the contact gap, so a robot stopped at a wall can slide past the corners in
  line with that wall; a grazing pass may overlap a corner by at most 1e-7 m).
- The bumper is the front half of the body. It reads closed when the wall blocks forward
  motion within ``BUMP_RANGE`` = 1e-6 m; the side is taken from the bearing β of the contact
  point relative to the heading: |β| <= 10° closes both switches, β > 10° the left one and
  β < −10° the right one. A contact behind the centre line (driving backwards into a wall) is
  not a bump: the robot stalls there, its clock runs on and the bumper stays open.
- Opt-in (``KinematicRobot(contact=...)``, ``KinematicBatch(..., contact=...)``): the contact
  rule of :mod:`envs.contact` (docs/model.md §9, shared with the event model): contacts met
  below the incidence β do not press the bumper; the body slides along the wall.
  ``glance_deg=g`` is the same rule with β = 90° − g and no friction. The default keeps the
  front-half bumper above.

Examples
--------
>>> import envs
>>> env = envs.load("lab")
>>> bot = KinematicRobot(env)
>>> bot.place(0.51, 0.51, 30.0)
>>> ev = bot.drive_until_bump(0.2, 60.0)
>>> ev.bumped, round(ev.elapsed, 4)          # centre reaches y = 1.02 - r = 0.85 after 0.68 m
(True, 3.4)
>>> tuple(round(v, 4) for v in bot.true_pose())
(1.0989, 0.85, 30.0)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from envs import Environment, UserError
from envs.contact import (
    REST_FLIGHT,
    advance,
    closes_bumper,
    front_contacts,
    glancing,
    leg_length,
    switches,
)

# The motion layer (shared with the coverage models in planners); the casters and constants
# are re-exported here under their old names.
from envs.motion import (  # noqa: F401
    BUMP_RANGE,
    CENTRE_ZONE_DEG,
    CONTACT_GAP,
    STEP_TOL,
    ContactParams,
    LocalCaster,
    WallCaster,
    casters,
    drive_distance,
    step,
    unit,
)
from planners.cells import CellSpace
from planners.measures import wrap180
from planners.metrics import tv_distance
from planners.plan import PolicyMix
from planners.turn_offsets import spin_sign

from .base import CREATE2, BumpEvent, Robot, RobotSpec
from .noise import NoiseModel, NoNoise, noise_and_rng, noise_for_mix

__all__ = ["WallCaster", "LocalCaster", "casters", "KinematicRobot", "KinematicBatch",
           "BatchCoverage", "unit", "CONTACT_GAP", "BUMP_RANGE", "STEP_TOL", "CENTRE_ZONE_DEG",
           "SIDE_RULES"]

SIDE_RULES = ("touched", "nearest")
"""How a twin's bumper switches read a contact (:class:`KinematicRobot`'s ``side_rule``)."""

_EXACT = NoNoise()
_SCALAR_MAX = 8          # batches up to this size cast robot by robot in plain Python


# ============================================================================ one robot
class KinematicRobot(Robot):
    """A disk robot with exact straight-line kinematics and simulated time.

    Parameters
    ----------
    env : Environment
    noise : NoiseModel, optional
        Rotation noise applied to every :meth:`turn` (default None: exact).
    rng : numpy.random.Generator or int, optional
        Source of the noise draws (an int is a seed). Required when the noise is not exact
        (:func:`bouncesim.robots.noise.noise_and_rng`, the contract of every simulated body).
    turn_speed : float
        Wheel speed used for in-place turns [m/s]; a turn by φ takes
        ``spec.turn_time(φ, turn_speed)`` of simulated time.
    turn : {"clock", "encoders"}
        Accepted for parity with the PyBullet robot; in the twin both are exact (the wheels
        turn by exactly the commanded arc) and take the same time.
    contact : envs.motion.ContactParams, optional
        Opt-in contact rule (docs/model.md §9, :mod:`envs.contact`). Default None: every
        contact on the front half stops the robot and closes the bumper (the docs/model.md §21
        twin). With β = ``contact.beta_deg``, a wall met at incidence below β does not press
        the bumper: the body slides along the wall (heading kept, speed
        v·(cos α − μ sin α) along it; around a corner it wraps on the corner's circle until it
        can go straight on). ``envs.motion.PYBULLET_CONTACT`` is the PyBullet robot's fit.
        Two glancing contacts at once (a pocket) count as a bump.
    glance_deg : float, optional
        The same rule given as a bumper arc ±glance_deg in (0°, 90°): β = 90° − glance_deg,
        μ = 0 (80 matches the PyBullet robot's arc). Not together with ``contact``.
    spec : RobotSpec, optional
        Body figures; default the Create 2 with the environment's radius.
    side_rule : {"touched", "nearest"}
        How the bumper's two switches read a contact. "touched" (default, docs/model.md §8):
        every wall feature touched within ``BUMP_RANGE`` presses the switches its bearing β
        selects (left when β >= −10°, right when β <= 10°: in a corner both often close).
        "nearest": the wall point nearest the robot's centre decides, its bearing within
        ±10° closing both switches, further left the left one, further right the right one
        (a body whose switches read one wall point: in a corner, or after sliding along a
        wall, it reports one side where "touched" reports both). The navigators must not
        depend on which.

    Notes
    -----
    The robot starts at the centre of position cell 0 facing east, clock 0. ``turn`` leaves
    the wheels stopped. Encoders count the wheel travel: straight motion actually made (a
    stalled robot's wheels do not count) and the *commanded* turn (noise is body slip, which
    encoders do not see).
    """

    def __init__(self, env: Environment, noise: NoiseModel | None = None, rng=None, *,
                 turn_speed: float = 0.1, turn: str = "clock",
                 spec: RobotSpec | None = None, glance_deg: float | None = None,
                 contact: ContactParams | None = None, side_rule: str = "touched") -> None:
        self.env = env
        if side_rule not in SIDE_RULES:
            raise UserError(f"side_rule must be one of {', '.join(SIDE_RULES)}, got "
                            f"{side_rule!r}.")
        self.side_rule = side_rule
        self.noise, self.rng = noise_and_rng(noise, rng)
        self.spec = spec if spec is not None else replace(CREATE2, radius=env.robot_radius)
        if not 0 < turn_speed <= self.spec.max_wheel_speed:
            raise UserError(f"turn speed must lie in (0, {self.spec.max_wheel_speed:g}] m/s, "
                            f"got {turn_speed:g}.")
        self.turn_speed = float(turn_speed)
        if turn not in ("clock", "encoders"):
            raise UserError(f"turn must be 'clock' or 'encoders', got {turn!r}.")
        self.turn_mode = turn
        if glance_deg is not None and not 0 < float(glance_deg) < 90:
            raise UserError(f"glance_deg must lie in (0, 90) degrees, got {glance_deg}.")
        if glance_deg is not None:
            if contact is not None:
                raise UserError("give the contact rule as contact or as glance_deg, not both.")
            contact = ContactParams(beta_deg=90.0 - float(glance_deg), slide_friction=0.0)
        self.contact = contact
        self.glance_deg = None if contact is None else 90.0 - contact.beta_deg
        self.caster, self.local = casters(env)
        cells = CellSpace(env)
        x, y = cells.centres[0]
        self._x, self._y = float(x), float(y)
        self._set_heading(0.0)
        self._speed = 0.0
        self._t = 0.0
        self._wheel = [0.0, 0.0]           # left, right wheel travel [m]

    # ------------------------------------------------------------------ helpers
    def _set_heading(self, deg: float) -> None:
        self._heading = float(deg)
        # the batch's array path, so both bodies use bitwise the same unit vectors
        ux, uy = unit(np.array([self._heading]))[0]
        self._ux, self._uy = float(ux), float(uy)

    def _free_distance(self, sign: float, need: float = math.inf) -> float:
        """Distance [m] to contact along ±heading; exact when below ``need`` (else >= need)."""
        ux, uy = sign * self._ux, sign * self._uy
        t = self.local.cast_one(self._x, self._y, ux, uy)
        if t < self.local.max_dist or need < self.local.max_dist:
            return t
        return self.caster.cast_one(self._x, self._y, ux, uy)

    def _advance(self, d: float) -> None:
        """Move d [m] along the heading (negative: backwards) without a collision check."""
        self._x += d * self._ux
        self._y += d * self._uy
        self._wheel[0] += d
        self._wheel[1] += d

    def _move(self, dist: float) -> float:
        """Move ``dist`` [m] along the heading (negative: backwards), stopping at contact.
        Returns the distance actually travelled (signed).
        """
        if dist == 0:
            return 0.0
        sign = 1.0 if dist > 0 else -1.0
        free = drive_distance(self._free_distance(sign, abs(dist) + CONTACT_GAP))
        d = sign * min(abs(dist), free)
        self._advance(d)
        return d

    # ------------------------------------------------------------------ Robot interface
    def drive(self, speed: float) -> None:
        """Start driving straight at ``speed`` [m/s] (negative: backwards)."""
        self._speed = self.spec.check_speed(speed)

    def stop(self) -> None:
        """Stop both wheels."""
        self._speed = 0.0

    def bumper(self) -> tuple[bool, bool]:
        """(left, right) switches: closed by a contact within the bumper arc (read by
        ``side_rule``).
        """
        touched = [c for c in front_contacts(self.local, self._x, self._y, self._ux, self._uy)
                   if closes_bumper(c[0], self.contact)]
        if self.side_rule == "nearest" and touched:
            return switches([self._nearest_wall_bearing()])
        return switches([beta for beta, *_ in touched])

    def _nearest_wall_bearing(self) -> float:
        """Bearing [deg] of the wall point nearest the centre, + to the left (ties: the
        first wall segment).
        """
        c = self.caster
        p = np.array([self._x, self._y])
        lam = np.clip(((p - c.A) * c.e).sum(1), 0.0, c.L)
        q = c.A + lam[:, None] * c.e
        wx, wy = q[int(np.argmin(np.hypot(*(q - p).T)))] - p
        return math.degrees(math.atan2(self._ux * wy - self._uy * wx,
                                       self._ux * wx + self._uy * wy))

    def clock(self) -> float:
        """Simulated time [s] since the robot was built."""
        return self._t

    def wait(self, duration: float) -> None:
        """Let ``duration`` [s] of simulated time pass with the current drive command."""
        duration = float(duration)
        if duration < 0 or not math.isfinite(duration):
            raise ValueError(f"cannot wait {duration} s.")
        if self._speed > 0:
            self._forward(self._speed, duration)
        else:
            self._move(self._speed * duration)
        self._t += duration

    def turn(self, angle_deg: float) -> None:
        """Turn in place CCW by ``angle_deg`` [deg] plus the noise model's draw."""
        angle = float(angle_deg)
        actual = self.noise.sample(self.rng, angle)
        self._set_heading((self._heading + actual) % 360.0)
        self._t += self.spec.turn_time(angle, self.turn_speed)
        arc = math.radians(angle) * self.spec.wheel_base / 2
        self._wheel[0] -= arc
        self._wheel[1] += arc
        self._speed = 0.0

    def encoders(self) -> tuple[int, int]:
        """(left, right) cumulative wheel encoder counts."""
        mpc = self.spec.metres_per_count
        return int(round(self._wheel[0] / mpc)), int(round(self._wheel[1] / mpc))

    def _forward(self, speed: float, duration: float) -> tuple[float | None, float]:
        """Drive forward at ``speed`` > 0 [m/s] for up to ``duration`` [s] (clock untouched).

        Returns (time of the bump that stopped the robot, or None; free distance left ahead
        [m] at the end). After a bump, or when wedged, the robot stays put.
        """
        reach = speed * duration
        if self.contact is None:
            ahead = self._free_distance(1.0, reach + CONTACT_GAP + BUMP_RANGE)
            dist = drive_distance(ahead)
            if dist > reach:
                self._advance(reach)
                return None, dist - reach
            self._advance(dist)
            return dist / speed, 0.0
        # the contact rule (envs.contact), shared with the event model
        x, y, used, bumped, legs, (vx, vy) = advance(self.caster, self._x, self._y, self._ux,
                                                     self._uy, self.contact, reach)
        self._x, self._y = x, y
        if (vx, vy) != (self._ux, self._uy):          # a slide that turned in (§9)
            self._heading = math.degrees(math.atan2(vy, vx)) % 360.0
            self._ux, self._uy = vx, vy
        travel = sum(leg_length(leg) for leg in legs)
        self._wheel[0] += travel
        self._wheel[1] += travel
        if bumped:
            return used / speed, 0.0
        return None, drive_distance(self._free_distance(1.0, BUMP_RANGE + CONTACT_GAP))

    def drive_until_bump(self, speed: float, timeout: float) -> BumpEvent:
        """Exact equivalent of the polling default: jump to the contact or to the timeout.

        A bumper already closed returns at once; otherwise the robot drives to the first
        contact (bump, elapsed = distance / speed) or for the whole timeout (no bump, unless
        the wall is then within ``BUMP_RANGE``: the polling loop reads the bumper once more
        at the timeout). Driving backwards never bumps (the bumper is the front half).
        """
        t0 = self._t
        self.drive(speed)
        try:
            timeout = max(float(timeout), 0.0)
            reach = max(speed, 0.0) * timeout
            ahead = self._free_distance(1.0, reach + CONTACT_GAP + BUMP_RANGE)
            if ahead <= BUMP_RANGE:              # touching something ahead: pressed?
                left, right = self.bumper()
                if left or right:
                    return BumpEvent(True, left, right, 0.0)
            if speed > 0:
                t_bump, left_ahead = self._forward(speed, timeout)
                if t_bump is not None:
                    self._t += t_bump
                    left, right = self.bumper()
                    return BumpEvent(True, left, right, t_bump)
                self._t += timeout
                if left_ahead <= BUMP_RANGE:
                    left, right = self.bumper()
                    return BumpEvent(bool(left or right), left, right, timeout)
                return BumpEvent(False, False, False, timeout)
            self.wait(timeout)
            left, right = self.bumper()
            return BumpEvent(bool(left or right), left, right, self._t - t0)
        finally:
            self.stop()

    # ------------------------------------------------------------------ simulation only
    def place(self, x: float, y: float, heading_deg: float) -> None:
        """Put the robot at (x [m], y [m]) facing ``heading_deg`` [deg], stopped."""
        x, y = float(x), float(y)
        if not bool(self.env.points_free([[x, y]])[0]):
            raise UserError(f"the robot does not fit at ({x:g}, {y:g}) in {self.env.name}.")
        self._x, self._y = x, y
        self._set_heading(float(heading_deg) % 360.0)
        self._speed = 0.0

    def true_pose(self) -> tuple[float, float, float]:
        """(x [m], y [m], heading [deg]) now."""
        return self._x, self._y, self._heading

    def __repr__(self) -> str:
        return (f"KinematicRobot({self.env.name!r}, pose=({self._x:.3f}, {self._y:.3f}, "
                f"{self._heading:.1f}°), t={self._t:.3f} s, noise={self.noise})")


# ============================================================================ many robots
@dataclass(frozen=True)
class BatchCoverage:
    """Step-sampled visit histogram of a batch run (docs/model.md §22).

    Attributes
    ----------
    counts : (P,) int array    steps counted in each free position cell
    dropped : int              steps counted in no free cell
    bumps : int                bump steps (move to contact + rotation)
    n_robots : int
    steps : int                steps per robot (after burn-in)
    """

    counts: np.ndarray
    dropped: int
    bumps: int
    n_robots: int
    steps: int

    @property
    def total(self) -> int:
        """All robot-steps, dropped ones included."""
        return int(self.counts.sum()) + self.dropped

    @property
    def coverage(self) -> np.ndarray:
        """(P,) fraction of the counted (non-dropped) steps in each position cell."""
        c = self.counts.astype(float)
        s = c.sum()
        return c / s if s > 0 else c

    def tv(self, q) -> float:
        """Total-variation distance ½ Σ |q − q̂| to a predicted coverage q (P,)."""
        q = np.asarray(q, dtype=float)
        return tv_distance(q / q.sum(), self.coverage, normalise=False)


class KinematicBatch:
    """Many independent kinematic robots stepped together (docs/model.md §8 step semantics).

    A step (the step rule, :func:`envs.motion.step`): if the wall ahead is at least h away,
    move h forward (counted in the cell where the step starts); otherwise move to contact,
    then rotate in place by the current bouncing angle plus noise (one step, counted in the
    cell of the contact position). A contact within ``STEP_TOL`` of h counts as a full
    forward step (the robot then bumps at the start of the next step), as
    :func:`bouncesim.runs.execute.execute` counts it on a Robot.

    Parameters
    ----------
    env : Environment
    n_robots : int
    rng : numpy.random.Generator or int
        Draws the starts, the epoch angles and the rotation noise.
    cells : CellSpace, optional
    step : float, optional   step length [m] (default the cell size h)
    starts : (n_robots,) int array, optional
        Start configurations z (default: drawn uniformly from the N configurations).
    contact : envs.motion.ContactParams, optional
        The contact rule of docs/model.md §9 (default None: the front-half bumper). A step
        is then h of clock: a robot that slides covers h·f of wall in it, and a step is a bump
        step when its bump comes more than STEP_TOL before the clock's h.

    Attributes
    ----------
    pos : (n, 2) array      robot centres [m]
    heading : (n,) array    headings [deg]; change it by assignment, not in place (the cached
                            unit vectors follow assignments and the batch's own turns)

    Notes
    -----
    Starts are uniform over the N free configurations: the centre of position cell p facing
    θ_k, (p, k) drawn uniformly (as docs/model.md §16 starts the chain).

    Examples
    --------
    >>> import envs
    >>> b = KinematicBatch(envs.load("lab"), 200, np.random.default_rng(0))
    >>> res = b.run(90.0, 50)
    >>> res.total, res.counts.shape
    (10000, (48,))
    """

    def __init__(self, env: Environment, n_robots: int, rng, *, cells: CellSpace | None = None,
                 step: float | None = None, starts=None,
                 contact: ContactParams | None = None) -> None:
        self.env = env
        self.contact = contact
        self.cells = cells if cells is not None else CellSpace(env)
        self.rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
        self.n = int(n_robots)
        if self.n < 1:
            raise ValueError("a batch needs at least one robot.")
        self.h = float(step if step is not None else env.cell_size)
        self.caster, self.local = casters(env, None if step is None else self.h)
        if starts is None:
            z = self.rng.integers(0, self.cells.N, size=self.n)
        else:
            z = np.asarray(starts, dtype=np.int64).reshape(-1)
            if z.shape != (self.n,) or (z < 0).any() or (z >= self.cells.N).any():
                raise ValueError(f"starts must be {self.n} configurations in [0, {self.cells.N}).")
        p, k = self.cells.pk(z)
        self.pos = self.cells.centres[p].copy()
        self.heading = (k * self.cells.delta_deg).astype(float)
        self._u = self._u_of = None      # cached unit headings, refreshed on turns
        self._flown = np.full(self.n, np.inf)   # [m] since the last turn (a start flies)

    def cell_of(self, pos: np.ndarray) -> np.ndarray:
        """Position cell p of each point (n, 2), or -1 outside the free cells
        (:meth:`planners.cells.CellSpace.cell_of_point`).
        """
        return self.cells.cell_of_point(pos)

    def step(self, angles_deg, noise: NoiseModel | None = None
             ) -> tuple[np.ndarray, np.ndarray]:
        """Advance every robot by one step.

        Parameters
        ----------
        angles_deg : float or (n,) array   each robot's current bouncing angle [deg]
        noise : NoiseModel, optional   rotation noise (default exact)

        Returns
        -------
        cells : (n,) int     the cell each step is counted in (-1: no free cell)
        bumped : (n,) bool   which robots bumped (and turned)
        """
        if self._u is None or self._u_of is not self.heading:
            self._u, self._u_of = unit(self.heading), self.heading
        u = self._u
        if self.n <= _SCALAR_MAX:          # a handful of robots: the scalar path is faster
            free = np.array([self.local.cast_one(x, y, a, b)
                             for (x, y), (a, b) in zip(self.pos.tolist(), u.tolist())])
        else:
            free = self.local.cast(self.pos, u)
        move, bumped = step(drive_distance(free), self.h)     # docs/model.md §8
        counted = self.cell_of(self.pos)
        noise = noise if noise is not None else _EXACT
        # a body that turns further after a bump from rest (§11b): the flight since the
        # last turn is tracked only for it (a run keeps one noise model)
        rest = float(getattr(noise, "rest_deg", 0.0))
        before = self.pos.copy() if rest else None
        self.pos += move[:, None] * u
        if self.contact is not None and bumped.any():         # slides: docs/model.md §9
            self._slide(bumped, move, u)
        if rest:
            self._flown += np.hypot(*(self.pos - before).T)
        if bumped.any():
            idx = np.flatnonzero(bumped)
            counted[idx] = self.cell_of(self.pos[idx])
            # every bump spins the shorter way, as the physics batches' (docs/model.md §21)
            spin = wrap180(np.broadcast_to(np.asarray(angles_deg, dtype=float), (self.n,))[idx])
            turn = noise.sample_many(self.rng, spin)
            if rest:                 # a bump from rest: no flight since the last turn; the
                # body spins further in the sense of its spin (§11b)
                turn = turn + rest * spin_sign(spin) * (self._flown[idx] < REST_FLIGHT)
                self._flown[idx] = 0.0
            self.heading[idx] = (self.heading[idx] + turn) % 360.0
            u[idx] = unit(self.heading[idx])
        return counted, bumped

    def _slide(self, bumped: np.ndarray, move: np.ndarray, u: np.ndarray) -> None:
        """Robots that met a contact outside the bumper arc in this step slide on with the
        rest of the step's clock (:func:`envs.contact.advance`); ``bumped`` is updated.
        """
        idx = np.flatnonzero(bumped)
        idx = idx[glancing(self.caster, self.pos[idx], u[idx], self.contact)]
        for i in idx.tolist():
            x, y, used, bump, _, v = advance(self.caster, *self.pos[i].tolist(),
                                             *u[i].tolist(), self.contact,
                                             self.h - float(move[i]))
            self.pos[i] = (x, y)
            if v != tuple(u[i].tolist()):                 # a slide that turned in (§9)
                u[i] = v
                self.heading[i] = math.degrees(math.atan2(v[1], v[0])) % 360.0
            bumped[i] = bump and float(move[i]) + used < self.h - STEP_TOL

    def run(self, policy, steps: int, *, epoch: int | None = None,
            noise: NoiseModel | None = None, burn_in: int = 0) -> BatchCoverage:
        """Run ``steps`` steps per robot and return the step-sampled visit histogram.

        Parameters
        ----------
        policy : float or PolicyMix
            One bouncing angle [deg], or a mix time-shared in epochs (docs/model.md §21): every
            robot draws, independently, one angle with probabilities α per epoch.
        steps : int          counted steps per robot
        epoch : int          steps per epoch (required for a mix of two or more angles)
        noise : NoiseModel   rotation noise; default the mix's §16 model (eps, r), else exact
        burn_in : int        steps run first and not counted
        """
        if isinstance(policy, PolicyMix):
            angles = np.asarray(policy.angles, dtype=float)
            alpha = np.asarray(policy.alpha, dtype=float)
            alpha = alpha / alpha.sum()
            if noise is None:
                noise = noise_for_mix(policy, self.cells.delta_deg)
        else:
            angles, alpha = np.array([float(policy)]), np.ones(1)
        for a in angles:
            self.cells.angle_steps(a)                  # a multiple of 360°/K (docs/model.md §7)
        noise = noise if noise is not None else NoNoise()
        mixed = np.count_nonzero(alpha > 0) > 1
        if mixed and (epoch is None or int(epoch) < 1):
            raise UserError("a policy mix of two or more angles needs an epoch length >= 1.")
        epoch = int(epoch) if epoch else 1
        counts = np.zeros(self.cells.P + 1, dtype=np.int64)   # last bin: dropped
        bumps = 0
        current = np.full(self.n, angles[0])
        for s in range(int(burn_in) + int(steps)):
            if mixed and s % epoch == 0:
                current = angles[self.rng.choice(len(angles), size=self.n, p=alpha)]
            cells, bumped = self.step(current, noise)
            if s >= burn_in:
                counts += np.bincount(np.where(cells < 0, self.cells.P, cells),
                                      minlength=self.cells.P + 1)
                bumps += int(bumped.sum())
        return BatchCoverage(counts=counts[:-1], dropped=int(counts[-1]), bumps=bumps,
                             n_robots=self.n, steps=int(steps))
