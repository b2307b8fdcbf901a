"""Feedback navigation on any body (docs/model.md §15): the runner of a
:class:`~planners.navigation.feedback.FeedbackPolicy` in the one run loop, and its record.

The runner uses only the bump-and-clock interface of :class:`bouncesim.robots.base.Robot`
(through :func:`bouncesim.runs.execute.execute`), so it runs unchanged on the kinematic twin,
PyBullet, the Create 2 and its emulator, and on a user's own body. After every bump the filter
(:class:`planners.navigation.feedback.ParticleFilter`) takes the flight's distance (speed ×
elapsed time) and bumper side, and the navigator
(:class:`planners.navigation.feedback.FeedbackNavigator`) picks the next bouncing angle; after
the last turn it picks the final drive that puts the most belief mass in the goal cell, and
makes it when enough of the belief ends there (``FeedbackConfig.final_min``; else it flies
on). Simulators are placed at the start and their true pose is logged and used for the
success check only.

The front door is :func:`bouncesim.runs.execute.navigate_feedback`.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from envs import UserError
from envs.motion import STEP_TOL, ContactParams
from planners.cells import CellSpace
from planners.measures import flight_cap
from planners.navigation.feedback import ParticleFilter
from planners.plan import Plan

from ..robots.base import Robot
from .moves import BackOff, Drive, Fly, Note, Turn
from .results import PlanRun
from .runners import place_if_simulated, plan_result, side_text
from .trace import Trace

__all__ = ["FeedbackRun", "FeedbackRunner", "body_contact", "body_turns"]


@dataclass(frozen=True)
class FeedbackRun(PlanRun):
    """A :class:`~bouncesim.runs.results.PlanRun` of a feedback run; ``plan`` is the plan
    that was executed (its angles, the measured flights and the final drive).

    Extra attributes
    ----------------
    decision_ms : tuple of float   wall time of each decision [ms] (filter update after the
                                   bump, planning, scoring, the turn, and the final drive's
                                   choice)
    decision_cpu_ms : tuple of float   the same in CPU time of this process [ms] (what a
                                   decision costs on a machine not shared with others)
    updates : tuple of FlightUpdate   the filter's record of every bump
    p_success : tuple of float     the chosen plan's estimated success at each decision
    no_plan : int                  decisions where no particle's pose had a plan (a random
                                   angle was turned)
    bumps_to_localize : int or None  bumps until the belief had localized (0 for a known
                                   start; None: it never did)
    turn_estimate : tuple          the belief's final estimate of the turn's constant factor
                                   and offset: (factor, its std, offset [deg], its std)
    stop_mass : float              the belief's mass in the goal cell when the final drive
                                   was chosen (nan: the run ended without one)
    assumed_turns : dict           the turn model the filter assumed: the declared noise
                                   with the body's own errors added (:func:`body_turns`):
                                   sigma [deg], scale, bias [deg], factor, offset [deg]
    """

    decision_ms: tuple = ()
    decision_cpu_ms: tuple = ()
    updates: tuple = ()
    p_success: tuple = ()
    no_plan: int = 0
    bumps_to_localize: int | None = 0
    turn_estimate: tuple = (1.0, 0.0, 0.0, 0.0)
    stop_mass: float = math.nan
    assumed_turns: dict | None = None

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
                    "bumps_to_localize": self.bumps_to_localize,
                    "turn_factor": round(self.turn_estimate[0], 5),
                    "turn_factor_sd": round(self.turn_estimate[1], 5),
                    "turn_offset_deg": round(self.turn_estimate[2], 4),
                    "turn_offset_sd": round(self.turn_estimate[3], 4),
                    "lost": sum(1 for u in self.updates if u.lost),
                    "stop_mass": None if math.isnan(self.stop_mass)
                    else round(float(self.stop_mass), 4),
                    "p_success": [round(float(v), 4) for v in self.p_success],
                    "assumed_turns": self.assumed_turns})
        return out


def body_contact(robot, speed: float | None = None) -> ContactParams | None:
    """The contact rule (docs/model.md §9) a body declares: for a body whose rule depends on
    its drive speed [m/s] (MuJoCo's, whose turn-in slides shorten as it slows) its
    ``contact_at(speed)``; else its ``contact`` attribute when that is a
    :class:`~envs.motion.ContactParams` (PyBullet's fitted ``envs.motion.PYBULLET_CONTACT``,
    the twin made with ``contact=`` or ``glance_deg=``, a wrapper's body's, the Create 2 and
    Create 3 adapters on an emulator: the emulated body's); for any other body (the twin by
    default, a real Create 2 or Create 3, a user's own) the front-half bumper (None).
    """
    at = getattr(robot, "contact_at", None)
    rule = at(speed) if callable(at) and speed is not None else getattr(robot, "contact", None)
    return rule if isinstance(rule, ContactParams) else None


def body_turns(robot, speed: float | None = None) -> str | None:
    """The turn errors a body declares of itself (docs/model.md §15, "A body's own turns"):
    for a body whose turns depend on the speed [m/s] of the drive into the bump before them
    (MuJoCo's) its ``turn_errors_at(speed)``; else its ``turn_errors`` attribute, a noise
    spec in the one grammar (:func:`planners.noise.parse_noise_spec`), e.g.
    ``"gauss:0.6,offset=-1.26"`` for a body whose turns are measured 1.26° short with a
    scatter of 0.6° (``python -m experiments.body_turns``). The filter adds them to the
    declared noise. None (a body that declares nothing: the twin, a real robot): exact turns
    of its own.
    """
    at = getattr(robot, "turn_errors_at", None)
    errors = at(speed) if callable(at) and speed is not None else \
        getattr(robot, "turn_errors", None)
    return errors if isinstance(errors, str) else None


class FeedbackRunner:
    """The runner of a :class:`~planners.navigation.feedback.FeedbackPolicy` (§15): decide,
    turn, fly, update the belief, back off, and so on, until the final drive.
    """

    finished = "plan finished"

    def __init__(self, policy, robot: Robot, *, start=None, goal=None,
                 cells: CellSpace | None = None, back_off: float = 0.0,
                 speed: float | None = None) -> None:
        planner = policy.planner
        self.policy, self.planner = policy, planner
        if cells is not None and cells is not planner.cells and \
                cells.env is not planner.cells.env:
            raise UserError("the feedback policy was planned for another cell space.")
        cs = self.cells = planner.cells
        if goal is not None and int(goal) != policy.goal:
            raise UserError(f"the feedback policy goes to {policy.goal}, not to {goal}.")
        start = policy.start if policy.start is not None else start
        if planner.rng is None:
            raise UserError("the feedback planner needs an rng (a numpy Generator).")
        if start is None:                       # unknown: the body starts wherever it is
            self.start_pose = None
        elif isinstance(start, (int, np.integer)):
            self.start_pose = cs.pose(int(start))
        else:
            self.start_pose = tuple(float(v) for v in start)
        self.back_off, self.rng = float(back_off), planner.rng
        self.contact = planner.resolved(body_contact(robot, speed))
        self.fnav = planner.navigator(policy.goal, self.contact, policy.max_bumps,
                                      body_turns(robot, speed) if planner.config.body_turns
                                      else None)
        self.cfg = self.fnav.cfg
        if self.fnav.by_value:
            _ = self.fnav.value                 # set-up before the robot moves, not a decision
        self.goal_pose = cs.pose(policy.goal)
        place_if_simulated(robot, self.start_pose)      # hardware: a person placed the robot
        self.belief = ParticleFilter(cs.env, self.cfg, self.rng, start=self.start_pose,
                                     region=policy.region)
        self.localizing = self.start_pose is None
        self.bumps_to_localize = None if self.localizing else 0
        self.label = f"feedback to {policy.goal}" + (" from an unknown start"
                                                      if self.localizing else "")
        self.turns, self.flights, self.final = [], [], 0.0
        self.decision_ms, self.decision_cpu, self.updates, self.p_succ = [], [], [], []
        self.no_plan, self.completed, self.stop_mass = 0, False, math.nan

    def moves(self, pose):
        """The run's moves from the true start ``pose`` (a generator; its value: the
        reason the run ended, '' when the policy finished).
        """
        fnav, belief, cfg, rng = self.fnav, self.belief, self.cfg, self.rng
        turns, flights, rest = self.turns, self.flights, ()
        self._tick, self._cpu, at_start = time.perf_counter(), time.process_time(), True
        while self.localizing:                 # an unknown start: angles that localize
            if not at_start:
                angle = fnav.localizing_angle(belief)
                self._note_decision()
                yield from self._turn(angle)
            reason = yield from self._fly()
            if reason is not None:
                return reason
            at_start = False
            if belief.localized(self.cells.h / 2, self.cells.delta_deg / 2):
                self.localizing = False
                self.bumps_to_localize = len(self.updates)
                belief.size = cfg.particles
        while True:
            shift = (fnav.heading_offset(belief) if cfg.correct_heading and not at_start
                     else 0.0)
            cands = fnav.choose(belief, rng, keep=rest, bumped=not at_start, shift=shift,
                                left=self.policy.max_bumps - len(flights))
            if cands:
                best = cands[0]
                self.p_succ.append(best.p_success)
            else:
                self.no_plan += 1
                best = None
            todo = list(best.angles) if best is not None else [float(rng.choice(fnav.nav.angles))]
            if not todo:                       # already on the final flight (or in the cell)
                self.final, self.stop_mass = fnav.final(belief.pos, belief.heading,
                                                        belief.weights)
                self._note_decision()
                if flights and len(flights) > len(turns):
                    self.final += flights.pop()     # the flight into the cell ends the plan
                if self.final > 0:
                    yield Drive(self.final)
                self.completed = True
                return ""
            if not at_start:
                yield from self._turn(float(todo.pop(0)) - shift)
            rest = tuple(todo)
            if not todo and best is not None:  # the last turn: the final drive
                self.final, mass = fnav.final(belief.pos, belief.heading, belief.weights)
                if fnav.stops(mass, last=len(flights) >= self.policy.max_bumps - 1,
                              need=best.stop_min):
                    # else (too little belief mass stops in the cell, §15): fly on
                    self.stop_mass = mass
                    self._note_decision()
                    if self.final > 0:
                        res = yield Drive(self.final)
                        ev = res.event
                        if ev.bumped and res.travelled < self.final - STEP_TOL:
                            yield Note("bump", side_text(ev), res.pose)
                    self.completed = True
                    return ""
            if not at_start:
                self._note_decision()
            reason = yield from self._fly()
            if reason is not None:
                return reason
            at_start = False

    def _note_decision(self) -> None:
        self.decision_ms.append(1e3 * (time.perf_counter() - self._tick))
        self.decision_cpu.append(1e3 * (time.process_time() - self._cpu))

    def _turn(self, angle: float):
        """Turn so that the robot turns by ``angle`` [deg] under the belief's estimate of the
        turn's factor and offset (the command itself when nothing is uncertain), and predict
        the command in the belief.
        """
        command = self.belief.command_for(angle)
        yield Turn(command)
        self.belief.turn(command)
        self.turns.append(command)
        if self.policy.on_belief is not None:
            self.policy.on_belief("turn", self.belief)

    def _fly(self):
        """Fly to the next bump and update the belief (a missed bump too, when declared);
        back off. Returns the reason to end the run, or None.
        """
        cap, belief = flight_cap(self.cells), self.belief
        if len(self.flights) >= self.policy.max_bumps:
            return f"gave up after {self.policy.max_bumps} bumps"
        res = yield Fly(cap)
        ev, d = res.event, res.travelled
        if not ev.bumped:
            yield Note("no_bump", f"{d:.3f} m", res.pose)
            if self.cfg.p_miss <= 0:
                return f"no bump within {cap:.2f} m"
        else:
            yield Note("bump", side_text(ev), res.pose)
        self._tick, self._cpu = time.perf_counter(), time.process_time()
        self.flights.append(d)
        # a drive that read no bump within the cap: a missed bump (docs/model.md §15)
        self.updates.append(belief.flight(d, ev.left, ev.right) if ev.bumped
                            else belief.missed(d))
        if self.policy.on_belief is not None:
            self.policy.on_belief("flight", belief)
        if self.back_off > 0:
            yield BackOff(self.back_off)
            belief.back_off(self.back_off)
        return None

    def result(self, reason: str, elapsed: float, final, trace: Trace) -> FeedbackRun:
        """The run's record from the loop's ending (reason, clock [s], final pose)."""
        flights = self.flights[:len(self.turns)]
        plan = Plan.exact(self.turns, flights, self.final, self.cells.h, planner="feedback")
        return plan_result(self.cells, plan, self.policy.goal, self.goal_pose, self.completed,
                           reason, final, elapsed, (), len(self.updates), self.start_pose,
                           trace, cls=FeedbackRun, decision_ms=tuple(self.decision_ms),
                           decision_cpu_ms=tuple(self.decision_cpu),
                           updates=tuple(self.updates), p_success=tuple(self.p_succ),
                           no_plan=self.no_plan, bumps_to_localize=self.bumps_to_localize,
                           turn_estimate=self.belief.turn_estimate(),
                           stop_mass=self.stop_mass, assumed_turns={
                               "sigma": round(self.cfg.turn_sigma_deg, 6),
                               "scale": self.cfg.turn_scale, "bias": self.cfg.turn_bias_deg,
                               "factor": self.cfg.turn_factor,
                               "offset": round(self.cfg.turn_offset_deg, 6)})
