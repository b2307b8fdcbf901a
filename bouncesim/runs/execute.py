"""The one run loop: :func:`execute` runs a plan, a policy mix or a feedback navigator on any
:class:`bouncesim.robots.Robot` (docs/model.md §8, §21, §15).

Every policy is a *runner* that yields moves (:mod:`bouncesim.runs.moves`: fly until a bump,
drive by the clock, turn, back off, note) and hears back what each move did; after every bump
it chooses the next turn. The loop alone talks to the robot through the bump-and-clock
interface (drive, stop, bumper, clock, wait, turn and the composite drive_until_bump /
drive_for), checks the time limit before every drive, logs turns and back-offs, and stops the
robot and logs the stop whatever ends the run (the end of the policy, a limit, a
:class:`~bouncesim.robots.RobotError`). Simulators are additionally *placed* at the start
(``Robot.place``; on hardware a person places the robot) and their true pose
(``Robot.true_pose``) is logged for the trace, the success check and the visit histogram; it
never feeds back into control. The room is the robot's (``robot.env``), or the given cells'.

- A :class:`~planners.plan.Plan` runs its observation string: for every segment (n zeros,
  angle) drive until a bump, log a deviation when the travelled distance (speed x elapsed
  time: the robot only has a clock) differs from the run's length by more than one cell,
  optionally back off, turn CCW by the angle; a trailing run of n zeros drives its length by
  the clock and stops. A run's length is the distance the step model moves in n steps at the
  current heading (:meth:`planners.cells.CellSpace.run_length`: n·h along an axis, n·√2·h
  along a diagonal at K = 8), known from the start heading and the angles before it.
  An exact plan (:mod:`planners.navigation.exact`, docs/model.md §13) runs by its angles
  instead: drive until a bump and turn, for every angle, then drive its final length by the
  clock; its expected flights only log deviations (more than h/4 off). Returns a
  :class:`PlanRun`.
- A :class:`~planners.plan.PolicyMix` is time-shared: epochs of ``epoch`` steps, each with one
  angle drawn with probabilities α; a step drives h by the clock or until a bump, and on a
  bump turns by the epoch's angle (the robot's own noise model perturbs the turn). Returns a
  :class:`MixRun`.
- A feedback policy (:meth:`planners.navigation.feedback.FeedbackPlanner.policy`) re-plans
  from a particle belief after every bump (docs/model.md §15;
  :mod:`bouncesim.runs.feedback`). Returns a :class:`~bouncesim.runs.feedback.FeedbackRun`.

Runs always end: every drive has a timeout, a plan has finitely many segments, a coverage run
has a step budget (and optionally a limit on bumps in a row without moving, and on time), a
feedback run a bump budget.

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

from envs import Environment, UserError
from planners.cells import CellSpace
from planners.navigation.feedback import (
    DEFAULT_MAX_BUMPS,
    FeedbackConfig,
    FeedbackPlanner,
    FeedbackPolicy,
)
from planners.plan import PolicyMix

from ..robots.base import Robot, RobotError
from .feedback import FeedbackRun, FeedbackRunner
from .moves import BackOff, Drive, Fly, Moved, Note, Turn
from .results import Deviation, MixRun, PlanRun, SegmentDone
from .runners import MixRunner, PlanRunner, check_speed, place_if_simulated, time_up
from .trace import Trace

__all__ = ["check_speed", "execute", "navigate_feedback", "place_if_simulated", "PlanRun",
           "MixRun", "FeedbackRun", "Deviation", "SegmentDone"]


def _cells_of(robot: Robot, cells: CellSpace | None) -> CellSpace:
    if cells is not None:
        return cells
    env = getattr(robot, "env", None)
    if env is None:
        raise UserError(f"{type(robot).__name__} knows no environment: pass "
                        f"cells=CellSpace(env) for the room it is in.")
    return CellSpace(env)


# ============================================================================ the loop
def execute(policy, robot: Robot, *, start=None, cells: CellSpace | None = None,
            speed: float = 0.2, back_off: float = 0.0, max_time: float | None = None,
            goal=None, max_factor: float = 2.0, steps: int | None = None,
            epoch: int | None = None, rng: np.random.Generator | None = None,
            max_stuck: int | None = None, record_trace: bool = True,
            on_segment=None):
    """Run a policy on a robot (docs/model.md §8, §21, §15): a plan's observation string, a
    policy mix by time-sharing, or a feedback navigator.

    Parameters
    ----------
    policy : Plan, str, PolicyMix, float or a feedback policy
        A :class:`~planners.plan.Plan` (or its text) runs its segments; a
        :class:`~planners.plan.PolicyMix` (or one angle [deg], a mix of one) runs ``steps``
        steps in epochs. The mix's noise is *not* applied here: the robot's own noise model
        perturbs its turns (build it with ``bouncesim.robots.noise.noise_for_mix(mix,
        delta)``). A feedback policy (:meth:`FeedbackPlanner.policy
        <planners.navigation.feedback.FeedbackPlanner.policy>`) chooses every turn from its
        belief (:mod:`bouncesim.runs.feedback`).
    robot : Robot
        Its environment (``robot.env``) is the room; a robot that knows none (hardware) needs
        ``cells``.
    start : int or (x, y, heading)
        Start configuration z or pose [m, m, deg]; simulators are placed there (on hardware
        the robot is assumed to be there already). A plan needs it (its heading fixes how far
        each run of zeros drives); a mix draws it uniformly over the N configurations when
        None (docs/model.md §8); a feedback policy brings its own.
    cells : CellSpace, optional
        The cell space (default: built from ``robot.env``).
    speed : float          drive speed [m/s]
    back_off : float
        Distance [m] to back off after every bump before turning (0: none; the Create 2
        manual suggests about 0.01 m so the bumper does not drag on the wall).
    max_time : float, optional
        Give up when the robot clock passes this many seconds after the start (checked
        before every drive).

    Plan only:

    goal : int or (x, y, heading), optional
        Goal configuration (or a pose mapped to its cell) for the success check.
    on_segment : callable, optional
        Called with a :class:`SegmentDone` after every completed segment (progress lines).
    max_factor : float
        A segment may drive at most :func:`planners.measures.flight_limit` (``max_factor``
        times its expected flight plus two cells, never more than the bounding-box diagonal
        plus h) before the run is declared failed ("no bump").

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
    record_trace : bool     log every move (False: only start and stop)

    Returns
    -------
    PlanRun, MixRun or FeedbackRun
        For a mix, a step is counted in the position cell where it starts (a forward step of
        h) or at the contact position (a bump step: the move to contact plus the turn). A bump
        within ``STEP_TOL`` of the full h completes a forward step; the robot then bumps at
        once.
    """
    speed = check_speed(speed, robot)
    back_off = float(back_off)
    if back_off < 0 or not math.isfinite(back_off):
        raise UserError(f"back-off must be a non-negative distance in metres, got {back_off:g}.")
    runner = _runner(policy, robot, start, cells, goal, back_off, max_factor, steps, epoch, rng,
                     max_stuck, record_trace, on_segment, max_time, speed)
    trace = Trace()
    t0 = robot.clock()
    trace.add(0.0, robot.true_pose(), "start", runner.label)
    reason = ""
    try:
        reason = _drive(runner, robot, trace, t0, speed, max_time, record_trace)
    except RobotError as exc:
        trace.add(robot.clock() - t0, robot.true_pose(), "error", str(exc))
        reason = f"robot error: {exc}"
    finally:
        robot.stop()
    elapsed = robot.clock() - t0
    final = robot.true_pose()
    trace.add(elapsed, final, "stop", reason or runner.finished)
    result = runner.result(reason, elapsed, final, trace)
    success = getattr(result, "success", None)
    if success is not None:                     # a run with a goal: how it ended
        trace.add(elapsed, final, "outcome",
                  f"{'success' if success else 'failure'}: {result.reason}")
    return result


def _runner(policy, robot, start, cells, goal, back_off, max_factor, steps, epoch, rng,
            max_stuck, record_trace, on_segment, max_time, speed=None):
    """The runner of a policy: a plan's, a mix's or a feedback policy's."""
    if isinstance(policy, FeedbackPolicy):                   # closed loop (§15)
        if steps is not None or epoch is not None or max_stuck is not None:
            raise UserError("steps, epoch and max_stuck are for policy mixes.")
        return FeedbackRunner(policy, robot, start=start, goal=goal, cells=cells,
                              back_off=back_off, speed=speed)
    cells = _cells_of(robot, cells)
    if isinstance(policy, (PolicyMix, int, float, np.integer, np.floating)):
        if goal is not None:
            raise UserError("a policy mix has no goal: it covers the room.")
        if steps is None or epoch is None or rng is None:
            raise UserError("a policy mix needs steps, epoch and rng.")
        return MixRunner(policy, robot, cells, start, back_off, steps, epoch, rng, max_stuck,
                         record_trace, max_time)
    if steps is not None or epoch is not None or max_stuck is not None:
        raise UserError("steps, epoch and max_stuck are for policy mixes; a plan runs its "
                        "segments.")
    return PlanRunner(policy, robot, cells, start, goal, back_off, max_factor, on_segment)


def _drive(runner, robot: Robot, trace: Trace, t0: float, speed: float,
           max_time: float | None, record: bool) -> str:
    """Make the robot do every move the runner yields; the run's reason ('' = finished)."""
    moves = runner.moves(robot.true_pose())
    answer = None
    while True:
        try:
            move = moves.send(answer)
        except StopIteration as done:
            return done.value or ""
        kind = type(move)
        if kind is Drive or kind is Fly:
            if max_time is not None:
                late = time_up(robot.clock() - t0, max_time)
                if late:
                    moves.close()
                    return late
            if kind is Fly:
                ev = robot.drive_until_bump(speed, move.limit_m / speed)
            else:
                ev = robot.drive_for(speed, move.distance_m / speed)
            answer = Moved(ev, speed * ev.elapsed, robot.true_pose(), robot.clock() - t0)
        elif kind is Turn:
            robot.turn(move.angle_deg)
            answer = Moved(None, 0.0, robot.true_pose(), robot.clock() - t0)
            if record:
                trace.add(answer.t, answer.pose, "turn", f"{move.angle_deg:g}")
        elif kind is BackOff:
            # by the clock, not drive_for: the bumper is still pressed
            robot.drive(-speed)
            try:
                robot.wait(move.distance_m / speed)
            finally:
                robot.stop()
            answer = Moved(None, 0.0, robot.true_pose(), robot.clock() - t0)
            if record:
                trace.add(answer.t, answer.pose, "back_off", f"{move.distance_m:g} m")
        elif kind is Note:
            if record:
                pose = move.pose if move.pose is not None else robot.true_pose()
                trace.add(robot.clock() - t0, pose, move.event, move.detail)
            answer = None
        else:
            raise TypeError(f"a runner yielded {move!r}, not a move.")


# ============================================================================ feedback
def navigate_feedback(robot: Robot, env: Environment | None, start, goal: int, noise,
                      rng: np.random.Generator, *, angles=(45.0, 90.0, 135.0),
                      cells: CellSpace | None = None, config: FeedbackConfig | None = None,
                      speed: float = 0.2, back_off: float = 0.0, w1: float = 1.0,
                      w2: float = 100.0, max_bumps: int = DEFAULT_MAX_BUMPS,
                      max_time: float | None = None,
                      on_belief=None, contact="auto") -> FeedbackRun:
    """Drive ``robot`` from ``start`` to the goal configuration by feedback (§15):
    ``execute(FeedbackPlanner(...).policy(start, goal), robot)``.

    Parameters
    ----------
    robot : Robot           any body with the bump-and-clock interface
    env : Environment       the room (default ``robot.env``)
    start : int or (x, y, heading)   start configuration z or pose [m, m, deg]; the filter
                            starts there, simulators are placed there
    goal : int              goal configuration z
    noise : NoiseModel, float or None
        The declared turn noise (the filter's motion model,
        :func:`planners.navigation.feedback.declared_sigma`); not applied to the robot,
        which brings its own.
    rng : numpy.random.Generator   the filter's and the decision rule's draws
    angles : bouncing angles Φ [deg];  w1, w2 : §13's weights
    config : FeedbackConfig   its ``turn_sigma_deg`` is replaced by the declared noise's σ
    speed : float [m/s];  back_off : float [m] reversed after every bump before turning
    max_bumps : int         give up after this many bumps
    max_time : float        give up after this many seconds of robot clock
    on_belief : callable, optional
        Called as ``on_belief(event, belief)`` after every filter step (``"flight"``,
        ``"turn"``): for tests and plots.
    contact : "auto", ContactParams or None
        The contact rule of the filter's motion model and the plan search (§15, §9).
        "auto" (default): ``config.contact`` when set, else the body's
        (:func:`body_contact`: PyBullet's fitted rule for a PyBullet body, the twin's own
        opt-in rule, else the front-half bumper); None: the front-half bumper.

    Returns
    -------
    FeedbackRun   success as §21 (final position in the goal cell, heading within ±Δ/2)

    Examples
    --------
    >>> import envs
    >>> import numpy as np
    >>> from bouncesim.robots.kinematic import KinematicRobot
    >>> env = envs.load("lab")
    >>> run = navigate_feedback(KinematicRobot(env), env, 8, 0, None,
    ...                         np.random.default_rng(0), angles=(90, 135))
    >>> run.success, run.reason, run.bumps
    (True, 'reached the goal', 4)
    """
    env = env if env is not None else getattr(robot, "env", None)
    if env is None:
        raise UserError(f"{type(robot).__name__} knows no environment: pass env.")
    cells = cells if cells is not None else CellSpace(env)
    planner = FeedbackPlanner(cells, angles, w1, w2, noise=noise, rng=rng, contact=contact,
                              config=config)
    policy = planner.policy(start, goal, max_bumps=max_bumps, on_belief=on_belief)
    return execute(policy, robot, cells=cells, speed=speed, back_off=back_off,
                   max_time=max_time)
