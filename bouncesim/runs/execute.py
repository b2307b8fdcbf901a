"""The one execution loop: :func:`execute` runs a plan or a policy mix on any
:class:`bouncesim.robots.Robot` (docs/model.md §8-9).

It controls the robot through the bump-and-clock interface only (drive, stop, bumper, clock,
wait, turn and the composite drive_until_bump / drive_for). Simulators are additionally
*placed* at the start (``Robot.place``; on hardware a person places the robot) and their true
pose (``Robot.true_pose``) is logged for the trace, the success check and the visit histogram;
it never feeds back into control. The room is the robot's (``robot.env``), or the given cells'.

- A :class:`~planners.plan.Plan` runs its observation string: for every segment (n zeros,
  angle) drive until a bump, log a deviation when the travelled distance (speed x elapsed
  time: the robot only has a clock) differs from the run's length by more than one cell,
  optionally back off, turn CCW by the angle; a trailing run of n zeros drives its length by
  the clock and stops. A run's length is the distance the step model moves in n steps at the
  current heading (:meth:`planners.cells.CellSpace.run_length`: n·h along an axis, n·√2·h
  along a diagonal at K = 8), known from the start heading and the angles before it.
  An exact plan (:mod:`planners.navigation.exact`, docs/model.md §15) runs by its angles instead: drive
  until a bump and turn, for every angle, then drive its final length by the clock; its
  expected flights only log deviations (more than h/4 off). Returns a :class:`PlanRun`.
- A :class:`~planners.plan.PolicyMix` is time-shared: epochs of ``epoch`` steps, each with one
  angle drawn with probabilities α; a step drives h by the clock or until a bump, and on a
  bump turns by the epoch's angle (the robot's own noise model perturbs the turn). Returns a
  :class:`MixRun`.

Runs always end: every drive has a timeout, a plan has finitely many segments, a coverage run
has a step budget (and optionally a limit on bumps in a row without moving, and on time).
Whatever ends a run (the end of the policy, a limit, a :class:`~bouncesim.robots.RobotError`)
stops the robot and logs the stop the same way.

Examples
--------
>>> import envs
>>> import numpy as np
>>> from planners.plan import Plan
>>> from bouncesim.robots.kinematic import KinematicRobot
>>> bot = KinematicRobot(envs.load("lab"))
>>> run = execute(Plan.parse("90° 90° 00000000 90° 90°"), bot, start=8, goal=0)
>>> run.success, run.reason, len(run.deviations)
(True, 'reached the goal', 0)
>>> round(run.position_error, 6), run.heading_error
(0.0, 0.0)
>>> mix = execute(90.0, bot, start=8, steps=100, epoch=10, rng=np.random.default_rng(0))
>>> mix.reason, mix.steps, int(mix.counts.sum())
('finished', 100, 100)
"""

from __future__ import annotations

import math

import numpy as np

from envs import UserError
from envs.motion import STEP_TOL, step
from planners.cells import CellSpace
from planners.plan import Plan, PolicyMix

from ..robots.base import Robot, RobotError
from .results import Deviation, MixRun, PlanRun, SegmentDone
from .trace import Trace

__all__ = ["check_speed", "execute", "place_if_simulated", "PlanRun", "MixRun", "Deviation",
           "SegmentDone"]


def _wrap180(deg: float) -> float:
    """Wrap an angle [deg] into (−180, 180]."""
    w = math.fmod(deg, 360.0)
    if w > 180.0:
        w -= 360.0
    elif w <= -180.0:
        w += 360.0
    return w


def _resolve_pose(spec, cells: CellSpace, what: str) -> tuple[int | None, tuple | None]:
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


def _back_off(robot: Robot, speed: float, distance: float) -> None:
    """Reverse ``distance`` [m] by the clock. Not drive_for: the bumper is still pressed."""
    robot.drive(-speed)
    try:
        robot.wait(distance / speed)
    finally:
        robot.stop()


def _robot_error(robot: Robot, trace: Trace, t0: float, exc: RobotError) -> str:
    """Log a RobotError that ended a run; return the run's reason."""
    trace.add(robot.clock() - t0, robot.true_pose(), "error", str(exc))
    return f"robot error: {exc}"


def _stopped(robot: Robot, trace: Trace, t0: float, reason: str) -> tuple:
    """Log the stop of a run; return (elapsed [s], final pose or None)."""
    elapsed = robot.clock() - t0
    final = robot.true_pose()
    trace.add(elapsed, final, "stop", reason)
    return elapsed, final


def _side(ev) -> str:
    return "+".join(s for s, on in (("left", ev.left), ("right", ev.right)) if on) or "none"


# ============================================================================ the loop
def execute(policy, robot: Robot, *, start=None, cells: CellSpace | None = None,
            speed: float = 0.2, back_off: float = 0.0, max_time: float | None = None,
            goal=None, max_factor: float = 2.0, steps: int | None = None,
            epoch: int | None = None, rng: np.random.Generator | None = None,
            max_stuck: int | None = None, record_trace: bool = True,
            on_segment=None) -> PlanRun | MixRun:
    """Run a policy on a robot (docs/model.md §8-9): a plan's observation string, or a policy
    mix by time-sharing.

    Parameters
    ----------
    policy : Plan, str, PolicyMix or float
        A :class:`~planners.plan.Plan` (or its text) runs its segments; a
        :class:`~planners.plan.PolicyMix` (or one angle [deg], a mix of one) runs ``steps``
        steps in epochs. The mix's eps and r are *not* applied here: the robot's own noise
        model perturbs its turns (build it with
        ``bouncesim.robots.noise.noise_for_mix(mix, delta)`` for the §7 model).
    robot : Robot
        Its environment (``robot.env``) is the room; a robot that knows none (hardware) needs
        ``cells``.
    start : int or (x, y, heading)
        Start configuration z or pose [m, m, deg]; simulators are placed there (on hardware
        the robot is assumed to be there already). A plan needs it (its heading fixes how far
        each run of zeros drives); a mix draws it uniformly over the N configurations when
        None (docs/model.md §9).
    cells : CellSpace, optional
        The cell space (default: built from ``robot.env``).
    speed : float          drive speed [m/s]
    back_off : float
        Distance [m] to back off after every bump before turning (0: none; the Create 2
        manual suggests about 0.01 m so the bumper does not drag on the wall).
    max_time : float, optional
        Give up when the robot clock passes this many seconds after the start.

    Plan only:

    goal : int or (x, y, heading), optional
        Goal configuration (or a pose mapped to its cell) for the success check.
    on_segment : callable, optional
        Called with a :class:`SegmentDone` after every completed segment (progress lines).
    max_factor : float
        A segment of n zeros may drive at most ``max_factor * (n + 2) * h`` before the run is
        declared failed ("no bump"), and never more than the bounding-box diagonal plus h
        (no straight line in the room is longer).

    Mix only:

    steps : int            step budget
    epoch : int            steps per epoch; each epoch draws one angle with probabilities α
    rng : numpy.random.Generator
        Draws the epoch angles (and the start when ``start`` is None).
    max_stuck : int, optional
        Stop ("stuck") after this many bumps in a row without moving. Default None: no such
        stop, because the step budget already bounds the run and immobile bump cycles are
        part of the dynamics (two angles in a row bump at once; 180° turns between two
        blocked diagonal headings in a corridor exactly one robot wide repeat until the
        epoch changes the angle, just as the discrete chain does).
    record_trace : bool     log every step (False: only start and stop)

    Returns
    -------
    PlanRun or MixRun
        For a mix, a step is counted in the position cell where it starts (a forward step of
        h) or at the contact position (a bump step: the move to contact plus the turn). A bump
        within ``STEP_TOL`` of the full h completes a forward step; the robot then bumps at
        once.
    """
    if cells is None:
        env = getattr(robot, "env", None)
        if env is None:
            raise UserError(f"{type(robot).__name__} knows no environment: pass "
                            f"cells=CellSpace(env) for the room it is in.")
        cells = CellSpace(env)
    speed = check_speed(speed, robot)
    back_off = float(back_off)
    if back_off < 0 or not math.isfinite(back_off):
        raise UserError(f"back-off must be a non-negative distance in metres, got {back_off:g}.")
    if isinstance(policy, (PolicyMix, int, float, np.integer, np.floating)):
        if goal is not None:
            raise UserError("a policy mix has no goal: it covers the room.")
        if steps is None or epoch is None or rng is None:
            raise UserError("a policy mix needs steps, epoch and rng.")
        runner = _MixRunner(policy, robot, cells, start, speed, back_off, steps, epoch, rng,
                            max_stuck, record_trace)
    else:
        if steps is not None or epoch is not None or max_stuck is not None:
            raise UserError("steps, epoch and max_stuck are for policy mixes; a plan runs its "
                            "segments.")
        runner = _PlanRunner(policy, robot, cells, start, goal, speed, back_off, max_factor)
        runner.on_segment = on_segment

    trace = Trace()
    t0 = robot.clock()
    trace.add(0.0, robot.true_pose(), "start", runner.label)
    reason = ""
    try:
        reason = runner.loop(trace, t0, max_time)
    except RobotError as exc:
        reason = _robot_error(robot, trace, t0, exc)
    finally:
        robot.stop()
    elapsed, final = _stopped(robot, trace, t0, reason or runner.finished)
    return runner.result(reason, elapsed, final, trace)


def _time_up(robot: Robot, t0: float, max_time: float | None) -> str:
    """The reason to stop when the robot clock has passed ``max_time``, else ''."""
    if max_time is not None and robot.clock() - t0 > max_time:
        return f"time limit of {max_time:g} s exceeded"
    return ""


# ============================================================================ plans
class _PlanRunner:
    """The plan half of :func:`execute` (docs/model.md §8): for every segment (n zeros,
    angle) drive until a bump, log a deviation, back off, turn.
    """

    finished = "plan finished"
    on_segment = None

    def __init__(self, plan, robot, cells, start, goal, speed, back_off, max_factor) -> None:
        self.plan = plan = Plan.parse(plan) if not isinstance(plan, Plan) else plan
        self.robot, self.cells, self.speed, self.back_off = robot, cells, speed, back_off
        self.max_factor = max_factor
        if start is None:
            raise UserError("a plan needs its start configuration or pose: the start heading "
                            "fixes how far each run of zeros drives.")
        _, self.start_pose = _resolve_pose(start, cells, "start")
        self.k = int(cells.orientation_of(self.start_pose[2]))   # orientation of the run
        self.goal_z, goal_pose = _resolve_pose(goal, cells, "goal")
        if goal is not None and self.goal_z is None:
            raise UserError(f"goal pose {goal_pose} is not in a free cell.")
        self.goal_pose = cells.pose(self.goal_z) if self.goal_z is not None else goal_pose
        x0, y0, x1, y1 = cells.env.bounds
        self.cap = math.hypot(x1 - x0, y1 - y0) + cells.h
        self.deviations: list[Deviation] = []
        self.bumps = 0
        self.completed = False
        self.label = plan.exact_text()
        place_if_simulated(robot, self.start_pose)

    def _segments(self) -> list[tuple]:
        """(zeros or None, expected flight [m] or None, angle or None) per segment: an exact
        plan runs by its angles (its expected flights only log deviations) and ends with its
        final drive; a step plan by its observation string (lengths from the cell space).
        """
        plan = self.plan
        if not plan.is_exact:
            return [(n, None, a) for n, a in plan.segments()]
        segs = [(None, f, a) for f, a in zip(plan.flights_m, plan.turns)]
        if plan.final_m > 0:
            segs.append((None, plan.final_m, None))
        return segs

    def loop(self, trace: Trace, t0: float, max_time: float | None) -> str:
        robot, cells, speed, h = self.robot, self.cells, self.speed, self.cells.h
        segs = self._segments()
        tol = h / 4 if self.plan.is_exact else h                 # deviation threshold [m]
        for i, (zeros, flight, angle) in enumerate(segs):
            late = _time_up(robot, t0, max_time)
            if late:
                return late
            if flight is None:
                expected = cells.run_length(self.k, zeros)  # the step model's distance [m]
            else:
                expected = flight                           # the exact planner's flight [m]
            if angle is None:                               # trailing zeros: drive and stop
                ev = robot.drive_for(speed, expected / speed)
                travelled = speed * ev.elapsed
                if ev.bumped and travelled < expected - STEP_TOL:  # not just touching at the end
                    self.bumps += 1
                    trace.add(robot.clock() - t0, robot.true_pose(), "bump", _side(ev))
                    if expected - travelled > tol:
                        dev = Deviation(i, expected, travelled, "early", robot.clock() - t0)
                        self.deviations.append(dev)
                        trace.add(dev.t, robot.true_pose(), "deviation",
                                  f"early: {travelled:.3f} m of {expected:.3f} m")
                self._report(i, len(segs), travelled, ev.elapsed, ev.bumped, None)
                continue
            if flight is None:
                limit = min(self.max_factor * (zeros + 2) * h, self.cap)
            else:
                limit = min(self.max_factor * (flight + 2 * h), self.cap)
            ev = robot.drive_until_bump(speed, limit / speed)
            travelled = speed * ev.elapsed
            if not ev.bumped:
                trace.add(robot.clock() - t0, robot.true_pose(), "no_bump",
                          f"segment {i}: {travelled:.3f} m")
                return f"no bump within {limit:.2f} m (segment {i + 1} of {len(segs)})"
            self.bumps += 1
            trace.add(robot.clock() - t0, robot.true_pose(), "bump", _side(ev))
            if abs(travelled - expected) > tol:
                kind = "early" if travelled < expected else "late"
                dev = Deviation(i, expected, travelled, kind, robot.clock() - t0)
                self.deviations.append(dev)
                trace.add(dev.t, robot.true_pose(), "deviation",
                          f"{kind}: {travelled:.3f} m instead of {expected:.3f} m")
            if self.back_off > 0:
                _back_off(robot, speed, self.back_off)
                trace.add(robot.clock() - t0, robot.true_pose(), "back_off",
                          f"{self.back_off:g} m")
            robot.turn(angle)
            self.k = int(cells.orientation_of(self.k * cells.delta_deg + angle))
            trace.add(robot.clock() - t0, robot.true_pose(), "turn", f"{angle:g}")
            self._report(i, len(segs), travelled, ev.elapsed, True, angle)
        self.completed = True
        return ""

    def _report(self, i, total, travelled, seconds, bumped, turn) -> None:
        if self.on_segment is not None:
            self.on_segment(SegmentDone(i + 1, total, float(travelled), float(seconds),
                                        bool(bumped), None if turn is None else float(turn)))

    def result(self, reason: str, elapsed: float, final, trace: Trace) -> PlanRun:
        cells, goal_z, goal_pose = self.cells, self.goal_z, self.goal_pose
        success: bool | None = None
        pos_err = head_err = None
        if final is not None and goal_pose is not None:
            gx, gy, gh = goal_pose
            pos_err = math.hypot(final[0] - gx, final[1] - gy)
            head_err = _wrap180(final[2] - gh)
        if self.completed:
            if goal_z is None:
                reason = "plan finished (no goal to check)"
            elif final is None:
                reason = "plan finished (success unknown without a pose)"
            else:
                p_goal = int(cells.pk(goal_z)[0])
                p_end = int(cells.cell_of_point([final[:2]])[0])
                in_cell = p_end == p_goal
                head_ok = abs(head_err) <= cells.delta_deg / 2 + 1e-9
                success = in_cell and head_ok
                if success:
                    reason = "reached the goal"
                elif not in_cell:
                    reason = (f"ended {pos_err:.3f} m from the goal cell's centre, outside "
                              f"the goal cell")
                else:
                    reason = (f"heading off by {head_err:+.1f}° (allowed ±"
                              f"{cells.delta_deg / 2:g}°)")
        elif goal_z is not None and final is not None:
            success = False
        return PlanRun(plan=self.plan, success=success, reason=reason,
                       completed=self.completed, final_pose=final, position_error=pos_err,
                       heading_error=head_err, deviations=tuple(self.deviations),
                       bumps=self.bumps, elapsed=elapsed, start_pose=self.start_pose,
                       goal_pose=goal_pose, trace=trace)


# ============================================================================ policy mixes
class _MixRunner:
    """The mix half of :func:`execute` (docs/model.md §8-9): epochs of ``epoch`` steps, each
    with one angle drawn with probabilities α; a step drives h by the clock or until a bump,
    and on a bump turns by the epoch's angle. Visits are counted per step.
    """

    finished = "finished"

    def __init__(self, policy_mix, robot, cells, start, speed, back_off, steps, epoch, rng,
                 max_stuck, record_trace) -> None:
        if not isinstance(policy_mix, PolicyMix):
            policy_mix = PolicyMix((float(policy_mix),), (1.0,))
        self.robot, self.cells, self.speed, self.back_off = robot, cells, speed, back_off
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
        self.rng, self.record_trace = rng, record_trace
        if start is None:
            start = int(rng.integers(0, cells.N))
        _, start_pose = _resolve_pose(start, cells, "start")
        place_if_simulated(robot, start_pose)
        self.counts = np.zeros(cells.P, dtype=np.int64)
        self.known = robot.true_pose() is not None
        self.dropped = self.bumps = self.done = 0
        self.epoch_angles: list[float] = []
        self.label = f"angles {list(self.angles)} alpha {list(self.alpha)}"

    def loop(self, trace: Trace, t0: float, max_time: float | None) -> str:
        robot, speed, back_off, rng = self.robot, self.speed, self.back_off, self.rng
        angles, alpha, epoch, max_stuck = self.angles, self.alpha, self.epoch, self.max_stuck
        record_trace, epoch_angles, counts = self.record_trace, self.epoch_angles, self.counts
        cells = self.cells
        h = cells.h

        def count(pose) -> None:
            if pose is None:
                return
            p = int(cells.cell_of_point(pose[:2])[0])
            if p < 0:
                self.dropped += 1
            else:
                counts[p] += 1

        stuck = 0
        angle = float(angles[0])
        for s in range(self.steps):
            late = _time_up(robot, t0, max_time)
            if late:
                return late
            if s % epoch == 0:
                angle = float(angles[rng.choice(len(angles), p=alpha)]) if len(angles) > 1 \
                    else float(angles[0])
                epoch_angles.append(angle)
            pose0 = robot.true_pose()
            ev = robot.drive_for(speed, h / speed)
            travelled = speed * ev.elapsed
            # the step rule (docs/model.md §9): a drive the bumper did not stop had h free
            _, bump_step = step(travelled if ev.bumped else math.inf, h)
            if not bump_step:
                count(pose0)
                stuck = 0
                if record_trace:
                    trace.add(robot.clock() - t0, robot.true_pose(), "step")
            else:
                pose_c = robot.true_pose()
                count(pose_c)
                self.bumps += 1
                stuck = stuck + 1 if travelled <= STEP_TOL else 0
                if record_trace:
                    trace.add(robot.clock() - t0, pose_c, "bump", _side(ev))
                if max_stuck is not None and stuck > max_stuck:
                    self.done += 1
                    return f"stuck: {stuck} bumps in a row without moving"
                if back_off > 0:
                    _back_off(robot, speed, back_off)
                robot.turn(angle)
                if record_trace:
                    trace.add(robot.clock() - t0, robot.true_pose(), "turn", f"{angle:g}")
            self.done += 1
        return ""

    def result(self, reason: str, elapsed: float, final, trace: Trace) -> MixRun:
        return MixRun(counts=self.counts if self.known else None, dropped=self.dropped,
                      steps=self.done, bumps=self.bumps, reason=reason or self.finished,
                      epoch_angles=tuple(self.epoch_angles), final_pose=final,
                      elapsed=elapsed, trace=trace)
