"""A team of kinematic twins in one room, in continuous time (docs/model.md §24).

K :class:`~bouncesim.robots.kinematic.KinematicRobot` bodies share one room and one clock.
Each robot turns in place (taking the twin's turn time), then drives straight at speed v
until its flight ends. Every wall flight is the twin's own (``drive_until_bump``: its ray
casts, contact gap and bumper), so with ``interact="off"`` (the robots pass through each
other) every robot's poses are exactly those of a lone twin given the same turns.

With ``interact="bump"`` two robots are two disks of radius r that may not overlap:

- Between events every robot is still or moves on a straight line, so the first contact of
  a pair, |Δp + Δw·s| = 2r with Δw·Δp < 0 (approaching), is the smaller root of a quadratic
  in s, solved in closed form (a pair already within 2r + ``BUMP_RANGE`` and approaching is
  in contact at once).
- At a contact a moving robot stops when its own motion approaches the other (the other's
  centre lies on its front half, bearing |β| < 90°): it stops ``CONTACT_GAP`` short along its
  flight and reports a bump, its switches read from β by the twin's side rule
  (:func:`envs.contact.switches`; walls touching at the same time close theirs too). A robot
  hit from behind or from the side feels nothing and drives on (it moves away from the
  other), as the twin's bumper ignores contacts behind the centre line. At least one robot of
  an approaching pair always stops; two robots meeting head-on both stop.
- A robot that is still (waiting, turning, parked) is an obstacle; it does not report a
  bump. If its next flight starts against a robot in front, it bumps at once (0 s), as the
  twin does against a wall.

The world advances from event to event (a turn ends, a flight reaches its wall, its clock
stop or its cap, two robots touch); :meth:`KinematicTeam.advance` returns at the first time
at which one or more flights end.

>>> import envs
>>> team = KinematicTeam(envs.load("lab"), 2, interact="bump")
>>> team.place(0, 0.17, 0.17, 0.0); team.place(1, 2.89, 0.17, 180.0)   # lab's row 0, head-on
>>> _ = team.launch(0); _ = team.launch(1)
>>> [(e.robot, e.by, e.left, e.right, round(e.elapsed, 6)) for e in team.advance()]
[(0, 'robot', True, True, 5.95), (1, 'robot', True, True, 5.95)]
>>> [round(p[0], 6) for p in team.poses()]       # they meet at the midpoint, 2r apart
[1.36, 1.7]
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from envs import Environment, UserError
from envs.contact import switches
from envs.motion import BUMP_RANGE, CONTACT_GAP, unit
from planners.measures import wrap180

from .base import BumpEvent
from .kinematic import KinematicRobot
from .noise import NoiseModel

__all__ = ["INTERACT", "KinematicTeam", "TeamFlight", "FlightEnd"]

INTERACT = ("off", "bump")
"""How the robots of a team meet: pass through each other, or bump like a wall."""

_STILL, _TURNING, _FLYING = 0, 1, 2


@dataclass(frozen=True)
class TeamFlight:
    """A planned flight: where it starts and where it would end against the walls alone.

    Attributes
    ----------
    start : (x [m], y [m], heading [deg])   after the turn
    end : (x [m], y [m])                    the wall contact (or the cap)
    event : BumpEvent                       the twin's reading there
    """

    start: tuple[float, float, float]
    end: tuple[float, float]
    event: BumpEvent


@dataclass(frozen=True)
class FlightEnd:
    """How a robot's flight ended.

    Attributes
    ----------
    robot : int
    by : {"wall", "robot", "clock", "cap"}
        a wall (the twin's bump), another robot, a clock stop (:meth:`KinematicTeam.clock_stop`)
        or the flight cap without a bump
    bumped, left, right : bool   the bumper and its switches
    elapsed : float              flight time [s] (the turn not included)
    time : float                 the team's clock at the end [s]
    start : (x, y, heading)      the flight's start pose [m, m, deg]
    end : (x, y, heading)        the pose at its end
    """

    robot: int
    by: str
    bumped: bool
    left: bool
    right: bool
    elapsed: float
    time: float
    start: tuple[float, float, float]
    end: tuple[float, float, float]


class KinematicTeam:
    """K kinematic twins in one room on one clock (docs/model.md §24).

    Parameters
    ----------
    env : Environment
    n_robots : int
    interact : {"off", "bump"}
        ``"off"``: the robots pass through each other; ``"bump"``: robot-robot contact is a
        bump (module docstring).
    noise : NoiseModel, optional   turn noise of every robot (default exact)
    rngs : sequence of numpy Generators, optional
        One per robot: robot i draws its turn errors from ``rngs[i]`` only (required when the
        noise draws).
    speed : float        drive speed v [m/s]
    turn_speed : float   wheel speed of the in-place turns [m/s] (the twin's turn time)
    max_flight : float   a flight without a bump ends after this many metres (default: the
                         room's bounding-box diagonal)
    """

    def __init__(self, env: Environment, n_robots: int, *, interact: str = "bump",
                 noise: NoiseModel | None = None, rngs=None, speed: float = 0.2,
                 turn_speed: float = 0.1, max_flight: float | None = None) -> None:
        if interact not in INTERACT:
            raise UserError(f"interact must be off or bump, got {interact!r}.")
        k = int(n_robots)
        if k < 1:
            raise UserError(f"a team needs at least one robot, got {n_robots}.")
        rngs = [None] * k if rngs is None else list(rngs)
        if len(rngs) != k:
            raise UserError(f"give one rng per robot: {k} robots, {len(rngs)} rngs.")
        self.env, self.n, self.interact = env, k, interact
        self.robots = [KinematicRobot(env, noise, rng, turn_speed=turn_speed) for rng in rngs]
        self.radius = float(self.robots[0].spec.radius)
        self.speed = float(speed)
        if not (math.isfinite(self.speed) and self.speed > 0):
            raise UserError(f"speed must be a positive number of m/s, got {speed}.")
        x0, y0, x1, y1 = env.bounds
        self.max_flight = float(max_flight) if max_flight else math.hypot(x1 - x0, y1 - y0)
        self.time = 0.0
        self._state = np.full(k, _STILL)
        self._pos = np.array([r.true_pose()[:2] for r in self.robots], dtype=float)
        self._start = self._pos.copy()            # flight start [m]
        self._u = np.zeros((k, 2))                # flight direction
        self._go = np.zeros(k)                    # time the flight starts (turn over) [s]
        self._dur = np.zeros(k)                   # planned flight time [s]
        self._end: list[tuple] = [None] * k       # planned end (x, y) [m]
        self._event: list[BumpEvent | None] = [None] * k
        self._by = [""] * k
        self._pose0: list[tuple] = [None] * k

    # ------------------------------------------------------------------ set-up and commands
    def place(self, i: int, x: float, y: float, heading_deg: float) -> None:
        """Put robot i at (x [m], y [m]) facing ``heading_deg``, still."""
        self.robots[i].place(x, y, heading_deg)
        self._state[i] = _STILL
        self._pos[i] = self.robots[i].true_pose()[:2]

    def launch(self, i: int, angle_deg: float | None = None) -> TeamFlight:
        """Robot i (still) turns CCW by ``angle_deg`` (with its noise; None: no turn), then
        drives; returns the flight it would make against the walls alone.
        """
        if self._state[i] != _STILL:
            raise UserError(f"robot {i} is still moving; it can only start at a stop.")
        bot = self.robots[i]
        turn = 0.0
        if angle_deg is not None:
            spin = wrap180(float(angle_deg))          # the shorter way (docs/model.md §21)
            bot.turn(spin)
            turn = bot.spec.turn_time(spin, bot.turn_speed)
        start = bot.true_pose()
        ev = bot.drive_until_bump(self.speed, self.max_flight / self.speed)
        end = bot.true_pose()
        self._pose0[i] = start
        self._start[i] = start[:2]
        self._u[i] = unit(np.array([start[2]]))[0]
        self._go[i] = self.time + turn
        self._dur[i] = ev.elapsed
        self._end[i] = end[:2]
        self._event[i] = ev
        self._by[i] = "wall" if ev.bumped else "cap"
        self._state[i] = _TURNING if turn > 0 else _FLYING
        return TeamFlight(start, end[:2], ev)

    def clock_stop(self, i: int, xy) -> None:
        """End robot i's planned flight at ``xy`` [m] on it, by the clock (no bump)."""
        x, y = (float(v) for v in xy)
        sx, sy, _ = self._pose0[i]
        self._end[i] = (x, y)
        self._dur[i] = math.hypot(x - sx, y - sy) / self.speed
        self._by[i] = "clock"

    # ------------------------------------------------------------------ state
    def moving(self) -> np.ndarray:
        """(K,) bool: turning or flying."""
        return self._state != _STILL

    def poses(self) -> list[tuple[float, float, float]]:
        """Every robot's (x [m], y [m], heading [deg]) at the team's clock."""
        return [(float(p[0]), float(p[1]), r.true_pose()[2]) for p, r in
                zip(self._pos, self.robots)]

    def _positions(self, t: float) -> np.ndarray:
        fly = self._state == _FLYING
        pos = self._pos.copy()
        if fly.any():
            d = self.speed * np.clip(t - self._go[fly], 0.0, self._dur[fly])
            pos[fly] = self._start[fly] + d[:, None] * self._u[fly]
        return pos

    def _velocities(self) -> np.ndarray:
        return np.where((self._state == _FLYING)[:, None], self.speed * self._u, 0.0)

    # ------------------------------------------------------------------ contacts
    def _first_contact(self) -> tuple[float, list[tuple[int, int]]]:
        """(time from now [s], the pairs in contact then) of the first robot-robot contact
        with the current motions; (inf, []) when none.
        """
        p, w = self._pos, self._velocities()
        i, j = np.triu_indices(self.n, 1)
        d = p[j] - p[i]
        dw = w[j] - w[i]
        a = (dw * dw).sum(1)
        b = 2.0 * (d * dw).sum(1)
        two_r = 2.0 * self.radius
        c = (d * d).sum(1) - two_r * two_r
        approach = b < 0
        touching = approach & (c <= (two_r + BUMP_RANGE) ** 2 - two_r * two_r)
        disc = b * b - 4.0 * a * c
        ok = approach & (disc >= 0) & (a > 0)
        s = np.full(len(i), np.inf)
        q = 0.5 * (-b[ok] + np.sqrt(np.maximum(disc[ok], 0.0)))   # > 0: the stable root c/q
        s[ok] = np.maximum(c[ok], 0.0) / q
        s[touching] = 0.0
        if not len(s) or not np.isfinite(s.min()):
            return math.inf, []
        first = s.min()
        return float(first), [(int(i[k]), int(j[k])) for k in np.flatnonzero(s == first)]

    def _robot_bearings(self, i: int) -> list[float]:
        """Bearings [deg] of the robots touching robot i's front half."""
        if self.interact == "off":
            return []
        x, y, deg = self.robots[i].true_pose()
        ux, uy = unit(np.array([deg]))[0]
        out = []
        for j in range(self.n):
            wx, wy = self._pos[j] - (x, y)
            if j == i or math.hypot(wx, wy) > 2.0 * self.radius + BUMP_RANGE:
                continue
            beta = math.degrees(math.atan2(ux * wy - uy * wx, ux * wx + uy * wy))
            if abs(beta) < 90.0:
                out.append(beta)
        return out

    def _finish(self, i: int, by: str, xy) -> FlightEnd:
        """End robot i's flight at ``xy`` on it. The body is still at the planned end (the
        twin's own pose after ``drive_until_bump``): a clock stop puts it at ``xy`` as
        Bounce-v0 does, a robot contact backs it up along its flight by the twin's motion.
        """
        bot = self.robots[i]
        start = self._pose0[i]
        if by == "clock":
            bot.place(float(xy[0]), float(xy[1]), start[2])
        elif by == "robot":
            back = math.hypot(*(np.subtract(bot.true_pose()[:2], xy)))
            if back > 0:
                bot.drive(-self.speed)
                bot.wait(back / self.speed)
                bot.stop()
            xy = bot.true_pose()[:2]
        self._pos[i] = xy
        self._state[i] = _STILL
        if by == "clock":
            bumped = left = right = False
        elif by in ("wall", "cap"):
            ev = self._event[i]
            rl, rr = switches(self._robot_bearings(i))
            left, right = ev.left or rl, ev.right or rr
            bumped = ev.bumped or rl or rr
        else:
            wl, wr = bot.bumper()
            rl, rr = switches(self._robot_bearings(i))
            left, right, bumped = wl or rl, wr or rr, True
        elapsed = math.hypot(xy[0] - start[0], xy[1] - start[1]) / self.speed
        if by in ("wall", "cap"):
            elapsed = self._event[i].elapsed
        return FlightEnd(i, by, bool(bumped), bool(left), bool(right), float(elapsed),
                         self.time, start, bot.true_pose())

    # ------------------------------------------------------------------ the clock
    def advance(self) -> list[FlightEnd]:
        """Run the team until one or more flights end; those ends, in robot order ([] when no
        robot is moving).
        """
        while self.moving().any():
            turning = self._state == _TURNING
            flying = self._state == _FLYING
            t_go = self._go[turning].min() if turning.any() else math.inf
            t_end = (self._go + self._dur)[flying].min() if flying.any() else math.inf
            t_hit, pairs = (self._first_contact() if self.interact == "bump"
                            else (math.inf, []))
            t = min(t_go, t_end, self.time + t_hit)
            self._pos = self._positions(t)
            self.time = t
            ends: dict[int, FlightEnd] = {}
            for i in np.flatnonzero(flying & (self._go + self._dur <= t)):
                ends[int(i)] = None
            if self.time + t_hit <= t:
                vel = self._velocities()
                for i, j in pairs:
                    d = self._pos[j] - self._pos[i]
                    for a, sign in ((i, 1.0), (j, -1.0)):
                        if a not in ends and sign * (vel[a] @ d) > 0:   # approaches the other
                            ends[a] = "robot"
            for i in sorted(ends):
                if ends[i] == "robot":
                    done = self.speed * (t - self._go[i]) - CONTACT_GAP
                    xy = self._start[i] + max(done, 0.0) * self._u[i]
                    ends[i] = self._finish(i, "robot", xy)
                else:
                    ends[i] = self._finish(i, self._by[i], self._end[i])
            self._state[turning & (self._go <= t)] = _FLYING
            if ends:
                return [ends[i] for i in sorted(ends)]
        return []
