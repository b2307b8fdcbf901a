"""experiments.body_turns on the kinematic twin, whose turns and bumps are exact by
construction (docs/model.md §21): every error is zero to round-off, and the table has a row
per angle plus the pooled one.
"""

from __future__ import annotations

import numpy as np

import envs
from experiments.body_turns import ANGLES, measure, table


def test_the_twin_turns_exactly_and_keeps_its_heading_at_bumps():
    runs = measure("kinematic", envs.load("lab"), 12, np.random.default_rng(3))
    assert len(runs) == 12
    assert np.abs(runs.turn_error_deg).max() < 1e-6
    assert np.abs(runs.flight_rotation_deg).max() < 1e-6
    t = table(runs)
    assert set(t.angle) <= set(ANGLES) | {"all"} and "all" in set(t.angle)
    assert int(t[t.angle == "all"].trials.iloc[0]) == 12
