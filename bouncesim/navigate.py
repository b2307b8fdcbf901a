"""Feedback navigation on any body: :func:`navigate_feedback` (docs/model.md §22).

The loop uses only the bump-and-clock interface of :class:`bouncesim.robots.base.Robot`
(drive until bump, turn, drive for a time, bumper sides, the clock), so it runs unchanged on
the kinematic twin, PyBullet, the Create 2 and its emulator, and on a user's own body. After
every bump the filter (:class:`planners.navigation.feedback.ParticleFilter`) takes the flight's
distance (speed × elapsed time) and bumper side, and the navigator
(:class:`planners.navigation.feedback.FeedbackNavigator`) picks the next bouncing angle; after the last
turn it picks the final drive that puts the most belief mass in the goal cell, and makes it
when enough of the belief ends there (``FeedbackConfig.final_min``; else it flies on).
Simulators are placed at the start and their true pose is logged and used for the success
check only.

Examples
--------
>>> import envs
>>> import numpy as np
>>> from bouncesim.robots.kinematic import KinematicRobot
>>> env = envs.load("lab")
>>> run = navigate_feedback(KinematicRobot(env), env, 8, 0, None, np.random.default_rng(0),
...                         angles=(90, 135))
>>> run.success, run.reason, run.bumps
(True, 'reached the goal', 4)
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace

import numpy as np

from envs import Environment, UserError
from envs.motion import PYBULLET_CONTACT, STEP_TOL, ContactParams
from planners.cells import CellSpace
from planners.navigation.feedback import FeedbackConfig, FeedbackNavigator, ParticleFilter
from planners.plan import Plan

from .robots.base import Robot, RobotError
from .runs.execute import check_speed, place_if_simulated
from .runs.results import PlanRun
from .runs.trace import Trace

__all__ = ["FeedbackRun", "body_contact", "declared_sigma", "navigate_feedback"]


@dataclass(frozen=True)
class FeedbackRun(PlanRun):
    """A :class:`~bouncesim.runs.results.PlanRun` of a feedback run; ``plan`` is the plan
    that was executed (its angles, the measured flights and the final drive).

    Extra attributes
    ----------------
    decision_ms : tuple of float   wall time of each decision [ms] (filter update after the
                                   bump, planning, scoring, and the final drive's choice)
    decision_cpu_ms : tuple of float   the same in CPU time of this process [ms] (what a
                                   decision costs on a machine not shared with others)
    updates : tuple of FlightUpdate   the filter's record of every bump
    p_success : tuple of float     the chosen plan's estimated success at each decision
    no_plan : int                  decisions where no particle's pose had a plan (a random
                                   angle was turned)
    """

    decision_ms: tuple = ()
    decision_cpu_ms: tuple = ()
    updates: tuple = ()
    p_success: tuple = ()
    no_plan: int = 0

    @property
    def reinits(self) -> int:
        """Bumps after which the belief was re-initialised (no particle fitted)."""
        return sum(1 for u in self.updates if u.reinit)

    def to_json(self) -> dict:
        """:meth:`PlanRun.to_json` plus the planner, decision times [ms], re-initialisations
        and the estimated success of every decision.
        """
        out = super().to_json()
        out.update({"planner": "feedback",
                    "decision_ms": [round(float(v), 3) for v in self.decision_ms],
                    "max_decision_ms": round(max(self.decision_ms, default=0.0), 3),
                    "decision_cpu_ms": [round(float(v), 3) for v in self.decision_cpu_ms],
                    "reinits": self.reinits, "no_plan": self.no_plan,
                    "p_success": [round(float(v), 4) for v in self.p_success]})
        return out


def declared_sigma(noise) -> float:
    """The turn noise σ [deg] the filter assumes for a noise model: a Gaussian's σ, the
    standard deviation of the §7 model's offsets, 0 for exact turns; a number is σ itself.
    """
    if noise is None:
        return 0.0
    if isinstance(noise, (int, float)):
        return float(noise)
    if getattr(noise, "exact", False):
        return 0.0
    if hasattr(noise, "sigma_deg"):
        return float(noise.sigma_deg)
    if hasattr(noise, "offsets"):
        d, p = noise.offsets()
        return float(math.sqrt(np.sum(p * d * d)))
    raise UserError(f"the feedback planner cannot read a turn noise σ from {noise!r}.")


def body_contact(robot) -> ContactParams | None:
    """The contact rule (docs/model.md §23) a body declares, as ``validate --contact auto``
    takes it: a PyBullet body has ``envs.motion.PYBULLET_CONTACT``; a body with a
    ``contact`` attribute that is a :class:`~envs.motion.ContactParams` (the twin made with
    ``contact=`` or ``glance_deg=``) has that one; any other body (the twin by default, the
    Create 2 and its emulator, a user's own) the front-half bumper (None).
    """
    if type(robot).__module__.startswith("bouncesim.robots.pybullet"):
        return PYBULLET_CONTACT
    rule = getattr(robot, "contact", None)
    return rule if isinstance(rule, ContactParams) else None


def _side(ev) -> str:
    return "+".join(s for s, on in (("left", ev.left), ("right", ev.right)) if on) or "none"


def navigate_feedback(robot: Robot, env: Environment | None, start, goal: int, noise,
                      rng: np.random.Generator, *, angles=(45.0, 90.0, 135.0),
                      cells: CellSpace | None = None, config: FeedbackConfig | None = None,
                      speed: float = 0.2, back_off: float = 0.0, w1: float = 1.0,
                      w2: float = 100.0, max_bumps: int = 40, max_time: float | None = None,
                      on_belief=None, contact="auto") -> FeedbackRun:
    """Drive ``robot`` from ``start`` to the goal configuration by feedback (§22).

    Parameters
    ----------
    robot : Robot           any body with the bump-and-clock interface
    env : Environment       the room (default ``robot.env``)
    start : int or (x, y, heading)   start configuration z or pose [m, m, deg]; the filter
                            starts there, simulators are placed there
    goal : int              goal configuration z
    noise : NoiseModel, float or None
        The declared turn noise (the filter's motion model, :func:`declared_sigma`); not
        applied to the robot, which brings its own.
    rng : numpy.random.Generator   the filter's and the decision rule's draws
    angles : bouncing angles Φ [deg];  w1, w2 : §15's weights
    config : FeedbackConfig   its ``turn_sigma_deg`` is replaced by the declared noise's σ
    speed : float [m/s];  back_off : float [m] reversed after every bump before turning
    max_bumps : int         give up after this many bumps
    max_time : float        give up after this many seconds of robot clock
    on_belief : callable, optional
        Called as ``on_belief(event, belief)`` after every filter step (``"flight"``,
        ``"turn"``): for tests and plots.
    contact : "auto", ContactParams or None
        The contact rule of the filter's motion model and the plan search (§22, §23).
        "auto" (default): ``config.contact`` when set, else the body's
        (:func:`body_contact`: PyBullet's fitted rule for a PyBullet body, the twin's own
        opt-in rule, else the front-half bumper); None: the front-half bumper.

    Returns
    -------
    FeedbackRun   success as §8 (final position in the goal cell, heading within ±Δ/2)
    """
    env = env if env is not None else getattr(robot, "env", None)
    if env is None:
        raise UserError(f"{type(robot).__name__} knows no environment: pass env.")
    cells = cells if cells is not None else CellSpace(env)
    speed = check_speed(speed, robot)
    back_off = float(back_off)
    if not (math.isfinite(back_off) and back_off >= 0):
        raise UserError(f"back-off must be a non-negative distance in metres, got {back_off:g}.")
    cfg = config if config is not None else FeedbackConfig()
    if isinstance(contact, str):
        if contact != "auto":
            raise UserError(f"contact must be 'auto', a ContactParams or None, got {contact!r}.")
        contact = cfg.contact if cfg.contact is not None else body_contact(robot)
    cfg = replace(cfg, turn_sigma_deg=declared_sigma(noise), contact=contact)
    fnav = FeedbackNavigator(cells, angles, goal, cfg, w1, w2)
    if isinstance(start, (int, np.integer)):
        start_pose = cells.pose(fnav.nav._check(start, "start"))
    else:
        start_pose = tuple(float(v) for v in start)
    goal_pose = cells.pose(fnav.goal)
    place_if_simulated(robot, start_pose)      # hardware: a person placed the robot
    belief = ParticleFilter(env, cfg, rng, start=start_pose)
    x0, y0, x1, y1 = env.bounds
    cap = math.hypot(x1 - x0, y1 - y0) + cells.h
    trace, t0 = Trace(), robot.clock()
    trace.add(0.0, robot.true_pose(), "start", f"feedback to {fnav.goal}")
    turns, flights, decision_ms, decision_cpu, updates, p_succ = [], [], [], [], [], []
    final, no_plan, completed, reason, rest = 0.0, 0, False, "", ()

    def note_decision() -> None:
        decision_ms.append(1e3 * (time.perf_counter() - tick))
        decision_cpu.append(1e3 * (time.process_time() - cpu))

    def log(event: str, detail: str = "") -> None:
        trace.add(robot.clock() - t0, robot.true_pose(), event, detail)

    try:
        tick, cpu, at_start = time.perf_counter(), time.process_time(), True
        while True:
            shift = (fnav.heading_offset(belief) if cfg.correct_heading and not at_start
                     else 0.0)
            cands = fnav.choose(belief, rng, keep=rest, bumped=not at_start, shift=shift)
            if cands:
                best = cands[0]
                p_succ.append(best.p_success)
            else:
                no_plan += 1
                best = None
            todo = list(best.angles) if best is not None else [float(rng.choice(fnav.nav.angles))]
            if not todo:                       # already on the final flight (or in the cell)
                final, _ = fnav.final(belief.pos, belief.heading, belief.weights)
                note_decision()
                if flights and len(flights) > len(turns):
                    final += flights.pop()     # the flight into the cell ends the plan
                if final > 0:
                    robot.drive_for(speed, final / speed)
                completed = True
                break
            if not at_start:
                angle = float(todo.pop(0)) - shift
                robot.turn(angle)
                belief.turn(angle)
                turns.append(angle)
                log("turn", f"{angle:g}")
                if on_belief is not None:
                    on_belief("turn", belief)
            rest = tuple(todo)
            if not todo and best is not None:  # the last turn: the final drive
                final, mass = fnav.final(belief.pos, belief.heading, belief.weights)
                if fnav.stops(mass, last=len(flights) >= max_bumps - 1):
                    # else (too little belief mass stops in the cell, §22): fly on
                    note_decision()
                    ev = robot.drive_for(speed, final / speed) if final > 0 else None
                    if ev is not None and ev.bumped and speed * ev.elapsed < final - STEP_TOL:
                        log("bump", _side(ev))
                    completed = True
                    break
            if not at_start:
                note_decision()
            if max_time is not None and robot.clock() - t0 > max_time:
                reason = f"time limit of {max_time:g} s exceeded"
                break
            if len(flights) >= max_bumps:
                reason = f"gave up after {max_bumps} bumps"
                break
            ev = robot.drive_until_bump(speed, cap / speed)
            d = speed * ev.elapsed
            if not ev.bumped:
                log("no_bump", f"{d:.3f} m")
                reason = f"no bump within {cap:.2f} m"
                break
            log("bump", _side(ev))
            tick, cpu = time.perf_counter(), time.process_time()
            flights.append(d)
            updates.append(belief.flight(d, ev.left, ev.right))
            if on_belief is not None:
                on_belief("flight", belief)
            if back_off > 0:
                robot.drive(-speed)
                try:
                    robot.wait(back_off / speed)
                finally:
                    robot.stop()
                belief.back_off(back_off)
                log("back_off", f"{back_off:g} m")
            at_start = False
    except RobotError as exc:
        log("error", str(exc))
        reason = f"robot error: {exc}"
    finally:
        robot.stop()
    flights = flights[:len(turns)]
    plan = Plan.exact(turns, flights, final, cells.h, planner="feedback")
    elapsed = robot.clock() - t0
    final_pose = robot.true_pose()
    success, pos_err, head_err = _check(cells, fnav.goal, goal_pose, final_pose)
    if completed:
        if success is None:
            reason = "plan finished (success unknown without a pose)"
        elif success:
            reason = "reached the goal"
        else:
            reason = (f"ended {pos_err:.3f} m from the goal cell's centre, heading off by "
                      f"{head_err:+.1f}°")
    elif final_pose is not None:
        success = False
    trace.add(elapsed, final_pose, "stop", reason)
    return FeedbackRun(plan=plan, success=success, reason=reason, completed=completed,
                       final_pose=final_pose, position_error=pos_err, heading_error=head_err,
                       deviations=(), bumps=len(updates), elapsed=elapsed,
                       start_pose=start_pose, goal_pose=goal_pose, trace=trace,
                       decision_ms=tuple(decision_ms), decision_cpu_ms=tuple(decision_cpu),
                       updates=tuple(updates),
                       p_success=tuple(p_succ), no_plan=no_plan)


def _check(cells: CellSpace, goal: int, goal_pose, final) -> tuple:
    """(success, position error [m], heading error [deg]) of a final pose, as §8."""
    if final is None:
        return None, None, None
    gx, gy, gh = goal_pose
    pos_err = math.hypot(final[0] - gx, final[1] - gy)
    head_err = (final[2] - gh + 180.0) % 360.0 - 180.0
    in_cell = int(cells.cell_of_point([final[:2]])[0]) == int(cells.pk(goal)[0])
    return bool(in_cell and abs(head_err) <= cells.delta_deg / 2 + 1e-9), pos_err, head_err

