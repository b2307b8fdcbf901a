"""The docstring examples are runnable: run them."""

from __future__ import annotations

import doctest
import importlib

import pytest

MODULES = ["envs", "envs.environment", "planners.cells", "planners.plan", "planners.roadmap",
           "planners.coverage",
           "planners.navigation", "bouncesim.commands.plan", "bouncesim.pybullet_world",
           "bouncesim.sweep", "envs.raycast", "planners.event_model",
           "planners.coverage_models", "planners.resources"]


@pytest.mark.parametrize("name", MODULES)
def test_doctests(name):
    mod = importlib.import_module(name)
    result = doctest.testmod(mod, optionflags=doctest.ELLIPSIS)
    assert result.attempted > 0, f"{name} has no examples"
    assert result.failed == 0
