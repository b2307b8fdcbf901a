"""Many PyBullet Create 2 bodies in one world, stepped in lockstep (docs/model.md §8, §21).

:class:`PyBulletBatch` runs a policy mix on ``n_robots`` independent Create 2 bodies that
share one ``DIRECT`` PyBullet world and its walls. By default (``interact="off"``) the robots
ignore each other (their links are in a collision group that only meets the walls and the
floor), so each one moves exactly as it would alone: what is shared is the cost of every
``stepSimulation`` call and of the static walls. With ``interact="bump"`` they are a team
(docs/model.md §24): their disks collide, another robot's disk in the bumper arc presses the
bumper as a wall does, the robots start in distinct position cells, every physics step is
simulated (no fast-forward: a steady drive may meet a robot) and a robot whose run has ended
stays where it stopped, an obstacle, until the others are done.

Each robot runs the same program as :func:`bouncesim.runs.execute.execute` on a
:class:`~bouncesim.robots.pybullet.PyBulletRobot` (a step drives h by the clock, polling the
bumper every 15 ms sensor period; a bump step turns in place by the epoch's angle by clock),
written as a small generator that yields how many physics steps it waits. A scheduler steps
the world to the next wake-up and resumes the robots due then. Every robot has its own
``numpy.random.Generator`` and draws from it in the order the single-robot path does (start
configuration, epoch angles, turn noise), and keeps its own drift-free clock the way
:meth:`PyBulletRobot.wait` does, so robot i with generator g follows the trajectory of a
single ``PyBulletRobot`` run by ``execute`` with the same g (the test suite checks the bump
points and turns against that path).

By default (``fast_forward=FastForward()``, docs/model.md Appendix C) a robot skips the physics
steps of steady motion: straight drives clear of the walls and steady slides along one wall side
are advanced in one move (the steady middle of turns in place too with
``FastForward(turns=True)``, which drops a spinning body's push-off from its wall)
(:class:`~bouncesim.robots.pybullet.fastforward.Coaster`), and the robot's own step clock
runs on by the steps skipped. Robots ignore each other, so their clocks need not agree; a
robot whose program has ended leaves the world.

Examples
--------
>>> import envs
>>> with PyBulletBatch(envs.load("lab"), 2, np.random.default_rng(0)) as batch:
...     res = batch.run(90.0, 3)
>>> res.counts.shape, res.steps, res.total
((2, 48), 3, 6)
"""

from __future__ import annotations

import math
import time

import numpy as np

from envs import Environment, UserError
from envs.motion import step as step_rule
from planners.cells import CellSpace
from planners.measures import wrap180

from ..batch_run import BatchRun, ProgramBatch
from ..noise import NoiseModel
from .bumper import read_bumper
from .fastforward import DEFAULT_FAST_FORWARD, Coaster, FastForward
from .robot import SETTLE_STEPS, PyBulletRobot

__all__ = ["PyBulletBatch", "BatchRun", "BATCH_PHYSICS", "ROBOT_GROUP", "ROBOT_MASK",
           "INTERACT"]

BATCH_PHYSICS = {"contact_threshold": 0.002}
"""The batch's physics defaults (each can be overridden): a 2 mm contact breaking threshold
and no speculative contacts in the solver (Bullet's defaults: 20 mm, all contacts), about
1.7x fewer CPU seconds per physics step. Turns stay at the single robot's 0.1 m/s: at 0.3 m/s
a batch ran 2.5x faster but its turns were off by up to 2.6° (mean 0.8°)."""

ROBOT_GROUP = 4
"""Collision filter group of every robot link (Bullet's default groups are 1 and 2)."""
ROBOT_MASK = 1 | 2
"""Robots collide with the default (1) and static (2) groups only: walls and floor, never
another robot."""
TEAM_MASK = ROBOT_MASK | ROBOT_GROUP
"""``interact="bump"``: a robot's base also collides with the other robots' bases (their wheels
keep ``ROBOT_MASK``, so a wheel meets no robot)."""
INTERACT = ("off", "bump")


class PyBulletBatch(ProgramBatch):
    """``n_robots`` Create 2 bodies in one PyBullet world, running a policy mix in lockstep.

    Parameters
    ----------
    env : Environment or str
    n_robots : int
    rng : numpy.random.Generator or int
        Parent of every robot's own generator (``rng.spawn(n_robots)``), unless ``rngs``.
    cells : CellSpace, optional
    noise : NoiseModel, optional
        Rotation noise (default: the mix's §16 model at :meth:`run`, else exact).
    speed : float
        Drive speed [m/s].
    rngs : sequence of numpy.random.Generator, optional
        One generator per robot (to reproduce single-robot runs seed for seed).
    starts : sequence of int, optional
        Start configurations z (default: each robot draws one uniformly from its generator,
        as ``execute`` does).
    fast_forward : FastForward or None
        Skip the physics steps of steady drives far from the walls and of steady slides
        (docs/model.md Appendix C; default ``FastForward()``, which simulates turns); None
        simulates every physics step.
    interact : {"off", "bump"}
        The robots pass through each other (default), or bump each other as a team (module
        docstring; every physics step is then simulated, whatever ``fast_forward`` says).
    **robot_kw
        Physics settings of :class:`PyBulletRobot` (``time_step``, ``turn_speed``,
        ``solver``, ``solver_iterations``, ``wheel_torque``, ``bumper_arc_deg``,
        ``clearance``, ``contact_threshold``); defaults :data:`BATCH_PHYSICS`, else the
        robot's. Turns are by clock without back-off.
    """

    def __init__(self, env: Environment | str, n_robots: int, rng=None, *,
                 cells: CellSpace | None = None, noise: NoiseModel | None = None,
                 speed: float = 0.3, rngs=None, starts=None,
                 fast_forward: FastForward | None = DEFAULT_FAST_FORWARD,
                 interact: str = "off", **robot_kw) -> None:
        self.n = int(n_robots)
        if self.n < 1:
            raise UserError(f"a batch needs at least one robot, got {n_robots}.")
        if interact not in INTERACT:
            raise UserError(f"interact must be off or bump, got {interact!r}.")
        self.interact = interact
        if interact == "bump":
            fast_forward = None
        for k in ("turn", "back_off", "gui", "record", "start"):
            if k in robot_kw:
                raise UserError(f"PyBulletBatch does not take {k}= (turns by clock, no "
                                f"back-off, headless).")
        self.host = PyBulletRobot(env, **{**BATCH_PHYSICS, **robot_kw})
        self.env = self.host.env
        self.cells = cells if cells is not None else CellSpace(self.env)
        if rngs is None:
            if rng is None:
                raise UserError("PyBulletBatch needs an rng (a numpy Generator or an int seed).")
            parent = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
            rngs = parent.spawn(self.n)
        self.rngs = list(rngs)
        if len(self.rngs) != self.n:
            raise UserError(f"rngs must hold {self.n} generators, got {len(self.rngs)}.")
        self.starts = None if starts is None else [int(z) for z in starts]
        self.noise = noise
        self.speed = float(speed)
        if not 0 < self.speed <= self.host.spec.max_wheel_speed:
            raise UserError(f"speed must lie in (0, {self.host.spec.max_wheel_speed:g}] m/s, "
                            f"got {self.speed:g}.")
        p, kw = self.host._p, self.host._kw
        if self.interact == "bump" and self.starts is None and self.n > self.cells.P:
            raise UserError(f"a team needs 1 to {self.cells.P} robots in {self.env.name} (one "
                            f"per cell at the start), got {self.n}.")
        self.bodies = [self.host._robot] + [self.host._create_body() for _ in range(self.n - 1)]
        for b in self.bodies:
            self._filter(b)
        self._steps = 0
        self.fast_forward = fast_forward
        self._coaster = None if fast_forward is None else Coaster(
            p, kw, self.env, self.host.body_radius, self.host._wheel_r,
            self.host.spec.wheel_base, fast_forward,
            0.02 if self.host.contact_threshold is None else self.host.contact_threshold)

    # ------------------------------------------------------------------ one body
    def _wheels(self, body: int, v_left: float, v_right: float) -> None:
        h = self.host
        R = h._wheel_r
        h._p.setJointMotorControlArray(body, [0, 1], h._p.VELOCITY_CONTROL,
                                       targetVelocities=[v_left / R, v_right / R],
                                       forces=[h.wheel_torque, h.wheel_torque], **h._kw)

    def _pose(self, body: int) -> tuple[float, float, float]:
        p, kw = self.host._p, self.host._kw
        (x, y, _), orn = p.getBasePositionAndOrientation(body, **kw)
        return x, y, math.degrees(p.getEulerFromQuaternion(orn)[2])

    def _place(self, body: int, x: float, y: float, heading_deg: float) -> None:
        h = self.host
        p, kw = h._p, h._kw
        orn = p.getQuaternionFromEuler([0, 0, math.radians(heading_deg)])
        p.resetBasePositionAndOrientation(body, [x, y, h._wheel_r], orn, **kw)
        p.resetBaseVelocity(body, [0, 0, 0], [0, 0, 0], **kw)
        for j in (0, 1):
            p.resetJointState(body, j, p.getJointState(body, j, **kw)[0], 0.0, **kw)
        self._wheels(body, 0.0, 0.0)

    def _filter(self, body: int) -> None:
        """Put ``body``'s links in the robots' collision group (module docstring)."""
        for link in (-1, 0, 1):
            mask = TEAM_MASK if self.interact == "bump" and link == -1 else ROBOT_MASK
            self.host._p.setCollisionFilterGroupMask(body, link, ROBOT_GROUP, mask,
                                                     **self.host._kw)

    def _new_body(self) -> int:
        body = self.host._create_body()
        self._filter(body)
        return body

    def _retire(self, i: int, out: dict) -> None:
        """Robot i's program has ended: keep its pose and, unless the robots bump each other
        (then it stays, an obstacle), take its body out of the world, so that it costs nothing
        while the others finish (:meth:`run` builds it anew).
        """
        out["poses"][i] = self._pose(self.bodies[i])
        if self.interact == "bump":
            return
        self.host._p.removeBody(self.bodies[i], **self.host._kw)
        self.bodies[i] = -1

    def _start_of(self, i: int, rng, taken: set) -> int:
        """Robot i's start configuration: given, or drawn uniformly from its generator, again
        while (``interact="bump"``) its cell holds an earlier robot's start.
        """
        if self.starts is not None:
            return self.starts[i]
        while True:
            z = int(rng.integers(0, self.cells.N))
            p = int(self.cells.pk(z)[0])
            if self.interact == "off" or p not in taken:
                taken.add(p)
                return z

    # ------------------------------------------------------------------ the program
    def _program(self, i: int, angles, alpha, steps: int, epoch: int, burn_in: int,
                 noise: NoiseModel, out: dict):
        """Robot i's run as execute's mix loop; yields physics steps to wait.

        The robot keeps its own step clock: the world's steps plus the steps it has
        fast-forwarded (Appendix C). Robots ignore each other, so their clocks need not agree.
        """
        host, cells, rng, body = self.host, self.cells, self.rngs[i], self.bodies[i]
        dt, period, speed, h = host.time_step, host.spec.sensor_period, self.speed, cells.h
        coast, ff = self._coaster, self.fast_forward
        skipped = out["skipped"]
        off = 0                               # steps fast-forwarded so far
        track: list = []                      # the last polls' poses (slides, Appendix C)
        t_goal = self._steps * dt             # the robot's clock target (PyBulletRobot.wait)

        def wait_steps(duration: float) -> int:
            nonlocal t_goal
            t_goal += duration
            return int(round(t_goal / dt)) - (self._steps + off)

        def jump(elapsed: float, T: float, t_max: float, move) -> int:
            """Skip the polls of the rest of this drive that end within ``t_max`` [s] and
            move the body over them with ``move(seconds)``; the steps skipped.
            """
            nonlocal t_goal, off
            goal, n_tot = t_goal, 0
            while elapsed < T:
                g = goal + min(period, max(T - elapsed, 1e-6))
                n = int(round(g / dt)) - (self._steps + off + n_tot)
                if (n_tot + n) * dt > t_max:
                    break
                goal, n_tot = g, n_tot + n
                elapsed = (self._steps + off + n_tot) * dt - t0
            if n_tot > 0:
                move(n_tot * dt)
                t_goal, off = goal, off + n_tot
                skipped[i] += n_tot
            return n_tot

        def coast_drive(elapsed: float, T: float) -> int:
            """Jump the polls of a steady drive that keep the margin, or of a steady slide
            along one wall (Appendix C): 1 if it did, 0 if not now, -1 if not before the step's end.
            """
            x, y, yaw = self._pose(body)
            gap, side = coast.near(x, y)
            if gap >= coast.clearance and coast.steady(body, speed, 0.0):
                th = math.radians(yaw)
                room = coast.free_travel(x, y, math.cos(th), math.sin(th))
                track.clear()
                n = jump(elapsed, T, room / speed, lambda t: coast.advance(body, t, speed, 0.0))
                return 1 if n > 0 else -1
            if not ff.slides:
                return 0
            now = (self._steps + off) * dt
            if track and track[-1][0] >= now:
                track.pop()                   # the same instant (a new step at once)
            track.append((now, x, y, math.radians(yaw), side))
            del track[:-3]
            slide = coast.slide(track, speed, 90.0 - host.bumper_arc_deg)
            if slide is None:
                return 0
            u, ux, uy, w, t_max = slide
            n = jump(elapsed, T, t_max,
                     lambda t: coast.advance(body, t, u, w, along=(ux, uy)))
            if n > 0:    # the measured polls, carried along: the slide goes on measured
                t = n * dt
                track[:] = [(tk + t, xk + u * t * ux, yk + u * t * uy, hk + w * t, k)
                            for tk, xk, yk, hk, k in track]
            return 1 if n > 0 else 0

        self._place(body, *cells.pose(self._start_of(i, rng, out.setdefault("taken", set()))))
        points, wall_set, arc = out["points"][i], host._wall_set, host.bumper_arc_deg
        p, kw = host._p, host._kw
        others = frozenset(b for b in self.bodies if b != body)
        if self.interact == "bump":
            wall_set = wall_set | others         # another robot presses the bumper too
        angle = float(angles[0])
        T = h / speed
        for s in range(burn_in + steps):
            if s % epoch == 0:
                angle = (float(angles[rng.choice(len(angles), p=alpha)]) if len(angles) > 1
                         else float(angles[0]))
            pose0 = self._pose(body)
            t0 = (self._steps + off) * dt
            self._wheels(body, speed, speed)                      # drive_for(speed, T)
            coasting = coast is not None
            while True:
                bumped = any(read_bumper(p, body, wall_set, arc, kw))
                elapsed = (self._steps + off) * dt - t0
                if bumped or elapsed >= T:
                    break
                if coasting:
                    jumped = coast_drive(elapsed, T)
                    coasting = jumped >= 0            # no room: simulate to the step's end
                    if jumped > 0:
                        continue
                n = wait_steps(min(period, max(T - elapsed, 1e-6)))
                if n > 0:
                    yield n
            self._wheels(body, 0.0, 0.0)
            _, bump_step = step_rule(speed * elapsed if bumped else math.inf, h)
            pose = self._pose(body) if bump_step else pose0
            if s >= burn_in:
                points.append(pose[:2])              # its cell: at the end, all at once
                out["bumps"][i] += bump_step
                if bump_step and self.interact == "bump":
                    out["meetings"][i] += any(read_bumper(p, body, others, arc, kw))
            if not bump_step:
                continue
            track.clear()
            actual = float(noise.sample(rng, wrap180(angle)))       # turn, the shorter way
            if out["turns"] is not None:
                out["turns"][i].append(pose + (actual,))
            if actual == 0:
                if out["turns"] is not None:
                    out["turns"][i][-1] += (pose[2],)
                continue
            v = math.copysign(host.turn_speed, actual)
            n_turn = round(host.spec.turn_time(actual, host.turn_speed) / dt)
            self._wheels(body, -v, v)
            left = n_turn                                         # turn steps to go
            if coast is not None and ff.turns:
                rate = 2 * v / host.spec.wheel_base
                while left > ff.turn_steps:
                    n = wait_steps(ff.turn_steps * dt)            # spin up in physics
                    left -= ff.turn_steps
                    if n > 0:
                        yield n
                    if coast.steady(body, 0.0, rate):                 # the steady spin (Appendix C)
                        n = wait_steps(left * dt)
                        left = 0
                        if n > 0:
                            coast.advance(body, n * dt, 0.0, rate)
                            off += n
                            skipped[i] += n
            n = wait_steps(left * dt)
            if n > 0:
                yield n
            self._wheels(body, 0.0, 0.0)
            n = wait_steps(SETTLE_STEPS * dt)
            if n > 0:
                yield n
            if out["turns"] is not None:
                out["turns"][i][-1] += (self._pose(body)[2],)

    def run(self, policy, steps: int, *, epoch: int = 1000, burn_in: int = 0,
            progress=None, record: bool = False) -> BatchRun:
        """Run ``burn_in + steps`` steps on every robot; count the last ``steps`` (§8).

        Each robot's body leaves the world when its run ends (``BatchRun.poses`` keeps
        where it stopped); the next call builds the bodies anew.

        Parameters
        ----------
        policy : float or PolicyMix   one bouncing angle [deg] or a mix (epochs, §21)
        steps : int                   counted steps per robot
        epoch : int                   steps per epoch of a mix
        burn_in : int                 steps per robot run first and not counted
        progress : callable, optional called with the fraction done, now and then
        record : bool                 keep every bump's pose and turn (``BatchRun.turns``)

        Returns
        -------
        BatchRun
        """
        angles, alpha, noise, out = self._start(policy, steps, epoch, burn_in, record)
        p, kw = self.host._p, self.host._kw
        stepsim = p.stepSimulation
        t_wall, t_cpu = time.perf_counter(), time.process_time()
        start_steps = self._steps
        self.bodies = [b if b >= 0 else self._new_body() for b in self.bodies]
        self.host._robot = self.bodies[0]
        programs = [self._program(i, angles, alpha, int(steps), int(epoch), int(burn_in),
                                  noise, out) for i in range(self.n)]

        def advance(n: int) -> None:
            for _ in range(n):
                stepsim(**kw)

        self._schedule(programs, advance,
                       lambda i: self._retire(i, out),   # done: it stops costing world steps
                       before=lambda: p.performCollisionDetection(**kw), progress=progress,
                       points=out["points"], total=self.n * (int(steps) + int(burn_in)))
        return self._result(out, steps, self._steps - start_steps, self.host.time_step,
                            t_wall, t_cpu)

    def close(self) -> None:
        """Disconnect the world (idempotent)."""
        self.host._disconnect()           # (no stop: retired bodies are gone)

    def __enter__(self) -> PyBulletBatch:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
