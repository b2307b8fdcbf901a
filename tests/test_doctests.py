"""The docstring examples are runnable: run them."""

from __future__ import annotations

import doctest
import importlib

import pytest

MODULES = ["envs", "envs.environment", "planners.cells", "planners.plan", "planners.roadmap",
           "planners.coverage", "planners.coverage.noise", "planners.coverage.step",
           "planners.navigation", "bouncesim.commands.plan", "bouncesim.robots.pybullet.walls",
           "bouncesim.robots", "bouncesim.robots.factory", "bouncesim.robots.conformance",
           "bouncesim.robots.create2.faults",
           "bouncesim.runs.options", "bouncesim.runs.execute",
           "bouncesim.runs.sweep", "envs.motion", "planners.coverage.event",
           "planners.coverage.api", "planners.coverage.mix", "planners.metrics",
           "bouncesim.robots.noise"]


@pytest.mark.parametrize("name", MODULES)
def test_doctests(name):
    mod = importlib.import_module(name)
    result = doctest.testmod(mod, optionflags=doctest.ELLIPSIS)
    assert result.attempted > 0, f"{name} has no examples"
    assert result.failed == 0
