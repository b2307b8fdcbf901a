"""steps_to_limit beyond the exact pass: the slow-mode extrapolation (docs/model.md §20) against
the exact answer of a pass that runs all the way, on maps the extrapolation was not tuned on.
"""

from __future__ import annotations

import numpy as np
import pytest

from experiments.coverage_horizon import two_room
from planners.cells import CellSpace
from planners.coverage import Horizon, TurnNoise, model_for, steps_to_limit, steps_to_limit_each
from planners.coverage.horizon import grid
from planners.coverage.to_limit import first_within, slow_mode

NOISE = TurnNoise(22.5, 0.8)
TWO_GRID_STEPS = 2 ** (2 / 8)


def _close(estimate, exact) -> bool:
    """Within two points of the 2^(1/8) grid."""
    return estimate is not None and 1 / TWO_GRID_STEPS <= estimate / exact <= TWO_GRID_STEPS


def _cases():
    """Slowly mixing (policy, map) pairs: two rooms joined by a door, step and event models."""
    for door, model_name, angles in ((0.34, "step", (67.5, 135.0, 157.5)),
                                     (0.68, "step", (67.5, 135.0)),
                                     (0.34, "event", (157.5,))):
        model = model_for(CellSpace(two_room(door, 16)), model_name)
        for angle in angles:
            yield f"two rooms, {door} m door, {model_name} model, {angle}°", model, angle


@pytest.mark.slow
def test_an_eighth_of_the_run_extrapolates_to_the_exact_answer():
    # the pass cut at an eighth of the exact steps_to_limit (by its cap) extrapolates from its
    # slow mode to within two grid points of what the full pass finds
    checked = []
    for name, model, angle in _cases():
        lim = model.analyse(angle, NOISE).q
        exact = steps_to_limit(Horizon(model), [angle], lim, noise=NOISE, cap=400_000)
        assert exact["method"] == "exact" and exact["estimate"] == exact["steps"], name
        if exact["steps"] < 1600:                      # too fast to cut: nothing to extrapolate
            continue
        cut = steps_to_limit(Horizon(model), [angle], lim, noise=NOISE,
                             cap=exact["steps"] // 8)
        assert cut["steps"] is None and cut["method"] == "extrapolated", name
        assert _close(cut["estimate"], exact["steps"]), (name, cut["estimate"], exact["steps"])
        assert cut["relaxation_steps"] > 0
        checked.append(name)
    assert len(checked) >= 5, checked


def test_a_mix_is_extrapolated_from_its_angles_slow_modes():
    model = model_for(CellSpace(two_room(0.34, 16)), "step")
    angles, alpha = (135.0, 112.5), np.array([0.4, 0.6])
    lims = [model.analyse(a, NOISE).q for a in angles]
    mix_lim = np.column_stack(lims) @ alpha
    exact = steps_to_limit(Horizon(model), angles, mix_lim, noise=NOISE, alpha=alpha,
                           cap=400_000)
    assert exact["steps"] is not None and exact["steps"] >= 1600
    each, mix = steps_to_limit_each(Horizon(model), angles, lims, noise=NOISE, alpha=alpha,
                                    mix_limit=mix_lim, cap=exact["steps"] // 8)
    assert mix["method"] == "extrapolated"
    assert _close(mix["estimate"], exact["steps"]), (mix["estimate"], exact["steps"])
    # the angles' own answers are exact or extrapolated, never a bare bound here
    assert {r["method"] for r in each} <= {"exact", "extrapolated"}


def test_the_bound_is_all_that_is_said_when_no_mode_decays():
    # the share of each step drifts away from the limit (λ > 1): no estimate, only "> last"
    q = np.array([0.5, 0.5])
    history = [(T, T * q + np.array([1.0, -1.0]) * 1e-3 * T ** 2) for T in grid(400)]
    assert slow_mode(history, q) is None
    # two modes that swap which cell they favour: the directions differ, no single mode
    u1, u2 = np.array([0.3, -0.3, 0.0]), np.array([0.0, -0.3, 0.3])
    q3 = np.full(3, 1 / 3)

    def counts(T):
        return T * q3 + u1 * (1 - 0.98 ** T) / 0.02 + u2 * 0.5 * (1.02 ** T - 1) / 0.02 * 1e-9

    hist3 = [(T, counts(T)) for T in grid(1000)]
    assert slow_mode(hist3, q3) is None
    # too short a run: fewer than three segments in its second half
    assert slow_mode([(100, 100 * q), (109, 109 * q)], q) is None


def test_one_decaying_mode_is_extrapolated():
    # counts of a chain whose share in each cell is q + u·λ^t exactly: the fit recovers λ and
    # the first grid T within a tenth of the first step's TV is found, for several λ
    rng, checked = np.random.default_rng(3), []
    for lam in (0.99, 0.999, 0.9999):
        q = rng.dirichlet(np.ones(5))
        u = rng.normal(size=5)
        u -= u.mean()
        u *= 0.8 * q.min() / np.abs(u).max()

        def counts(T, u=u, q=q, lam=lam):
            return T * q + u * (1 - lam ** T) / (1 - lam)

        tol = 0.1 * 0.5 * np.abs(u).sum()              # a tenth of the first step's TV
        exact = next(T for T in grid(10 ** 9)
                     if 0.5 * np.abs(counts(T) / counts(T).sum() - q).sum() <= tol)
        sm = slow_mode([(T, counts(T)) for T in grid(max(400, exact // 16))], q)
        assert sm is not None and abs(sm.relaxation * (1 - lam) - 1) < 0.01, lam
        if exact > sm.T:
            assert _close(first_within(sm.counts_at, q, tol, after=sm.T), exact), lam
            checked.append(lam)
    assert len(checked) == 3


def test_every_coverage_run_reports_steps_to_limit(tmp_path, capsys):
    # no --horizon: alpha.json and the table still carry each policy's steps_to_limit, exact
    # or extrapolated once stable, and the answers are steps_to_limit's own with settle
    import json

    from bouncesim.cli import main
    env_file = tmp_path / "two_room.json"
    env_file.write_text(json.dumps(two_room(0.34, 16).to_dict()))
    out = tmp_path / "o"
    rc = main(["coverage", str(env_file), "--angles", "67.5,135", "--eps", "22.5", "--r",
               "0.8", "--limit-cap", "3000", "--out", str(out), "--no-plots"])
    assert rc == 0
    table = capsys.readouterr().out
    assert "steps to the limit (TV <= 0.05, from the uniform start):" in table
    assert "steps_to_limit = about" in table and "(extrapolated from" in table
    stl = json.loads((out / "alpha.json").read_text())["steps_to_limit"]
    assert stl["tol"] == 0.05 and [r["angle"] for r in stl["per_angle"]] == [67.5, 135]
    model = model_for(CellSpace(two_room(0.34, 16)), "step")
    for r in stl["per_angle"]:
        ref = steps_to_limit(Horizon(model), [r["angle"]], model.analyse(r["angle"], NOISE).q,
                             noise=NOISE, cap=3000, settle=True)
        assert r["method"] == ref["method"] == "extrapolated"
        assert (r["estimate"], r["last"]) == (ref["estimate"], ref["last"])
    assert stl["mix"]["method"] in ("exact", "extrapolated")


@pytest.mark.slow
def test_settling_on_a_stable_extrapolation_stays_within_two_grid_points():
    # settle=True ends the pass once two doublings of T in a row extrapolate to the same grid
    # point: much shorter passes, answers within two grid points of the exact ones
    for name, model, angle in _cases():
        lim = model.analyse(angle, NOISE).q
        exact = steps_to_limit(Horizon(model), [angle], lim, noise=NOISE, cap=400_000)
        fast = steps_to_limit(Horizon(model), [angle], lim, noise=NOISE, cap=400_000,
                              settle=True)
        if fast["method"] == "exact":
            assert fast["steps"] == exact["steps"], name
            continue
        assert fast["method"] == "extrapolated" and fast["last"] < exact["steps"], name
        assert _close(fast["estimate"], exact["steps"]), (name, fast, exact["steps"])
