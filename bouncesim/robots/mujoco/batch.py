"""Many MuJoCo Create 2 bodies in one world, stepped in lockstep (docs/model.md §8, §21, §22).

:class:`MuJoCoBatch` runs a policy mix on ``n_robots`` independent bodies that share one MuJoCo
model and its walls. The robots ignore each other (collision filtering, :mod:`.world`), so
each moves as it would alone; what is shared is the cost of every ``mj_step`` call.

Each robot runs the program of :func:`bouncesim.runs.execute.execute` on a
:class:`~bouncesim.robots.mujoco.MuJoCoRobot` (a step drives h by the clock, polling the bumper
every 15 ms; a bump step turns in place by the epoch's angle by clock), written as a generator
that yields the physics steps it waits, as :class:`~bouncesim.robots.pybullet.batch.PyBulletBatch`
does (without its fast-forward: every physics step is simulated). Every robot has its own
generator and draws in the single-robot order (start configuration, epoch angles, turn noise).

Examples
--------
>>> import envs
>>> with MuJoCoBatch(envs.load("lab"), 2, np.random.default_rng(0)) as batch:
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
from .robot import SETTLE_STEPS, Bodies, MuJoCoRobot, bumper_of, place_body, pose_of, wall_bearings
from .world import world_xml

__all__ = ["MuJoCoBatch"]


class MuJoCoBatch(ProgramBatch):
    """``n_robots`` MuJoCo Create 2 bodies in one world, running a policy mix in lockstep.

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
        One generator per robot.
    starts : sequence of int, optional
        Start configurations z (default: drawn uniformly from each robot's generator).
    **robot_kw
        Physics settings of :class:`MuJoCoRobot` (``time_step``, ``turn_speed``,
        ``wheel_torque``, ``wheel_gain``, ``bumper_arc_deg``, ``clearance``,
        ``solver_iterations``, ``cone``).
    """

    def __init__(self, env: Environment | str, n_robots: int, rng=None, *,
                 cells: CellSpace | None = None, noise: NoiseModel | None = None,
                 speed: float = 0.3, rngs=None, starts=None, **robot_kw) -> None:
        self.n = int(n_robots)
        if self.n < 1:
            raise UserError(f"a batch needs at least one robot, got {n_robots}.")
        for k in ("start", "spec"):
            if k in robot_kw:
                raise UserError(f"MuJoCoBatch does not take {k}=.")
        # the single robot checks the settings; its world is replaced by one with n bodies
        self.host = host = MuJoCoRobot(env, **robot_kw)
        self.env = host.env
        self.cells = cells if cells is not None else CellSpace(self.env)
        if rngs is None:
            if rng is None:
                raise UserError("MuJoCoBatch needs an rng (a numpy Generator or an int seed).")
            parent = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
            rngs = parent.spawn(self.n)
        self.rngs = list(rngs)
        if len(self.rngs) != self.n:
            raise UserError(f"rngs must hold {self.n} generators, got {len(self.rngs)}.")
        self.starts = None if starts is None else [int(z) for z in starts]
        self.noise = noise
        self.speed = float(speed)
        if not 0 < self.speed <= host.spec.max_wheel_speed:
            raise UserError(f"speed must lie in (0, {host.spec.max_wheel_speed:g}] m/s, "
                            f"got {self.speed:g}.")
        mj = self._mj = host._mj
        self.model = mj.MjModel.from_xml_string(world_xml(
            self.env, self.n, spec=host.spec, params=host.params, time_step=host.time_step,
            solver_iterations=host.solver_iterations, cone=host.cone))
        self.data = mj.MjData(self.model)
        self.bodies = Bodies(mj, self.model, self.n)
        self._steps = 0
        self._seen = -1                   # the world step of the cached contact bearings
        self._bearings: dict = {}

    # ------------------------------------------------------------------ one body
    def _wheels(self, i: int, v_left: float, v_right: float) -> None:
        R = self.host._wheel_r
        self.data.ctrl[self.bodies.act[i]] = (v_left / R, v_right / R)

    def _pose(self, i: int) -> tuple[float, float, float]:
        return pose_of(self.data, self.bodies.qadr[i])

    def _bumper(self, i: int) -> tuple[bool, bool]:
        if self._seen != self._steps:
            self._bearings = wall_bearings(self.data, self.bodies)
            self._seen = self._steps
        return bumper_of(self._bearings.get(i, ()), self.host.bumper_arc_deg)

    # ------------------------------------------------------------------ the program
    def _program(self, i: int, angles, alpha, steps: int, epoch: int, burn_in: int,
                 noise: NoiseModel, out: dict):
        """Robot i's run as execute's mix loop; yields physics steps to wait."""
        host, cells, rng = self.host, self.cells, self.rngs[i]
        dt, period, speed, h = host.time_step, host.spec.sensor_period, self.speed, cells.h
        t_goal = self._steps * dt             # the robot's clock target (MuJoCoRobot.wait)

        def wait_steps(duration: float) -> int:
            nonlocal t_goal
            t_goal += duration
            return int(round(t_goal / dt)) - self._steps

        z = self.starts[i] if self.starts is not None else int(rng.integers(0, cells.N))
        place_body(self._mj, self.model, self.data, self.bodies, i, *cells.pose(z),
                   host._wheel_r)
        self._seen = -1
        points = out["points"][i]
        angle = float(angles[0])
        T = h / speed
        for s in range(burn_in + steps):
            if s % epoch == 0:
                angle = (float(angles[rng.choice(len(angles), p=alpha)]) if len(angles) > 1
                         else float(angles[0]))
            pose0 = self._pose(i)
            t0 = self._steps * dt
            self._wheels(i, speed, speed)                     # drive_for(speed, T)
            while True:
                bumped = any(self._bumper(i))
                elapsed = self._steps * dt - t0
                if bumped or elapsed >= T:
                    break
                n = wait_steps(min(period, max(T - elapsed, 1e-6)))
                if n > 0:
                    yield n
            self._wheels(i, 0.0, 0.0)
            _, bump_step = step_rule(speed * elapsed if bumped else math.inf, h)
            pose = self._pose(i) if bump_step else pose0
            if s >= burn_in:
                points.append(pose[:2])
                out["bumps"][i] += bump_step
            if not bump_step:
                continue
            actual = float(noise.sample(rng, wrap180(angle)))      # turn, the shorter way
            if out["turns"] is not None:
                out["turns"][i].append(pose + (actual,))
            if actual == 0:
                if out["turns"] is not None:
                    out["turns"][i][-1] += (pose[2],)
                continue
            v = math.copysign(host.turn_speed, actual)
            self._wheels(i, -v, v)
            n = wait_steps(round(host.spec.turn_time(actual, host.turn_speed) / dt) * dt)
            if n > 0:
                yield n
            self._wheels(i, 0.0, 0.0)
            n = wait_steps(SETTLE_STEPS * dt)
            if n > 0:
                yield n
            if out["turns"] is not None:
                out["turns"][i][-1] += (self._pose(i)[2],)

    def run(self, policy, steps: int, *, epoch: int = 1000, burn_in: int = 0,
            progress=None, record: bool = False) -> BatchRun:
        """Run ``burn_in + steps`` steps on every robot; count the last ``steps`` (§8).

        Parameters and result as :meth:`PyBulletBatch.run
        <bouncesim.robots.pybullet.batch.PyBulletBatch.run>` (``skipped`` is all zeros: every
        physics step is simulated). A robot whose run has ended stands still, stopped, until
        the others finish.
        """
        angles, alpha, noise, out = self._start(policy, steps, epoch, burn_in, record)
        mj, model, data = self._mj, self.model, self.data
        t_wall, t_cpu = time.perf_counter(), time.process_time()
        start_steps = self._steps
        programs = [self._program(i, angles, alpha, int(steps), int(epoch), int(burn_in),
                                  noise, out) for i in range(self.n)]

        def done(i: int) -> None:
            out["poses"][i] = self._pose(i)

        self._schedule(programs, lambda n: mj.mj_step(model, data, nstep=n), done,
                       progress=progress, points=out["points"],
                       total=self.n * (int(steps) + int(burn_in)))
        return self._result(out, steps, self._steps - start_steps, self.host.time_step,
                            t_wall, t_cpu)

    def close(self) -> None:
        """Release the world (idempotent)."""
        self.host.close()

    def __enter__(self) -> MuJoCoBatch:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
