"""CI regression: predicted coverage, α, plans and predicted-vs-simulated TV against golden
files (tests/golden/*.json; regenerate with ``python -m tests.regression --write`` after
reviewing why they moved).

Bounds:
- q and α: 1e-9 absolute for the step model (exact sparse linear algebra), 1e-6 for the
  event model (its power iteration stops at an L1 error below 1e-6).
- plans: identical strings and costs; zero-noise execution outcome identical.
- TV: within ``TV_SLACK`` (1.5) noise floors of the stored TV, either way (why the floor is
  the right unit: tests/regression.py). The floor is the largest TV between four independent
  seeds at the same step count, measured when the file was written; the numbers are in
  tests/golden/tv.json (twin, lab at K = 72, 10^5 steps; PyBullet, lab at K = 72, 75°,
  24 000 steps of validate's PyBulletBatch against the event model with PyBullet's contact
  rule, as ``bouncesim validate --backend pybullet`` compares).
"""

from __future__ import annotations

import numpy as np
import pytest

from . import regression as reg


@pytest.fixture(scope="module")
def coverage_now():
    return reg.compute_coverage()


@pytest.mark.parametrize("name", [s[0] for s in reg.COVERAGE_SETTINGS])
def test_coverage_matches_golden(name, coverage_now):
    gold, now = reg.load("coverage")[name], coverage_now[name]
    assert set(gold["q"]) == set(now["q"])
    atol = reg.ATOL[gold["model"]]
    for angle, q in gold["q"].items():
        np.testing.assert_allclose(now["q"][angle], q, rtol=0, atol=atol,
                                   err_msg=f"{name}: q of {angle}° drifted")
    np.testing.assert_allclose(now["alpha"], gold["alpha"], rtol=0, atol=atol,
                               err_msg=f"{name}: α drifted")
    np.testing.assert_allclose(now["mix_epochs"], gold["mix_epochs"], rtol=0,
                               atol=reg.ATOL["timeshared"],
                               err_msg=f"{name}: the time-shared mix drifted")
    if "alpha_configurations" in gold:
        np.testing.assert_allclose(now["alpha_configurations"], gold["alpha_configurations"],
                                   rtol=0, atol=atol)


def test_plans_match_golden():
    gold = reg.load("plans")
    now = reg.compute_plans(pybullet=False)
    assert len(now) == len(gold)
    for g, n in zip(gold, now):
        where = f"{g['env']} {g['start']} -> {g['goal']}"
        assert n["plan"] == g["plan"], f"{where}: the plan changed"
        assert n["cost"] == g["cost"], f"{where}: the cost changed"
        assert n.get("twin_success") == g.get("twin_success"), \
            f"{where}: zero-noise twin outcome changed"


@pytest.mark.physics
def test_fig3_plans_succeed_in_pybullet_as_pinned():
    pytest.importorskip("pybullet")
    import envs
    from planners.cells import CellSpace
    from planners.navigation import Navigator
    gold = [g for g in reg.load("plans") if "pybullet_success" in g]
    assert len(gold) == reg.PYBULLET_PLANS
    for g in gold:
        env = envs.load(g["env"])
        cells = CellSpace(env)
        route = Navigator(cells, g["angles"]).plan(g["start"], g["goal"])
        assert reg._execute(env, cells, route, "pybullet") == g["pybullet_success"]


def _check_tv(gold: dict, now: dict, where: str) -> None:
    for angle, g in gold.items():
        slack = reg.TV_SLACK * g["noise_floor"]
        assert abs(now[angle]["tv"] - g["tv"]) <= slack, (
            f"{where} {angle}°: TV(predicted, simulated) = {now[angle]['tv']:.4f}, golden "
            f"{g['tv']:.4f} ± {slack:.4f} ({reg.TV_SLACK:g} noise floors)")


def test_twin_tv_within_noise_floor_of_golden():
    gold = reg.load("tv")
    now = reg.compute_tv(pybullet=False, floors=False)
    assert set(gold["twin"]) == {f"{a:g}" for a in reg.TV_SETTING["angles"]}
    _check_tv(gold["twin"], now["twin"], "twin (step model)")
    _check_tv(gold["twin_event"], now["twin_event"], "twin (event model)")
    # and the event model's own promise (docs/model_continuous.md): TV ≤ 0.05 up to noise
    for angle, g in now["twin_event"].items():
        assert g["tv"] <= 0.05 + gold["twin_event"][angle]["noise_floor"], angle


@pytest.mark.slow
@pytest.mark.physics
def test_pybullet_tv_within_noise_floor_of_golden():
    pytest.importorskip("pybullet")
    gold = reg.load("tv")
    now = reg.compute_tv(pybullet=True, floors=False, twin=False)
    assert set(now["pybullet"]) == {f"{reg.TV_SETTING['pybullet_angle']:g}"}
    _check_tv(gold["pybullet"], now["pybullet"], "pybullet (event model, contact rule)")


def test_pybullet_setting_is_what_validate_compares():
    """The regression's PyBullet contact rule is the one ``validate --backend pybullet``
    gives the event model by default (--contact auto), and its stored setting is current.
    """
    import argparse

    from bouncesim.commands.common import contact_rule
    rule = contact_rule(argparse.Namespace(contact="auto", backend="pybullet", model="event"))
    s = reg.TV_SETTING
    assert s["pybullet_model"] == "event"
    assert tuple(s["pybullet_contact"]) == (rule.beta_deg, rule.slide_friction)
    stored = reg.load("tv")["setting"]
    assert {k: v for k, v in stored.items() if k.startswith("pybullet")} == {
        k: (list(v) if isinstance(v, tuple) else v) for k, v in s.items()
        if k.startswith("pybullet")}


def test_golden_bounds_are_informative():
    """The allowed band must leave room to fail on both sides (TV lies in [0, 1])."""
    gold = reg.load("tv")
    for angle, g in gold["twin"].items():
        slack = reg.TV_SLACK * g["noise_floor"]
        assert 0 < slack < min(g["tv"], 1 - g["tv"]), ("twin", angle)
    # the event model (against PyBullet: with PyBullet's contact rule) sits near the floor:
    # only the upward side can fail, and must be tight
    for backend in ("twin_event", "pybullet"):
        for angle, g in gold[backend].items():
            assert 0 < g["noise_floor"], (backend, angle)
            assert g["tv"] + reg.TV_SLACK * g["noise_floor"] < 0.15, (backend, angle)
