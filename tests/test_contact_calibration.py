"""The contact calibration (experiments/contact_calibration.py) and its fitted defaults.

Independent evidence: geometry (a disk meeting a wall at incidence α touches it at bearing
α − 90°; a bumper arc of ±80° therefore misses contacts below 10°), a frictionless wall (the
along-wall speed of a slide is v cos α) and hand-made trial tables for the fit.
"""

from __future__ import annotations

import importlib.util
import math

import pandas as pd
import pytest

from envs.motion import PYBULLET_CONTACT, ContactParams
from experiments.contact_calibration import fit, trial, wall_room


def test_fit_on_a_hand_made_table():
    """β interpolates the bump rate's 1/2 crossing; μ solves k = cos α − μ sin α."""
    a = [5.0, 5.0, 8.0, 8.0, 12.0]
    mu = 0.1
    k = [math.cos(math.radians(x)) - mu * math.sin(math.radians(x)) for x in a]
    t = pd.DataFrame({"incidence_deg": a, "bump": [0, 0, 0, 1, 1], "contact": [1] * 5,
                      "speed_factor": k, "heading_change_deg": [0.0] * 5,
                      "slide_m": [1.0] * 5})
    f = fit(t)
    assert f["beta_deg"] == pytest.approx(8.0)        # rate 0.5 at 8°
    assert f["slide_friction"] == pytest.approx(mu)


def test_defaults_are_the_pybullet_geometry():
    """The fitted β lies within 0.5° of the geometric 90° − 80° arc, the slide is nearly
    frictionless; the dataclass is frozen data.
    """
    assert isinstance(PYBULLET_CONTACT, ContactParams)
    assert abs(PYBULLET_CONTACT.beta_deg - 10.0) <= 0.5
    assert 0 <= PYBULLET_CONTACT.slide_friction <= 0.05
    with pytest.raises(AttributeError):
        PYBULLET_CONTACT.beta_deg = 1.0


@pytest.mark.physics
@pytest.mark.skipif(importlib.util.find_spec("pybullet") is None, reason="needs pybullet")
def test_trials_slide_below_and_bump_above_beta():
    """At 5° the robot slides at v cos 5° without bumping; at 20° it bumps with the contact
    at a bearing of 20° − 90° (within 1°) and no slide.
    """
    from bouncesim.robots.pybullet import PyBulletRobot
    with PyBulletRobot(wall_room()) as bot:
        slide = trial(bot, 5.0, 0.002, 0.3, 0.5)
        bump = trial(bot, 20.0, 0.002, 0.3, 0.5)
    assert slide["contact"] == 1 and slide["bump"] == 0
    assert slide["bearing_deg"] == pytest.approx(5.0 - 90.0, abs=1.0)
    assert slide["speed_factor"] == pytest.approx(math.cos(math.radians(5.0)), abs=0.003)
    assert abs(slide["heading_change_deg"]) <= 0.5
    assert bump["bump"] == 1 and bump["slide_m"] <= 0.005
    assert bump["bearing_deg"] == pytest.approx(20.0 - 90.0, abs=1.0)


@pytest.mark.physics
@pytest.mark.skipif(importlib.util.find_spec("pybullet") is None, reason="needs pybullet")
def test_quick_run_writes_outputs_and_agrees_with_the_defaults(tmp_path):
    """The --quick run writes trials.csv, fit.csv, config.json (with the fit and the defaults
    in code) and contact.png; its β is within 1.5° of the stored default (the quick grid
    brackets β by 9, 9.75, 10.25 and 11°, and a trial within about a degree of β can flip
    between bump and slide with PyBullet's process state: this run gave 9.6° alone and
    10.6° after other PyBullet tests in the same process), its μ within 0.01.
    """
    import json

    from experiments import contact_calibration as cc
    out = tmp_path / "cc"
    assert cc.main(["--quick", "--out", str(out)]) == 0
    for name in ("trials.csv", "fit.csv", "config.json", "contact.png"):
        assert (out / name).exists()
    cfg = json.loads((out / "config.json").read_text())
    assert cfg["defaults_in_code"] == {"beta_deg": PYBULLET_CONTACT.beta_deg,
                                       "slide_friction": PYBULLET_CONTACT.slide_friction,
                                       "turn_in": []}
    assert abs(cfg["fit"]["beta_deg"] - PYBULLET_CONTACT.beta_deg) <= 1.5
    assert abs(cfg["fit"]["slide_friction"] - PYBULLET_CONTACT.slide_friction) <= 0.01
    trials = pd.read_csv(out / "trials.csv")
    assert len(trials) == 2 * len(cc.QUICK_INCIDENCES)
