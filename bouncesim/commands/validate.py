"""``bouncesim validate ENV``: predicted against simulated coverage, angle by angle.

For every bouncing angle (and, with ``--alpha``, the policy mix) it predicts the coverage q
with a coverage model (:func:`planners.coverage.model_for`, ``analyse``; a mix with
:func:`planners.coverage.timeshared_coverage`), simulates the step-sampled visit histogram q̂
(docs/model.md §8) on the kinematic twin (:class:`~bouncesim.robots.kinematic.KinematicBatch`)
in PyBullet (:class:`~bouncesim.robots.pybullet.batch.PyBulletBatch`) or in MuJoCo
(:class:`~bouncesim.robots.mujoco.batch.MuJoCoBatch`) through the seeded,
resumable sweep runner (:mod:`bouncesim.runs.sweep`), and compares them: TV(q, q̂), the noise
floor (TV between two independent halves of the simulation), the steps behind q̂ and the
bumps per step of the model and of the simulation.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

import envs
from envs import UserError
from envs.motion import ContactParams
from planners.cells import CellSpace
from planners.coverage import (
    MODELS,
    TurnNoise,
    check_angles,
    design_mix,
    model_for,
    timeshared_coverage,
)
from planners.metrics import floors, tv_distance
from planners.plan import PolicyMix

from ..runs.executors import add_executor_args, make_executor
from ..runs.sweep import Sweep, run_sweep
from .common import (
    add_angle_noise_args,
    add_contact_arg,
    add_env_args,
    cli_provenance,
    contact_name,
    contact_rule,
    load_env,
    make_cells,
    parse_angles,
    print_json,
    report_written,
    writable_path,
)

__all__ = ["register", "run", "simulate_trial", "more_trials", "floors", "protocol_prediction",
           "BACKENDS"]

BACKENDS = ("kinematic", "pybullet", "mujoco")
DEFAULT_STEPS = {"kinematic": 1_000_000, "pybullet": 40_000, "mujoco": 40_000}
"""Steps per angle: all of them (kinematic), or the first round's (pybullet, mujoco, which
then add trials until the floor target is met)."""
DEFAULT_FLOOR = {"kinematic": None, "pybullet": 0.02, "mujoco": 0.02}
"""The floor target of a run without --steps (None: the steps are fixed)."""
MAX_STEPS = 1_000_000
"""Default cap on the steps per angle of a run with a floor target."""
ROBOTS = {"kinematic": 200, "pybullet": 16, "mujoco": 16}
"""Robots per simulated batch (one sweep trial)."""
PER_ROBOT = {"kinematic": 2500, "pybullet": 625, "mujoco": 625}
"""Counted steps per robot in one trial, about (trials are cut to at least two halves)."""
BURN_IN = {"kinematic": 200, "pybullet": 50, "mujoco": 50}
TEAM_STEPS = 100_000
"""Default steps per angle of a team run (--robots K: one world of K robots per trial)."""
TEAM_PER_ROBOT = 2500
BACKEND_TEAMS = {"kinematic": True, "pybullet": True, "mujoco": False}
"""Backends whose worlds run teams that bump each other (--robots K)."""
FAST_FORWARD = {"on": {}, "turns": {"turns": True}, "no-slides": {"slides": False},
                "off": None}
"""``--fast-forward``: the :class:`FastForward` settings changed from the default, or None
(every physics step simulated)."""


def fast_forward(name: str):
    """The PyBulletBatch ``fast_forward`` of a ``--fast-forward`` choice.

    >>> fast_forward("off") is None, fast_forward("on").turns, fast_forward("turns").turns
    (True, False, True)
    """
    from ..robots.pybullet.fastforward import FastForward
    changes = FAST_FORWARD[name]
    return None if changes is None else FastForward(**changes)

DESCRIPTION = """\
For every bouncing angle: the coverage q predicted by --model and the step-sampled visit
histogram of a simulation on --backend (docs/model.md section 22: a step drives one cell by the
clock or until a bump; runs start uniformly over the configurations and a burn-in is not
counted). Prints per angle: tv = TV(q, simulated), floor = TV between two independent halves of
the simulation (what sampling noise alone gives at half the steps; a model that is right has
tv near floor/2: each half has sqrt(2) times the pooled noise), steps = simulated steps, and
the bumps per step of the model and of the simulation. With --alpha also the policy mix,
executed in epochs of --epoch steps and predicted by the model's time-shared coverage
(docs/model.md section 19). --contact sets the contact rule of the event model and the
kinematic twin (docs/model.md section 9); the default follows the simulated body.

tv compares the simulation with the model's limit; tv_runs with the model's prediction of the
runs themselves (the horizon coverage of docs/model.md section 20: the uniform start, the
burn-in not counted, the counted steps of one run), and runs_to_limit (JSON) is the TV
between the two predictions. Where runs_to_limit exceeds the floor, validate says the runs
are too short for the limit: compare tv_runs.

Halves are groups of whole trials (batches of independent robots with their own seeds), never
stretches of one robot's run, so they are independent. floor_splits (JSON) is the mean floor
over 200 random splits of the trials into two equal groups: the same quantity, less noisy.
Steps: the kinematic default is 1e6 per angle. PyBullet (and MuJoCo) without --steps runs
until every floor and floor_splits is <= 0.02: a first round of 40 000 steps per angle (4
trials of 16 robots x 625 steps), then more trials for the angles still above, sized by
floor ~ 1/sqrt(steps), up to 1e6 steps per angle (--max-steps; an angle that stops at the
cap is reported on stderr).
--steps N fixes the count; --floor F with --steps N makes N the first round.

Teams (--robots K, kinematic or pybullet; docs/model.md section 24): each trial is one room
with K robots that start in distinct cells and bounce by the angle; --interact bump (default)
makes robot-robot contact a bump, as real robots feel it, --interact off lets them pass
through each other. The prediction stays the model's single-robot coverage (K independent
robots share it), so with --interact bump tv measures how far the robots' meetings move the
team's coverage; meetings_per_1000_steps says how often a robot's flight was ended by
another. Steps default to 100 000 per angle (2500 per robot and trial); in PyBullet a team
that bumps simulates every physics step (no fast-forward), about 13x slower than passing.
"""

EXAMPLES = """\
examples:
  bouncesim validate lab --orientations 72 --angles 30,75,315 --eps 5 --r 0.8 --model event
  bouncesim validate lab --orientations 72 --angles 75 --eps 5 --r 0.8 --model event \\
      --backend pybullet --steps 20000 --json
  bouncesim validate fig1 --orientations 72 --angles 30,75,315 --eps 5 --r 0.8 --alpha design
  bouncesim validate complex --orientations 72 --angles 75 --eps 5 --r 0.8 --robots 4
"""


def register(sub) -> None:
    """Add the ``validate`` sub-command to the CLI's sub-parsers."""
    p = sub.add_parser("validate", help="predicted against simulated coverage, per angle",
                       description=DESCRIPTION, epilog=EXAMPLES,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    add_env_args(p)
    add_angle_noise_args(p)
    p.add_argument("--model", choices=list(MODELS), default="event",
                   help="coverage model (default event)")
    p.add_argument("--backend", choices=BACKENDS, default="kinematic",
                   help="simulator (default kinematic)")
    p.add_argument("--steps", type=int, default=None, metavar="N",
                   help="simulated steps per angle, after the burn-in (default 1e6 "
                   "kinematic; pybullet, mujoco: until the floor target, see --floor)")
    p.add_argument("--floor", type=float, default=None, metavar="F",
                   help="add trials until every angle's floor (and floor_splits) is <= F "
                   "(default 0.02 for pybullet and mujoco without --steps; with --steps N, "
                   "N is the first round)")
    p.add_argument("--max-steps", type=int, default=MAX_STEPS, metavar="N",
                   help="cap on the steps per angle with a floor target (default 1e6)")
    p.add_argument("--burn-in", type=int, default=None, metavar="N",
                   help="steps per robot run first and not counted (default 200 kinematic, "
                   "50 pybullet and mujoco)")
    p.add_argument("--alpha", default=None, metavar="A1,A2,...|design",
                   help="also validate the mix with these weights over --angles, or 'design' "
                   "for the model's best mix for the uniform target")
    p.add_argument("--epoch", type=int, default=1000, metavar="STEPS",
                   help="steps per epoch of the mix (default 1000)")
    p.add_argument("--robots", type=int, default=None, metavar="K",
                   help="kinematic or pybullet: simulate teams of K robots in one room (see "
                   "below; default: independent robots)")
    p.add_argument("--interact", choices=("bump", "off"), default=None,
                   help="with --robots: robot-robot contact is a bump (default) or the robots "
                   "pass through each other")
    p.add_argument("--fast-forward", choices=tuple(FAST_FORWARD), default="on",
                   help="PyBullet: skip the physics steps of steady motion (on, the default: "
                   "free drives and slides along one wall), not the slides' (no-slides), "
                   "also the middle of turns (turns: faster, but it drops the push-off of a "
                   "body spinning at its wall), or simulate every step (off, about 2x "
                   "slower than on; docs/model.md Appendix C)")
    p.add_argument("--speed", type=float, default=0.3, metavar="M/S",
                   help="PyBullet and MuJoCo drive speed [m/s] (default 0.3)")
    add_contact_arg(p, auto=True, what=" of the event model and the twin")
    p.add_argument("--body-turns", default="auto", metavar="auto|off|SPEC",
                   help="auto (default): the model adds the simulated body's own declared "
                   "turn errors at --speed to --eps/--r, and to the event model its errors "
                   "after a bump from rest (docs/model.md section 11b; MuJoCo's at 0.3 m/s: "
                   "gauss:0.45,offset=-1,factor=0.9979, its turns by clock lag 1.00 deg + "
                   "0.21%% of the spin, 0.72 deg less after a bump from rest; at 0.2 "
                   "m/s 0.77 deg; none declared at other speeds); off: the model assumes "
                   "the body turns exactly as --eps/--r say; a spec gauss:S,offset=O: the "
                   "model adds these errors, and on --backend kinematic the twin turns with "
                   "them too (a stand-in for a body whose turns are off: with --contact "
                   "mujoco and MuJoCo's errors it separates the model's error from the "
                   "engine's)")
    p.add_argument("--body-turns-rest", default=None, metavar="SPEC",
                   help="with --body-turns SPEC: the errors after a bump from rest (a flight "
                   "of length zero, docs/model.md section 11b), for the event model and the "
                   "twin (with --body-turns auto the body's own are taken: MuJoCo's "
                   "DECLARED_REST_TURNS)")
    p.add_argument("--seed", type=int, default=0, help="root seed (default 0)")
    p.add_argument("--out", type=Path, default=None, metavar="DIR",
                   help="keep the sweep's journal, runs.csv and config.json here (a re-run "
                   "resumes); default a temporary folder")
    p.add_argument("--json", action="store_true", help="print one JSON object per angle")
    add_executor_args(p)
    p.set_defaults(func=run)


# ----------------------------------------------------------------------------- simulate
def simulate_trial(params: dict, rng: np.random.Generator) -> dict:
    """One batch of robots (a sweep trial, pure in params + rng).

    params: env (name or path), cell_size, orientations, angles and alpha (space-separated),
    eps, r, backend, robots, steps (per robot, counted), burn_in, epoch, speed.
    Returns counted, dropped, bumps, wall_s and counts (space-separated, per position cell).
    """
    env = envs.load(params["env"], cell_size=params["cell_size"],
                    orientations=params["orientations"])
    cs = CellSpace(env)
    mix = PolicyMix(tuple(float(a) for a in params["angles"].split()),
                    tuple(float(a) for a in params["alpha"].split()),
                    float(params["eps"]), float(params["r"]))
    n, steps = int(params["robots"]), int(params["steps"])
    contact = params.get("contact", "off")
    contact = None if contact == "off" else ContactParams.from_text(contact)
    epoch, burn_in = int(params["epoch"]), int(params["burn_in"])
    t0 = time.perf_counter()
    team = params.get("team")
    if team and params["backend"] == "kinematic":
        from ..robots.noise import parse_noise
        from ..runs.team_runs import team_coverage
        noise = parse_noise(f"model:eps={params['eps']},r={params['r']}", cs.delta_deg)
        res = team_coverage(env, mix.angles[0], noise, robots=n, steps=steps,
                            burn_in=burn_in, interact=params["interact"], rng=rng, cells=cs)
        counts, dropped, bumps, meetings = res.counts, res.dropped, res.flights, res.meetings
    elif params["backend"] == "kinematic":
        from ..robots.kinematic import KinematicBatch
        from ..robots.noise import body_noise
        # the twin turns with a body's own errors when the trial names them (--body-turns)
        noise = body_noise(TurnNoise(mix.eps, mix.r).with_body(
            params.get("body_turns"), params.get("body_turns_rest")),
            cs.delta_deg) if params.get("body_turns") else None
        res = KinematicBatch(env, n, rng, cells=cs, contact=contact).run(
            mix, steps, epoch=epoch, burn_in=burn_in, noise=noise)
        counts, dropped, bumps, meetings = res.counts, res.dropped, res.bumps, None
    else:
        if params["backend"] == "mujoco":
            from ..robots.mujoco.batch import MuJoCoBatch as Batch
        else:
            from ..robots.pybullet.batch import PyBulletBatch as Batch
        extra = {"interact": params["interact"]} if team else {}
        if params["backend"] == "pybullet":
            extra["fast_forward"] = fast_forward(params.get("fast_forward", "on"))
        with Batch(env, n, rng, cells=cs, speed=float(params["speed"]), **extra) as batch:
            res = batch.run(mix, steps, epoch=epoch, burn_in=burn_in)
        counts, dropped, bumps = res.pooled, int(res.dropped.sum()), int(res.bumps.sum())
        meetings = int(res.meetings.sum()) if team else None
    return {"counted": int(counts.sum()), "dropped": int(dropped), "bumps": int(bumps),
            "wall_s": round(time.perf_counter() - t0, 3),
            **({} if meetings is None else {"meetings": int(meetings)}),
            "counts": " ".join(str(int(c)) for c in counts)}


# ----------------------------------------------------------------------------- predict
def more_trials(floor: float, steps: int, trial_steps: int, target: float,
                cap: int) -> int:
    """Trials to add to a policy whose floor is ``floor`` after ``steps`` steps.

    0 when ``floor`` ≤ ``target`` or ``steps`` has reached ``cap``. Otherwise the floor of
    independent trials falls as 1/√steps, so the policy needs about steps·(floor/target)²;
    this asks for 10 % more, at least two trials (one per half) and an even number (the
    halves stay equal), and no more than the cap allows.

    >>> more_trials(0.04, 40_000, 10_000, 0.02, 1_000_000)   # 4x the steps, +10 %: 136 000
    14
    >>> more_trials(0.019, 40_000, 10_000, 0.02, 1_000_000)
    0
    >>> more_trials(0.5, 990_000, 10_000, 0.02, 1_000_000)   # the cap: one more trial only
    1
    """
    if floor <= target or steps >= cap:
        return 0
    need = steps * (floor / target) ** 2 * 1.1 - steps
    n = max(2, 2 * math.ceil(need / (2 * trial_steps)))
    return int(min(n, math.ceil((cap - steps) / trial_steps)))


def _label(a: float) -> str:
    return f"{int(round(a))}" if abs(a - round(a)) < 1e-9 else f"{a:g}"


def _parse_alpha(text: str | None, model, angles, noise) -> tuple | None:
    if text is None:
        return None
    if text.strip() == "design":
        return tuple(float(a) for a in design_mix(model, angles, noise).alpha)
    try:
        alpha = [float(t) for t in text.replace(" ", "").split(",") if t]
    except ValueError:
        raise UserError(f"--alpha must be comma-separated weights or 'design', got "
                        f"{text!r}.") from None
    if (len(alpha) != len(angles) or not all(math.isfinite(a) and a >= 0 for a in alpha)
            or sum(alpha) <= 0):
        raise UserError(f"--alpha needs {len(angles)} non-negative weights with a positive "
                        f"sum (one per angle), got {text!r}.")
    s = sum(alpha)
    return tuple(a / s for a in alpha)


# ----------------------------------------------------------------------------- run
def _check(args) -> None:
    if args.steps is not None and args.steps < 2:
        raise UserError(f"--steps must be at least 2, got {args.steps}.")
    if args.floor is None and args.steps is None:
        args.floor = DEFAULT_FLOOR[args.backend]
    if args.floor is not None and not (math.isfinite(args.floor) and 0 < args.floor < 1):
        raise UserError(f"--floor must lie in (0, 1), got {args.floor:g}.")
    if args.max_steps < 2:
        raise UserError(f"--max-steps must be at least 2, got {args.max_steps}.")
    if args.burn_in is None:
        args.burn_in = BURN_IN[args.backend]
    if args.burn_in < 0:
        raise UserError(f"--burn-in must be non-negative, got {args.burn_in}.")
    if args.epoch < 1:
        raise UserError(f"--epoch must be at least one step, got {args.epoch}.")
    if not (math.isfinite(args.speed) and 0 < args.speed <= 0.5):
        raise UserError(f"--speed must lie in (0, 0.5] m/s, got {args.speed:g}.")
    if args.seed < 0:
        raise UserError(f"--seed must be a non-negative integer, got {args.seed}.")
    if args.fast_forward != "on" and args.backend != "pybullet":
        raise UserError("--fast-forward is for --backend pybullet.")
    if args.body_turns_rest is not None and not explicit_body_turns(args):
        raise UserError("--body-turns-rest goes with an explicit --body-turns SPEC.")
    if args.body_turns_rest is not None and not MODELS[args.model].rest_turns:
        raise UserError(f"--body-turns-rest is for the event model: the {args.model} model "
                        f"turns every bump alike.")
    if args.robots is not None and explicit_body_turns(args):
        raise UserError("--body-turns SPEC is for single robots: teams turn as --eps/--r say.")
    if args.robots is None:
        if args.interact is not None:
            raise UserError("--interact is for teams: give --robots K.")
        return
    if args.robots < 1:
        raise UserError(f"--robots must be at least 1, got {args.robots}.")
    if not BACKEND_TEAMS[args.backend] or args.alpha is not None:
        raise UserError("--robots runs teams in the kinematic twin or PyBullet, one angle at a "
                        "time (no --backend mujoco, no --alpha).")
    if args.backend == "kinematic" and args.contact not in (None, "auto", "off"):
        raise UserError("--robots teams of twins use the front-half bumper (--contact off).")
    args.interact = args.interact or "bump"


def explicit_body_turns(args) -> bool:
    """True for an explicit ``--body-turns`` spec (not auto or off): the model takes it, and
    on ``--backend kinematic`` the twin turns with it too.
    """
    return args.body_turns not in ("auto", "off")


def body_turn_errors(backend: str, speed: float = 0.3) -> tuple[str | None, str | None]:
    """The turn errors a simulated body of ``backend`` declares of itself (noise specs,
    docs/model.md §11b): after bumps driven at ``speed`` [m/s], MuJoCo's ``DECLARED_TURNS_AT``
    (0.3 and 0.2 m/s; None at a speed not measured), and after a bump from rest (a flight of
    length zero), its ``DECLARED_REST_TURNS`` (measured with drives at 0.3 m/s, taken at every
    speed: a bump from rest is slow at any). (None, None) for the twin and PyBullet, whose
    turns are exact or nearly (PyBullet: −0.23° ± 0.28°).
    """
    if backend == "mujoco":
        from ..robots.mujoco.robot import DECLARED_REST_TURNS, declared_turns_at
        return declared_turns_at(speed), DECLARED_REST_TURNS
    return None, None


def run(args) -> int:
    """Run ``bouncesim validate``: predict, simulate, compare; print the table; exit status."""
    _check(args)
    env = load_env(args)
    cs = make_cells(args, env)
    noise = TurnNoise(args.eps, args.r)
    angles = check_angles(cs.K, parse_angles(args.angles), noise)
    auto = args.body_turns == "auto"
    declared, declared_rest = body_turn_errors(args.backend, args.speed)
    body_turns = declared if auto else None if args.body_turns == "off" else args.body_turns
    # after a bump from rest: the event model's zero-length flights (§11b, §17)
    rest_turns = (declared_rest if auto and body_turns else
                  None if auto else args.body_turns_rest)
    if not MODELS[args.model].rest_turns:
        rest_turns = None                       # a model that turns every bump alike
    noise = noise.with_body(body_turns, rest_turns)   # the model's: the body's own errors
    # a twin told to turn like a body (an explicit spec on the kinematic backend)
    twin_turns = body_turns if explicit_body_turns(args) and args.backend == "kinematic" else None
    twin_rest = rest_turns if twin_turns else None
    out = writable_path(args.out, folder=True) if args.out is not None else None
    backend = args.backend
    team = args.robots is not None
    total = args.steps if args.steps is not None else (
        TEAM_STEPS if team else DEFAULT_STEPS[backend])
    robots = args.robots if team else ROBOTS[backend]
    per_robot_trial = TEAM_PER_ROBOT if team else PER_ROBOT[backend]
    # two halves, each of at least one batch: an even number of trials per policy
    trials_per = max(2, 2 * math.ceil(total / (2 * robots * per_robot_trial)))
    per_robot = max(1, math.ceil(total / (trials_per * robots)))
    if backend == "pybullet":
        from ..robots.pybullet.robot import import_pybullet
        import_pybullet()                      # one sentence when pybullet is missing
    if backend == "mujoco":
        from ..robots.mujoco.robot import import_mujoco
        import_mujoco()                        # one sentence when mujoco is missing
    t0 = time.perf_counter()
    contact = contact_rule(args)
    contact_text = "off" if contact is None else contact.text

    def trial(lab, angs, al, j) -> dict:
        return {"policy": lab, "half": j % 2, "env": args.env, "cell_size": args.cell_size,
                "orientations": cs.K, "angles": " ".join(repr(float(a)) for a in angs),
                "alpha": " ".join(repr(float(a)) for a in al), "eps": float(args.eps),
                "r": float(args.r), "backend": backend, "robots": robots,
                "steps": per_robot, "burn_in": args.burn_in, "epoch": args.epoch,
                "speed": float(args.speed), "contact": contact_text,
                **({"team": robots, "interact": args.interact} if team else {}),
                **({"body_turns": twin_turns} if twin_turns else {}),
                **({"fast_forward": args.fast_forward} if args.fast_forward != "on" else {}),
                **({"body_turns_rest": twin_rest} if twin_rest else {})}

    # the sweep's identity: what decides the trials and their meaning, never a timing (a
    # second run, or one after Ctrl-C, resumes the same sweep)
    record = {"subcommand": "validate", "model": args.model}
    designed = args.alpha is not None and args.alpha.strip() == "design"
    alpha = None if designed else _parse_alpha(args.alpha, None, angles, noise)

    def policy_list(alpha) -> list:
        return [(_label(a), (a,), (1.0,)) for a in angles] + (
            [] if alpha is None else [("mix", tuple(angles), alpha)])

    def round_trials(policies, done, todo) -> list:
        """Each policy's trials done[lab] … done[lab] + todo[lab] − 1."""
        return [trial(lab, angs, al, done[lab] + j) for lab, angs, al in policies
                for j in range(todo[lab])]

    def check_out(alpha) -> None:
        """Refuse a folder that holds another sweep before the prediction's work."""
        if out is not None:
            pols = policy_list(alpha)
            Sweep(simulate_trial, round_trials(pols, {p[0]: 0 for p in pols},
                                               {p[0]: trials_per for p in pols}),
                  args.seed, out, {**record, "round": 0}).check_folder()

    if not designed:
        check_out(alpha)
    model = model_for(cs, args.model, None if contact is None else {"contact": contact})
    per = [model.analyse(a, noise) for a in angles]
    if designed:                                 # α is the model's: checked once designed
        alpha = _parse_alpha(args.alpha, model, angles, noise)
        check_out(alpha)
    policies = policy_list(alpha)
    q = {lab: ac.q for (lab, _, _), ac in zip(policies, per)}
    bumps_model = {lab: model.bump_rate(ac) for (lab, _, _), ac in zip(policies, per)}
    if alpha is not None:
        mix = PolicyMix(tuple(angles), alpha, args.eps, args.r)
        q["mix"] = timeshared_coverage(model, mix, epoch=args.epoch, noise=noise).q
        bumps_model["mix"] = float(sum(a * bumps_model[_label(x)]
                                       for x, a in zip(angles, alpha)))
    run_q = protocol_prediction(model, policies, noise, args.burn_in, per_robot, args.epoch)
    predict_s = time.perf_counter() - t0
    progress = not args.no_progress and sys.stderr.isatty()
    trial_steps = robots * per_robot
    cap = max(args.max_steps, trials_per * trial_steps)
    todo = {lab: trials_per for lab, _, _ in policies}      # trials to add, per policy
    done = {lab: 0 for lab, _, _ in policies}
    tables, stats = [], {}
    with tempfile.TemporaryDirectory() as tmp:
        base = out or Path(tmp)
        for rnd in itertools.count():
            trials = round_trials(policies, done, todo)
            if not trials:
                break
            # round 0 is the fixed-steps sweep (its seed and folder); later rounds have their
            # own folder and a root seed drawn from (seed, round): new, independent trials
            seed = args.seed if rnd == 0 else int(
                np.random.SeedSequence([args.seed, rnd]).generate_state(1, np.uint64)[0] >> 1)
            tables.append(run_sweep(simulate_trial, trials, seed,
                                    base if rnd == 0 else base / f"round{rnd}",
                                    {**record, "round": rnd}, make_executor(args),
                                    progress=progress, name="runs",
                                    provenance=cli_provenance(args, env)))
            for lab in done:
                done[lab] += todo[lab]
            table = pd.concat(tables, ignore_index=True)
            for lab, _, _ in policies:
                sub = table[table.policy == lab]
                counts = np.array([np.array(c.split(), dtype=float) for c in sub.counts])
                # "half" alternates along each policy's trials over all rounds
                fl = floors(counts, sub.half.to_numpy(), np.random.default_rng([args.seed, 7]))
                stats[lab] = (sub, counts, fl)
                steps = int(sub.counted.sum() + sub.dropped.sum())
                todo[lab] = (0 if args.floor is None else
                             more_trials(max(fl), steps, trial_steps, args.floor, cap))
    rows = []
    for lab, angs, al in policies:
        sub, counts, (floor, floor_splits) = stats[lab]
        pooled = counts.sum(axis=0)
        steps = int(sub.counted.sum() + sub.dropped.sum())
        if args.floor is not None and max(floor, floor_splits) > args.floor:
            print(f"validate: {lab}: floor {max(floor, floor_splits):.4f} > {args.floor:g} "
                  f"at the cap of {steps} steps (--max-steps).", file=sys.stderr)
        short, noise_floor = float(tv_distance(run_q[lab], q[lab])), max(floor, floor_splits)
        if short > noise_floor:
            print(f"validate: {_label_text(lab)}: the runs ({args.burn_in} steps of burn-in, "
                  f"then {per_robot}) are too short for the limit: the model's prediction of "
                  f"them is TV {short:.4f} from it, above the floor {noise_floor:.4f}; "
                  f"compare tv_runs.", file=sys.stderr)
        rows.append({"angle": lab if lab == "mix" else float(angs[0]),
                     "tv": float(tv_distance(q[lab], pooled)),
                     "tv_runs": float(tv_distance(run_q[lab], pooled)),
                     "runs_to_limit": short,
                     "floor": floor, "floor_splits": floor_splits,
                     "steps": steps, "trials": len(sub), "dropped": int(sub.dropped.sum()),
                     "bumps_per_step_model": bumps_model[lab],
                     "bumps_per_step_sim": float(sub.bumps.sum()) / steps if steps else math.nan,
                     "model": args.model, "backend": backend, "env": env.name,
                     "predict_s": round(predict_s, 3),
                     "contact": contact_name(contact), "body_turns": body_turns,
                     "body_turns_rest": rest_turns,
                     **({"robots": robots, "interact": args.interact,
                         "meetings_per_1000_steps": 1000 * float(sub.meetings.sum()) / steps}
                        if team else {}),
                     **({"alpha": list(al)} if lab == "mix" else {})})
    if out is not None:
        pd.DataFrame(rows).to_csv(out / "validation.csv", index=False)
        (out / "validation.json").write_text(json.dumps(rows, indent=2) + "\n")
    if args.json:
        for r in rows:
            print_json(r)
    else:
        _print_table(rows, env, backend, cs, args)
    if out is not None:
        report_written(sorted(p for p in out.rglob("*") if p.is_file()), args)
    return 0


def _label_text(lab: str) -> str:
    return lab if lab == "mix" else f"{lab}°"


def protocol_prediction(model, policies, noise, burn_in: int, steps: int,
                        epoch: int) -> dict:
    """What the simulated runs measure, predicted by the model (docs/model.md §20): per
    policy (label, angles, α), the expected share of counted steps in each cell over steps
    ``burn_in`` … ``burn_in + steps`` − 1 of a run from the uniform start over the
    configurations (the batches' start), a mix in epochs of ``epoch`` steps from step 0.
    Equal to the limit q once ``burn_in`` is long enough for the chain to forget its start.
    """
    from planners.coverage import horizon_of
    hz, out = horizon_of(model), {}
    ends = sorted({int(burn_in), int(burn_in) + int(steps)} - {0})
    for lab, angs, al in policies:
        mix = len(angs) > 1
        got = {T: c for T, c, _ in hz.run(angs, ends, noise=noise,
                                          alpha=al if mix else None,
                                          epoch=epoch if mix else None)}
        window = got[ends[-1]] - (got[ends[0]] if burn_in > 0 else 0.0)
        out[lab] = window / window.sum()
    return out


def _print_table(rows, env, backend, cs, args) -> None:
    print(f"{env.name}: {args.model} model against {backend} (K = {cs.K}, eps {args.eps:g}, "
          f"r {args.r:g}, seed {args.seed})")
    team = "robots" in rows[0]
    if team:
        print(f"teams of {rows[0]['robots']} robots, interact {rows[0]['interact']}; the "
              "prediction is one robot's")
    print(f"{'angle':>6} {'tv':>7} {'tv_runs':>8} {'floor':>7} {'steps':>10} "
          f"{'bumps/step model':>17} {'sim':>6}" + (f" {'meetings/1000':>14}" if team else ""))
    for r in rows:
        a = r["angle"] if r["angle"] == "mix" else _label(r["angle"])
        print(f"{a:>6} {r['tv']:7.4f} {r['tv_runs']:8.4f} {r['floor']:7.4f} {r['steps']:10d} "
              f"{r['bumps_per_step_model']:17.3f} {r['bumps_per_step_sim']:6.3f}"
              + (f" {r['meetings_per_1000_steps']:14.1f}" if team else ""))

