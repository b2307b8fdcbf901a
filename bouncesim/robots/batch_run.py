"""What the physics batches share (:class:`bouncesim.robots.pybullet.batch.PyBulletBatch`,
:class:`bouncesim.robots.mujoco.batch.MuJoCoBatch`): many robots in one world, each running
its own program (a generator that yields how many physics steps to wait), scheduled on one
clock, and their step-sampled visit histograms (docs/model.md §22) as a :class:`BatchRun`.

A batch class that inherits :class:`ProgramBatch` writes ``_program`` (one robot's §8 steps
under the policy) and calls :meth:`ProgramBatch._start` and :meth:`ProgramBatch._schedule`
from its ``run``; the engine supplies how to advance the world by n physics steps and what to
do with a robot whose program has ended.
"""

from __future__ import annotations

import heapq
import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from envs import UserError
from planners.metrics import tv_distance
from planners.plan import PolicyMix

from .noise import NoNoise, noise_for_mix

__all__ = ["BatchRun", "ProgramBatch"]


@dataclass(frozen=True)
class BatchRun:
    """Per-robot step-sampled visit histograms of a physics batch's run (§22).

    Attributes
    ----------
    counts : (n, P) int array   steps counted per robot and free position cell
    dropped : (n,) int array    steps counted in no free cell, per robot
    bumps : (n,) int array      bump steps per robot
    steps : int                 counted steps per robot (after the burn-in)
    physics_steps : int         world steps taken (5 ms each by default)
    sim_time : float            simulated time of the world steps [s] (each robot's own
                                clock ran on by its ``skipped`` steps besides)
    wall_s, cpu_s : float       wall-clock and process CPU time of the run [s]
    skipped : (n,) int array    physics steps each robot fast-forwarded (Appendix C; 0 without)
    poses : (n, 3) array        each robot's (x [m], y [m], heading [deg]) at its end
    meetings : (n,) int array   counted bump steps whose bumper another robot pressed (a team
                                whose robots bump each other; 0 otherwise)
    turns : list, optional      with ``record=True``, per robot, one
                                (x [m], y [m], heading [deg], turn [deg], heading after
                                [deg]) per bump: the contact pose, the executed turn (noise
                                included) and the heading once the turn has settled
    """

    counts: np.ndarray
    dropped: np.ndarray
    bumps: np.ndarray
    steps: int
    physics_steps: int
    sim_time: float
    wall_s: float
    cpu_s: float
    turns: list | None = None
    skipped: np.ndarray | None = None
    poses: np.ndarray | None = None
    meetings: np.ndarray | None = None

    @property
    def total(self) -> int:
        """All counted robot-steps, dropped ones included."""
        return int(self.counts.sum() + self.dropped.sum())

    @property
    def pooled(self) -> np.ndarray:
        """(P,) counts summed over the robots."""
        return self.counts.sum(axis=0)

    def halves(self) -> tuple[np.ndarray, np.ndarray]:
        """(P,) counts of the even- and of the odd-numbered robots: two independent halves."""
        return self.counts[0::2].sum(axis=0), self.counts[1::2].sum(axis=0)

    def floor(self) -> float:
        """TV between the two halves (docs/model.md §22's noise floor at half the budget)."""
        a, b = self.halves()
        return tv_distance(a, b) if a.sum() > 0 and b.sum() > 0 else math.nan



class ProgramBatch:
    """The scheduling and the bookkeeping of a physics batch (module docstring). A subclass
    has ``n`` (robots), ``cells``, ``noise`` (None: the policy's) and ``_steps`` (physics
    steps taken since the world was built).
    """

    def _start(self, policy, steps: int, epoch: int, burn_in: int, record: bool):
        """Check a run's arguments; (angles, α, noise, out) where ``out`` collects counts,
        drops, bumps, turns (``record``), skipped steps, final poses and counted points.
        """
        if not isinstance(policy, PolicyMix):
            policy = PolicyMix((float(policy),), (1.0,))
        angles = np.asarray(policy.angles, dtype=float)
        alpha = np.asarray(policy.alpha, dtype=float)
        alpha = alpha / alpha.sum()
        for a in angles:
            self.cells.angle_steps(a)
        noise = self.noise if self.noise is not None else noise_for_mix(policy,
                                                                         self.cells.delta_deg)
        noise = noise if noise is not None else NoNoise()
        if int(epoch) < 1 or int(steps) < 0 or int(burn_in) < 0:
            raise UserError("epoch must be >= 1 and steps, burn_in >= 0.")
        n, P = self.n, self.cells.P
        out = {"counts": np.zeros((n, P), dtype=np.int64),
               "dropped": np.zeros(n, dtype=np.int64),
               "bumps": np.zeros(n, dtype=np.int64),
               "turns": [[] for _ in range(n)] if record else None,
               "skipped": np.zeros(n, dtype=np.int64),
               "poses": np.zeros((n, 3)),
               "meetings": np.zeros(n, dtype=np.int64),
               "points": [[] for _ in range(n)]}
        return angles, alpha, noise, out

    def _schedule(self, programs: list, advance: Callable[[int], None],
                  done: Callable[[int], None], *, before: Callable[[], None] | None = None,
                  progress=None, points: list | None = None, total: int = 1) -> None:
        """Run every robot's program on one clock: resume each robot when the steps it waits
        for have passed (ties in robot order), ``advance(n)`` the world between, ``done(i)``
        when robot i's program ends; ``before()`` once all have started; ``progress`` gets
        the fraction of ``total`` that the lists in ``points`` hold, every 2 s.
        """
        heap: list[tuple[int, int]] = []

        def resume(i: int) -> None:
            for n in programs[i]:
                heapq.heappush(heap, (self._steps + n, i))
                return
            done(i)

        for i in range(len(programs)):
            resume(i)
        if before is not None:
            before()
        last = time.perf_counter()
        while heap:
            wake = heap[0][0]
            if wake > self._steps:
                advance(wake - self._steps)
            self._steps = wake
            while heap and heap[0][0] == wake:
                resume(heapq.heappop(heap)[1])
            if progress is not None and time.perf_counter() - last > 2.0:
                last = time.perf_counter()
                progress(sum(len(pts) for pts in points or ()) / max(1, total))

    def _result(self, out: dict, steps: int, physics_steps: int, time_step: float,
                t_wall: float, t_cpu: float) -> BatchRun:
        """The :class:`BatchRun` of a finished run (the counted points binned into cells)."""
        P = self.cells.P
        for i, pts in enumerate(out["points"]):
            if pts:
                c = self.cells.cell_of_body(pts)
                out["counts"][i] = np.bincount(c[c >= 0], minlength=P)
                out["dropped"][i] = int(np.count_nonzero(c < 0))
        return BatchRun(counts=out["counts"], dropped=out["dropped"], bumps=out["bumps"],
                        steps=int(steps), physics_steps=int(physics_steps),
                        sim_time=physics_steps * time_step,
                        wall_s=time.perf_counter() - t_wall,
                        cpu_s=time.process_time() - t_cpu, turns=out["turns"],
                        skipped=out["skipped"], poses=out["poses"],
                        meetings=out["meetings"])
