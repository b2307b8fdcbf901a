"""The runners of open-loop policies in the one run loop (:func:`bouncesim.runs.execute.execute`):
a plan's (docs/model.md §21, §13) and a policy mix's (§8, §21), and the helpers every runner
shares (start and goal poses, placing a simulated body, the goal rule's verdict in words).

A runner is a generator of moves (:mod:`bouncesim.runs.moves`) plus ``label``, ``finished``
and ``result``; see :func:`bouncesim.runs.execute.execute`.
"""

from __future__ import annotations

import math

import numpy as np

from envs import UserError
from envs.motion import STEP_TOL, step
from planners.cells import CellSpace
from planners.measures import flight_limit, goal_check, step_flights, wrap180
from planners.plan import Plan, PolicyMix

from ..robots.base import Robot
from .moves import BackOff, Drive, Fly, Note, Turn
from .results import Deviation, MixRun, PlanRun, SegmentDone
from .trace import Trace

__all__ = ["MixRunner", "PlanRunner", "check_speed", "place_if_simulated", "plan_result",
           "resolve_pose", "side_text", "time_up"]


def resolve_pose(spec, cells: CellSpace, what: str) -> tuple[int | None, tuple | None]:
    """(z or None, pose) of a configuration index or an (x, y, heading) pose."""
    if spec is None:
        return None, None
    if isinstance(spec, (int, np.integer)):
        z = int(spec)
        if not 0 <= z < cells.N:
            raise UserError(f"{what} {z} is out of range: configurations are 0 to "
                            f"{cells.N - 1}.")
        return z, cells.pose(z)
    try:
        x, y, h = (float(v) for v in spec)
    except (TypeError, ValueError):
        raise UserError(f"{what} must be a configuration index or a pose (x, y, heading).") \
            from None
    if not all(map(math.isfinite, (x, y, h))):
        raise UserError(f"{what} pose ({x:g}, {y:g}, {h:g}) has a part that is not a finite "
                        "number.")
    z = cells.config_of_pose(x, y, h)
    return (z if z >= 0 else None), (x, y, h)


def place_if_simulated(robot: Robot, pose) -> bool:
    """Place a simulated robot; False on hardware (a person places it)."""
    if pose is None:
        return False
    try:
        robot.place(*pose)
        return True
    except NotImplementedError:
        return False


def check_speed(speed: float, robot: Robot) -> float:
    """``speed`` [m/s] as a float; :class:`UserError` unless 0 < speed <= the robot's maximum."""
    speed = float(speed)
    vmax = robot.spec.max_wheel_speed
    if not (math.isfinite(speed) and 0 < speed <= vmax):
        raise UserError(f"speed must lie in (0, {vmax:g}] m/s, got {speed:g}.")
    return speed


def time_up(t: float, max_time: float | None) -> str:
    """The reason to stop when the run's clock ``t`` [s] has passed ``max_time``, else ''."""
    if max_time is not None and t > max_time:
        return f"time limit of {max_time:g} s exceeded"
    return ""


def side_text(ev) -> str:
    """A bump event's bumper side as a trace detail: 'left', 'right', 'left+right' or 'none'."""
    return "+".join(s for s, on in (("left", ev.left), ("right", ev.right)) if on) or "none"


# ============================================================================ plans
class PlanRunner:
    """The plan runner (docs/model.md §21): for every segment (n zeros, angle) fly until a
    bump, log a deviation, back off, turn; a trailing run or final drive by the clock.
    """

    finished = "plan finished"

    def __init__(self, plan, robot, cells, start, goal, back_off, max_factor,
                 on_segment) -> None:
        self.plan = plan = Plan.parse(plan) if not isinstance(plan, Plan) else plan
        self.cells, self.back_off, self.max_factor = cells, back_off, max_factor
        self.on_segment = on_segment
        if start is None:
            raise UserError("a plan needs its start configuration or pose: the start heading "
                            "fixes how far each run of zeros drives.")
        _, self.start_pose = resolve_pose(start, cells, "start")
        self.k = int(cells.orientation_of(self.start_pose[2]))   # the start's orientation
        self.goal_z, goal_pose = resolve_pose(goal, cells, "goal")
        if goal is not None and self.goal_z is None:
            raise UserError(f"goal pose {goal_pose} is not in a free cell.")
        self.goal_pose = cells.pose(self.goal_z) if self.goal_z is not None else goal_pose
        self.deviations: list[Deviation] = []
        self.bumps = 0
        self.completed = False
        self.label = plan.exact_text()
        place_if_simulated(robot, self.start_pose)

    def _segments(self) -> list[tuple]:
        """(zeros or None, expected flight [m], angle or None) per segment: an exact plan runs
        by its angles (its expected flights only log deviations) and ends with its final
        drive; a step plan by its observation string (its runs' lengths from the start
        heading: :func:`planners.measures.step_flights`).
        """
        plan = self.plan
        if not plan.is_exact:
            flights, final = step_flights(self.cells, plan, self.k)
            lengths = iter([*flights, final])
            return [(n, next(lengths), a) for n, a in plan.segments()]
        segs = [(None, f, a) for f, a in zip(plan.flights_m, plan.turns)]
        if plan.final_m > 0:
            segs.append((None, plan.final_m, None))
        return segs

    def moves(self, pose):
        """The run's moves from the true start ``pose`` (a generator; its value: the
        reason the run ended, '' when the policy finished).
        """
        cells, h = self.cells, self.cells.h
        segs = self._segments()
        tol = h / 4 if self.plan.is_exact else h                 # deviation threshold [m]
        for i, (zeros, expected, angle) in enumerate(segs):
            if angle is None:                               # trailing zeros: drive and stop
                res = yield Drive(expected)
                ev, travelled = res.event, res.travelled
                if ev.bumped and travelled < expected - STEP_TOL:  # not just touching at the end
                    self.bumps += 1
                    yield Note("bump", side_text(ev), res.pose)
                    if expected - travelled > tol:
                        dev = Deviation(i, expected, travelled, "early", res.t)
                        self.deviations.append(dev)
                        yield Note("deviation", f"early: {travelled:.3f} m of {expected:.3f} m",
                                   res.pose)
                self._report(i, len(segs), travelled, ev.elapsed, ev.bumped, None)
                continue
            if zeros is not None:
                limit = flight_limit(cells, self.max_factor, zeros=zeros)
            else:
                limit = flight_limit(cells, self.max_factor, flight_m=expected)
            res = yield Fly(limit)
            ev, travelled = res.event, res.travelled
            if not ev.bumped:
                yield Note("no_bump", f"segment {i}: {travelled:.3f} m", res.pose)
                return f"no bump within {limit:.2f} m (segment {i + 1} of {len(segs)})"
            self.bumps += 1
            yield Note("bump", side_text(ev), res.pose)
            if abs(travelled - expected) > tol:
                kind = "early" if travelled < expected else "late"
                dev = Deviation(i, expected, travelled, kind, res.t)
                self.deviations.append(dev)
                yield Note("deviation", f"{kind}: {travelled:.3f} m instead of {expected:.3f} m",
                           res.pose)
            if self.back_off > 0:
                yield BackOff(self.back_off)
            yield Turn(wrap180(angle))            # the shorter way (docs/model.md §21)
            self._report(i, len(segs), travelled, ev.elapsed, True, angle)
        self.completed = True
        return ""

    def _report(self, i, total, travelled, seconds, bumped, turn) -> None:
        if self.on_segment is not None:
            self.on_segment(SegmentDone(i + 1, total, float(travelled), float(seconds),
                                        bool(bumped), None if turn is None else float(turn)))

    def result(self, reason: str, elapsed: float, final, trace: Trace) -> PlanRun:
        """The run's record from the loop's ending (reason, clock [s], final pose)."""
        return plan_result(self.cells, self.plan, self.goal_z, self.goal_pose, self.completed,
                           reason, final, elapsed, self.deviations, self.bumps,
                           self.start_pose, trace)


def plan_result(cells: CellSpace, plan: Plan, goal_z, goal_pose, completed: bool, reason: str,
                final, elapsed: float, deviations, bumps: int, start_pose, trace: Trace,
                cls=PlanRun, **extra) -> PlanRun:
    """The :class:`PlanRun` (or subclass ``cls`` with ``extra`` fields) of a navigation run:
    the goal rule of docs/model.md §21 (:func:`planners.measures.goal_check`) on the final
    pose, and the reason in words.
    """
    success: bool | None = None
    pos_err = head_err = None
    if final is not None and goal_pose is not None:
        gx, gy, gh = goal_pose
        pos_err = math.hypot(final[0] - gx, final[1] - gy)
        head_err = wrap180(final[2] - gh)
    if completed:
        if goal_z is None:
            reason = "plan finished (no goal to check)"
        elif final is None:
            reason = "plan finished (success unknown without a pose)"
        else:
            g = goal_check(cells, goal_z, final)
            success = g.success
            if success:
                reason = "reached the goal"
            elif not g.in_cell:
                reason = (f"ended {pos_err:.3f} m from the goal cell's centre, outside "
                          f"the goal cell")
            else:
                reason = (f"heading off by {head_err:+.1f}° (allowed ±"
                          f"{cells.delta_deg / 2:g}°)")
    elif goal_z is not None and final is not None:
        success = False
    return cls(plan=plan, success=success, reason=reason, completed=completed,
               final_pose=final, position_error=pos_err, heading_error=head_err,
               deviations=tuple(deviations), bumps=bumps, elapsed=elapsed,
               start_pose=start_pose, goal_pose=goal_pose, trace=trace, **extra)


# ============================================================================ policy mixes
class MixRunner:
    """The mix runner (docs/model.md §8, §21): epochs of ``epoch`` steps, each with one angle
    drawn with probabilities α; a step drives h by the clock or until a bump, and on a bump
    turns by the epoch's angle. Visits are counted per step.
    """

    finished = "finished"

    def __init__(self, policy_mix, robot, cells, start, back_off, steps, epoch, rng,
                 max_stuck, record_trace, max_time) -> None:
        if not isinstance(policy_mix, PolicyMix):
            policy_mix = PolicyMix((float(policy_mix),), (1.0,))
        self.cells, self.back_off = cells, back_off
        self.angles = np.asarray(policy_mix.angles, dtype=float)
        alpha = np.asarray(policy_mix.alpha, dtype=float)
        self.alpha = alpha / alpha.sum()
        self.epoch = int(epoch)
        if self.epoch < 1:
            raise UserError(f"epoch must be at least one step, got {self.epoch}.")
        self.steps = int(steps)
        if self.steps < 0:
            raise UserError(f"the step budget must be non-negative, got {self.steps}.")
        self.max_stuck = None if max_stuck is None else int(max_stuck)
        self.rng, self.record_trace, self.max_time = rng, record_trace, max_time
        if start is None:
            start = int(rng.integers(0, cells.N))
        _, start_pose = resolve_pose(start, cells, "start")
        place_if_simulated(robot, start_pose)
        self.counts = np.zeros(cells.P, dtype=np.int64)
        self.known = robot.true_pose() is not None
        self.dropped = self.bumps = self.done = 0
        self.epoch_angles: list[float] = []
        self.label = f"angles {list(self.angles)} alpha {list(self.alpha)}"

    def _count(self, pose) -> None:
        if pose is None:
            return
        p = int(self.cells.cell_of_body(pose[:2])[0])
        if p < 0:
            self.dropped += 1
        else:
            self.counts[p] += 1

    def moves(self, pose):
        """The run's moves from the true start ``pose`` (a generator; its value: the
        reason the run ended, '' when the policy finished).
        """
        angles, alpha, epoch, max_stuck = self.angles, self.alpha, self.epoch, self.max_stuck
        rng, record, h, t = self.rng, self.record_trace, self.cells.h, 0.0
        stuck = 0
        angle = float(angles[0])
        forward = Drive(h)                          # one move object for every step
        for s in range(self.steps):
            late = time_up(t, self.max_time)        # before the epoch's draw, not after it
            if late:
                return late
            if s % epoch == 0:
                angle = float(angles[rng.choice(len(angles), p=alpha)]) if len(angles) > 1 \
                    else float(angles[0])
                self.epoch_angles.append(angle)
            res = yield forward
            ev, t = res.event, res.t
            # the step rule (docs/model.md §8): a drive the bumper did not stop had h free
            _, bump_step = step(res.travelled if ev.bumped else math.inf, h)
            if not bump_step:
                self._count(pose)
                stuck = 0
                if record:
                    yield Note("step", "", res.pose)
                pose = res.pose
            else:
                self._count(res.pose)
                self.bumps += 1
                stuck = stuck + 1 if res.travelled <= STEP_TOL else 0
                if record:
                    yield Note("bump", side_text(ev), res.pose)
                if max_stuck is not None and stuck > max_stuck:
                    self.done += 1
                    return f"stuck: {stuck} bumps in a row without moving"
                if self.back_off > 0:
                    yield BackOff(self.back_off)
                res = yield Turn(wrap180(angle))  # the shorter way (docs/model.md §21)
                pose, t = res.pose, res.t
            self.done += 1
        return ""

    def result(self, reason: str, elapsed: float, final, trace: Trace) -> MixRun:
        """The run's record from the loop's ending (reason, clock [s], final pose)."""
        return MixRun(counts=self.counts if self.known else None, dropped=self.dropped,
                      steps=self.done, bumps=self.bumps, reason=reason or self.finished,
                      epoch_angles=tuple(self.epoch_angles), final_pose=final,
                      elapsed=elapsed, trace=trace)
